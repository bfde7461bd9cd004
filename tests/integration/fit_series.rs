//! `tissuefit fit-series` (issue 25, time-lapse): a series of label volumes mapped in order, cells
//! tracked by overlap through relabelling and motion, each frame started with the previous frame's
//! correction, resumable, and refusing what it cannot map.

use crate::support::cli::tissuefit;
use crate::support::run_dirs::{csv_maps as rows, number};
use ndarray::Axis;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use tissuefit::imaging::{LabelReadOptions, LabelWriteOptions, read_labels, write_label_tiff};

fn hetero4() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/evolver/fixtures/hetero4/labels_10.tif")
}

/// Frame 1: Evolver's hetero4 cluster moved by one voxel along x and renumbered 1→4, 2→1, 3→2, 4→3
/// (as a segmentation of the next time point numbers its cells).
fn next_frame(path: &Path) {
    let mut volume = read_labels(&hetero4(), &LabelReadOptions::default()).unwrap().volume;
    let shape = volume.shape();
    assert!(volume.labels().index_axis(Axis(2), shape[2] - 1).iter().all(|&l| l == 0), "room to move");
    let moved = {
        let src = volume.labels().clone();
        let dst = volume.labels_mut();
        dst.fill(0);
        for ((z, y, x), &l) in src.indexed_iter() {
            if l != 0 && x + 1 < shape[2] {
                dst[[z, y, x + 1]] = [0, 4, 1, 2, 3][l as usize];
            }
        }
        volume
    };
    write_label_tiff(path, &moved, &LabelWriteOptions::default()).unwrap();
}

fn config(dir: &Path) -> PathBuf {
    let text = format!(
        "mode = \"per_cell\"\n[observed]\nlabels = {:?}\n[observed.meshing]\ntarget_nodes = 200\n{}[per_cell]\niterations = 2\ntolerance = 0.002\n",
        hetero4().display().to_string(),
        crate::per_cell_fit::MODEL
    );
    let path = dir.join("fit.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_series_tracks_renumbered_moving_cells_and_starts_each_frame_from_the_last_answer() {
    let dir = tempfile::tempdir().unwrap();
    let config = config(dir.path());
    let f1 = dir.path().join("t1.tif");
    next_frame(&f1);
    let out = dir.path().join("series");
    let f0 = hetero4();
    let run = |extra: &[&str]| {
        let mut args = vec!["fit-series", "--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        args.extend([f0.to_str().unwrap(), f1.to_str().unwrap()]);
        let o = tissuefit(&args);
        (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    // A tolerance below the forward model's noise: every frame runs its iterations and says it did
    // not converge (exit 1), its best map written.
    let (code, stderr) = run(&[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("frame 1") && stderr.contains("4 cells tracked from frame 0, 0 new, 0 ended"), "{stderr}");
    // The renumbered cells are matched back to their tracks.
    let tracks = rows(&out.join("tracks.csv"));
    let frame1: BTreeMap<String, String> =
        tracks.iter().filter(|r| r["frame"] == "1").map(|r| (r["label"].clone(), r["track"].clone())).collect();
    let want: BTreeMap<String, String> =
        [("4", "1"), ("1", "2"), ("2", "3"), ("3", "4")].iter().map(|(a, b)| (a.to_string(), b.to_string())).collect();
    assert_eq!(frame1, want);
    assert!(tracks.iter().filter(|r| r["frame"] == "1").all(|r| number(r, "iou") > 0.6), "{tracks:?}");
    // Frame 1 started with frame 0's correction, its cells under their track ids.
    let series: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("series.json")).unwrap()).unwrap();
    assert_eq!(series["frames"][0]["previous_frame_cells"], 0);
    assert_eq!(series["frames"][1]["previous_frame_cells"], 4);
    assert_eq!(series["succeeded"], false);
    let cells = rows(&out.join("series_cells.csv"));
    assert_eq!(cells.len(), 8);
    for r in &cells {
        let want = if r["frame"] == "0" { "direct estimate" } else { "corrected by previous frame" };
        assert_eq!(r["start"], want, "{r:?}");
    }
    // The same tissue one voxel on maps to the same tensions per track (within the forward
    // model's noise of a few per cent).
    let interfaces = rows(&out.join("series_interfaces.csv"));
    let at = |frame: &str| -> BTreeMap<(String, String), f64> {
        interfaces
            .iter()
            .filter(|r| r["frame"] == frame)
            .map(|r| ((r["cell_a"].clone(), r["cell_b"].clone()), number(r, "tension_mn_per_m")))
            .collect()
    };
    let (t0, t1) = (at("0"), at("1"));
    assert_eq!(t0.keys().collect::<Vec<_>>(), t1.keys().collect::<Vec<_>>());
    for (k, a) in &t0 {
        assert!((t1[k] / a - 1.0).abs() < 0.1, "interface {k:?}: {a} then {}", t1[k]);
    }
    // Resumed: nothing runs again, the same tables.
    let before = std::fs::read_to_string(out.join("series_cells.csv")).unwrap();
    let before_interfaces = std::fs::read_to_string(out.join("series_interfaces.csv")).unwrap();
    let (code, stderr) = run(&["--resume"]);
    assert_eq!(code, Some(1), "{stderr}");
    assert_eq!(stderr.matches("not run again").count(), 2, "{stderr}");
    let series: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("series.json")).unwrap()).unwrap();
    assert!(series["frames"].as_array().unwrap().iter().all(|f| f["resumed"] == true), "{series}");
    assert_eq!(std::fs::read_to_string(out.join("series_cells.csv")).unwrap(), before);
    // Interrupted after frame 0: the correction read back from its files starts frame 1 exactly
    // as the uninterrupted series did.
    std::fs::remove_dir_all(out.join("t001")).unwrap();
    let (code, stderr) = run(&["--resume"]);
    assert_eq!(code, Some(1), "{stderr}");
    assert_eq!(stderr.matches("not run again").count(), 1, "{stderr}");
    assert_eq!(std::fs::read_to_string(out.join("series_cells.csv")).unwrap(), before);
    assert_eq!(std::fs::read_to_string(out.join("series_interfaces.csv")).unwrap(), before_interfaces);
}

#[test]
fn a_series_refuses_a_global_fit_frames_on_other_grids_and_a_bad_threshold() {
    let dir = tempfile::tempdir().unwrap();
    let config = config(dir.path());
    let out = dir.path().join("series");
    let other = dir.path().join("other.tif");
    let volume = read_labels(&hetero4(), &LabelReadOptions::default()).unwrap().volume;
    let cropped = tissuefit::imaging::LabelVolume::new(
        volume.labels().slice(ndarray::s![.., .., 1..]).to_owned(),
        volume.voxel_size(),
        volume.origin(),
    )
    .unwrap();
    write_label_tiff(&other, &cropped, &LabelWriteOptions::default()).unwrap();
    let h = hetero4();
    let (c, o) = (config.to_str().unwrap(), out.to_str().unwrap());
    let e = tissuefit(&["fit-series", "--config", c, "--out", o, "--min-iou", "1.5", h.to_str().unwrap()]);
    assert_eq!(e.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&e.stderr).contains("--min-iou 1.5"), "{e:?}");
    let global = dir.path().join("global.toml");
    std::fs::write(
        &global,
        std::fs::read_to_string(&config).unwrap().replace("mode = \"per_cell\"", "mode = \"global\""),
    )
    .unwrap();
    let e = tissuefit(&["fit-series", "--config", global.to_str().unwrap(), "--out", o, h.to_str().unwrap()]);
    assert_eq!(e.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&e.stderr).contains("per_cell"), "{e:?}");
    // Different grids: refused before any frame is mapped, naming the file.
    let e = tissuefit(&["fit-series", "--config", c, "--out", o, h.to_str().unwrap(), other.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&e.stderr);
    assert_eq!(e.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("other.tif") && stderr.contains("one grid"), "{stderr}");
    assert!(!out.join("series.json").exists(), "no series.json after a refused series");
}

