//! A fit never says "converged" over a failure (issue 22, items 1–3): a fit whose every evaluation
//! was penalised is an error with the reasons and what to change (`tissuefit fit`, the pipeline's fit
//! stage); a fitted parameter that cannot change the model is refused before the fit starts.
//!
//! Kept cheap: the demo doublet meshed at 60 nodes per cell, relaxations of one step (which never
//! converge, so every evaluation is penalised), two evaluations.

use crate::support::cli::{repo, tissuefit};
use std::path::{Path, PathBuf};
use tissuefit::inference::{FitConfig, FitOptions, InferenceError, run_fit};

/// The fit part shared by the fit config and the pipeline (`prefix` "" or "fit."): the demo's
/// truth as the model (with `numerics` TOML lines under `model_overrides.numerics`), γ_lateral
/// fitted, relaxations of one step that never converge.
fn fit_body(prefix: &str, numerics: &str) -> String {
    let model = repo().join("data/demo/doublet_truth.toml");
    format!(
        r#"
{prefix}model = {model:?}
[{prefix}model_overrides.numerics]
{numerics}
[{prefix}parameters.surface_tension]
value = 1e-3
[{prefix}parameters.surface_tension_lateral]
bounds = [2e-4, 1e-3]
[{prefix}optimizer]
max_evaluations = 2
[{prefix}forward]
max_steps = 1
accept_residual = 0.0
volume_passes = 0
measure_like_data = false
"#,
        model = model.display().to_string()
    )
}

