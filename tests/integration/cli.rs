//! End-to-end tests of the `tissuefit` binary in a temporary directory.

use crate::support::cli::tissuefit;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use tissuefit::mechanics::Parameters;

fn demo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/cell_quartet.vtk")
}

fn json(out: &Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("stdout is not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)))
}

#[test]
fn inspect_json_has_the_documented_keys() {
    let out = tissuefit(&["inspect", demo().to_str().unwrap(), "--json"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let v = json(&out);
    assert!(v["file"].as_str().unwrap().ends_with("cell_quartet.vtk"));
    let cells = v["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 4);
    for c in cells {
        for key in ["id", "kind", "nodes", "faces", "volume", "area", "sphericity", "valid", "defect"] {
            assert!(c.get(key).is_some(), "cell lacks {key}: {c}");
        }
        assert_eq!(c["valid"], true);
        let psi = c["sphericity"].as_f64().unwrap();
        assert!(psi > 0.99 && psi < 1.0, "near-spherical demo cells: Ψ = {psi}");
    }
    let t = &v["totals"];
    assert_eq!((t["cells"].as_u64(), t["valid_cells"].as_u64()), (Some(4), Some(4)));
    let nodes: u64 = cells.iter().map(|c| c["nodes"].as_u64().unwrap()).sum();
    assert_eq!(t["nodes"].as_u64(), Some(nodes));
}

#[test]
fn inspect_exits_1_on_a_defective_cell_and_2_on_a_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    // Flip one face of the demo's first cell by swapping two ids in its first face record.
    let text = std::fs::read_to_string(demo()).unwrap();
    let cells_at = text.find("CELLS").unwrap();
    let line_end = text[cells_at..].find('\n').unwrap() + cells_at + 1;
    let record_end = text[line_end..].find('\n').unwrap() + line_end;
    let record: Vec<&str> = text[line_end..record_end].split(' ').collect();
    let mut flipped = record.clone();
    flipped.swap(3, 4); // record: nInts nFaces 3 a b c …
    let broken = format!("{}{}{}", &text[..line_end], flipped.join(" "), &text[record_end..]);
    let path = dir.path().join("flipped.vtk");
    std::fs::write(&path, broken).unwrap();
    let out = tissuefit(&["inspect", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("3/4 cells valid") && stdout.contains("oriented inconsistently"), "{stdout}");

    let out = tissuefit(&["inspect", dir.path().join("absent.vtk").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("absent.vtk"));
}

#[test]
fn convert_round_trips_through_vtp_and_legacy() {
    let dir = tempfile::tempdir().unwrap();
    let vtp = dir.path().join("quartet.vtp");
    let vtk = dir.path().join("quartet.vtk");
    let out = tissuefit(&["convert", demo().to_str().unwrap(), vtp.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let out = tissuefit(&["convert", vtp.to_str().unwrap(), vtk.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let volumes = |p: &Path| -> Vec<f64> {
        let v = json(&tissuefit(&["inspect", p.to_str().unwrap(), "--json"]));
        v["cells"].as_array().unwrap().iter().map(|c| c["volume"].as_f64().unwrap()).collect()
    };
    let (a, b, c) = (volumes(&demo()), volumes(&vtp), volumes(&vtk));
    assert_eq!(a, b);
    assert_eq!(a, c);
    // The .vtp carries the pressure field computed from the default parameters.
    let bytes = std::fs::read(&vtp).unwrap();
    assert!(String::from_utf8_lossy(&bytes[..bytes.len().min(20000)]).contains("Name=\"pressure\""));
}

#[test]
fn convert_to_an_unknown_format_fails_cleanly_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("quartet.xyz");
    let out = tissuefit(&["convert", demo().to_str().unwrap(), out_path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("quartet.xyz"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "a failed convert must leave no file");
}

#[test]
fn length_unit_scales_lengths() {
    let base = json(&tissuefit(&["inspect", demo().to_str().unwrap(), "--json"]));
    let scaled = json(&tissuefit(&["inspect", demo().to_str().unwrap(), "--json", "--length-unit", "2um"]));
    let (v0, v1) = (base["cells"][0]["volume"].as_f64().unwrap(), scaled["cells"][0]["volume"].as_f64().unwrap());
    assert!((v1 / v0 - 8e-18).abs() < 1e-27, "{v1} / {v0}");
    let bad = tissuefit(&["inspect", demo().to_str().unwrap(), "--length-unit", "furlongs"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("furlongs"));
}

#[test]
fn config_defaults_is_a_complete_valid_config() {
    let out = tissuefit(&["config", "defaults"]);
    assert_eq!(out.status.code(), Some(0));
    let text = String::from_utf8(out.stdout).unwrap();
    let parsed = Parameters::from_toml_str(&text, "defaults").unwrap();
    assert_eq!(parsed, Parameters::default());
    assert!(text.lines().filter(|l| l.starts_with('#')).count() > 60, "every field is commented");

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("defaults.toml");
    std::fs::write(&path, &text).unwrap();
    let check = tissuefit(&["config", "check", path.to_str().unwrap()]);
    assert_eq!(check.status.code(), Some(0), "{}", String::from_utf8_lossy(&check.stderr));
}

#[test]
fn config_check_names_the_bad_key_and_value() {
    let dir = tempfile::tempdir().unwrap();
    let typo = dir.path().join("typo.toml");
    std::fs::write(&typo, "[numerics]\ntime_stepp = 1e-7\n").unwrap();
    let out = tissuefit(&["config", "check", typo.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("typo.toml") && err.contains("time_stepp"), "{err}");

    let unstable = dir.path().join("unstable.toml");
    std::fs::write(&unstable, "[numerics]\ntime_step = 1e-4\n").unwrap();
    let out = tissuefit(&["config", "check", unstable.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("unstable.toml") && err.contains("time_step"), "{err}");
}

#[test]
fn simulate_relaxes_the_demo_and_writes_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = tissuefit(&["simulate", demo().to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    for key in [
        "steps",
        "force_evaluations",
        "converged",
        "residual",
        "wall_seconds",
        "threads",
        "cells",
        "nodes",
        "seconds_per_node_step",
    ] {
        assert!(summary.get(key).is_some(), "summary.json lacks {key}: {summary}");
    }
    assert_eq!(summary["converged"], true);
    assert!(summary["residual"].as_f64().unwrap() < 1e-3);
    let frames = summary["frames"].as_u64().unwrap() as usize;
    assert!(frames >= 2);
    // stats.csv: a header and one row per cell per sample.
    let stats = std::fs::read_to_string(out.join("stats.csv")).unwrap();
    assert_eq!(stats.lines().count(), 1 + 4 * frames);
    assert!(stats.lines().next().unwrap().starts_with("step,time,cell,kind,"));
    assert!(!out.join("stats.csv.partial").exists());
    let pvd = std::fs::read_to_string(out.join("frames.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), frames);
    assert_eq!(std::fs::read_dir(out.join("frames")).unwrap().count(), frames);
    // final.vtk is a valid input again, and config.toml a valid config.
    let again = json(&tissuefit(&["inspect", out.join("final.vtk").to_str().unwrap(), "--json"]));
    assert_eq!(again["totals"]["valid_cells"].as_u64(), Some(4));
    Parameters::load(&out.join("config.toml")).unwrap();

    // The same folder again: refused without --force, accepted with it.
    let o = tissuefit(&["simulate", demo().to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--force"));
    let o = tissuefit(&[
        "simulate",
        demo().to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--force",
        "--max-steps",
        "3",
    ]);
    // Three steps cannot relax the demo: completed, not converged, exit 1.
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!((summary["converged"].as_bool(), summary["steps"].as_u64()), (Some(false), Some(3)));
}

#[test]
fn simulate_time_mode_runs_the_duration() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("time");
    let o = tissuefit(&[
        "simulate",
        demo().to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--mode",
        "time",
        "--duration",
        "2e-6",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["steps"].as_u64(), Some(20));
    assert!((summary["simulated_time"].as_f64().unwrap() - 2e-6).abs() < 1e-12);
}

#[test]
fn simulate_rejects_a_bad_config_before_writing_anything() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("bad.toml");
    std::fs::write(&config, "[simulation]\nmode = \"forever\"\n").unwrap();
    let out = dir.path().join("run");
    let o = tissuefit(&[
        "simulate",
        demo().to_str().unwrap(),
        "--config",
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.toml") && err.contains("forever"), "{err}");
    assert!(!out.exists());
}

#[test]
fn bench_prints_one_json_object() {
    let o = tissuefit(&["bench", "forces-cell", "--repeat", "2"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let v = json(&o);
    for key in ["scenario", "threads", "cells", "nodes", "steps", "wall_seconds", "seconds_per_node_step"] {
        assert!(v.get(key).is_some(), "bench output lacks {key}: {v}");
    }
    assert_eq!(v["nodes"].as_u64(), Some(1016));
    assert!(v["seconds_per_node_step"].as_f64().unwrap() > 0.0);
}

/// Issue 24's scenario benchmark: `bench relax` runs the relaxation `simulate` would run and says
/// where the time went; the stages it names are parts of the run, so they sum to at most its wall
/// time, and the node-steps are the force evaluations times the nodes.
#[test]
fn bench_relax_reports_the_cost_of_each_stage_per_node_step() {
    let o = tissuefit(&["--threads", "1", "bench", "relax", demo().to_str().unwrap(), "--steps", "30"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let v = json(&o);
    assert_eq!(v["scenario"], "relax");
    let (evaluations, node_steps) = (v["force_evaluations"].as_u64().unwrap(), v["node_steps"].as_u64().unwrap());
    let nodes = v["nodes"].as_u64().unwrap();
    assert!(evaluations >= 30 && v["steps"].as_u64() == Some(30), "{v}");
    assert!(node_steps >= evaluations * nodes / 2 && node_steps <= evaluations * nodes * 2, "{v}");
    let parts = v["breakdown_seconds_per_node_step"].as_object().unwrap();
    let staged: f64 = ["coupling", "internal_forces", "contact_broad", "contact_narrow", "contact_apply", "remeshing"]
        .iter()
        .map(|k| parts[*k].as_f64().unwrap())
        .sum();
    let per_step = v["seconds_per_node_step"].as_f64().unwrap();
    assert!(parts["internal_forces"].as_f64().unwrap() > 0.0 && parts["contact_narrow"].as_f64().unwrap() > 0.0, "{v}");
    assert!(staged > 0.0 && staged <= per_step * 1.000001, "stages {staged} > the whole {per_step}: {v}");
    assert!(parts["contact_lists"].as_f64().unwrap() <= parts["contact_broad"].as_f64().unwrap(), "{v}");
    let o = tissuefit(&["bench", "relax"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("relax needs a tissue FILE"));
}

/// Issue 24's fit benchmark: `bench fit` runs the aggregate round trip (truth, labels, fit) and prints
/// its cost and accuracy; on a small aggregate with a tiny budget the fit misses the truth, and the
/// benchmark says so in its JSON and its exit status (1) instead of printing a time as if it counted.
#[test]
fn bench_fit_reports_cost_and_accuracy_and_fails_when_inaccurate() {
    let o = tissuefit(&["bench", "fit", "--cells", "8", "--evaluations", "3", "--shifts", "1"]);
    let v = json(&o);
    assert_eq!(v["scenario"], "fit");
    let accurate = v["accurate"].as_bool().unwrap();
    assert_eq!(o.status.code(), Some(if accurate { 0 } else { 1 }), "{v}");
    let error = v["error_percent"].as_f64().unwrap();
    let recovered = v["recovered"].as_f64().unwrap();
    assert!((100.0 * (recovered - 0.2) / 0.2 - error).abs() < 1e-9, "{v}");
    assert_eq!(accurate, error.abs() <= 10.0 && v["determined"] == true, "{v}");
    // Every evaluation (the fit's and the profile's) runs two passes of at most 1,500 steps.
    let evaluations = v["evaluations"].as_u64().unwrap() + v["profile_evaluations"].as_u64().unwrap();
    let steps = v["fit_steps"].as_u64().unwrap();
    assert!(evaluations >= 3 && steps > 0 && steps <= evaluations * 3000, "{v}");
    let nodes = v["nodes"].as_f64().unwrap();
    assert_eq!(v["fit_node_steps"].as_f64().unwrap(), steps as f64 * nodes);
    let at_truth = &v["evaluation_at_truth"];
    assert_eq!(at_truth["steps"].as_u64(), Some(3000), "{v}");
    for key in ["relax_wall_seconds", "measure_wall_seconds"] {
        assert!(at_truth[key].as_f64().unwrap() > 0.0, "{key}: {v}");
    }
    assert!(v["fit_wall_seconds"].as_f64().unwrap() > at_truth["relax_wall_seconds"].as_f64().unwrap(), "{v}");
    let o = tissuefit(&["bench", "fit", "--ratio=-1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--ratio"));
}

/// Issue 23, item 2: no output may destroy an input or replace what is not a regular file. Each
/// refusal exits 2 with a message naming the option and the path, before any work, and leaves the
/// file it would have replaced byte for byte (and a FIFO a FIFO).
#[test]
fn an_output_that_is_an_input_a_folder_a_fifo_or_of_the_wrong_format_is_refused_and_nothing_changes() {
    let dir = tempfile::tempdir().unwrap();
    let labels = dir.path().join("labels.tif");
    std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/doublet.tif"), &labels).unwrap();
    let tissue = dir.path().join("t.vtk");
    std::fs::copy(demo(), &tissue).unwrap();
    let original = std::fs::read(&labels).unwrap();
    let (l, t) = (labels.to_str().unwrap(), tissue.to_str().unwrap());
    let out_vtp = dir.path().join("t.vtp");
    let o = out_vtp.to_str().unwrap();
    let refused = |args: &[&str], expect: &[&str]| {
        let out = tissuefit(args);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        for e in expect {
            assert!(err.contains(e), "{args:?}: `{e}` not in: {err}");
        }
        assert_eq!(std::fs::read(&labels).unwrap(), original, "{args:?} changed the input");
    };
    // The reproducers of the issue.
    refused(&["mesh", l, "--out", o, "--report", l], &["--report", "labels.tif", "extension .json"]);
    refused(&["voxelize", t, "--like", l, "--out", l], &["--out", "also the input --like", "labels.tif"]);
    assert!(!out_vtp.exists(), "the mesh was written although the report was refused");
    // The input under another name (a hard link) is still the input.
    let alias = dir.path().join("alias.tif");
    std::fs::hard_link(&labels, &alias).unwrap();
    refused(&["voxelize", t, "--like", l, "--out", alias.to_str().unwrap()], &["also the input --like"]);
    // A FIFO (what `--report /dev/null` is to the program) is refused, never replaced by a file.
    let fifo = dir.path().join("report.json");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    refused(&["mesh", l, "--out", o, "--report", fifo.to_str().unwrap()], &["--report", "FIFO", "never replaces"]);
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
    // A folder where a file is meant, and a file where a folder is meant.
    refused(&["convert", t, dir.path().to_str().unwrap()], &["OUTPUT", "is a directory"]);
    refused(&["measure", t, "--out", l], &["--out", "where a folder is meant"]);
    // Wrong extensions for the format.
    refused(&["voxelize", t, "--voxel-size", "1um", "--out", o], &["--out", "extension .tif or .tiff"]);
    refused(&["render", t, "--out", dir.path().join("v.jpg").to_str().unwrap()], &["--out", ".png"]);
    // The tissue given as its own conversion target.
    let before = std::fs::read(&tissue).unwrap();
    let out = tissuefit(&["convert", t, t]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("also the input INPUT"));
    assert_eq!(std::fs::read(&tissue).unwrap(), before);
}

/// Issue 23, item 8: `fit --resume` with nothing to resume started afresh, silently. Now an error
/// naming the folder, before any work, and nothing written.
#[test]
fn fit_resume_without_a_trace_is_an_error_naming_the_folder() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fit");
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/demo.toml");
    let o = tissuefit(&["fit", "--config", config.to_str().unwrap(), "--out", out.to_str().unwrap(), "--resume"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("nothing to resume") && err.contains(&out.display().to_string()), "{err}");
    assert!(!out.exists(), "{}", out.display());
}
