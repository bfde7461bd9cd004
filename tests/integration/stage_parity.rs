//! One stage layer: `tissuefit mesh` / `tissuefit measure` with flags, `tissuefit simulate` with a
//! model file, and `tissuefit run` with the same settings in a pipeline file write the same files (byte for byte, the wall-time fields
//! `wall_seconds` and `threads` aside), because both call `tissuefit::stages`.

use crate::support::cli::{ok, repo, short_demo_fit_pipeline, tissuefit};
use crate::support::run_dirs::{normalised_hash, stage_hashes};
use std::collections::BTreeMap;
use std::path::Path;

/// `name → normalised hash` of every file in `dir`.
fn hashes(dir: &Path) -> BTreeMap<String, String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let path = e.unwrap().path();
            (path.file_name().unwrap().to_string_lossy().into_owned(), normalised_hash(&path))
        })
        .collect()
}

#[test]
fn mesh_and_measure_write_the_same_files_from_the_cli_and_from_a_pipeline() {
    let tmp = tempfile::tempdir().unwrap();
    let labels = repo().join("data/demo/doublet.tif");
    let pipeline = tmp.path().join("p.toml");
    std::fs::write(
        &pipeline,
        format!(
            "[input]\nlabels = {labels:?}\nseed = 3\n\n[mesh]\ntarget_nodes = 150\nmin_voxels = 50\nborder = \"static\"\n\n\
             [measure]\ncontact_distance = 1e-7\ninclude_static = true\nexterior_free_fraction = 0.2\n",
            labels = labels.display().to_string()
        ),
    )
    .unwrap();
    let run = tmp.path().join("run");
    ok(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);

    let cli = tmp.path().join("cli");
    let (tissue, report) = (cli.join("mesh/tissue.vtp"), cli.join("mesh/report.json"));
    std::fs::create_dir_all(cli.join("mesh")).unwrap();
    ok(&[
        "mesh",
        labels.to_str().unwrap(),
        "--out",
        tissue.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
        "--seed",
        "3",
        "--target-nodes",
        "150",
        "--min-voxels",
        "50",
        "--border",
        "static",
    ]);
    // The pipeline measures its own mesh stage's tissue and names it relative to its measure folder
    // (`../mesh/tissue.vtp`): measure that very file from there.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .current_dir(run.join("measure"))
        .args(["measure", "../mesh/tissue.vtp", "--out", cli.join("measure").to_str().unwrap()])
        .args(["--contact-distance", "1e-7", "--include-static", "--exterior-free-fraction", "0.2"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    for stage in ["mesh", "measure"] {
        let (a, b) = (hashes(&run.join(stage)), hashes(&cli.join(stage)));
        assert_eq!(a, b, "{stage}: the pipeline's files differ from the CLI's");
    }
    let names: Vec<String> = hashes(&run.join("measure")).into_keys().collect();
    assert_eq!(names, ["cells.csv", "contacts.csv", "summary.json"]);
    // The reports are the full ones (timing and options included), not a pipeline-only subset.
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("mesh/report.json")).unwrap()).unwrap();
    for key in ["wall_seconds", "threads", "output", "min_voxels", "border", "cells"] {
        assert!(report.get(key).is_some(), "mesh/report.json has no `{key}`: {report}");
    }
    assert_eq!(report["output"], "tissue.vtp");
    assert_eq!(report["border"], "static");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("measure/summary.json")).unwrap()).unwrap();
    assert_eq!(summary["input"], "tissue");
    assert_eq!(summary["file"], "../mesh/tissue.vtp");
    assert_eq!(summary["cells"], 2);
    assert!(summary["wall_seconds"].as_f64().is_some(), "{summary}");
}

