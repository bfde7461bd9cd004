//! Presets (`preset = "NAME"` in a pipeline file): the preset's sections are the base, the file's own
//! keys win, unknown names are refused with the choices, and every preset gives a valid pipeline.

use crate::support::cli::{repo, tissuefit};
use std::path::Path;
use tissuefit::pipeline::PipelineConfig;
use tissuefit::pipeline::preset::PRESETS;

const DEMO_LABELS: &str = "[input]\nlabels = \"data/demo/doublet.tif\"\n";

fn load(text: &str) -> Result<PipelineConfig, String> {
    PipelineConfig::load_text(text, &repo().join("p.toml")).map_err(|e| e.to_string())
}

#[test]
fn every_preset_makes_a_valid_pipeline_that_fits() {
    for preset in PRESETS {
        let config = load(&format!("preset = \"{}\"\n{DEMO_LABELS}", preset.name))
            .unwrap_or_else(|e| panic!("preset {}: {e}", preset.name));
        let fit = config.fit.as_ref().unwrap_or_else(|| panic!("preset {} has no [fit]", preset.name));
        let fitted: Vec<&String> = fit.parameters.iter().filter(|(_, p)| p.bounds.is_some()).map(|(n, _)| n).collect();
        assert!(!fitted.is_empty(), "preset {} fits nothing", preset.name);
        fit.base_parameters().unwrap_or_else(|e| panic!("preset {}: model: {e}", preset.name));
        assert_eq!(config.preset.as_deref(), Some(preset.name));
        // The text `tissuefit config preset NAME` prints is the preset.
        let o = tissuefit(&["config", "preset", preset.name]);
        assert_eq!(o.status.code(), Some(0));
        assert_eq!(String::from_utf8_lossy(&o.stdout), preset.text);
    }
    let o = tissuefit(&["config", "presets"]);
    let listed = String::from_utf8_lossy(&o.stdout);
    assert!(PRESETS.iter().all(|p| listed.contains(p.name) && listed.contains(&p.summary[..20])), "{listed}");
}

#[test]
fn the_files_own_keys_win_over_the_preset_and_tables_merge() {
    let text = format!(
        "preset = \"compact-embryo\"\n{DEMO_LABELS}[mesh]\ntarget_nodes = 150\n\
         [fit.optimizer]\nmax_evaluations = 5\n[fit.parameters.surface_tension_lateral]\nbounds = [3e-4, 9e-4]\n"
    );
    let config = load(&text).unwrap();
    let fit = config.fit.unwrap();
    assert_eq!(config.mesh.target_nodes, 150);
    assert_eq!(fit.optimizer.max_evaluations, 5);
    // The preset's other optimizer keys and the parameter's other keys stay.
    assert_eq!(fit.optimizer.tolerance, 0.5);
    let lateral = &fit.parameters["surface_tension_lateral"];
    assert_eq!(lateral.bounds, Some([3e-4, 9e-4]));
    assert_eq!(lateral.initial, Some(6e-4));
    let model = fit.base_parameters().unwrap();
    assert_eq!(model.numerics.contact_model, tissuefit::mechanics::ContactModel::Coupling);
}

#[test]
fn a_model_file_of_ones_own_replaces_the_presets_model() {
    let text = format!("preset = \"compact-embryo\"\n{DEMO_LABELS}[fit]\nmodel = \"data/demo/doublet_truth.toml\"\n");
    let config = load(&text).unwrap();
    let fit = config.fit.unwrap();
    assert!(fit.model_overrides.is_none(), "the preset's model_overrides must go with its model");
    assert!(fit.model.as_deref().is_some_and(|m| m.ends_with(Path::new("data/demo/doublet_truth.toml"))));
}

#[test]
fn an_unknown_preset_or_key_is_refused_naming_the_file_and_the_choices() {
    let e = load(&format!("preset = \"compact_embryo\"\n{DEMO_LABELS}")).unwrap_err();
    assert!(e.contains("p.toml") && e.contains("did you mean `compact-embryo`"), "{e}");
    assert!(PRESETS.iter().all(|p| e.contains(p.name)), "{e}");
    // A misspelt key still gets its line in the file, preset or not.
    let e = load(&format!("preset = \"epithelium\"\n{DEMO_LABELS}[fit.optimizr]\nmax_evaluations = 3\n")).unwrap_err();
    assert!(e.contains("p.toml:4") && e.contains("optimizer"), "{e}");
    // A value the merged pipeline refuses names the preset.
    let e = load(&format!(
        "preset = \"epithelium\"\n{DEMO_LABELS}[fit.parameters.surface_tension_lateral]\nbounds = [1e-3, 1e-4]\n"
    ))
    .unwrap_err();
    assert!(e.contains("with preset `epithelium`"), "{e}");
}