fn write_fit_config(dir: &Path, numerics: &str) -> PathBuf {
    let labels = repo().join("data/demo/doublet.tif");
    let text = format!(
        "{}[observed]\nlabels = {:?}\n[observed.meshing]\ntarget_nodes = 60\n",
        fit_body("", numerics),
        labels.display().to_string()
    );
    let path = dir.join("fit.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_fit_whose_every_evaluation_fails_exits_non_zero_with_the_reasons_and_never_says_converged() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_fit_config(dir.path(), "");
    let out = dir.path().join("out");
    let o = tissuefit(&["--threads", "2", "fit", "--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_ne!(o.status.code(), Some(0), "{stderr}");
    assert_ne!(o.status.code(), Some(1), "an error, not a finished fit whose check failed: {stderr}");
    assert!(!stderr.contains("(converged)"), "{stderr}");
    assert!(stderr.contains("the fit failed") && stderr.contains("none of the 2 evaluations was usable"), "{stderr}");
    // The reasons, summarised (two unconverged runs, one kind), and the remedy naming the keys.
    assert!(stderr.contains("2 × unconverged (not converged within 1 steps"), "{stderr}");
    assert!(stderr.contains("forward.max_steps (now 1)") && stderr.contains("forward.accept_residual"), "{stderr}");
    assert!(stderr.contains("trace.csv") && stderr.contains("no result.json"), "{stderr}");
    assert!(!out.join("result.json").exists(), "no result for a fit that has none");
    let trace = std::fs::read_to_string(out.join("trace.csv")).unwrap();
    assert_eq!(trace.lines().count(), 3, "header and the two evaluations:\n{trace}");
    // stderr is not a terminal here (as in `2>log` or a cluster job): one progress line per
    // evaluation, with how it ended (issue 22, item 5).
    let lines: Vec<&str> = stderr.lines().filter(|l| l.starts_with("fit: evaluation ")).collect();
    assert_eq!(lines.len(), 2, "{stderr}");
    assert!(lines[0].starts_with("fit: evaluation 1/2, unconverged (not converged within 1 steps"), "{stderr}");
    assert!(lines[1].starts_with("fit: evaluation 2/2, ") && lines[1].contains("best objective"), "{stderr}");

    // The library says the same with its own error kind.
    let config = FitConfig::load(&config).unwrap();
    let e = run_fit(&config, &dir.path().join("lib"), &FitOptions::default()).unwrap_err();
    assert!(matches!(e, InferenceError::Failed(_)), "{e}");
}

/// A log hears from inside a long evaluation too (issue 22, item 5: an evaluation of minutes left a
/// cluster log empty): with lines due at once (`TISSUEFIT_PROGRESS_SECONDS=0`), the relaxation
/// writes where it is, at which point; with the default 30 s this fast fit writes none.
#[test]
fn a_log_shows_a_running_evaluation_with_its_point_step_and_residual() {
    let dir = tempfile::tempdir().unwrap();
    let config = write_fit_config(dir.path(), "");
    let text = std::fs::read_to_string(&config).unwrap().replace("max_steps = 1\n", "max_steps = 600\n");
    std::fs::write(&config, text).unwrap();
    let out = dir.path().join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .args(["--threads", "2", "fit", "--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .env("TISSUEFIT_PROGRESS_SECONDS", "0")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    let beats: Vec<&str> = stderr.lines().filter(|l| l.starts_with("fit: evaluation at ")).collect();
    // Two evaluations of up to 600 steps, a line every 256 steps.
    assert!(beats.len() >= 2, "{stderr}");
    let re_line = beats.iter().find(|l| l.contains("step 256 ")).unwrap_or_else(|| panic!("{stderr}"));
    assert!(re_line.starts_with("fit: evaluation at surface_tension_lateral = "), "{re_line}");
    assert!(re_line.contains("running: step 256 of at most 600 per pass, residual "), "{re_line}");
    assert!(re_line.ends_with(" s"), "{re_line}");
    assert!(!re_line.contains("surface_tension ="), "the fixed parameter is not named: {re_line}");

    let o =
        tissuefit(&["fit", "--config", config.to_str().unwrap(), "--out", dir.path().join("quiet").to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!stderr.contains("fit: evaluation at "), "no line before 30 s: {stderr}");
    assert!(stderr.contains("fit: evaluation 1/2"), "{stderr}");
}

#[test]
fn a_pipeline_fit_stage_whose_every_evaluation_fails_is_marked_failed() {
    let dir = tempfile::tempdir().unwrap();
    let labels = repo().join("data/demo/doublet.tif");
    let text = format!(
        "{}[input]\nlabels = {:?}\n[mesh]\ntarget_nodes = 60\n",
        fit_body("fit.", ""),
        labels.display().to_string()
    );
    let pipeline = dir.path().join("pipeline.toml");
    std::fs::write(&pipeline, text).unwrap();
    let run = dir.path().join("run");
    let o = tissuefit(&["--threads", "2", "run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_ne!(o.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("none of the 2 evaluations was usable"), "{stderr}");
    assert!(!stderr.contains("(converged)"), "{stderr}");
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("manifest.json")).unwrap()).unwrap();
    let fit = manifest["stages"].as_array().unwrap().iter().find(|s| s["name"] == "fit").unwrap();
    assert_eq!(fit["status"].as_str(), Some("failed"), "{manifest}");
    assert!(fit["note"].as_str().unwrap().contains("unconverged"), "{manifest}");
    assert!(!run.join("fit").exists(), "no fit folder that looks complete");
}

#[test]
fn fitting_a_lateral_tension_that_no_face_can_have_is_refused_before_the_fit_starts() {
    let dir = tempfile::tempdir().unwrap();
    // Without polarisation a meshed label volume keeps its apical faces: no lateral face ever exists.
    let config = write_fit_config(dir.path(), "polarity = \"none\"");
    let config = FitConfig::load(&config).unwrap();
    let out = dir.path().join("out");
    let e = run_fit(&config, &out, &FitOptions::default()).unwrap_err().to_string();
    assert!(e.contains("parameters.surface_tension_lateral") && e.contains("cannot change the model"), "{e}");
    assert!(e.contains("numerics.polarity = \"none\"") && e.contains("\"contacts\""), "{e}");
    assert!(!out.exists(), "refused before anything was written or simulated");
}

/// The demo's fit (γ_lateral of the coupled doublet, truth 0.5e-3) with `lateral` bounds and
/// `objective` lines; a short search and a one-point profile. `prefix`: "" for a fit config, "fit."
/// for a pipeline's `[fit]`.
fn demo_fit_body(prefix: &str, bounds: &str, objective: &str) -> String {
    let model = repo().join("data/demo/doublet_truth.toml");
    format!(
        r#"
{prefix}model = {:?}
[{prefix}model_overrides.simulation]
max_steps = 1000
[{prefix}parameters.surface_tension]
value = 1e-3
[{prefix}parameters.surface_tension_lateral]
bounds = {bounds}
[{prefix}objective]
contact_fraction = 0.0
coordination = 0.0
contact_angle = 0.0
{objective}
[{prefix}optimizer]
max_evaluations = 4
[{prefix}forward]
accept_residual = 1e9
[{prefix}profile]
points = 1
span = 1.3
"#,
        model.display().to_string(),
    )
}

fn write_demo_fit(dir: &Path, bounds: &str, objective: &str) -> PathBuf {
    let labels = repo().join("data/demo/doublet.tif");
    let text = format!(
        "{}[observed]\nlabels = {:?}\n[observed.meshing]\ntarget_nodes = 100\n",
        demo_fit_body("", bounds, objective),
        labels.display().to_string()
    );
    let path = dir.join("fit.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn cli_fit(config: &Path, out: &Path) -> (Option<i32>, String, serde_json::Value) {
    let o = tissuefit(&["--threads", "2", "fit", "--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    let json =
        std::fs::read_to_string(out.join("result.json")).unwrap_or_else(|e| panic!("no result.json ({e}): {stderr}"));
    (o.status.code(), stderr, serde_json::from_str(&json).unwrap())
}

/// A CSV file as rows of column → field.
fn read_csv_rows(path: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let headers = r.headers().unwrap().clone();
    r.records()
        .map(|row| headers.iter().zip(row.unwrap().iter()).map(|(h, v)| (h.to_string(), v.to_string())).collect())
        .collect()
}

/// A finished fit's best-point files (issue 22, "Best-fit outputs"): `best.vtp` is the relaxed
/// observed tissue (every cell, valid meshes), `best.toml` a model file that `tissuefit simulate`
/// takes whose fitted values are `result.json`'s, `residuals.csv` one row per moving cell whose
/// observed columns are what `tissuefit measure` reports for the observed tissue.
fn assert_best_outputs(config: &Path, out: &Path, json: &serde_json::Value) {
    use tissuefit::io::{ReadOptions, read_tissue, write_tissue};
    use tissuefit::mesh::{CellKind, FaceType};
    let fit = FitConfig::load(config).unwrap();
    let observation = tissuefit::inference::load_observation(&fit).unwrap();
    let relaxation = &json["best_relaxation"];
    assert_eq!(relaxation["failed"].as_bool(), Some(false), "{json}");
    assert_eq!(relaxation["tissue_written"].as_bool(), Some(true), "{json}");
    // The deterministic forward model relaxes the best point to the best evaluation again.
    assert_eq!(relaxation["objective"].as_f64(), json["objective"].as_f64(), "{json}");

    let best = read_tissue(&out.join("best.vtp"), &ReadOptions::default()).unwrap().tissue;
    assert_eq!(best.cells().len(), observation.tissue.cells().len());
    for (cell, observed) in best.cells().iter().zip(observation.tissue.cells()) {
        assert_eq!(cell.id(), observed.id());
        cell.mesh().validate().unwrap_or_else(|e| panic!("cell {:?} of best.vtp: {e}", cell.id()));
        assert!(cell.mesh().signed_volume() > 0.0);
    }
    assert_ne!(
        best.cells()[0].mesh().positions(),
        observation.tissue.cells()[0].mesh().positions(),
        "best.vtp is the relaxed tissue, not the observed one"
    );

    let model = tissuefit::mechanics::Parameters::load(&out.join("best.toml")).unwrap();
    let si = |name: &str| json["parameters"][name]["si"].as_f64().unwrap();
    let epithelial: Vec<_> = model.cell_types.iter().filter(|t| t.kind == CellKind::Epithelial).collect();
    assert!(!epithelial.is_empty());
    for t in epithelial {
        assert_eq!(t.faces.get(FaceType::Lateral).surface_tension, si("surface_tension_lateral"), "{json}");
        assert_eq!(t.faces.get(FaceType::Apical).surface_tension, si("surface_tension"), "{json}");
    }
    let sim = out.join("simulate");
    let o = tissuefit(&[
        "simulate",
        out.join("best.vtp").to_str().unwrap(),
        "--config",
        out.join("best.toml").to_str().unwrap(),
        "--max-steps",
        "5",
        "--out",
        sim.to_str().unwrap(),
    ]);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", String::from_utf8_lossy(&o.stderr));

    // The observed tissue measured by `tissuefit measure`, cell by cell.
    let observed_file = out.join("observed.vtp");
    write_tissue(&observed_file, &observation.tissue, &[]).unwrap();
    let measured = out.join("measured");
    let o = tissuefit(&["measure", observed_file.to_str().unwrap(), "--out", measured.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let cells = read_csv_rows(&measured.join("cells.csv"));
    let residuals = read_csv_rows(&out.join("residuals.csv"));
    assert_eq!(residuals.len(), observation.cell_labels.len(), "one row per moving cell");
    let number = |row: &std::collections::HashMap<String, String>, key: &str| -> f64 {
        row[key].parse().unwrap_or_else(|e| panic!("{key} = {:?}: {e}", row[key]))
    };
    for row in &residuals {
        let cell = cells.iter().find(|c| c["cell"] == row["cell"]).unwrap_or_else(|| panic!("cell {}", row["cell"]));
        for (column, measure) in [
            ("volume_m3", "volume"),
            ("area_m2", "area"),
            ("sphericity", "sphericity"),
            ("contact_fraction", "contact_fraction"),
            ("free_area_m2", "free_area"),
            ("neighbours", "neighbours"),
            ("elongation", "elongation"),
        ] {
            let observed = number(row, &format!("{column}_observed"));
            assert_eq!(observed, number(cell, measure), "cell {}: {column}", row["cell"]);
            let simulated = number(row, &format!("{column}_simulated"));
            let difference = number(row, &format!("{column}_difference"));
            assert_eq!(difference, simulated - observed, "cell {}: {column}", row["cell"]);
        }
        // The µm columns are the SI ones converted.
        let um3 = number(row, "volume_um3_observed");
        assert!((um3 / (number(row, "volume_m3_observed") * 1e18) - 1.0).abs() < 1e-12, "{row:?}");
    }
}

#[test]
fn a_best_value_at_a_search_bound_is_never_determined_and_a_poor_fit_is_flagged() {
    let dir = tempfile::tempdir().unwrap();
    // The truth (0.5e-3) lies below the bounds: the search ends at the lower bound.
    let config = write_demo_fit(dir.path(), "[6e-4, 1e-3]", "");
    let (code, stderr, json) = cli_fit(&config, &dir.path().join("bound"));
    // The same fit's best point as files (issue 22, "Best-fit outputs").
    assert_best_outputs(&config, &dir.path().join("bound"), &json);
    let p = &json["parameters"]["surface_tension_lateral"];
    assert!((p["si"].as_f64().unwrap() / 6e-4 - 1.0).abs() < 1e-9, "{json}");
    assert_eq!(p["at_bound"].as_str(), Some("lower"), "{json}");
    assert_eq!(p["determined"].as_bool(), Some(false), "{json}");
    let r = &json["ratios"]["lateral_over_apical"];
    assert_eq!((r["at_bound"].as_str(), r["determined"].as_bool()), (Some("lower"), Some(false)), "{json}");
    // The ratio's range stays within what the bounds allow (0.6 … 1.0).
    assert!(r["range"][0].as_f64().unwrap() >= 0.6 * (1.0 - 1e-12), "{json}");
    let says = json["identifiability"].as_array().unwrap().iter().map(|l| l.as_str().unwrap()).collect::<Vec<_>>();
    assert!(says.iter().any(|l| l.contains("widen parameters.surface_tension_lateral.bounds")), "{says:?}");
    assert!(
        stderr.contains("surface_tension_lateral = 6.0000e-4") && stderr.contains("AT THE LOWER SEARCH BOUND"),
        "{stderr}"
    );
    assert!(!stderr.contains("(determined)"), "{stderr}");
    assert_eq!(json["poor_fit"].as_bool(), Some(false), "{json}");
    assert!(!stderr.contains("POOR FIT"), "{stderr}");
    assert!(code == Some(0) || code == Some(1), "{stderr}");

    // The same misfit measured on a scale 100 times finer (objective × 10⁴, still below the failure
    // penalty): far above the forward model's noise.
    let config = write_demo_fit(dir.path(), "[6e-4, 1e-3]", "sphericity_scale = 5e-5");
    let (code, stderr, json) = cli_fit(&config, &dir.path().join("poor"));
    let objective = json["objective"].as_f64().unwrap();
    let sigma = json["noise"]["std"].as_f64().unwrap_or(0.0);
    eprintln!("poor fit: objective {objective}, σ {sigma}");
    assert!(objective > tissuefit::inference::POOR_FIT_OBJECTIVE + 2.0 * sigma, "{json}");
    assert_eq!(json["poor_fit"].as_bool(), Some(true), "{json}");
    assert!(stderr.contains("POOR FIT"), "{stderr}");
    let says = json["identifiability"].as_array().unwrap().iter().map(|l| l.as_str().unwrap()).collect::<Vec<_>>();
    assert!(says.iter().any(|l| l.starts_with("POOR FIT")), "{says:?}");
    assert_eq!(code, Some(1), "a poor fit exits 1: {stderr}");
}

#[test]
fn a_demo_truth_that_the_fit_bounds_cannot_reach_is_refused_naming_both_keys() {
    let dir = tempfile::tempdir().unwrap();
    let labels = repo().join("data/demo/doublet.tif");
    let text = format!(
        "[input]\nlabels = {:?}\n[fit.parameters.surface_tension]\nvalue = 1e-3\n\
         [fit.parameters.surface_tension_lateral]\nbounds = [6e-4, 1e-3]\n[demo]\ntruth = {{ lateral_over_apical = 0.5 }}\n",
        labels.display().to_string()
    );
    let pipeline = dir.path().join("pipeline.toml");
    std::fs::write(&pipeline, text).unwrap();
    let run = dir.path().join("run");
    let o = tissuefit(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("demo.truth.lateral_over_apical = 0.5"), "{stderr}");
    assert!(
        stderr.contains("fit.parameters.surface_tension_lateral.bounds")
            && stderr.contains("fit.parameters.surface_tension.value"),
        "{stderr}"
    );
    assert!(!run.exists(), "nothing run for a contradictory config");
}

#[test]
fn lengths_and_tensions_in_the_wrong_unit_are_refused_with_a_hint() {
    let dir = tempfile::tempdir().unwrap();
    let labels = repo().join("data/demo/doublet.tif");
    let labels = labels.to_str().unwrap();
    // `--voxel-size 0.235,0.15,0.15` meant µm: 0.235 m.
    let out = dir.path().join("m.vtp");
    let o = tissuefit(&["mesh", labels, "--voxel-size", "0.235,0.15,0.15", "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("did you mean 0.235,0.15,0.15um?"), "{stderr}");
    let o = tissuefit(&["mesh", labels, "--l-min", "0.33", "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("did you mean 0.33um?"), "{stderr}");
    assert!(!out.exists());

    // A fit config: a voxel size in metres that was meant as µm, tension bounds typed in mN/m.
    let fit = |body: &str| {
        let text = format!("[observed]\nlabels = {labels:?}\n{body}");
        FitConfig::from_toml_str(&text, "fit.toml").unwrap_err().to_string()
    };
    let e = fit("voxel_size = [0.31, 0.31, 0.31]\n[parameters.surface_tension]\nbounds = [1e-4, 1e-3]\n");
    assert!(e.contains("observed.voxel_size") && e.contains("did you mean 0.31um?"), "{e}");
    let e = fit("[parameters.surface_tension]\nbounds = [0.2, 1.0]\n");
    assert!(e.contains("parameters.surface_tension.bounds") && e.contains("did you mean 0.2e-3 N/m?"), "{e}");
    let e = fit("[parameters.surface_tension]\nvalue = 0.5\n[parameters.adhesion]\nbounds = [1e8, 1e9]\n");
    assert!(e.contains("parameters.surface_tension.value") && e.contains("did you mean 0.5e-3 N/m?"), "{e}");

    // A pipeline: input.voxel_size in bare metres.
    let pipeline = dir.path().join("p.toml");
    std::fs::write(&pipeline, format!("[input]\nlabels = {labels:?}\nvoxel_size = [0.235, 0.15, 0.15]\n")).unwrap();
    let o = tissuefit(&["run", pipeline.to_str().unwrap(), "--out", dir.path().join("run").to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("input.voxel_size") && stderr.contains("did you mean 0.235um?"), "{stderr}");
}

#[test]
fn voxelize_refuses_a_bare_metre_voxel_size_and_never_writes_an_empty_volume() {
    let dir = tempfile::tempdir().unwrap();
    let tissue = repo().join("data/demo/cell_quartet.vtk");
    let out = dir.path().join("labels.tif");
    let voxelize = |size: &str| {
        let o =
            tissuefit(&["voxelize", tissue.to_str().unwrap(), "--voxel-size", size, "--out", out.to_str().unwrap()]);
        (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    // The issue's `--voxel-size 0.5`: 0.5 m.
    let (code, stderr) = voxelize("0.5");
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("did you mean 0.5um?"), "{stderr}");
    assert!(!out.exists());
    // A plausible voxel far coarser than the cells: no voxel centre falls inside one.
    let (code, stderr) = voxelize("0.9mm");
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("would hold no label") && stderr.contains("--voxel-size"), "{stderr}");
    assert!(!out.exists(), "no all-background volume written");
    // A fine voxel still works.
    let (code, stderr) = voxelize("0.5um");
    assert_eq!(code, Some(0), "{stderr}");
    assert!(out.exists());
}

#[test]
fn the_pipeline_fit_line_says_a_value_is_at_its_search_bound_as_tissuefit_fit_does() {
    let dir = tempfile::tempdir().unwrap();
    let labels = repo().join("data/demo/doublet.tif");
    // The truth (0.5e-3) lies below the bounds: the search ends at the lower bound. Plus a short
    // relaxation with the default model, whose l_min and cutoff then come from the mesh (item 4).
    let text = format!(
        "{}[input]\nlabels = {:?}\n[mesh]\ntarget_nodes = 100\n[simulate.model_overrides.simulation]\nmax_steps = 200\n",
        demo_fit_body("fit.", "[6e-4, 1e-3]", ""),
        labels.display().to_string()
    );
    let pipeline = dir.path().join("pipeline.toml");
    std::fs::write(&pipeline, text).unwrap();
    let run = dir.path().join("run");
    let o = tissuefit(&["--threads", "2", "run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    let (stdout, stderr) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(matches!(o.status.code(), Some(0 | 1)), "{stdout}{stderr}");
    let line = stdout.lines().find(|l| l.starts_with("fit: done in ")).unwrap_or_else(|| panic!("{stdout}"));
    assert!(
        line.contains("surface_tension_lateral = 6.0000e-4") && line.contains("AT THE LOWER SEARCH BOUND"),
        "{line}"
    );
    assert!(line.contains("lateral_over_apical = ") && !line.contains("(determined)"), "{line}");
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("fit/result.json")).unwrap()).unwrap();
    assert_eq!(result["parameters"]["surface_tension_lateral"]["at_bound"].as_str(), Some("lower"));
    // The fit's progress, one line per evaluation, in the run's stderr (not a terminal here), and
    // the relaxation's first line.
    let evaluations = stderr.lines().filter(|l| l.starts_with("fit: evaluation ")).count();
    assert!(evaluations >= result["evaluations"].as_u64().unwrap() as usize, "{stderr}");
    assert!(stderr.lines().any(|l| l.starts_with("simulate: step 16/200, residual ")), "{stderr}");
    // The simulate stage derived the mesh-dependent numerics, said so in its line and recorded them.
    let line = stdout.lines().find(|l| l.starts_with("simulate: done in ")).unwrap_or_else(|| panic!("{stdout}"));
    assert!(line.contains("from the mesh's mean edge length") && line.contains("min_edge_length"), "{line}");
    let simulation: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("simulate/summary.json")).unwrap()).unwrap();
    let derived = simulation["mesh_defaults"]["derived"].as_array().unwrap();
    let keys: Vec<&str> = derived.iter().map(|d| d["key"].as_str().unwrap()).collect();
    // And the default spring model's repulsion, from the cells' Laplace pressure (issue 20 item 3).
    assert_eq!(
        keys,
        ["numerics.min_edge_length", "numerics.contact_cutoff", "cell_types[0].faces.*.repulsion"],
        "{simulation}"
    );
    let l_mesh: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("mesh/report.json")).unwrap()).unwrap();
    let (l_min, l_mesh) = (derived[0]["value"].as_f64().unwrap(), l_mesh["l_min"].as_f64().unwrap());
    assert!((l_min / l_mesh - 1.0).abs() < 0.05, "derived {l_min:e}, meshing {l_mesh:e}");
}

/// A label volume of `n` slabs along x filling the whole box: every label touches the image border.
fn write_border_labels(path: &Path, n: usize) {
    use tissuefit::imaging::{LabelVolume, LabelWriteOptions, write_label_tiff};
    let (nz, ny, nx) = (14, 14, 12 * n);
    let labels = ndarray::Array3::from_shape_fn((nz, ny, nx), |(_, _, x)| (x / 12 + 1) as u32);
    let volume = LabelVolume::new(labels, [0.5e-6; 3], tissuefit::geometry::Vec3::zeros()).unwrap();
    write_label_tiff(path, &volume, &LabelWriteOptions::default()).unwrap();
}

#[test]
fn a_fit_of_a_volume_whose_every_label_touches_the_border_is_refused_with_the_reason_and_the_remedy() {
    let dir = tempfile::tempdir().unwrap();
    let labels = dir.path().join("border.tif");
    write_border_labels(&labels, 2);
    let says_why = |e: &str| {
        assert!(e.contains("no cell the simulation moves (2 static)"), "{e}");
        assert!(e.contains("border = \"static\"") && e.contains("all 2 of them touch it"), "{e}");
        assert!(e.contains("border = \"keep\"") && e.contains("crop the volume"), "{e}");
        assert!(e.contains("some cells do not touch the border"), "{e}");
    };
    // `tissuefit fit`, meshing with border = "static": refused before any evaluation.
    let text = format!(
        "{}[observed]\nlabels = {:?}\n[observed.meshing]\ntarget_nodes = 60\nborder = \"static\"\n",
        fit_body("", ""),
        labels.display().to_string()
    );
    let config = dir.path().join("fit.toml");
    std::fs::write(&config, text).unwrap();
    let out = dir.path().join("out");
    let o = tissuefit(&["--threads", "2", "fit", "--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    says_why(&stderr);
    assert!(!out.join("trace.csv").exists(), "nothing simulated");

    // The same as a pipeline's [fit] (the real-ovule case): the fit stage fails saying so.
    let text = format!(
        "{}[input]\nlabels = {:?}\n[mesh]\ntarget_nodes = 60\nborder = \"static\"\n[measure]\ninclude_static = true\n",
        fit_body("fit.", ""),
        labels.display().to_string()
    );
    let pipeline = dir.path().join("pipeline.toml");
    std::fs::write(&pipeline, text).unwrap();
    let run = dir.path().join("run");
    let o = tissuefit(&["--threads", "2", "run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    says_why(&stderr);
    // With border = "keep" the same volume has free cells, and the fit gets past that check.
    let observation = tissuefit::inference::load_observation(
        &FitConfig::from_toml_str(
            &format!(
                "{}[observed]\nlabels = {:?}\n[observed.meshing]\ntarget_nodes = 60\nborder = \"keep\"\n",
                fit_body("", ""),
                labels.display().to_string()
            ),
            "keep.toml",
        )
        .unwrap(),
    );
    assert!(observation.is_ok(), "{:?}", observation.err().map(|e| e.to_string()));
}