#[test]
fn a_tissue_without_contacts_gets_a_contacts_header_from_run_and_from_measure() {
    let tmp = tempfile::tempdir().unwrap();
    let pipeline = tmp.path().join("p.toml");
    std::fs::write(&pipeline, "[input]\ngenerate = { kind = \"sphere\", cell_size = 4e-6 }\n\n[measure]\n").unwrap();
    let run = tmp.path().join("run");
    ok(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    let alone = tmp.path().join("alone");
    ok(&["measure", run.join("mesh/tissue.vtp").to_str().unwrap(), "--out", alone.to_str().unwrap()]);
    for dir in [run.join("measure"), alone] {
        let text = std::fs::read_to_string(dir.join("contacts.csv")).unwrap();
        let mut lines = text.lines();
        let header = lines.next().unwrap_or_default();
        assert!(header.starts_with("cell_a,cell_b,area"), "{}: {text:?}", dir.display());
        assert_eq!(lines.count(), 0, "one cell touches nothing: {text:?}");
        let cells = std::fs::read_to_string(dir.join("cells.csv")).unwrap();
        assert_eq!(cells.lines().count(), 2, "header and one cell: {cells}");
    }
    assert_eq!(
        normalised_hash(&run.join("measure/contacts.csv")),
        normalised_hash(&tmp.path().join("alone/contacts.csv"))
    );
}

#[test]
fn a_pipeline_meshes_nuclei_as_tissuefit_mesh_does_and_its_fit_refuses_them() {
    let tmp = tempfile::tempdir().unwrap();
    let (cells, nuclei) = (tmp.path().join("cells.tif"), tmp.path().join("nuclei.tif"));
    ok(&[
        "generate",
        "labels",
        "--kind",
        "aggregate",
        "--cells",
        "6",
        "--shape",
        "64",
        "--voxel-size",
        "0.5um",
        "--seed",
        "2",
        "--out",
        cells.to_str().unwrap(),
        "--nuclei",
        nuclei.to_str().unwrap(),
    ]);
    let pipeline = tmp.path().join("p.toml");
    let text = "[input]\nlabels = \"cells.tif\"\nnuclei = \"nuclei.tif\"\n\n[mesh]\ntarget_nodes = 150\n";
    std::fs::write(&pipeline, text).unwrap();
    let run = tmp.path().join("run");
    ok(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);

    // The same meshing from the CLI; the report names its inputs as given, so give the paths the
    // pipeline resolved (relative to its file).
    let cli = tmp.path().join("cli");
    std::fs::create_dir_all(&cli).unwrap();
    let (tissue, report) = (cli.join("tissue.vtp"), cli.join("report.json"));
    ok(&[
        "mesh",
        cells.to_str().unwrap(),
        "--nuclei",
        nuclei.to_str().unwrap(),
        "--target-nodes",
        "150",
        "--out",
        tissue.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(hashes(&run.join("mesh")), hashes(&cli));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("mesh/report.json")).unwrap()).unwrap();
    let kept = report["nuclei"].as_array().unwrap().iter().filter(|n| n["status"] == "kept").count();
    assert_eq!(kept, 6, "{report}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("measure/summary.json")).unwrap()).unwrap();
    assert_eq!(summary["cells_with_nucleus"], 6, "{summary}");
    // The nuclei file is an input of the run: hashed in the manifest.
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("manifest.json")).unwrap()).unwrap();
    let inputs: Vec<&str> =
        manifest["inputs"].as_array().unwrap().iter().map(|i| i["path"].as_str().unwrap()).collect();
    assert!(inputs.iter().any(|p| p.ends_with("nuclei.tif")), "{inputs:?}");

    // A fit does not take nuclei yet: refused before anything runs, naming the key.
    std::fs::write(&pipeline, format!("{text}\n[fit.parameters.surface_tension]\nbounds = [1e-4, 1e-3]\n")).unwrap();
    let o = tissuefit(&["run", pipeline.to_str().unwrap(), "--out", tmp.path().join("fit").to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("input.nuclei"), "{stderr}");
    assert!(!tmp.path().join("fit").exists(), "nothing written for a refused pipeline");
}

/// `tissuefit simulate TISSUE --config MODEL --max-steps N` and the pipeline's `[simulate]` with the
/// same model write the same files: the frames, `stats.csv`, `events.csv`, the final tissue, the run
/// summary (wall times aside), `config.toml` and the final tissue measured (`cells.csv`,
/// `contacts.csv`, `morphology.json`).
#[test]
fn simulate_writes_the_same_files_from_the_cli_and_from_a_pipeline() {
    let tmp = tempfile::tempdir().unwrap();
    let labels = repo().join("data/demo/doublet.tif");
    let model = repo().join("data/demo/doublet_truth.toml");
    let pipeline = tmp.path().join("p.toml");
    std::fs::write(
        &pipeline,
        format!(
            "[input]\nlabels = {labels:?}\n\n[mesh]\ntarget_nodes = 120\n\n[simulate]\nmodel = {model:?}\n\
             [simulate.model_overrides.simulation]\nmax_steps = 300\n",
            labels = labels.display().to_string(),
            model = model.display().to_string()
        ),
    )
    .unwrap();
    let run = tmp.path().join("run");
    let o = tissuefit(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", String::from_utf8_lossy(&o.stderr));

    // The same model file with the same overrides given as flags; the tissue named as the run names
    // it (relative to its simulate folder), so that summary.json's `input` agrees too.
    let cli = tmp.path().join("cli");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .current_dir(run.join("simulate"))
        .args(["simulate", "../mesh/tissue.vtp", "--config", model.to_str().unwrap()])
        .args(["--max-steps", "300", "--out", cli.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", String::from_utf8_lossy(&o.stderr));
    let (a, b) = (stage_hashes(&run, &["simulate"]), stage_hashes(tmp.path(), &["cli"]));
    let b: BTreeMap<String, String> = b.into_iter().map(|(k, v)| (k.replacen("cli/", "simulate/", 1), v)).collect();
    assert_eq!(a, b, "the pipeline's simulate files differ from `tissuefit simulate`'s");
    for file in ["summary.json", "morphology.json", "cells.csv", "contacts.csv", "stats.csv", "frames.pvd"] {
        assert!(a.contains_key(&format!("simulate/{file}")), "{file} missing: {a:?}");
    }
    assert!(a.keys().any(|k| k.starts_with("simulate/frames/frame_")), "{a:?}");
}

/// `tissuefit fit --config PIPELINE.toml` and `tissuefit run PIPELINE.toml` write the same fit
/// files: the CLI meshes the labels itself, the pipeline reads back its mesh stage's tissue, and both
/// fit it with the same resolved config (`fit.toml`), the same trace, result and plots (wall times
/// aside).
#[test]
fn fit_writes_the_same_files_from_the_cli_and_from_a_pipeline() {
    let tmp = tempfile::tempdir().unwrap();
    let pipeline = tmp.path().join("p.toml");
    std::fs::write(&pipeline, short_demo_fit_pipeline(5, 8e-4, 3)).unwrap();
    // A short budget: neither may converge (exit code 1), but both must finish and write a result.
    let run = tmp.path().join("run");
    let o = tissuefit(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", String::from_utf8_lossy(&o.stderr));
    let cli = tmp.path().join("fit");
    let o = tissuefit(&["fit", "--config", pipeline.to_str().unwrap(), "--out", cli.to_str().unwrap()]);
    assert!(o.status.code().is_some_and(|c| c <= 1), "{}", String::from_utf8_lossy(&o.stderr));

    let (a, b) = (stage_hashes(&run, &["fit"]), stage_hashes(tmp.path(), &["fit"]));
    assert_eq!(a, b, "the pipeline's fit files differ from `tissuefit fit`'s");
    for file in [
        "trace.csv",
        "result.json",
        "fit.toml",
        "model.toml",
        "objective.png",
        "best.vtp",
        "best.toml",
        "residuals.csv",
    ] {
        assert!(a.contains_key(&format!("fit/{file}")), "{file} missing: {a:?}");
    }
}
