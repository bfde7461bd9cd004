//! `tissuefit simulate` on meshed data (issue 22, item 4): the mesh-dependent numerics a config
//! leaves unset (l_min, contact cutoff, an unstable time step) come from the input mesh and are
//! printed and recorded; values that contradict the mesh are warned about with the numbers and the
//! fix. And progress lines (item 5): a run whose stderr is not a terminal logs its progress, at a
//! sane rate.
//!
//! Kept cheap: the demo doublet meshed at 100 nodes per cell (l_min 0.56 µm), short relaxations.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tissuefit::io::{ReadOptions, read_tissue};
use tissuefit::mechanics::{ExplicitNumerics, MEAN_EDGE_PER_MIN_EDGE, MeshScale, Parameters};
use tissuefit::morphology::{MeasureSettings, measure_tissue};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn tissuefit(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_tissuefit"));
    command.args(args).env_remove("TISSUEFIT_PROGRESS_SECONDS");
    for (k, v) in env {
        command.env(k, v);
    }
    command.output().expect("runs the binary")
}

/// The demo doublet meshed from its labels at 100 nodes per cell → (tissue, l_min of the meshing).
fn meshed_doublet(dir: &Path) -> (PathBuf, f64) {
    let tissue = dir.join("doublet.vtp");
    let labels = repo().join("data/demo/doublet.tif");
    let o =
        tissuefit(&["mesh", labels.to_str().unwrap(), "--target-nodes", "100", "--out", tissue.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("doublet.report.json")).unwrap()).unwrap();
    (tissue, report["l_min"].as_f64().unwrap())
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

#[test]
fn a_doublet_meshed_from_labels_and_simulated_with_defaults_gets_the_mesh_l_min_and_stays_in_contact() {
    let dir = tempfile::tempdir().unwrap();
    let (tissue, l_mesh) = meshed_doublet(dir.path());
    let out = dir.path().join("sim");
    let o = tissuefit(
        &[
            "--threads",
            "2",
            "simulate",
            tissue.to_str().unwrap(),
            "--max-steps",
            "3000",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{stderr}");
    // What was derived is said, with where it came from.
    assert!(
        stderr.contains("note: numerics.min_edge_length = ")
            && stderr.contains("from the input mesh's mean edge length"),
        "{stderr}"
    );
    assert!(stderr.contains("note: numerics.contact_cutoff = "), "{stderr}");
    // The derived l_min is the meshing's within a few percent (⟨edge⟩/1.4 against the l_min used; the
    // default 0.2 µm is 2.8 times off), and the cutoff follows it.
    let summary = json(&out.join("summary.json"));
    let defaults = &summary["mesh_defaults"];
    let derived = |key: &str| {
        defaults["derived"].as_array().unwrap().iter().find(|d| d["key"] == key).map(|d| d["value"].as_f64().unwrap())
    };
    let l_min = derived("numerics.min_edge_length").unwrap_or_else(|| panic!("{defaults}"));
    assert!((l_min / l_mesh - 1.0).abs() < 0.05, "derived {l_min:e} vs the meshing's {l_mesh:e}");
    assert_eq!(derived("numerics.contact_cutoff"), Some(l_min), "{defaults}");
    assert!(defaults["warnings"].as_array().unwrap().is_empty(), "{defaults}");
    // Issue 20 item 3: the default spring repulsion (1e9 Pa/m, ξ·c = 570 Pa at this cutoff) let the
    // cells sink into each other (3.5 % of a cell's volume after this run); the derived one holds 25 × the Laplace pressure 2γ̄/R of the
    // cells (about 1.1 kPa at R ≈ 1.8 µm and 1 mN/m) at depth c, and the overlap stays small.
    let repulsion = defaults["derived"]
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["key"].as_str().unwrap().ends_with(".faces.*.repulsion"))
        .map(|d| d["value"].as_f64().unwrap())
        .unwrap_or_else(|| panic!("no derived repulsion: {defaults}"));
    let held = repulsion * l_min / 25.0;
    assert!((800.0..1500.0).contains(&held), "ξ = {repulsion:e} Pa/m holds {held} Pa per 1/25 of c");
    assert!(stderr.contains(".faces.*.repulsion = "), "{stderr}");
    let overlap = summary["max_overlap_fraction"].as_f64().unwrap_or_else(|| panic!("{summary}"));
    assert!(overlap <= 0.005, "overlap {overlap}");
    let mean_edge = defaults["mesh_mean_edge"].as_f64().unwrap();
    assert!((mean_edge / MEAN_EDGE_PER_MIN_EDGE - l_min).abs() < 1e-15, "{defaults}");
    // The resolved config holds them too, so the run can be repeated from it.
    let config = Parameters::load(&out.join("config.toml")).unwrap();
    assert_eq!(config.numerics.min_edge_length, l_min);
    assert_eq!(config.numerics.contact_cutoff, l_min);
    // The cells are still in contact at the end: each has its neighbour, over part of its surface
    // (measured like the input: δ a quarter of the input's mean edge).
    let read = |p: &Path| read_tissue(p, &ReadOptions::default()).unwrap().tissue;
    let settings = MeasureSettings { contact_distance: Some(0.25 * mean_edge), ..MeasureSettings::default() };
    let m = measure_tissue(&read(&out.join("final.vtk")), &settings).unwrap();
    assert_eq!(m.summary.mean_coordination, Some(1.0), "{:?}", m.summary);
    let phi = m.summary.mean_contact_fraction.unwrap();
    assert!(phi > 0.02, "contact fraction {phi}");
}

#[test]
fn a_config_whose_l_min_and_cutoff_contradict_the_mesh_is_warned_about_with_the_numbers_and_the_fix() {
    let dir = tempfile::tempdir().unwrap();
    let (tissue, _) = meshed_doublet(dir.path());
    // Table 2's 0.2 µm, set explicitly on a 0.57 µm mesh: kept (the user's choice), but warned.
    let config = dir.path().join("model.toml");
    std::fs::write(&config, "[numerics]\nmin_edge_length = 2e-7\ncontact_cutoff = 2e-7\n").unwrap();
    let out = dir.path().join("sim");
    let o = simulate_two_steps(&tissue, &config, &out);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{stderr}");
    assert!(!stderr.contains("note: numerics.min_edge_length"), "nothing derived: {stderr}");
    let summary = json(&out.join("summary.json"));
    let defaults = &summary["mesh_defaults"];
    let l = defaults["mesh_min_edge_length"].as_f64().unwrap();
    // Only the spring repulsion, which the config leaves unset, is derived (from the cells' pressure).
    let derived = defaults["derived"].as_array().unwrap();
    assert!(derived.iter().all(|d| d["key"].as_str().unwrap().ends_with(".repulsion")), "{defaults}");
    let warnings: Vec<&str> = defaults["warnings"].as_array().unwrap().iter().map(|w| w.as_str().unwrap()).collect();
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    let fix = format!("{l:.3e}");
    for (key, words) in [("min_edge_length", "× the input mesh's l_min"), ("contact_cutoff", "drift apart")] {
        let line = format!("numerics.{key} = 0.200 µm");
        assert!(stderr.contains(&line) && stderr.contains(words), "{key}: {stderr}");
        assert!(stderr.contains(&format!("set {key} = {fix}")), "{key}: the fix {fix}: {stderr}");
    }
    let config = Parameters::load(&out.join("config.toml")).unwrap();
    assert_eq!((config.numerics.min_edge_length, config.numerics.contact_cutoff), (2e-7, 2e-7), "kept");

    // Values that agree with the mesh: no warning.
    let agreeing = dir.path().join("agreeing.toml");
    std::fs::write(&agreeing, format!("[numerics]\nmin_edge_length = {l:e}\ncontact_cutoff = {l:e}\n")).unwrap();
    let out = dir.path().join("sim2");
    let o = simulate_two_steps(&tissue, &agreeing, &out);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!stderr.contains("the input mesh's l_min"), "{stderr}");
    assert!(json(&out.join("summary.json"))["mesh_defaults"]["warnings"].as_array().unwrap().is_empty());
}

#[test]
fn a_time_step_is_derived_only_when_the_derived_l_min_makes_the_default_unstable() {
    // Overdamped on a 1.5 µm mesh: the contact stiffness ξ·a_n grows with l_min², and the default
    // Δt = 1e-7 s lands above half the stability limit.
    let text = "[numerics]\ndynamics = \"overdamped\"\n";
    let table: toml::Table = toml::from_str(text).unwrap();
    let scale = MeshScale { mean_edge: 2.1e-6, min_edge_length: 1.5e-6 };
    let mut params = Parameters::from_toml_str(text, "test").unwrap();
    let fit = params.fit_to_mesh(&ExplicitNumerics::of_table(&table), &scale);
    let dt = fit.derived_value("numerics.time_step").unwrap_or_else(|| panic!("{fit:?}"));
    assert!(dt < 1e-7 && params.numerics.time_step == dt, "{fit:?}");
    let warnings = params.validate().unwrap();
    assert!(!warnings.iter().any(|w| w.contains("numerics.time_step")), "stable now: {warnings:?}");
    // Without the derivation the same l_min leaves the default close to diverging.
    let mut unstable = Parameters::from_toml_str(text, "test").unwrap();
    unstable.numerics.min_edge_length = 1.5e-6;
    unstable.numerics.contact_cutoff = 1.5e-6;
    assert!(unstable.validate().unwrap().iter().any(|w| w.contains("numerics.time_step")));

    // A time step the config sets is kept; so is the default where the estimate allows it.
    let text = "[numerics]\ndynamics = \"overdamped\"\ntime_step = 1e-7\n";
    let mut params = Parameters::from_toml_str(text, "test").unwrap();
    let fit = params.fit_to_mesh(&ExplicitNumerics::of_table(&toml::from_str(text).unwrap()), &scale);
    assert_eq!((fit.derived_value("numerics.time_step"), params.numerics.time_step), (None, 1e-7));
    let mut params = Parameters::default();
    let fit =
        params.fit_to_mesh(&ExplicitNumerics::default(), &MeshScale { mean_edge: 0.8e-6, min_edge_length: 0.57e-6 });
    assert_eq!(fit.derived_value("numerics.time_step"), None, "{fit:?}");
    assert_eq!(fit.derived_value("numerics.min_edge_length"), Some(0.57e-6));
}

/// The progress lines of a run's stderr (`simulate PATH: step N/M, ...`).
fn progress_lines(stderr: &str) -> Vec<&str> {
    stderr.lines().filter(|l| l.starts_with("simulate ") && l.contains(": step ")).collect()
}

#[test]
fn a_simulation_with_stderr_in_a_file_logs_progress_lines_at_a_bounded_rate() {
    let dir = tempfile::tempdir().unwrap();
    let (tissue, _) = meshed_doublet(dir.path());
    let run = |out: &str, extra: &[&str], env: &[(&str, &str)]| {
        let out = dir.path().join(out);
        let mut args = vec!["--threads", "2"];
        args.extend_from_slice(extra);
        args.extend(["simulate", tissue.to_str().unwrap(), "--max-steps", "1500", "--out", out.to_str().unwrap()]);
        // The test harness captures stderr: not a terminal, as `2>log` or a cluster job's log.
        let o = tissuefit(&args, env);
        assert!(matches!(o.status.code(), Some(0 | 1)), "{}", String::from_utf8_lossy(&o.stderr));
        let steps = json(&out.join("summary.json"))["steps"].as_u64().unwrap();
        (String::from_utf8_lossy(&o.stderr).into_owned(), steps)
    };
    // Default: a line when the run starts, then one per 30 s (this run takes well under one).
    let (stderr, _) = run("default", &[], &[]);
    let lines = progress_lines(&stderr);
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(lines[0].contains("step 16/1500, residual "), "{stderr}");
    // A short interval: lines as the run goes, each with its step, never one per step.
    let (stderr, steps) = run("often", &[], &[("TISSUEFIT_PROGRESS_SECONDS", "0.01")]);
    let lines = progress_lines(&stderr);
    assert!(lines.len() >= 2, "{stderr}");
    assert!(lines.len() as u64 <= steps / 16 + 1, "{} lines for {steps} steps", lines.len());
    let step_of = |l: &str| l.split(": step ").nth(1).unwrap().split('/').next().unwrap().parse::<u64>().unwrap();
    assert!(lines.windows(2).all(|w| step_of(w[0]) < step_of(w[1])), "{lines:?}");
    // -q: none.
    let (stderr, _) = run("quiet", &["-q"], &[("TISSUEFIT_PROGRESS_SECONDS", "0")]);
    assert!(progress_lines(&stderr).is_empty(), "{stderr}");
}

#[test]
fn a_cell_whose_centre_lies_inside_another_is_found_and_nuclei_are_not() {
    use tissuefit::geometry::Vec3;
    use tissuefit::mechanics::{CellInside, cells_inside_others, passage_warning};
    use tissuefit::mesh::shapes::icosphere;
    use tissuefit::mesh::{Cell, CellId, CellKind, Tissue};
    let sphere = |id: u32, kind: CellKind, r: f64, x: f64| {
        Cell::new(CellId(id), kind, 0, icosphere(r, 2, Vec3::new(x, 0.0, 0.0)))
    };
    // Two touching cells: nothing. (Radii in m, 5 µm cells.)
    let apart = Tissue::from_cells(vec![
        sphere(1, CellKind::Epithelial, 5e-6, 0.0),
        sphere(2, CellKind::Epithelial, 5e-6, 9.9e-6),
    ])
    .unwrap();
    assert!(cells_inside_others(&apart).is_empty());
    assert_eq!(passage_warning(&[]), None);
    // A doublet that went through itself (centres 0.03 µm apart): each centre inside the other.
    let merged = Tissue::from_cells(vec![
        sphere(1, CellKind::Epithelial, 5e-6, 0.0),
        sphere(2, CellKind::Epithelial, 5e-6, 3e-8),
    ])
    .unwrap();
    let inside = cells_inside_others(&merged);
    assert_eq!(inside, [CellInside { cell: 1, host: 2 }, CellInside { cell: 2, host: 1 }]);
    let warning = passage_warning(&inside).unwrap();
    assert!(warning.contains("cell 1 inside cell 2") && warning.contains("raise the repulsion"), "{warning}");
    // A nucleus inside its cell is where it belongs.
    let nucleated =
        Tissue::from_cells(vec![sphere(1, CellKind::Epithelial, 5e-6, 0.0), sphere(2, CellKind::Nucleus, 2e-6, 0.0)])
            .unwrap();
    assert!(cells_inside_others(&nucleated).is_empty());
}

/// `tissuefit simulate TISSUE --config CONFIG --max-steps 2 --out OUT`.
fn simulate_two_steps(tissue: &Path, config: &Path, out: &Path) -> Output {
    tissuefit(
        &[
            "simulate",
            tissue.to_str().unwrap(),
            "--config",
            config.to_str().unwrap(),
            "--max-steps",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    )
}

/// Issue 20 item 3: `config check --tissue` says what `simulate` would derive for that tissue and
/// warns when a config's spring repulsion cannot hold the cells' Laplace pressure.
#[test]
fn config_check_against_a_tissue_derives_the_repulsion_and_warns_when_a_set_one_is_too_weak() {
    let dir = tempfile::tempdir().unwrap();
    let (tissue, _) = meshed_doublet(dir.path());
    let weak = dir.path().join("weak.toml");
    let mut text = String::from("[numerics]\ncontact_model = \"spring\"\n[[cell_types]]\n");
    for face in ["apical", "lateral", "basal"] {
        text += &format!("[cell_types.faces.{face}]\nrepulsion = 1e9\n");
    }
    std::fs::write(&weak, text).unwrap();
    let unset = dir.path().join("unset.toml");
    std::fs::write(&unset, "[numerics]\ncontact_model = \"spring\"\n").unwrap();
    let check = |config: &Path| {
        let o = tissuefit(&["config", "check", config.to_str().unwrap(), "--tissue", tissue.to_str().unwrap()], &[]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    // Both also warn that the derived cutoff c = l_min = 0.571 µm makes Table 2's ω adhere at
    // w/(2γ) = 0.081, where the vertex quadrature's contact angles are biased.
    let quadrature = "contact_quadrature = \"vertices\" with spring adhesion (cell_types[0].faces.apical: w/(2γ) = ωc²/(4γ) = 0.081)";
    let stderr = check(&weak);
    assert!(stderr.contains("its weakest repulsion ξ = 1.000e9 Pa/m") && stderr.contains("(2 warnings)"), "{stderr}");
    assert!(stderr.contains(quadrature), "{stderr}");
    let stderr = check(&unset);
    assert!(stderr.contains("note: cell_types[0].faces.*.repulsion = ") && stderr.contains("(1 warnings)"), "{stderr}");
    assert!(stderr.contains(quadrature), "{stderr}");
}
