//! `[fit] mode = "per_cell"` (issue 25): a per-cell tension map by forward refinement of the direct
//! estimate, scored against Surface Evolver's heterogeneous cluster (hetero4: six different
//! interface tensions) at 10 voxels per diameter, the same on 1 and 2 threads, honest about not
//! converging, in a pipeline, and with clear errors on bad settings.

use crate::support::cli::tissuefit;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use tissuefit::geometry::{Real, Vec3};
use tissuefit::inference::FitConfig;
use tissuefit::io::{LengthScale, ReadOptions, read_tissue};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/evolver/fixtures").join(name)
}

/// The model of the "compact-embryo" preset (coupled contacts, faces typed by contact).
pub(crate) const MODEL: &str = r#"
[model_overrides.numerics]
contact_model = "coupling"
polarity = "contacts"
dynamics = "overdamped"
damping = 3e-9
[[model_overrides.cell_types]]
kind = "epithelial"
area_elasticity = 0.0
max_pressure = inf
growth_rate = 0.0
faces.apical = { surface_tension = 1e-3, bending_modulus = 0.0, adhesion = 0.0 }
faces.basal = { surface_tension = 1e-3, bending_modulus = 0.0, adhesion = 0.0 }
faces.lateral = { surface_tension = 0.5e-3, bending_modulus = 0.0, adhesion = 0.0 }
[model_overrides.simulation]
mode = "equilibrium"
method = "fire"
max_steps = 1500
settle_steps = 500
remesh_every_steps = 50
[forward]
accept_residual = 1e9
measure_shifts = 2
"#;

fn write_config(dir: &Path, per_cell: &str) -> PathBuf {
    let labels = fixture("hetero4").join("labels_10.tif");
    let text = format!(
        "mode = \"per_cell\"\n[observed]\nlabels = {:?}\n[observed.meshing]\ntarget_nodes = 200\n{MODEL}[per_cell]\n{per_cell}\n",
        labels.display().to_string()
    );
    let path = dir.join("fit.toml");
    std::fs::write(&path, text).unwrap();
    path
}

use crate::support::run_dirs::{csv_maps as rows, number};

fn median(mut v: Vec<Real>) -> Real {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { (v[n / 2 - 1] + v[n / 2]) / 2.0 }
}

/// Relative errors of `column` (mN/m, scaled so the mean free tension is the truth's γ) against the
/// Evolver truth, every interface (cell–cell and cell–medium).
fn errors(interfaces: &[BTreeMap<String, String>], column: &str) -> Vec<Real> {
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture("hetero4").join("truth.json")).unwrap()).unwrap();
    let gamma = truth["gamma_a"].as_f64().unwrap();
    let free: Vec<Real> = interfaces.iter().filter(|r| r["cell_b"] == "0").map(|r| number(r, column)).collect();
    let scale = gamma / (free.iter().sum::<Real>() / free.len() as Real);
    interfaces
        .iter()
        .map(|r| {
            let (a, b) = (&r["cell_a"], &r["cell_b"]);
            let want =
                if b == "0" { gamma } else { truth["interfaces"][format!("{a}-{b}")]["tension"].as_f64().unwrap() };
            (number(r, column) * scale / want - 1.0).abs()
        })
        .collect()
}

