//! End to end: `tissuefit simulate` of one sphere with `pipelines/growth.toml` writes frames with a
//! changing number of cells, the `parent` column, `events.csv` and the topology counts; and
//! `tissuefit bench growth` prints its JSON.

use crate::support::cli::tissuefit;
use std::path::Path;
use tissuefit::io::{ReadOptions, read_tissue, write_simucell3d};
use tissuefit::mesh::shapes::sphere_for_min_edge;
use tissuefit::mesh::{Cell, CellId, CellKind, Tissue};

#[test]
fn simulate_with_the_growth_config_records_divisions_and_lineage() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = dir.path().join("sphere.vtk");
    let mesh = sphere_for_min_edge(3e-6, 6e-7).unwrap();
    write_simucell3d(
        &sphere,
        &Tissue::from_cells(vec![Cell::new(CellId(1), CellKind::Epithelial, 0, mesh)]).unwrap(),
        &[],
    )
    .unwrap();
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("pipelines/growth.toml");
    let out_dir = dir.path().join("run");
    // 300 steps: the first division at step ≈ 145, the second wave at ≈ 273.
    let out = tissuefit(&[
        "--threads",
        "2",
        "simulate",
        sphere.to_str().unwrap(),
        "--config",
        config.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--duration",
        "3e-5",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));

    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["divisions"], 3, "{summary}");
    assert_eq!(summary["final_cells"], 4);
    assert_eq!(summary["topology"]["divisions"], 3);
    assert!(summary["topology"]["splits"].as_u64().unwrap() > 0);

    let events = std::fs::read_to_string(out_dir.join("events.csv")).unwrap();
    let rows: Vec<&str> = events.lines().collect();
    assert_eq!(rows[0], "step,time,event,cell,daughter_a,daughter_b,volume");
    assert_eq!(rows.len(), 4);
    assert!(rows[1].contains(",division,1,2,3,"), "{}", rows[1]);

    let stats = std::fs::read_to_string(out_dir.join("stats.csv")).unwrap();
    let header: Vec<&str> = stats.lines().next().unwrap().split(',').collect();
    let parent = header.iter().position(|h| *h == "parent").expect("a parent column");
    let cell = header.iter().position(|h| *h == "cell").unwrap();
    let last_step = stats.lines().last().unwrap().split(',').next().unwrap().to_owned();
    let last: Vec<Vec<&str>> =
        stats.lines().skip(1).map(|l| l.split(',').collect::<Vec<_>>()).filter(|r| r[0] == last_step).collect();
    assert_eq!(last.len(), 4);
    for row in &last {
        assert!(["2", "3"].contains(&row[parent]), "cell {} has parent {:?}", row[cell], row[parent]);
    }
    let first: Vec<Vec<&str>> =
        stats.lines().skip(1).map(|l| l.split(',').collect::<Vec<_>>()).filter(|r| r[0] == "0").collect();
    assert_eq!((first.len(), first[0][parent]), (1, ""));

    // Frames follow the cell count: 1 cell at step 0, 4 at the end.
    let frames = out_dir.join("frames");
    let count = |name: &str| read_tissue(&frames.join(name), &ReadOptions::default()).unwrap().tissue.len();
    assert_eq!(count("frame_000000.vtp"), 1);
    let mut names: Vec<String> =
        std::fs::read_dir(&frames).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(count(names.last().unwrap()), 4);
}

#[test]
fn bench_growth_prints_milestones() {
    let out = tissuefit(&["--threads", "2", "bench", "growth", "--cells", "4"]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "scenario",
        "threads",
        "cells",
        "nodes",
        "steps",
        "wall_seconds",
        "seconds_per_node_step",
        "milestones",
        "alpha",
        "breakdown_seconds_per_node_step",
        "candidate_rebuilds",
    ] {
        assert!(v.get(key).is_some(), "missing {key}: {v}");
    }
    assert_eq!(v["scenario"], "growth");
    assert_eq!(v["cells"], 4);
    let milestones = v["milestones"].as_array().unwrap();
    assert_eq!(milestones.iter().map(|m| m["milestone"].as_u64().unwrap()).collect::<Vec<_>>(), [2, 4]);
    assert!(milestones[1]["steps"].as_u64() > milestones[0]["steps"].as_u64());
    // Peak memory (Linux): at least the tissue's node positions, and never less at a later milestone.
    if let (Some(first), Some(last)) = (milestones[0]["peak_memory_bytes"].as_u64(), v["peak_memory_bytes"].as_u64()) {
        assert!(first >= 24 * v["nodes"].as_u64().unwrap() && last >= first, "{v}");
    }
    // A step limit that is too small ends the run with the reason and exit code 1, not an abort.
    let out = tissuefit(&["bench", "growth", "--cells", "4", "--max-steps", "10"]);
    assert_eq!(out.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["reached"], false);
    assert!(v["stop_reason"].as_str().unwrap().contains("step limit"), "{v}");
}
