//! The scenario pipelines of `pipelines/` (issue 10) and the generated input they use: every pipeline,
//! sweep and model file there loads and validates (so none can rot), and a pipeline with
//! `[input] generate = {...}` runs, reruns its mesh stage when the table changes, and rejects unknown
//! keys with a suggestion.

use crate::support::cli::{repo, tissuefit};
use std::path::{Path, PathBuf};
use tissuefit::mechanics::Parameters;
use tissuefit::pipeline::{PipelineConfig, Sweep, is_pipeline_file};

fn toml_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    files
}

#[test]
fn every_pipeline_sweep_and_model_file_of_the_repository_loads_and_validates() {
    let dir = repo().join("pipelines");
    let (mut pipelines, mut sweeps) = (0, 0);
    for path in toml_files(&dir) {
        if is_pipeline_file(&path) {
            // The real-data pipeline needs the data, which CI does not have: schema only.
            let name = path.file_name().unwrap().to_string_lossy();
            if name.starts_with("real-") {
                let text = std::fs::read_to_string(&path).unwrap();
                PipelineConfig::from_toml_str(&text, &path).unwrap_or_else(|e| panic!("{e}"));
            } else {
                PipelineConfig::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            }
            pipelines += 1;
        } else if std::fs::read_to_string(&path).unwrap().parse::<toml::Table>().unwrap().contains_key("base") {
            let sweep = Sweep::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(!sweep.runs.is_empty(), "{}", path.display());
            let o = tissuefit(&["sweep", path.to_str().unwrap(), "--list"]);
            let stdout = String::from_utf8_lossy(&o.stdout);
            assert!(o.status.success(), "{}: {}", path.display(), String::from_utf8_lossy(&o.stderr));
            assert_eq!(stdout.lines().count(), sweep.runs.len(), "{}: {stdout}", path.display());
            sweeps += 1;
        } else {
            // A model file (`simulate --config`), e.g. growth.toml.
            let params = Parameters::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            params.validate().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
    }
    assert!(pipelines >= 3 && sweeps >= 2, "{pipelines} pipelines, {sweeps} sweeps");
    for path in toml_files(&dir.join("models")) {
        let params = Parameters::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        params.validate().unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
}

#[test]
fn the_vesicle_sweep_sets_all_three_face_types_of_each_run_to_one_value() {
    let sweep = Sweep::load(&repo().join("pipelines/vesicle-layers-sweep.toml")).unwrap();
    assert_eq!(sweep.runs.len(), 6);
    for run in &sweep.runs {
        let config: toml::Table = toml::from_str(&run.pipeline).unwrap();
        let faces = &config["simulate"]["model_overrides"]["cell_types"][0]["faces"];
        for key in ["surface_tension", "adhesion"] {
            let values: Vec<f64> =
                ["apical", "lateral", "basal"].iter().map(|f| faces[f][key].as_float().unwrap()).collect();
            assert!(values.iter().all(|v| *v == values[0]), "run {}: {key} {values:?}", run.index);
        }
    }
}

fn write_pipeline(dir: &Path, generate: &str) -> PathBuf {
    let path = dir.join("generated.toml");
    std::fs::write(&path, format!("[input]\ngenerate = {{ {generate} }}\nseed = 3\n")).unwrap();
    path
}

#[test]
fn a_generated_input_is_meshed_by_the_mesh_stage_and_rerun_when_its_table_changes() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let spec = "kind = \"sheet\", cells = 7, cell_size = 8e-6, min_edge_length = 2e-6, static_border = true";
    let path = write_pipeline(tmp.path(), spec);
    let run = |path: &Path| {
        let o = tissuefit(&["run", path.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let first = run(&path);
    assert!(first.contains("mesh: done") && first.contains("generated a sheet"), "{first}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("mesh/report.json")).unwrap()).unwrap();
    assert_eq!(report["spec"]["cells"], 7);
    assert_eq!(report["spec"]["seed"], 3, "the seed defaults to input.seed");
    assert_eq!(
        report["kinds"]["epithelial"]["bodies"].as_u64().unwrap()
            + report["kinds"]["static"]["bodies"].as_u64().unwrap(),
        7
    );
    assert!(report["length_scale"].as_f64().unwrap() > 6e-6);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("measure/summary.json")).unwrap()).unwrap();
    assert!(summary["cells"].as_u64().unwrap() >= 1, "{summary}");
    // Unchanged: skipped. A changed table: the mesh stage runs again.
    let second = run(&path);
    assert!(second.contains("mesh: skipped"), "{second}");
    let path = write_pipeline(tmp.path(), &spec.replace("cells = 7", "cells = 8"));
    let third = run(&path);
    assert!(third.contains("mesh: done"), "{third}");
}

#[test]
fn a_bad_generate_table_is_an_error_naming_the_key() {
    let tmp = tempfile::tempdir().unwrap();
    let check = |generate: &str, expect: &[&str]| {
        let path = write_pipeline(tmp.path(), generate);
        let out = tmp.path().join("run");
        let o = tissuefit(&["run", path.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{generate}: {err}");
        for e in expect {
            assert!(err.contains(e), "{generate}: expected `{e}` in: {err}");
        }
    };
    check("kind = \"vesicle\", cell = 24", &["cell", "did you mean `cells`?"]);
    check("kind = \"vesicel\"", &["input.generate.kind", "vesicle"]);
    check("kind = \"sphere\", static_border = true", &["input.generate", "static border"]);
    check("kind = \"sheet\", nucleus_radius = 0.4", &["input.generate.nucleus_radius", "nuclei = true"]);
    check("kind = \"vesicle\", cells = 24, cell_size = 8e-6, min_edge_length = 4e-6", &["input.generate", "4 ×"]);
    // Exactly one input.
    let path = tmp.path().join("two.toml");
    std::fs::write(&path, "[input]\nmesh = \"x.vtp\"\ngenerate = { kind = \"sphere\" }\n").unwrap();
    let o = tissuefit(&["run", path.to_str().unwrap(), "--out", tmp.path().join("r2").to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("not several"), "{err}");
}