/// The issue's target, per-interface median error ≤ 10 % at 10 voxels per diameter, on an outside
/// truth; every file written; the same map on 1 and 2 threads; a refinement that did not reach its
/// tolerance says so and exits 1 (its best map still written and usable).
#[test]
fn a_per_cell_fit_maps_evolvers_hetero4_at_10_voxels_the_same_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    // A tolerance below the forward model's noise: the refinement runs every iteration.
    let config = write_config(dir.path(), "iterations = 3\ntolerance = 0.002");
    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}"));
        let o = tissuefit(&[
            "fit",
            "--config",
            config.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--threads",
            threads,
        ]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{stderr}");
        assert!(stderr.contains("per-cell map of 4 cells") && stderr.contains("NOT converged"), "{stderr}");
        for f in [
            "cells.csv",
            "interfaces.csv",
            "iterations.csv",
            "tissue.vtp",
            "relaxed.vtp",
            "cell_overrides.toml",
            "model.toml",
            "result.json",
            "fit.toml",
        ] {
            assert!(out.join(f).is_file(), "{f} missing");
        }
        let read = |f: &str| std::fs::read_to_string(out.join(f)).unwrap();
        // iterations.csv without its seconds column.
        let iterations: Vec<String> = read("iterations.csv")
            .lines()
            .map(|l| l.split(',').enumerate().filter(|(i, _)| *i != 7).map(|(_, x)| x).collect::<Vec<_>>().join(","))
            .collect();
        assert_eq!(iterations.len(), 4, "{iterations:?}");
        outputs.push((read("cells.csv"), read("interfaces.csv"), iterations, read("cell_overrides.toml")));
    }
    assert!(outputs[0] == outputs[1], "1 and 2 threads differ");
    let out = dir.path().join("t2");
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap()).unwrap();
    assert_eq!(result["mode"], "per_cell");
    assert_eq!(result["converged"], false);
    assert_eq!(result["iterations"], 3);
    let interfaces = rows(&out.join("interfaces.csv"));
    assert_eq!(interfaces.len(), 10, "6 cell–cell and 4 cell–medium interfaces");
    let refined = errors(&interfaces, "tension_mn_per_m");
    let direct = errors(&interfaces, "direct_mn_per_m");
    eprintln!(
        "hetero4, 10 voxels per diameter: per-interface median / max error refined {:.4} / {:.4}, direct {:.4} / {:.4}",
        median(refined.clone()),
        refined.iter().copied().fold(0.0, Real::max),
        median(direct.clone()),
        direct.iter().copied().fold(0.0, Real::max)
    );
    assert!(median(refined.clone()) <= 0.10, "{refined:?}");
    // The map is scaled to the free tension (the model's apical 1 mN/m) and is the model's: a
    // cell–cell tension is the sum of the two cells' lateral tensions.
    let cells = rows(&out.join("cells.csv"));
    let free: Vec<Real> = cells.iter().map(|c| number(c, "free_tension_mn_per_m")).collect();
    assert!((free.iter().sum::<Real>() / 4.0 - 1.0).abs() < 1e-9, "{free:?}");
    let lateral: BTreeMap<String, Real> =
        cells.iter().map(|c| (c["cell"].clone(), number(c, "lateral_tension_mn_per_m"))).collect();
    for r in interfaces.iter().filter(|r| r["cell_b"] != "0") {
        let sum = lateral[&r["cell_a"]] + lateral[&r["cell_b"]];
        assert!((number(r, "tension_mn_per_m") / sum - 1.0).abs() < 1e-9);
    }
    // The observed tissue, coloured by the map, carries each cell's tensions as a model would read them.
    let read = read_tissue(
        &out.join("tissue.vtp"),
        &ReadOptions { length_scale: LengthScale(Vec3::repeat(1.0)), orient: false },
    )
    .unwrap()
    .tissue;
    for c in &cells {
        let id: u32 = c["cell"].parse().unwrap();
        let cell = read.cells().iter().find(|x| x.id().0 == id).unwrap();
        let [_, l, b] = cell.overrides().surface_tension;
        assert!((l.unwrap() * 1e3 / number(c, "lateral_tension_mn_per_m") - 1.0).abs() < 1e-9);
        assert!((b.unwrap() * 1e3 / number(c, "free_tension_mn_per_m") - 1.0).abs() < 1e-9);
    }
    let snippet = std::fs::read_to_string(out.join("cell_overrides.toml")).unwrap();
    assert_eq!(snippet.matches("[[cell_overrides]]").count(), 4, "{snippet}");
    // Each interval is the mismatch left, the spread over the 2 placements and the model error
    // (per voxel size over the ~8 µm cells' diameter at 0.8 µm voxels: ~10 voxels per diameter),
    // combined in quadrature: rebuild it from its parts.
    let per_diameter = result["voxels_per_diameter"].as_f64().unwrap();
    assert!((8.0..12.0).contains(&per_diameter), "{per_diameter}");
    let config = FitConfig::from_toml_str(&std::fs::read_to_string(&config).unwrap(), "fit.toml").unwrap();
    let m = config.per_cell.model_error;
    for r in &interfaces {
        assert_eq!(r["sd_source"], "placements", "{r:?}");
        assert_eq!(number(r, "placements"), 2.0, "{r:?}");
        let (coefficient, floor) =
            if r["cell_b"] == "0" { (m.cell_medium, m.cell_medium_floor) } else { (m.cell_cell, m.cell_cell_floor) };
        let want = (floor.powi(2) + (coefficient / per_diameter).powi(2)).sqrt();
        assert!((number(r, "model_error") - want).abs() < 1e-12, "{r:?}");
        let (mismatch, s) = (number(r, "mismatch"), number(r, "placement_sd"));
        let want = (mismatch.powi(2) + 1.5 * s * s + number(r, "model_error").powi(2)).sqrt();
        let sd = number(r, "tension_sd_mn_per_m") / number(r, "tension_mn_per_m");
        assert!(s > 0.0 && (sd / want - 1.0).abs() < 1e-9, "{r:?}: {sd} against {want}");
    }
    assert!(result["uncertainty"].as_str().unwrap().contains("placements"), "{result}");
    // Each pressure's interval is its free surface's relative sd and the pressure model error.
    let m_p = (m.pressure_floor.powi(2) + (m.pressure / per_diameter).powi(2)).sqrt();
    for c in &cells {
        assert!((number(c, "pressure_model_error") - m_p).abs() < 1e-12, "{c:?}");
        let free = interfaces.iter().find(|r| r["cell_a"] == c["cell"] && r["cell_b"] == "0").unwrap();
        let s = number(free, "tension_sd_mn_per_m") / number(free, "tension_mn_per_m");
        assert!((number(c, "pressure_tension_sd") / s - 1.0).abs() < 1e-9, "{c:?}");
        let want = number(c, "pressure_pa").abs() * s.hypot(m_p);
        assert!(want > 0.0 && (number(c, "pressure_sd_pa") / want - 1.0).abs() < 1e-9, "{c:?}: against {want}");
        assert!((number(c, "pressure_sd_kpa") * 1e3 / number(c, "pressure_sd_pa") - 1.0).abs() < 1e-12);
    }
    // Each lateral tension's interval is the least squares a_i + a_j = T_ij through the cell–cell
    // interfaces' sds (independent errors: the pseudo-inverse's row weighted by the sds) and the
    // lateral model error, in quadrature.
    let m_l = (m.lateral_floor.powi(2) + (m.lateral / per_diameter).powi(2)).sqrt();
    let ids: Vec<&str> = cells.iter().map(|c| c["cell"].as_str()).collect();
    let pairs: Vec<_> = interfaces.iter().filter(|r| r["cell_b"] != "0").collect();
    let a = nalgebra::DMatrix::<Real>::from_fn(pairs.len(), ids.len(), |i, k| {
        Real::from(pairs[i]["cell_a"] == ids[k] || pairs[i]["cell_b"] == ids[k])
    });
    let pinv = a.pseudo_inverse(1e-9).unwrap();
    for (k, c) in cells.iter().enumerate() {
        assert!((number(c, "lateral_model_error") - m_l).abs() < 1e-12, "{c:?}");
        let least_squares: Real =
            pairs.iter().enumerate().map(|(i, r)| (pinv[(k, i)] * number(r, "tension_sd_mn_per_m")).powi(2)).sum();
        let want = least_squares.sqrt().hypot(m_l * number(c, "lateral_tension_mn_per_m"));
        let sd = number(c, "lateral_tension_sd_mn_per_m");
        assert!(want > 0.0 && (sd / want - 1.0).abs() < 1e-9, "{c:?}: against {want}");
    }
}