/// The pipeline form: `[series]` beside a per-cell `[fit]` maps `input.labels` and the later frames
/// into the run's `series/` folder (the fit stage does not run), records every frame as an input,
/// and a second run skips the finished stage.
#[test]
fn a_pipeline_maps_a_series_into_its_series_stage_and_skips_it_when_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let f1 = dir.path().join("t1.tif");
    next_frame(&f1);
    let text = format!(
        "preset = \"compact-embryo\"\n[input]\nlabels = {:?}\nseed = 0\n[series]\nframes = [\"t1.tif\"]\n\
         [fit]\nmode = \"per_cell\"\n[fit.forward]\nmeasure_shifts = 1\n[fit.per_cell]\niterations = 2\ntolerance = 0.2\n",
        hetero4().display().to_string()
    );
    let pipeline = dir.path().join("pipeline.toml");
    std::fs::write(&pipeline, text).unwrap();
    let out = dir.path().join("run");
    let run = || {
        let o = tissuefit(&["run", pipeline.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        (o.status.success(), format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr)))
    };
    let (ok, all) = run();
    assert!(ok, "{all}");
    assert!(all.contains("series: done") && all.contains("time series of 2 frames: 2 mapped and converged"), "{all}");
    assert!(!out.join("fit").exists(), "the fit stage ran beside the series");
    let series = out.join("series");
    for f in ["t000/cells.csv", "t001/interfaces.csv", "tracks.csv", "series_interfaces.csv", "series.json"] {
        assert!(series.join(f).is_file(), "series/{f} missing: {all}");
    }
    let tracks = rows(&series.join("tracks.csv"));
    assert_eq!(
        tracks.iter().filter(|r| r["frame"] == "1" && r["label"] == "4").map(|r| &r["track"]).next().unwrap(),
        "1"
    );
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(series.join("series.json")).unwrap()).unwrap();
    assert_eq!(
        (result["succeeded"].as_bool(), result["frames"][1]["previous_frame_cells"].as_u64()),
        (Some(true), Some(4))
    );
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let inputs = manifest["inputs"].as_array().unwrap();
    assert!(inputs.iter().any(|i| i["path"].as_str().is_some_and(|p| p.ends_with("t1.tif"))), "{inputs:?}");
    // Unchanged: skipped. A changed later frame: mapped again.
    let (ok, all) = run();
    assert!(ok && all.contains("series: skipped"), "{all}");
    std::fs::copy(hetero4(), &f1).unwrap();
    let (ok, all) = run();
    assert!(ok && all.contains("series: done"), "{all}");
}