/// The "Fit your own segmentation" tutorial (docs/src/tutorials/own-data.md): the real C. elegans
/// 4-cell embryo of ../shared/data/real through `pipelines/own-embryo.toml` (the preset and the
/// labels, nothing else) gives a converged fit and a determined ratio. ≈150 s on 2 threads.
/// Needs ../shared/data/real (CI runs the ignored tests when it is there).
#[test]
#[ignore = "needs ../shared/data/real"]
fn the_own_data_tutorial_fits_the_real_embryo_to_a_determined_ratio() {
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    let pipeline = repo().join("pipelines/own-embryo.toml");
    let o = tissuefit(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("fit/result.json")).unwrap()).unwrap();
    assert_eq!(result["converged"].as_bool(), Some(true), "{result}");
    let ratio = &result["ratios"]["lateral_over_apical"];
    assert_eq!(ratio["determined"].as_bool(), Some(true), "{ratio}");
    let (value, lo, hi) =
        (ratio["value"].as_f64().unwrap(), ratio["range"][0].as_f64().unwrap(), ratio["range"][1].as_f64().unwrap());
    eprintln!("C. elegans 4-cell: lateral_over_apical = {value:.4} [{lo:.4}, {hi:.4}]");
    // Inside the search bounds [0.1, 1] with both sides of the range closed away from them.
    assert!(0.1 < lo && lo < value && value < hi && hi < 1.0, "{ratio}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("lateral_over_apical") && stdout.contains("(determined)"), "{stdout}");
}

/// An outside truth for the spring model: Surface Evolver's doublet (validation/evolver/fixtures,
/// γ_lateral/γ_free = 0.6, voxelised at 10 voxels per diameter) has the shape of a spring doublet
/// with w/(2γ) = 1 − 0.6 = 0.4 (γ_free·A_free + 2γ_lateral·A_contact = γ·A_free + (2γ − w)·A_contact).
/// The "aggregate" preset with nothing but the labels must recover it within 10 % (the issue's
/// round-trip bound; measured −0.1…+4.3 % at 10 voxels as the preset's optimiser settings changed,
/// +2.7 % at 20 voxels, by validation/evolver/run_fits.py --spring: the optimiser stops within the
/// forward model's own scatter), report it determined with a range that holds it, and relax its best point with a
/// repulsion that holds the fitted adhesion (ξ ≥ 20·ω, raised with ω in every evaluation: with the
/// default ξ = 1e9 Pa/m evaluations at w/(2γ) ≥ 0.5 let the cells detach or one vanish). ≈ 20 s.
#[test]
fn the_aggregate_preset_recovers_surface_evolvers_doublet_as_spring_adhesion() {
    let tmp = tempfile::tempdir().unwrap();
    let labels = repo().join("validation/evolver/fixtures/doublet/labels_10.tif");
    let pipeline = tmp.path().join("p.toml");
    std::fs::write(
        &pipeline,
        format!(
            "preset = \"aggregate\"\n[input]\nlabels = \"{}\"\n[demo]\ntruth = {{ adhesion_energy_over_tension = 0.4 }}\n\
             tolerance = 0.1\n",
            labels.display()
        ),
    )
    .unwrap();
    let run = tmp.path().join("run");
    let o = tissuefit(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("fit/result.json")).unwrap()).unwrap();
    let ratio = &result["ratios"]["adhesion_energy_over_tension"];
    let (value, lo, hi) =
        (ratio["value"].as_f64().unwrap(), ratio["range"][0].as_f64().unwrap(), ratio["range"][1].as_f64().unwrap());
    eprintln!("Evolver doublet as springs: w/(2γ) = {value:.4} [{lo:.4}, {hi:.4}] (truth 0.4)");
    assert!((value - 0.4).abs() <= 0.1 * 0.4, "{ratio}");
    assert_eq!(ratio["determined"].as_bool(), Some(true), "{ratio}");
    assert!(lo <= 0.4 && 0.4 <= hi, "{ratio}");
    let best = tissuefit::mechanics::Parameters::load(&run.join("fit/best.toml")).unwrap();
    for (_, face) in best.cell_types[0].faces.iter() {
        assert!(face.adhesion > 0.0 && face.repulsion >= 20.0 * face.adhesion * (1.0 - 1e-12), "{face:?}");
    }
}