#[test]
fn bad_per_cell_settings_are_refused_naming_the_key() {
    let base = "mode = \"per_cell\"\n[observed]\nlabels = \"x.tif\"\n";
    for (extra, want) in [
        ("[per_cell]\niterations = 0\n", "per_cell.iterations"),
        ("[per_cell]\nstep = 2.0\n", "per_cell.step"),
        ("[per_cell]\ntolerance = 0.0\n", "per_cell.tolerance"),
        ("[per_cell]\nfree_tension = 1.0\n", "per_cell.free_tension"),
        ("[per_cell]\niteration = 3\n", "unknown field `iteration`"),
        ("[per_cell]\nmodel_error = { cell_cell = -1.0 }\n", "per_cell.model_error.cell_cell"),
        ("[per_cell]\nmodel_error = { cell_medium = nan }\n", "per_cell.model_error.cell_medium"),
        ("[per_cell]\nmodel_error = { lateral = -0.1 }\n", "per_cell.model_error.lateral"),
        ("[per_cell]\nmodel_error = { cell_cell_floor = -0.01 }\n", "per_cell.model_error.cell_cell_floor"),
        ("[per_cell]\nmodel_error = { pressure_floor = inf }\n", "per_cell.model_error.pressure_floor"),
        ("[per_cell]\nmodel_error = { cell = 1.0 }\n", "unknown field `cell`"),
        ("[per_cell]\nspring_model_error = 0\n", "per_cell.spring_model_error"),
    ] {
        let e = FitConfig::from_toml_str(&format!("{base}{extra}"), "fit.toml").unwrap_err().to_string();
        assert!(e.contains(want), "{extra}: {e}");
    }
    let e = FitConfig::from_toml_str("mode = \"per_cel\"\n[observed]\nlabels = \"x.tif\"\n", "fit.toml").unwrap_err();
    assert!(e.to_string().contains("per_cell"), "{e}");
    // A global fit still needs its parameters; a per-cell one does not.
    let e = FitConfig::from_toml_str("[observed]\nlabels = \"x.tif\"\n", "fit.toml").unwrap_err().to_string();
    assert!(e.contains("mode = \"per_cell\""), "{e}");
    FitConfig::from_toml_str(base, "fit.toml").unwrap();
}

