//! `tissuefit sweep`: a 2×2 grid over the demo doublet (mesh + measure + a 200-step relaxation) gives
//! four run directories, results.csv and plots; `--index` alone reproduces a run byte for byte; `--list`;
//! re-running skips; `--collect`; bad keys are errors with suggestions (exit 2); a failed run is
//! recorded, not fatal. And the pipeline pieces sweeps need: a mesh input (`[input] mesh`) and a
//! time run (growth and divisions) in the simulate stage, measured at its end.

use crate::support::cli::{repo, tissuefit};
use crate::support::run_dirs::stage_hashes;
use std::path::{Path, PathBuf};
use std::process::Output;
use tissuefit::io::{ReadOptions, read_tissue, write_simucell3d};
use tissuefit::mesh::shapes::sphere_for_min_edge;
use tissuefit::mesh::{Cell, CellId, CellKind, Tissue};

fn text(o: &Output) -> (String, String) {
    (String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The demo pipeline without its fit, relaxing for 200 steps, as `dir/base.toml`.
fn base_pipeline(dir: &Path) -> PathBuf {
    let demo = std::fs::read_to_string(repo().join("pipelines/demo.toml")).unwrap();
    let data = repo().join("data/demo");
    let body = demo.split("[fit]").next().unwrap().replace("\"../data/demo/", &format!("\"{}/", data.display()));
    let body = body.replace("max_steps = 1000", "max_steps = 200");
    let path = dir.join("base.toml");
    std::fs::write(&path, body).unwrap();
    path
}

const GRID: &str = "base = \"base.toml\"\n[grid]\n\"mesh.target_nodes\" = [100, 200]\n\
    \"simulate.model_overrides.cell_types[0].faces.lateral.surface_tension\" = [3e-4, 6e-4]\n";
const LATERAL: &str = "simulate.model_overrides.cell_types[0].faces.lateral.surface_tension";

fn csv_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let header = r.headers().unwrap().iter().map(str::to_string).collect();
    let rows = r.records().map(|rec| rec.unwrap().iter().map(str::to_string).collect()).collect();
    (header, rows)
}

/// Every data file of a run folder's stages (frames included), hashed with the wall-time fields taken
/// out (byte for byte otherwise, see [`normalised_hash`]).
fn data_files(run: &Path) -> Vec<(String, String)> {
    stage_hashes(run, &["mesh", "measure", "simulate"]).into_iter().collect()
}

#[test]
fn a_two_by_two_grid_runs_lists_reproduces_skips_and_collects() {
    let tmp = tempfile::tempdir().unwrap();
    base_pipeline(tmp.path());
    let sweep = tmp.path().join("s.toml");
    std::fs::write(&sweep, GRID).unwrap();
    let s = sweep.to_str().unwrap();

    // --list: one line per run, index then key=value, tab-separated; the last key varies fastest.
    let o = tissuefit(&["sweep", s, "--list"]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    let expected: Vec<String> = [(100, "0.0003"), (100, "0.0006"), (200, "0.0003"), (200, "0.0006")]
        .iter()
        .enumerate()
        .map(|(i, (n, g))| format!("{i}\tmesh.target_nodes={n}\t{LATERAL}={g}"))
        .collect();
    assert_eq!(stdout.lines().collect::<Vec<_>>(), expected);

    // The whole sweep, 2 runs at a time on 2 threads.
    let out = tmp.path().join("out");
    let o = tissuefit(&["--threads", "2", "sweep", s, "--out", out.to_str().unwrap(), "--jobs", "2"]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stdout}\n{stderr}");
    assert!(stdout.contains("2 jobs × 1 threads") && stdout.contains("4 complete"), "{stdout}");
    for i in 0..4 {
        let run = out.join(format!("run-{i:04}"));
        assert!(run.join("manifest.json").is_file() && run.join("config.resolved.toml").is_file());
        assert!(run.join("simulate/final.vtp").is_file());
    }
    // Each run's resolved config holds its values.
    let resolved = std::fs::read_to_string(out.join("run-0003/config.resolved.toml")).unwrap();
    assert!(resolved.contains("target_nodes = 200"), "{resolved}");
    let (header, rows) = csv_rows(&out.join("results.csv"));
    assert_eq!(&header[..4], ["index", "run", "mesh.target_nodes", LATERAL]);
    assert!(header.contains(&"simulate/morphology.json:mean_sphericity".to_string()), "{header:?}");
    assert!(header.contains(&"simulate/morphology.json:layers".to_string()), "{header:?}");
    assert!(header.contains(&"simulate/summary.json:steps".to_string()), "{header:?}");
    assert_eq!(&header[header.len() - 3..], ["status", "reason", "wall_seconds"]);
    assert_eq!(rows.len(), 4);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row[0], i.to_string());
        assert_eq!(row[col("status")], "complete", "{row:?}");
        // The table's values are the run's own outputs.
        let morphology = read_json(&out.join(format!("run-{i:04}/simulate/morphology.json")));
        let psi: f64 = row[col("simulate/morphology.json:mean_sphericity")].parse().unwrap();
        assert_eq!(psi, morphology["mean_sphericity"].as_f64().unwrap());
        assert_eq!(row[col("simulate/morphology.json:cells")], "2");
        let summary = read_json(&out.join(format!("run-{i:04}/simulate/summary.json")));
        assert_eq!(row[col("simulate/summary.json:steps")], summary["steps"].to_string());
    }
    assert_eq!(rows[2][2], "200");
    assert_eq!(rows[2][3], "0.0003");
    // A higher lateral tension makes rounder cells (smaller contact): the sweep resolves the parameter.
    let psi = |r: &Vec<String>| r[col("simulate/morphology.json:mean_sphericity")].parse::<f64>().unwrap();
    assert!(psi(&rows[1]) > psi(&rows[0]) && psi(&rows[3]) > psi(&rows[2]), "{rows:?}");
    let plot = out.join("plots/simulate_morphology_json_mean_sphericity.png");
    assert!(std::fs::metadata(&plot).unwrap().len() > 1000);

    // --index 2 alone (one thread) into another directory: byte-identical data outputs.
    let alone = tmp.path().join("alone");
    let o = tissuefit(&["--threads", "1", "sweep", s, "--out", alone.to_str().unwrap(), "--index", "2"]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    // (Besides the sweep folder's lock file, `.tissuefit.lock`.)
    let names: Vec<String> = std::fs::read_dir(&alone)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n != ".tissuefit.lock")
        .collect();
    assert_eq!(names, ["run-0002"], "only run 2, no results table");
    let (a, b) = (data_files(&out.join("run-0002")), data_files(&alone.join("run-0002")));
    assert!(a.len() >= 12, "{:?}", a.iter().map(|f| &f.0).collect::<Vec<_>>());
    for ((na, ba), (nb, bb)) in a.iter().zip(&b) {
        assert_eq!(na, nb);
        assert!(ba == bb, "{na} differs");
    }
    assert_eq!(a.len(), b.len());

    // Again: every run skipped, the results the same (wall times aside).
    let o = tissuefit(&["--threads", "2", "sweep", s, "--out", out.to_str().unwrap()]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stdout}\n{stderr}");
    assert!(stdout.contains("0 complete, 4 skipped, 0 failed"), "{stdout}");
    let m = read_json(&out.join("run-0001/manifest.json"));
    assert!(m["stages"].as_array().unwrap().iter().all(|s| s["status"] == "skipped"), "{m}");
    let strip = |rows: Vec<Vec<String>>| {
        rows.into_iter().map(|mut r| {
            r.pop();
            r
        })
    };
    let again = csv_rows(&out.join("results.csv")).1;
    assert!(strip(again).eq(strip(rows.clone())));

    // --collect from the directories alone.
    std::fs::remove_file(out.join("results.csv")).unwrap();
    let o = tissuefit(&["sweep", s, "--out", out.to_str().unwrap(), "--collect"]);
    assert_eq!(o.status.code(), Some(0), "{:?}", text(&o));
    assert_eq!(csv_rows(&out.join("results.csv")).1.len(), 4);
    // Collected where runs are missing: recorded as missing, exit 1.
    let o = tissuefit(&["sweep", s, "--out", alone.to_str().unwrap(), "--collect"]);
    assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
    let (_, rows) = csv_rows(&alone.join("results.csv"));
    let statuses: Vec<&str> = rows.iter().map(|r| r[col("status")].as_str()).collect();
    assert_eq!(statuses, ["missing", "missing", "complete", "missing"]);

    // A run folder whose lock another process holds (a run into it) is reported running, not read.
    let held = std::fs::File::create(out.join("run-0001/.tissuefit.lock")).unwrap();
    held.lock().unwrap();
    let o = tissuefit(&["sweep", s, "--out", out.to_str().unwrap(), "--collect"]);
    assert_eq!(o.status.code(), Some(1), "{:?}", text(&o));
    let (_, rows) = csv_rows(&out.join("results.csv"));
    assert_eq!(rows[1][col("status")], "running", "{:?}", rows[1]);
    assert!(rows[1][col("reason")].contains("run-0001"), "{:?}", rows[1]);
    assert_eq!(rows.iter().filter(|r| r[col("status")] == "complete").count(), 3);
    drop(held);
    // A whole sweep (exclusive) or a job-array task (shared) working in the sweep folder: --collect
    // refuses (exit 2), naming the folder, and leaves results.csv as it was.
    let before = std::fs::read(out.join("results.csv")).unwrap();
    for shared in [false, true] {
        let holder = std::fs::File::options().write(true).open(out.join(".tissuefit.lock")).unwrap();
        if shared { holder.lock_shared() } else { holder.lock() }.unwrap();
        let o = tissuefit(&["sweep", s, "--out", out.to_str().unwrap(), "--collect"]);
        assert_eq!(o.status.code(), Some(2), "{:?}", text(&o));
        assert!(text(&o).1.contains(out.to_str().unwrap()), "{:?}", text(&o));
        assert_eq!(std::fs::read(out.join("results.csv")).unwrap(), before, "results.csv untouched");
    }
}

