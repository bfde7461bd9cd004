//! `tissuefit run`: the demo pipeline end to end (truth recovered, stage skipping, `--force` and
//! thread-count reproducibility, resume after an interruption) and pipeline-file errors (exit 2,
//! naming the file and the key).

use crate::support::run_dirs;

use crate::support::cli::{repo, tissuefit};
use run_dirs::{data_hashes, normalised_hash, read_json, stage_hashes, strip_wall_times};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn text(o: &Output) -> (String, String) {
    (String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// pipelines/demo.toml with its data paths made absolute and `edit` applied, written into `dir`.
fn demo_pipeline(dir: &Path, edit: impl Fn(String) -> String) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("pipelines/demo.toml")).unwrap();
    let data = repo().join("data/demo");
    let text = edit(text.replace("\"../data/demo/", &format!("\"{}/", data.display())));
    let path = dir.join("demo.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn statuses(run: &Path) -> Vec<(String, String)> {
    let m = read_json(&run.join("manifest.json"));
    m["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| (s["name"].as_str().unwrap().to_string(), s["status"].as_str().unwrap().to_string()))
        .collect()
}

#[test]
fn the_demo_pipeline_recovers_its_truth_skips_reruns_and_reproduces_its_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    // A smaller budget than the demo's 24 evaluations (it converges in 9) and a one-point profile.
    let pipeline = demo_pipeline(tmp.path(), |t| {
        t.replace("max_evaluations = 24", "max_evaluations = 14").replace("points = 2", "points = 1")
    });
    let p = pipeline.to_str().unwrap();
    let a = tmp.path().join("a");
    let a_str = a.to_str().unwrap();

    // 1. End to end on 2 threads: every stage complete, the truth recovered within the demo's ±10 %.
    let o = tissuefit(&["--threads", "2", "run", p, "--out", a_str]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stdout}\n{stderr}");
    let all = |status: &str| -> Vec<(String, String)> {
        ["mesh", "measure", "simulate", "fit"].iter().map(|s| (s.to_string(), status.to_string())).collect()
    };
    assert_eq!(statuses(&a), all("complete"));
    let result = read_json(&a.join("fit/result.json"));
    let ratio = result["ratios"]["lateral_over_apical"]["value"].as_f64().unwrap();
    assert!((ratio - 0.5).abs() / 0.5 <= 0.1, "γ_l/γ_a = {ratio}, truth 0.5");
    assert!(stdout.contains("lateral_over_apical") && stdout.contains("yes"), "{stdout}");
    // Names as the config and model files spell them, not Rust's (`NelderMead`).
    assert_eq!(
        (result["optimizer"].as_str(), result["contact_model"].as_str()),
        (Some("nelder_mead"), Some("coupling"))
    );
    // The manifest's input hash is the label file's blake3; the resolved config is beside it.
    let manifest = read_json(&a.join("manifest.json"));
    let labels = std::fs::read(repo().join("data/demo/doublet.tif")).unwrap();
    assert_eq!(manifest["inputs"][0]["blake3"].as_str().unwrap(), blake3::hash(&labels).to_hex().as_str());
    assert_eq!(manifest["threads"].as_u64(), Some(2));
    assert!(a.join("config.resolved.toml").is_file());
    let first = data_hashes(&a);
    assert!(first.len() >= 15, "{first:?}");

    // 2. Again: every stage skipped, nothing rewritten.
    let fit_mtime = std::fs::metadata(a.join("fit/trace.csv")).unwrap().modified().unwrap();
    let o = tissuefit(&["--threads", "2", "run", p, "--out", a_str]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stdout}\n{stderr}");
    assert_eq!(stdout.matches(": skipped").count(), 4, "{stdout}");
    assert_eq!(statuses(&a), all("skipped"));
    assert_eq!(std::fs::metadata(a.join("fit/trace.csv")).unwrap().modified().unwrap(), fit_mtime);
    assert_eq!(data_hashes(&a), first);

    // 3. --force re-runs every stage and reproduces every data output byte for byte.
    let o = tissuefit(&["--threads", "2", "run", p, "--out", a_str, "--force"]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    assert_eq!(statuses(&a), all("complete"));
    assert_eq!(data_hashes(&a), first);

    // 4. An interrupted run (the fit marked running, a temporary folder left behind) resumes at the
    //    fit: the earlier stages are skipped and the result is the same.
    let manifest_path = a.join("manifest.json");
    let mut m = read_json(&manifest_path);
    m["stages"][3]["status"] = serde_json::json!("running");
    std::fs::write(&manifest_path, serde_json::to_vec_pretty(&m).unwrap()).unwrap();
    std::fs::create_dir_all(a.join(".fit.tmp-999999")).unwrap();
    let o = tissuefit(&["--threads", "2", "run", p, "--out", a_str]);
    let (stdout, _) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    let expected: Vec<(String, String)> =
        [("mesh", "skipped"), ("measure", "skipped"), ("simulate", "skipped"), ("fit", "complete")]
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
    assert_eq!(statuses(&a), expected, "{stdout}");
    assert!(!a.join(".fit.tmp-999999").exists());
    assert_eq!(data_hashes(&a), first);

    // 5. One thread gives the same bytes as two.
    let b = tmp.path().join("b");
    let o = tissuefit(&["--threads", "1", "run", p, "--out", b.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    assert_eq!(data_hashes(&b), first);

    // 6. `tissuefit fit --config PIPELINE.toml` runs the pipeline's fit stage alone: the same bytes.
    let alone = tmp.path().join("fit-alone");
    let o = tissuefit(&["--threads", "2", "fit", "--config", p, "--out", alone.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    for file in ["trace.csv", "result.json", "fit.toml", "model.toml", "objective.png", "landscape.png"] {
        assert_eq!(normalised_hash(&alone.join(file)), first[&format!("fit/{file}")], "{file}");
    }
}

#[test]
fn a_changed_section_reruns_its_stage_and_those_after_it_only() {
    let tmp = tempfile::tempdir().unwrap();
    let cut = |t: String| t.split("[simulate]").next().unwrap().to_string();
    let pipeline = demo_pipeline(tmp.path(), cut);
    let run = tmp.path().join("run");
    let args = ["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()];
    assert_eq!(tissuefit(&args).status.code(), Some(0));
    let pair = |a: &str, b: &str| (a.to_string(), b.to_string());
    assert_eq!(statuses(&run), vec![pair("mesh", "complete"), pair("measure", "complete")]);
    demo_pipeline(tmp.path(), |t| cut(t).replace("include_static = false", "exterior_free_fraction = 0.2"));
    let o = tissuefit(&args);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    assert_eq!(statuses(&run), vec![pair("mesh", "skipped"), pair("measure", "complete")]);
    // A changed label file re-runs the mesh too.
    let labels = tmp.path().join("labels.tif");
    std::fs::copy(repo().join("data/demo/doublet.tif"), &labels).unwrap();
    let body = std::fs::read_to_string(&pipeline).unwrap();
    let body = body.replace(&format!("{}/doublet.tif", repo().join("data/demo").display()), labels.to_str().unwrap());
    std::fs::write(&pipeline, body).unwrap();
    let o = tissuefit(&args);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    // Same bytes, same hash: still skipped (the key is the content, not the path).
    assert_eq!(statuses(&run), vec![pair("mesh", "skipped"), pair("measure", "skipped")]);
}

/// Runs a pipeline made from `body` and returns its exit code and stderr.
fn run_bad(body: &str) -> (Option<i32>, String, PathBuf, tempfile::TempDir) {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::copy(repo().join("data/demo/doublet.tif"), tmp.path().join("labels.tif")).unwrap();
    let path = tmp.path().join("bad.toml");
    std::fs::write(&path, body).unwrap();
    let out = tmp.path().join("run");
    let o = tissuefit(&["run", path.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    (o.status.code(), text(&o).1, path, tmp)
}

#[test]
fn an_unknown_key_is_an_error_naming_the_file_the_key_and_the_nearest_valid_one() {
    let (code, err, path, _t) = run_bad("[input]\nlabels = \"labels.tif\"\n[mesh]\ntarget_node = 200\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&format!("{}:4", path.display())), "{err}");
    assert!(err.contains("mesh.target_node") && err.contains("did you mean `target_nodes`?"), "{err}");
    // Inside a reused schema (the fit's optimiser section).
    let body = "[input]\nlabels = \"labels.tif\"\n[fit.parameters.surface_tension]\nbounds = [1e-4, 1e-3]\n\
                [fit.optimizer]\nmax_evaluation = 3\n";
    let (code, err, _, _t) = run_bad(body);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("fit.optimizer.max_evaluation") && err.contains("did you mean `max_evaluations`?"), "{err}");
    // A section name.
    let (code, err, _, _t) = run_bad("[input]\nlabels = \"labels.tif\"\n[mesure]\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("did you mean `measure`?"), "{err}");
}

#[test]
fn a_wrong_type_a_missing_input_and_conflicting_options_are_errors_naming_the_key() {
    let (code, err, path, _t) = run_bad("[input]\nlabels = \"labels.tif\"\n[mesh]\ntarget_nodes = \"many\"\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&format!("{}:4", path.display())) && err.contains("mesh.target_nodes"), "{err}");

    let (code, err, path, t) = run_bad("[input]\nlabels = \"missing.tif\"\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&path.display().to_string()) && err.contains("input.labels"), "{err}");
    assert!(err.contains("missing.tif") && err.contains("does not exist"), "{err}");
    assert!(!t.path().join("run").exists(), "nothing written for a bad config");

    let body =
        "[input]\nlabels = \"labels.tif\"\n[fit.parameters.surface_tension]\nbounds = [1e-4, 1e-3]\nvalue = 1e-3\n";
    let (code, err, _, _t) = run_bad(body);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("fit.parameters.surface_tension") && err.contains("not both"), "{err}");

    let (code, err, _, _t) = run_bad("[input]\nlabels = \"labels.tif\"\n[mesh]\nborder = \"sometimes\"\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("mesh.border"), "{err}");
}

/// Needs ../shared/data/real (CI runs the ignored tests when it is there).
#[test]
#[ignore]
fn the_real_ovule_pipeline_meshes_and_measures_every_border_cell_as_static() {
    let pipeline = repo().join("pipelines/real-ovule.toml");
    let tmp = tempfile::tempdir().unwrap();
    let run = tmp.path().join("run");
    let o = tissuefit(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    let report = read_json(&run.join("mesh/report.json"));
    // All 50 labels touch the crop's border: none is a free cell; most are meshed as static.
    assert_eq!(report["kept"].as_u64(), Some(0));
    let static_cells = report["static"].as_u64().unwrap();
    assert!(static_cells >= 40, "{static_cells} static cells");
    let summary = read_json(&run.join("measure/summary.json"));
    assert_eq!(summary["cells"].as_u64(), Some(static_cells));
    assert!(summary["mean_coordination"].as_f64().unwrap() > 4.0, "a dense tissue: {summary}");
}

#[test]
fn a_failing_stage_leaves_no_folder_that_looks_complete_and_is_recorded_as_failed() {
    // Every label below min_voxels: the mesh stage fails.
    let (code, err, _, t) = run_bad("[input]\nlabels = \"labels.tif\"\n[mesh]\nmin_voxels = 100000000\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("stage mesh") && err.contains("dropped"), "{err}");
    let run = t.path().join("run");
    assert!(!run.join("mesh").exists() && !run.join("measure").exists());
    let leftovers: Vec<_> = std::fs::read_dir(&run)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    let manifest = read_json(&run.join("manifest.json"));
    assert_eq!(manifest["stages"][0]["name"].as_str(), Some("mesh"));
    assert_eq!(manifest["stages"][0]["status"].as_str(), Some("failed"));
    assert!(manifest["stages"][0]["note"].as_str().unwrap().contains("dropped"));
}

/// The demo pipeline without its fit (cheap: mesh, measure, one relaxation) in `dir`.
fn demo_without_fit(dir: &Path) -> PathBuf {
    demo_pipeline(dir, |t| t.split("[fit]").next().unwrap().to_string())
}

#[test]
fn the_stage_subcommands_fed_the_pipeline_file_write_the_bytes_of_tissuefit_run() {
    let tmp = tempfile::tempdir().unwrap();
    let pipeline = demo_without_fit(tmp.path());
    let p = pipeline.to_str().unwrap();
    let whole = tmp.path().join("whole");
    let o = tissuefit(&["run", p, "--out", whole.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));

    // The same pipeline stage by stage, each subcommand reading its section of the same file.
    let by = tmp.path().join("stages");
    let dir = |stage: &str| by.join(stage).to_str().unwrap().to_string();
    let tissue = by.join("mesh/tissue.vtp");
    let tissue = tissue.to_str().unwrap();
    let o = tissuefit(&["mesh", "--config", p, "--out", &dir("mesh")]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    let o = tissuefit(&["measure", tissue, "--config", p, "--out", &dir("measure")]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    let o = tissuefit(&["simulate", tissue, "--config", p, "--out", &dir("simulate")]);
    // The demo's 1000 steps end unconverged (the coupling model's hovering residual): exit 1, as
    // `simulate` says for any unconverged relaxation.
    let converged = read_json(&by.join("simulate/summary.json"))["converged"].as_bool().unwrap();
    assert_eq!(o.status.code(), Some(if converged { 0 } else { 1 }), "{:?}", text(&o));

    let hashes = |run: &Path| stage_hashes(run, &["mesh", "measure", "simulate"]);
    let expected = hashes(&whole);
    assert!(expected.len() >= 10, "{expected:?}");
    assert_eq!(hashes(&by), expected);
    // The data files proper are byte-identical, not just equal after taking wall times out.
    // (mesh/report.json holds the meshing's wall time, as `tissuefit mesh` writes it.)
    for file in ["mesh/tissue.vtp", "measure/cells.csv", "measure/contacts.csv", "simulate/final.vtk"] {
        assert_eq!(std::fs::read(whole.join(file)).unwrap(), std::fs::read(by.join(file)).unwrap(), "{file}");
    }

    // The manifest records the commit the binary was built from (build.rs reads .git without git).
    let commit = read_json(&whole.join("manifest.json"))["git_commit"].clone();
    if repo().join(".git").exists() && std::env::var_os("TISSUEFIT_GIT_COMMIT").is_none() {
        let c = commit.as_str().unwrap_or_else(|| panic!("git_commit is {commit} in a git checkout"));
        assert!(c.len() == 40 && c.bytes().all(|b| b.is_ascii_hexdigit()), "{c}");
    }
}

/// Runs `tissuefit ARGS` where `{p}` stands for a pipeline made from `body` (labels.tif beside it) and
/// `{t}` for a meshed tissue; returns the exit code, stderr and the pipeline's path.
fn stage_with_bad(args: &[&str], body: &str) -> (Option<i32>, String, PathBuf, tempfile::TempDir) {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::copy(repo().join("data/demo/doublet.tif"), tmp.path().join("labels.tif")).unwrap();
    let path = tmp.path().join("bad.toml");
    std::fs::write(&path, body).unwrap();
    let tissue = repo().join("data/demo/cell_quartet.vtk");
    let out = tmp.path().join("out");
    let args: Vec<String> = args
        .iter()
        .map(|a| {
            a.replace("{p}", path.to_str().unwrap())
                .replace("{t}", tissue.to_str().unwrap())
                .replace("{o}", out.to_str().unwrap())
        })
        .collect();
    let o = Command::new(env!("CARGO_BIN_EXE_tissuefit")).args(&args).output().unwrap();
    assert!(!out.join("tissue.vtp").exists() && !out.join("cells.csv").exists(), "nothing written on an error");
    (o.status.code(), text(&o).1, path, tmp)
}

#[test]
fn every_stage_subcommand_reports_pipeline_config_errors_with_the_file_and_key_and_exit_2() {
    let stages: [&[&str]; 4] = [
        &["mesh", "--config", "{p}", "--out", "{o}"],
        &["measure", "{t}", "--config", "{p}", "--out", "{o}"],
        &["simulate", "{t}", "--config", "{p}", "--out", "{o}"],
        &["fit", "--config", "{p}", "--out", "{o}"],
    ];
    let fit = "[simulate]\n[fit.parameters.surface_tension]\nbounds = [1e-4, 1e-3]\n";
    for args in stages {
        let stage = args[0];
        // Unknown key, with the nearest valid one.
        let body = format!("[input]\nlabels = \"labels.tif\"\n[mesh]\ntarget_node = 200\n{fit}");
        let (code, err, path, _t) = stage_with_bad(args, &body);
        assert_eq!(code, Some(2), "{stage}: {err}");
        assert!(err.contains(&format!("{}:4", path.display())), "{stage}: {err}");
        assert!(err.contains("mesh.target_node") && err.contains("did you mean `target_nodes`?"), "{stage}: {err}");
        // Wrong type.
        let body = format!("[input]\nlabels = \"labels.tif\"\n[measure]\ninclude_static = \"no\"\n{fit}");
        let (code, err, path, _t) = stage_with_bad(args, &body);
        assert_eq!(code, Some(2), "{stage}: {err}");
        assert!(err.contains(&format!("{}:4", path.display())) && err.contains("measure.include_static"), "{err}");
        // Missing input file.
        let body = format!("[input]\nlabels = \"missing.tif\"\n{fit}");
        let (code, err, path, _t) = stage_with_bad(args, &body);
        assert_eq!(code, Some(2), "{stage}: {err}");
        assert!(err.contains(&path.display().to_string()) && err.contains("input.labels"), "{stage}: {err}");
        assert!(err.contains("does not exist"), "{stage}: {err}");
        // Conflicting options inside the file.
        let body = "[input]\nlabels = \"labels.tif\"\n[simulate]\n[fit.parameters.surface_tension]\n\
                    bounds = [1e-4, 1e-3]\nvalue = 1e-3\n";
        let (code, err, _, _t) = stage_with_bad(args, body);
        assert_eq!(code, Some(2), "{stage}: {err}");
        assert!(err.contains("fit.parameters.surface_tension") && err.contains("not both"), "{stage}: {err}");
    }
    // Conflicting options between the command line and the file: the file configures the stage.
    let good = format!("[input]\nlabels = \"labels.tif\"\n{fit}");
    let cases: [(&[&str], &str); 4] = [
        (&["mesh", "--config", "{p}", "--out", "{o}", "--target-nodes", "50"], "--target-nodes"),
        (&["mesh", "{t}", "--config", "{p}", "--out", "{o}"], "--config"),
        (&["measure", "{t}", "--config", "{p}", "--out", "{o}", "--include-static"], "--include-static"),
        (&["simulate", "{t}", "--config", "{p}", "--out", "{o}", "--max-steps", "3"], "--max-steps"),
    ];
    for (args, flag) in cases {
        let (code, err, _, _t) = stage_with_bad(args, &good);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(err.contains(flag) && err.contains("cannot be used with"), "{args:?}: {err}");
    }
    // A stage whose section is missing.
    let (code, err, path, _t) = stage_with_bad(stages[2], "[input]\nlabels = \"labels.tif\"\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains(&path.display().to_string()) && err.contains("no [simulate] section"), "{err}");
    let (code, err, _, _t) = stage_with_bad(stages[3], "[input]\nlabels = \"labels.tif\"\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no [fit] section"), "{err}");
}

/// `[input] labels = "labels.tif"` beside the pipeline file `p.toml` in `dir` (plus `extra`).
fn labels_pipeline(dir: &Path, labels: &str, extra: &str) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("p.toml");
    std::fs::write(&path, format!("[input]\nlabels = \"{labels}\"\n{extra}")).unwrap();
    path
}

/// Issue 23, item 1: `tissuefit run --out DIR` deleted DIR/mesh and all it held. Now a stage folder
/// holding files the program did not make is refused, naming them; `--force` runs beside them and
/// still removes or replaces only the program's own files.
#[test]
fn a_run_never_deletes_or_replaces_files_it_did_not_make_in_its_stage_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let doublet = repo().join("data/demo/doublet.tif");
    let run = |p: &Path, out: &Path, force: bool| {
        let mut args = vec!["run", p.to_str().unwrap(), "--out", out.to_str().unwrap()];
        if force {
            args.push("--force");
        }
        let o = tissuefit(&args);
        let (stdout, stderr) = text(&o);
        (o.status.code(), format!("{stdout}{stderr}"))
    };

    // The reproducer: notes in proj/mesh, the pipeline and its labels in proj, --out proj.
    let proj = tmp.path().join("proj");
    std::fs::create_dir_all(proj.join("mesh")).unwrap();
    std::fs::write(proj.join("mesh/notes.txt"), "notes\n").unwrap();
    std::fs::copy(&doublet, proj.join("labels.tif")).unwrap();
    let p = labels_pipeline(&proj, "labels.tif", "");
    let (code, out) = run(&p, &proj, false);
    assert_eq!(code, Some(2), "{out}");
    assert!(out.contains("notes.txt") && out.contains("did not make") && out.contains("--force"), "{out}");
    assert_eq!(std::fs::read_to_string(proj.join("mesh/notes.txt")).unwrap(), "notes\n");
    let (code, out) = run(&p, &proj, true);
    assert_eq!(code, Some(0), "{out}");
    assert_eq!(std::fs::read_to_string(proj.join("mesh/notes.txt")).unwrap(), "notes\n");
    assert!(proj.join("mesh/tissue.vtp").is_file() && proj.join("measure/summary.json").is_file());
    let manifest = read_json(&proj.join("manifest.json"));
    let owned = manifest["stages"][0]["outputs"].as_object().unwrap();
    assert!(owned.contains_key("tissue.vtp") && !owned.contains_key("notes.txt"), "{owned:?}");
    // Unchanged: skipped, notes or not. A changed [mesh] re-runs the stage beside the notes with
    // --force: the program's old files are replaced, the notes stay.
    let (code, out) = run(&p, &proj, false);
    assert_eq!((code, out.matches(": skipped").count()), (Some(0), 2), "{out}");
    let p = labels_pipeline(&proj, "labels.tif", "[mesh]\ntarget_nodes = 150\n");
    assert_eq!(run(&p, &proj, false).0, Some(2));
    let (code, out) = run(&p, &proj, true);
    assert_eq!(code, Some(0), "{out}");
    assert_eq!(std::fs::read_to_string(proj.join("mesh/notes.txt")).unwrap(), "notes\n");
    assert_eq!(statuses(&proj), vec![("mesh".into(), "complete".into()), ("measure".into(), "complete".into())]);

    // The input TIFF kept inside OUT/mesh survives, with or without --force, byte for byte.
    let kept = tmp.path().join("kept");
    std::fs::create_dir_all(kept.join("mesh")).unwrap();
    std::fs::copy(&doublet, kept.join("mesh/labels.tif")).unwrap();
    let original = std::fs::read(&doublet).unwrap();
    let p = labels_pipeline(&kept, "mesh/labels.tif", "");
    let (code, out) = run(&p, &kept, false);
    assert_eq!(code, Some(2), "{out}");
    assert!(out.contains("labels.tif"), "{out}");
    let (code, out) = run(&p, &kept, true);
    assert_eq!(code, Some(0), "{out}");
    assert_eq!(std::fs::read(kept.join("mesh/labels.tif")).unwrap(), original);

    // A file of a name the stage writes, not made by the program, is not replaced even with --force.
    let clash = tmp.path().join("clash");
    std::fs::create_dir_all(clash.join("measure")).unwrap();
    std::fs::write(clash.join("measure/summary.json"), "{\"mine\": true}\n").unwrap();
    std::fs::copy(&doublet, clash.join("labels.tif")).unwrap();
    let p = labels_pipeline(&clash, "labels.tif", "");
    let (code, out) = run(&p, &clash, true);
    assert_eq!(code, Some(2), "{out}");
    assert!(out.contains("summary.json") && out.contains("did not make the one there"), "{out}");
    assert_eq!(std::fs::read_to_string(clash.join("measure/summary.json")).unwrap(), "{\"mine\": true}\n");

    // Nor a manifest.json or config.resolved.toml that no run made, in the run folder itself.
    for (name, text) in [("manifest.json", "{\"my\": \"notes\"}\n"), ("config.resolved.toml", "mine = 1\n")] {
        let own = tmp.path().join(format!("own-{name}"));
        std::fs::create_dir_all(&own).unwrap();
        std::fs::write(own.join(name), text).unwrap();
        std::fs::copy(&doublet, own.join("labels.tif")).unwrap();
        let p = labels_pipeline(&own, "labels.tif", "");
        let (code, out) = run(&p, &own, true);
        assert_eq!(code, Some(2), "{out}");
        assert!(out.contains(name) && out.contains("move it away"), "{out}");
        assert_eq!(std::fs::read_to_string(own.join(name)).unwrap(), text);
        assert!(!own.join("mesh").exists());
    }
}

fn stage_status(run: &Path, stage: &str) -> Option<String> {
    let text = std::fs::read_to_string(run.join("manifest.json")).ok()?;
    let m: serde_json::Value = serde_json::from_str(&text).ok()?;
    m["stages"].as_array()?.iter().find(|s| s["name"] == stage).map(|s| s["status"].as_str().unwrap().to_string())
}

/// Starts `tissuefit run` and waits until its simulate stage is running.
fn start_until_simulating(p: &Path, run: &Path) -> std::process::Child {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .args(["run", p.to_str().unwrap(), "--out", run.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while stage_status(run, "simulate").as_deref() != Some("running") {
        assert!(child.try_wait().unwrap().is_none(), "the first run ended before simulating");
        assert!(started.elapsed().as_secs() < 300, "the simulate stage did not start");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child
}

/// Issue 23, item 7: a second run into a folder in use fails at once, naming the folder and the
/// process; SIGTERM leaves the stage `interrupted` (not `running`); after a kill -9 the next run
/// records the stage it finds `running` as interrupted and runs it again.
#[test]
fn a_second_run_into_a_busy_folder_fails_at_once_and_an_interrupted_stage_is_recorded_so() {
    let tmp = tempfile::tempdir().unwrap();
    // A relaxation that cannot converge: it runs until stopped.
    let endless = |t: String| {
        t.split("[fit]").next().unwrap().replace(
            "max_steps = 1000",
            "max_steps = 100000000\nforce_tolerance = 1e-30\nenergy_tolerance = 1e-30\nvolume_tolerance = 1e-30",
        )
    };
    let p = demo_pipeline(tmp.path(), endless);
    let run = tmp.path().join("run");
    let mut first = start_until_simulating(&p, &run);
    let asked = std::time::Instant::now();
    let o = tissuefit(&["run", p.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(asked.elapsed().as_secs() < 60, "the second run waited");
    assert!(err.contains(&run.display().to_string()) && err.contains(&format!("process id {}", first.id())), "{err}");
    assert!(err.contains("kill -9"), "{err}");
    assert_eq!(stage_status(&run, "simulate").as_deref(), Some("running"), "the second run touched the manifest");
    // SIGTERM: exit 130, the stage marked interrupted.
    assert!(Command::new("kill").args(["-TERM", &first.id().to_string()]).status().unwrap().success());
    assert_eq!(first.wait().unwrap().code(), Some(130));
    assert_eq!(stage_status(&run, "simulate").as_deref(), Some("interrupted"));
    let mut said = String::new();
    std::io::Read::read_to_string(&mut first.stderr.take().unwrap(), &mut said).unwrap();
    assert!(
        said.contains("interrupted: stage simulate is marked interrupted in ")
            && said.contains("run the same command again to resume it from its last checkpoint"),
        "{said}"
    );

    // kill -9 leaves `running`; the next run (a relaxation that ends) says it was interrupted.
    let mut second = start_until_simulating(&p, &run);
    second.kill().unwrap();
    second.wait().unwrap();
    assert_eq!(stage_status(&run, "simulate").as_deref(), Some("running"));
    let p = demo_without_fit(tmp.path());
    let o = tissuefit(&["run", p.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    let (stdout, err) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stdout}{err}");
    assert!(
        err.contains("stage simulate: the run that started it") && err.contains("ended before it finished"),
        "{err}"
    );
    assert_eq!(stage_status(&run, "simulate").as_deref(), Some("complete"));
}

/// The fit's temporary folder (`.fit.tmp-PID`) in a run directory, if any.
fn fit_temporary(run: &Path) -> Option<PathBuf> {
    stage_temporary(run, "fit")
}

/// A stage's temporary folder (`.STAGE.tmp-PID`) in a run directory, if any.
fn stage_temporary(run: &Path, stage: &str) -> Option<PathBuf> {
    let prefix = format!(".{stage}.tmp-");
    std::fs::read_dir(run)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .find(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with(&prefix)))
}

/// A pipeline's simulation killed with SIGKILL goes on from its last periodic checkpoint at the next
/// run (not from step 0) and ends with the files of an uninterrupted run (wall times aside).
#[test]
fn a_pipeline_simulation_killed_with_sigkill_resumes_from_its_checkpoint_to_the_uninterrupted_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    // 30,000 steps (the demo's relaxation does not converge before: the coupling residual hovers),
    // a checkpoint every 1,000.
    let pipeline = demo_pipeline(tmp.path(), |t| {
        t.split("[fit]")
            .next()
            .unwrap()
            .replace("max_steps = 1000", "max_steps = 30000\ncheckpoint_every_steps = 1000\nsample_every_steps = 5000")
    });
    let p = pipeline.to_str().unwrap();
    let reference = tmp.path().join("reference");
    let o = tissuefit(&["run", p, "--out", reference.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    assert_eq!(read_json(&reference.join("simulate/summary.json"))["steps"], 30000);

    let run = tmp.path().join("run");
    let mut child = Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .args(["run", p, "--out", run.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while !stage_temporary(&run, "simulate").is_some_and(|d| d.join("checkpoint.bin").is_file()) {
        assert!(child.try_wait().unwrap().is_none(), "the run ended before its first checkpoint");
        assert!(started.elapsed().as_secs() < 300, "no checkpoint after 5 minutes");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(stage_status(&run, "simulate").as_deref(), Some("running"));

    let o = tissuefit(&["run", p, "--out", run.to_str().unwrap()]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stdout}{stderr}");
    assert!(stdout.contains("simulate: resuming the interrupted run from its checkpoint at step "), "{stdout}");
    assert!(stage_temporary(&run, "simulate").is_none(), "a temporary simulate folder is left");
    assert_eq!(data_hashes(&run), data_hashes(&reference));
    let manifest = read_json(&run.join("manifest.json"));
    let simulate = manifest["stages"].as_array().unwrap().iter().find(|s| s["name"] == "simulate").unwrap();
    let (ran, wall) = (simulate["ran_seconds"].as_f64().unwrap(), simulate["wall_seconds"].as_f64().unwrap());
    assert!(ran > wall, "ran_seconds {ran} counts only the last session ({wall} s)");
}

/// Issue 23, item 7: a pipeline's fit lost every evaluation to kill -9. Now the next run goes on from
/// the trace the killed fit left (its evaluations are not simulated again) and ends with the outputs
/// of an uninterrupted run.
#[test]
fn a_pipeline_fit_killed_with_sigkill_resumes_from_its_trace_to_the_uninterrupted_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let pipeline = demo_pipeline(tmp.path(), |t| {
        t.replace("max_evaluations = 24", "max_evaluations = 14").replace("points = 2", "points = 1")
    });
    let p = pipeline.to_str().unwrap();
    let reference = tmp.path().join("reference");
    let o = tissuefit(&["--threads", "2", "run", p, "--out", reference.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));

    let run = tmp.path().join("run");
    let mut child = Command::new(env!("CARGO_BIN_EXE_tissuefit"))
        .args(["--threads", "2", "run", p, "--out", run.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Killed once the trace holds two evaluations.
    let started = std::time::Instant::now();
    loop {
        let rows = fit_temporary(&run)
            .and_then(|d| std::fs::read_to_string(d.join("trace.csv")).ok())
            .map_or(0, |t| t.lines().count());
        if rows >= 3 {
            break;
        }
        assert!(child.try_wait().unwrap().is_none(), "the run ended before its fit had two evaluations");
        assert!(started.elapsed().as_secs() < 300, "no fit evaluation after 5 minutes");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(stage_status(&run, "fit").as_deref(), Some("running"));
    let killed = std::fs::read_to_string(fit_temporary(&run).unwrap().join("trace.csv")).unwrap();
    let killed_rows: Vec<&str> = killed.lines().collect();

    let o = tissuefit(&["--threads", "2", "run", p, "--out", run.to_str().unwrap()]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stdout}{stderr}");
    assert!(stdout.contains("fit: resuming the interrupted run from the"), "{stdout}");
    assert_eq!(stage_status(&run, "fit").as_deref(), Some("complete"));
    assert!(fit_temporary(&run).is_none(), "a temporary fit folder is left");
    // result.json's `simulated_here` counts this process's simulations (fewer: the rest came from
    // the trace); everything else is the uninterrupted run's.
    let result = |dir: &Path| {
        let mut v = read_json(&dir.join("fit/result.json"));
        let here = v.as_object_mut().unwrap().remove("simulated_here").unwrap().as_u64().unwrap();
        strip_wall_times(&mut v);
        (v, here)
    };
    let ((resumed, here), (uninterrupted, all)) = (result(&run), result(&reference));
    assert_eq!(resumed, uninterrupted);
    assert!(here + (killed_rows.len() as u64 - 1) <= all, "simulated {here} of {all} again");
    let without_result = |dir: &Path| {
        let mut h = data_hashes(dir);
        h.remove("fit/result.json");
        h
    };
    assert_eq!(without_result(&run), without_result(&reference));
    // The killed run's evaluations were reused, not simulated again: their rows, wall times
    // included, open the final trace.
    let trace = std::fs::read_to_string(run.join("fit/trace.csv")).unwrap();
    let rows: Vec<&str> = trace.lines().collect();
    assert!(rows.len() > killed_rows.len());
    assert_eq!(rows[..killed_rows.len()], killed_rows[..]);
    // The time that made the fit counts the killed session's recorded part too; result.json's
    // wall_seconds likewise.
    let manifest = read_json(&run.join("manifest.json"));
    let fit = manifest["stages"].as_array().unwrap().iter().find(|s| s["name"] == "fit").unwrap();
    let (ran, wall) = (fit["ran_seconds"].as_f64().unwrap(), fit["wall_seconds"].as_f64().unwrap());
    assert!(ran > wall, "ran_seconds {ran} counts only the last session ({wall} s)");
    let result = read_json(&run.join("fit/result.json"));
    let (total, session) = (result["wall_seconds"].as_f64().unwrap(), result["session_wall_seconds"].as_f64().unwrap());
    assert!(total > session, "wall_seconds {total} counts only the last session ({session} s)");
}