/// A pipeline's `[fit]` with `mode = "per_cell"` on top of the compact-embryo preset (whose fitted
/// parameter then only sets the start): the map lands in the fit folder and the run's summary says
/// what the refinement did.
#[test]
fn a_pipeline_maps_per_cell_with_the_compact_embryo_preset() {
    let dir = tempfile::tempdir().unwrap();
    let labels = fixture("hetero4").join("labels_10.tif");
    let text = format!(
        "preset = \"compact-embryo\"\n[input]\nlabels = {:?}\nseed = 0\n[fit]\nmode = \"per_cell\"\n[fit.forward]\nmeasure_shifts = 1\n[fit.per_cell]\niterations = 2\ntolerance = 0.2\n",
        labels.display().to_string()
    );
    let path = dir.path().join("pipeline.toml");
    std::fs::write(&path, text).unwrap();
    let out = dir.path().join("out");
    // With lines due at once (`TISSUEFIT_PROGRESS_SECONDS=0`) a log hears from inside each
    // relaxation (a 200-cell iteration runs for many minutes), naming the iteration.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .args(["run", path.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .env("TISSUEFIT_PROGRESS_SECONDS", "0")
        .output()
        .unwrap();
    let all = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{all}");
    assert!(all.contains("per-cell map of 4 cells"), "{all}");
    assert!(
        all.lines()
            .any(|l| l.starts_with("fit: iteration 1 of 2 running: step 256 of at most 1500 per pass, residual ")),
        "{all}"
    );
    assert_eq!(rows(&out.join("fit/cells.csv")).len(), 4);
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("fit/result.json")).unwrap()).unwrap();
    assert_eq!((result["mode"].as_str(), result["converged"].as_bool()), (Some("per_cell"), Some(true)));
}