fn sweep_error(dir: &Path, body: &str) -> (Option<i32>, String) {
    let path = dir.join("bad.toml");
    std::fs::write(&path, body).unwrap();
    let out = dir.join("bad-out");
    let o = tissuefit(&["sweep", path.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(!out.exists(), "nothing written for a bad sweep");
    (o.status.code(), text(&o).1)
}

#[test]
fn unknown_keys_and_bad_sweeps_are_errors_naming_the_key_and_the_nearest_one() {
    let tmp = tempfile::tempdir().unwrap();
    base_pipeline(tmp.path());
    let d = tmp.path();
    let (code, err) = sweep_error(d, &GRID.replace("\"mesh.target_nodes\"", "\"mesh.target_node\""));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("grid key `mesh.target_node`") && err.contains("did you mean `target_nodes`?"), "{err}");
    let (code, err) = sweep_error(d, &GRID.replace("\"mesh.target_nodes\"", "\"mesh_.target_nodes\""));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("did you mean `mesh`?"), "{err}");
    // Inside the model's schema.
    let (code, err) = sweep_error(d, &GRID.replace("lateral.surface_tension", "lateral.surface_tensio"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("surface_tensio") && err.contains("did you mean `surface_tension`?"), "{err}");
    // A list index out of range, a value that is not a list, grid and runs together, a bad column.
    let (code, err) = sweep_error(d, &GRID.replace("cell_types[0]", "cell_types[7]"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("cell_types[7]"), "{err}");
    let (code, err) = sweep_error(d, "base = \"base.toml\"\n[grid]\n\"mesh.target_nodes\" = 100\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("give a list of values"), "{err}");
    let (code, err) = sweep_error(d, &format!("{GRID}[[runs]]\n\"mesh.target_nodes\" = 100\n"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("not both"), "{err}");
    let (code, err) = sweep_error(d, &format!("{GRID}[table]\ncolumns = [\"simulate/sumary.json:layers\"]\n"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("did you mean `simulate/summary.json`?"), "{err}");
    // A value that breaks a check of the pipeline names the run and the key.
    let (code, err) = sweep_error(d, "base = \"base.toml\"\n[grid]\n\"mesh.target_nodes\" = [100, 2]\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("run 1") && err.contains("mesh.target_nodes: need at least 4"), "{err}");
    let (code, err) = sweep_error(d, "base = \"missing.toml\"\n[grid]\n\"mesh.target_nodes\" = [100]\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("missing.toml") && err.contains("does not exist"), "{err}");
}

#[test]
fn a_failed_run_is_recorded_with_its_reason_and_the_others_complete() {
    let tmp = tempfile::tempdir().unwrap();
    let base = base_pipeline(tmp.path());
    // Measure only: cut [simulate].
    let body = std::fs::read_to_string(&base).unwrap();
    std::fs::write(&base, body.split("[simulate]").next().unwrap()).unwrap();
    let sweep = tmp.path().join("s.toml");
    std::fs::write(
        &sweep,
        "base = \"base.toml\"\n[[runs]]\nmesh.min_voxels = 100000000\n[[runs]]\nmesh.target_nodes = 100\n\
         [table]\ncolumns = [\"measure/summary.json:cells\", \"mesh/report.json:kept\"]\n",
    )
    .unwrap();
    let out = tmp.path().join("out");
    let o = tissuefit(&["sweep", sweep.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{stdout}\n{stderr}");
    assert!(stdout.contains("1 complete, 0 skipped, 1 failed"), "{stdout}");
    let (header, rows) = csv_rows(&out.join("results.csv"));
    assert_eq!(
        header,
        ["index", "run", "mesh.min_voxels", "mesh.target_nodes", "measure/summary.json:cells", "mesh/report.json:kept"]
            .iter()
            .chain(&["status", "reason", "wall_seconds"])
            .map(|s| s.to_string())
            .collect::<Vec<_>>()
    );
    assert_eq!(rows[0][2], "100000000");
    assert_eq!(rows[0][3], "", "run 0 leaves target_nodes at the base's value");
    assert_eq!(rows[0][6], "failed");
    assert!(rows[0][7].contains("stage mesh") && rows[0][7].contains("dropped"), "{:?}", rows[0]);
    assert_eq!(&rows[1][4..7], ["2", "2", "complete"]);
}

/// One sphere of radius 3 µm (the growth test's cell) as a SimuCell3D .vtk (metres).
fn sphere_vtk(path: &Path) {
    let mesh = sphere_for_min_edge(3e-6, 6e-7).unwrap();
    let tissue = Tissue::from_cells(vec![Cell::new(CellId(1), CellKind::Epithelial, 0, mesh)]).unwrap();
    write_simucell3d(path, &tissue, &[]).unwrap();
}

#[test]
fn a_sweep_over_a_mesh_input_runs_growth_and_measures_the_final_tissue() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    sphere_vtk(&d.join("sphere.vtk"));
    let growth = repo().join("pipelines/growth.toml");
    // 300 steps of the growth benchmark: three divisions (tests/integration/growth_cli.rs).
    let pipeline = format!(
        "[input]\nmesh = \"sphere.vtk\"\nlength_unit = \"m\"\n[simulate]\nmodel = \"{}\"\n\
         [simulate.model_overrides.simulation]\nduration = 3e-5\n",
        growth.display()
    );
    std::fs::write(d.join("grow.toml"), &pipeline).unwrap();
    std::fs::write(
        d.join("s.toml"),
        "base = \"grow.toml\"\n[grid]\n\"simulate.model_overrides.cell_types[0].growth_rate\" = [0.0, 1e-11]\n",
    )
    .unwrap();
    let out = d.join("out");
    let o = tissuefit(&["--threads", "2", "sweep", d.join("s.toml").to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stdout}\n{stderr}");
    let (header, rows) = csv_rows(&out.join("results.csv"));
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    assert_eq!(rows[0][col("simulate/morphology.json:cells")], "1");
    assert_eq!(rows[1][col("simulate/morphology.json:cells")], "4");
    assert_eq!(rows[1][col("simulate/summary.json:steps")], "300");

    let run = out.join("run-0001");
    // The mesh stage copied the input into mesh/tissue.vtp; the manifest hashes the input.
    let m = read_json(&run.join("manifest.json"));
    let input = std::fs::read(d.join("sphere.vtk")).unwrap();
    assert_eq!(m["inputs"][0]["blake3"].as_str().unwrap(), blake3::hash(&input).to_hex().as_str());
    let copied = read_tissue(&run.join("mesh/tissue.vtp"), &ReadOptions::default()).unwrap().tissue;
    let original = sphere_for_min_edge(3e-6, 6e-7).unwrap();
    assert_eq!(copied.len(), 1);
    assert_eq!(copied.cells()[0].mesh().positions().len(), original.positions().len());
    let volume = copied.cells()[0].mesh().signed_volume();
    assert!((volume - original.signed_volume()).abs() < 1e-6 * original.signed_volume(), "{volume:e}");
    assert_eq!(read_json(&run.join("mesh/report.json"))["cells"], 1);
    // The time run: three divisions, the final tissue written and measured like the measure stage.
    let sim = read_json(&run.join("simulate/summary.json"));
    assert_eq!(
        (sim["mode"].as_str(), sim["divisions"].as_u64(), sim["final_cells"].as_u64()),
        (Some("time"), Some(3), Some(4))
    );
    let last = read_tissue(&run.join("simulate/final.vtp"), &ReadOptions::default()).unwrap().tissue;
    assert_eq!(last.len(), 4);
    assert_eq!(std::fs::read_to_string(run.join("simulate/events.csv")).unwrap().lines().count(), 4);
    let summary = read_json(&run.join("simulate/morphology.json"));
    let measured = read_json(&run.join("measure/summary.json"));
    // The measure stage's summary also says what it measured and how long it took.
    let keys = |v: &serde_json::Value| {
        let about = ["file", "input", "wall_seconds", "threads"];
        v.as_object().unwrap().keys().filter(|k| !about.contains(&k.as_str())).cloned().collect::<Vec<_>>()
    };
    assert_eq!(keys(&summary), keys(&measured));
    assert!(summary.get("layers").is_some());
    assert_eq!(summary["cells"], 4);
    assert_eq!(std::fs::read_to_string(run.join("simulate/cells.csv")).unwrap().lines().count(), 5);
}

#[test]
fn an_input_is_labels_or_a_mesh_not_both_nor_neither() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    sphere_vtk(&d.join("sphere.vtk"));
    std::fs::copy(repo().join("data/demo/doublet.tif"), d.join("labels.tif")).unwrap();
    for (body, expect) in [
        ("[input]\nlabels = \"labels.tif\"\nmesh = \"sphere.vtk\"\n", "not several"),
        ("[input]\nseed = 1\n", "give `labels` (a label TIFF), `mesh` (a .vtp/.vtk tissue) or `generate`"),
        ("[input]\nmesh = \"sphere.vtk\"\nvoxel_size = [1e-6, 1e-6, 1e-6]\n", "input.voxel_size"),
        ("[input]\nmesh = \"labels.tif\"\n", "expected a .vtp or .vtk"),
        ("[input]\nmesh = \"gone.vtk\"\n", "input.mesh"),
    ] {
        std::fs::write(d.join("p.toml"), body).unwrap();
        let o = tissuefit(&["run", d.join("p.toml").to_str().unwrap(), "--out", d.join("run").to_str().unwrap()]);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{body}: {err}");
        assert!(err.contains(expect), "{body}: {err}");
    }
}

/// Many samples (issue 22): a glob in a grid's path key is one run per matching file, sorted, named
/// relative to the sweep file in `--list` and results.csv; each run measures its own volume; a
/// pattern that matches nothing is an error naming the key and the pattern.
#[test]
fn a_glob_over_label_volumes_is_one_run_per_sample() {
    let tmp = tempfile::tempdir().unwrap();
    let base = base_pipeline(tmp.path());
    // Mesh and measure only.
    let body = std::fs::read_to_string(&base).unwrap();
    std::fs::write(&base, body.split("[simulate]").next().unwrap()).unwrap();
    let samples = tmp.path().join("embryos");
    std::fs::create_dir(&samples).unwrap();
    for (name, seed) in [("b.tif", "5"), ("a.tif", "4")] {
        let o = tissuefit(&[
            "generate",
            "labels",
            "--kind",
            "aggregate",
            "--cells",
            "3",
            "--seed",
            seed,
            "--out",
            samples.join(name).to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o).1);
    }
    std::fs::write(samples.join("notes.txt"), "not a sample").unwrap();
    let sweep = tmp.path().join("s.toml");
    std::fs::write(&sweep, "base = \"base.toml\"\n[grid]\n\"input.labels\" = [\"embryos/*.tif\"]\n").unwrap();
    let o = tissuefit(&["sweep", sweep.to_str().unwrap(), "--list"]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stderr}");
    assert_eq!(
        stdout.lines().collect::<Vec<_>>(),
        ["0\tinput.labels=\"embryos/a.tif\"", "1\tinput.labels=\"embryos/b.tif\""]
    );

    let out = tmp.path().join("out");
    let o = tissuefit(&["sweep", sweep.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let (stdout, stderr) = text(&o);
    assert_eq!(o.status.code(), Some(0), "{stdout}\n{stderr}");
    let (header, rows) = csv_rows(&out.join("results.csv"));
    assert_eq!(&header[..3], ["index", "run", "input.labels"]);
    let labels: Vec<&str> = rows.iter().map(|r| r[2].as_str()).collect();
    assert_eq!(labels, ["embryos/a.tif", "embryos/b.tif"]);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap_or_else(|| panic!("{header:?}"));
    for (i, row) in rows.iter().enumerate() {
        assert_eq!(row[col("status")], "complete", "{row:?}");
        let report = read_json(&out.join(format!("run-{i:04}/mesh/report.json")));
        assert!(report["input"].as_str().unwrap().ends_with(labels[i]), "run {i} meshed its own sample: {report}");
    }
    // Two different samples, two different measurements.
    let a = std::fs::read(out.join("run-0000/measure/cells.csv")).unwrap();
    let b = std::fs::read(out.join("run-0001/measure/cells.csv")).unwrap();
    assert_ne!(a, b);

    let (code, stderr) =
        sweep_error(tmp.path(), "base = \"base.toml\"\n[grid]\n\"input.labels\" = [\"embryos/*.zarr\"]\n");
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("grid key `input.labels`: pattern \"embryos/*.zarr\" matches no file"), "{stderr}");
}