/// Spring contacts (issue 25, adhesion maps): each cell has one tension γ_i on every face and its
/// own adhesion ω_i, and a cell–cell interface's tension is γ_a + γ_b − (ω_a + ω_b)·c²/4. The map
/// reports ω_i, the adhesion energy of a cell's side W_i = ω_i·c²/4 and W_i/γ_i; the model's
/// repulsion is raised to hold the strongest adhesion; the map recovers Evolver's tensions within
/// the target (an outside truth that knows nothing of springs: it fixes T_ij, and with it W_i).
#[test]
fn a_spring_contact_map_gives_each_cell_its_adhesion() {
    let dir = tempfile::tempdir().unwrap();
    let labels = fixture("hetero4").join("labels_10.tif");
    let model = MODEL
        .replace("contact_model = \"coupling\"", "contact_model = \"spring\"\ncontact_quadrature = \"faces\"")
        .replace("polarity = \"contacts\"", "polarity = \"none\"");
    let config = dir.path().join("fit.toml");
    std::fs::write(
        &config,
        format!(
            "mode = \"per_cell\"\n[observed]\nlabels = {:?}\n[observed.meshing]\ntarget_nodes = 200\n{model}\
             [per_cell]\niterations = 3\ntolerance = 0.002\n",
            labels.display().to_string()
        ),
    )
    .unwrap();
    let out = dir.path().join("out");
    let o = tissuefit(&["fit", "--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{stderr}");
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap()).unwrap();
    assert_eq!(result["contact_model"], "spring", "{result}");
    let c = result["contact_cutoff_m"].as_f64().unwrap();
    assert!(c > 1e-7 && c < 2e-6, "the cutoff follows the mesh's l_min: {c}");
    let cells = rows(&out.join("cells.csv"));
    let interfaces = rows(&out.join("interfaces.csv"));
    let mut strongest: Real = 0.0;
    let mut omega = BTreeMap::new();
    let mut gamma = BTreeMap::new();
    for cell in &cells {
        let (f, a) = (number(cell, "free_tension_n_per_m"), number(cell, "lateral_tension_n_per_m"));
        let w = number(cell, "adhesion_pa_per_m");
        assert!(a <= f * (1.0 + 1e-12), "{cell:?}: a spring adhesion cannot make a > f");
        assert!((w / (4.0 * (f - a) / (c * c)) - 1.0).abs() < 1e-9, "{cell:?}");
        assert!((number(cell, "adhesion_energy_j_per_m2") / (f - a) - 1.0).abs() < 1e-9, "{cell:?}");
        assert!((number(cell, "adhesion_over_tension") / (1.0 - a / f) - 1.0).abs() < 1e-9, "{cell:?}");
        let sd = number(cell, "adhesion_energy_sd_mj_per_m2");
        let want = number(cell, "free_tension_sd_mn_per_m").hypot(number(cell, "lateral_tension_sd_mn_per_m"));
        assert!(sd > 0.0 && (sd / want - 1.0).abs() < 1e-9, "{cell:?}");
        strongest = strongest.max(w);
        omega.insert(cell["cell"].clone(), w);
        gamma.insert(cell["cell"].clone(), f);
    }
    assert!(strongest > 1e8, "hetero4's interfaces need adhesion: {omega:?}");
    // The interface's tension is the spring model's: two membranes less both wells.
    for r in interfaces.iter().filter(|r| r["cell_b"] != "0") {
        let (a, b) = (&r["cell_a"], &r["cell_b"]);
        let want = gamma[a] + gamma[b] - (omega[a] + omega[b]) * c * c / 4.0;
        assert!((number(r, "tension_n_per_m") / want - 1.0).abs() < 1e-9, "{r:?}");
    }
    // Raised repulsion: at least 20 × the strongest adhesion, written into the model that makes the map.
    let raised = result["raised"]["cell_types[0].faces.*.repulsion"].as_f64().expect("repulsion raised");
    assert!(raised >= 20.0 * strongest * (1.0 - 1e-9), "{raised} against ω {strongest}");
    let model_toml: toml::Value = toml::from_str(&std::fs::read_to_string(out.join("model.toml")).unwrap()).unwrap();
    let written = model_toml["cell_types"][0]["faces"]["lateral"]["repulsion"].as_float().unwrap();
    assert!(written >= 20.0 * strongest * (1.0 - 1e-9), "model.toml's repulsion {written} against ω {strongest}");
    // The warning about adhesion beyond the checked regime comes exactly when a cell is there.
    let strong = cells.iter().any(|c| number(c, "adhesion_over_tension") > 0.6);
    let warned =
        result["warnings"].as_array().unwrap().iter().any(|w| w.as_str().unwrap().contains("beyond the range"));
    assert_eq!(strong, warned, "{result}");
    // The observed tissue carries each cell's tension and adhesion as a model reads them.
    let read = read_tissue(
        &out.join("tissue.vtp"),
        &ReadOptions { length_scale: LengthScale(Vec3::repeat(1.0)), orient: false },
    )
    .unwrap()
    .tissue;
    for cell in read.cells() {
        let id = cell.id().0.to_string();
        let o = cell.overrides();
        assert!(o.surface_tension.iter().all(|t| (t.unwrap() / gamma[&id] - 1.0).abs() < 1e-9), "{o:?}");
        assert!(o.adhesion.iter().all(|w| (w.unwrap() / omega[&id] - 1.0).abs() < 1e-9), "{o:?}");
    }
    // The intervals carry the coupled calibration's model error times per_cell.spring_model_error.
    let per_diameter = result["voxels_per_diameter"].as_f64().unwrap();
    let m = tissuefit::inference::PerCellConfig::default();
    for r in &interfaces {
        let free = r["cell_b"] == "0";
        let want = m.spring_model_error * m.model_error.at(free, Some(1.0 / per_diameter));
        assert!(m.spring_model_error > 1.0 && (number(r, "model_error") / want - 1.0).abs() < 1e-12, "{r:?}");
    }
    let refined = errors(&interfaces, "tension_mn_per_m");
    eprintln!("hetero4, spring map at 10 voxels per diameter: per-interface median {:.4}", median(refined.clone()));
    assert!(median(refined.clone()) <= 0.10, "{refined:?}");
}
