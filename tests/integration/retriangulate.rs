//! Re-triangulating tissue files (`meshing::retriangulate`, `tissuefit mesh TISSUE.vtk`): a synthetic
//! multi-material mesh of boxes with coarse, seam-sharing triangles (and an edge-only contact, a
//! non-manifold edge of the soup) comes back as valid cells at l_min with the same shapes; the real
//! multi-material meshes of the C. elegans 4-cell embryo likewise (ignored: real data).

use std::collections::HashMap;
use std::path::Path;
use std::process::Command;
use tissuefit::imaging::{VoxelGrid, label_overlap, voxelize};
use tissuefit::io::{ReadOptions, read_tissue};
use tissuefit::mesh::{CellKind, Tissue};

/// A legacy VTK 4.2 multi-material mesh of axis-aligned integer boxes `(label, lo, hi)`: every unit
/// square of a box face is two triangles; a square shared by two boxes is written once with both labels.
fn boxes_mm_vtk(boxes: &[(u32, [i32; 3], [i32; 3])]) -> String {
    // Unit squares keyed by (axis, corner): the labels on their low and high side.
    let mut squares: HashMap<(usize, [i32; 3]), [u32; 2]> = HashMap::new();
    for &(label, lo, hi) in boxes {
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for (side, plane) in [(1usize, lo[axis]), (0usize, hi[axis])] {
                for a in lo[u]..hi[u] {
                    for b in lo[v]..hi[v] {
                        let mut c = [0; 3];
                        c[axis] = plane;
                        c[u] = a;
                        c[v] = b;
                        // The box lies on the high side of its low face, the low side of its high face.
                        squares.entry((axis, c)).or_insert([0, 0])[side] = label;
                    }
                }
            }
        }
    }
    let mut keys: Vec<_> = squares.keys().copied().collect();
    keys.sort();
    let mut points: Vec<[i32; 3]> = Vec::new();
    let mut index: HashMap<[i32; 3], usize> = HashMap::new();
    let mut id = |p: [i32; 3], points: &mut Vec<[i32; 3]>| {
        *index.entry(p).or_insert_with(|| {
            points.push(p);
            points.len() - 1
        })
    };
    let mut tris: Vec<([usize; 3], u32, u32)> = Vec::new();
    for key in keys {
        let (axis, c) = key;
        let [low, high] = squares[&key];
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let corner = |du: i32, dv: i32| {
            let mut p = c;
            p[u] += du;
            p[v] += dv;
            p
        };
        let q = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)].map(|p| id(p, &mut points));
        // (u, v, axis) is right-handed: this winding's normal points along +axis, from `low` into `high`.
        tris.push(([q[0], q[1], q[2]], low, high));
        tris.push(([q[0], q[2], q[3]], low, high));
    }
    let mut s = format!(
        "# vtk DataFile Version 4.2\nboxes\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n",
        points.len()
    );
    for p in &points {
        s += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    s += &format!("CELLS {} {}\n", tris.len(), 4 * tris.len());
    for t in &tris {
        s += &format!("3 {} {} {}\n", t.0[0], t.0[1], t.0[2]);
    }
    s += &format!("CELL_TYPES {}\n", tris.len());
    s += &"5\n".repeat(tris.len());
    s += &format!("CELL_DATA {}\nFIELD FieldData 2\nlabel1 1 {} int\n", tris.len(), tris.len());
    s += &tris.iter().map(|t| t.1.to_string()).collect::<Vec<_>>().join(" ");
    s += &format!("\nlabel2 1 {} int\n", tris.len());
    s += &tris.iter().map(|t| t.2.to_string()).collect::<Vec<_>>().join(" ");
    s + "\n"
}

fn run_cli(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tissuefit")).args(args).output().unwrap()
}

/// Per-cell IoU of two tissues voxelised on one grid of `step` (m) covering both.
fn tissue_iou(a: &Tissue, b: &Tissue, step: f64) -> Vec<(u32, f64)> {
    let all: Vec<_> = a.cells().iter().chain(b.cells()).flat_map(|c| c.mesh().positions().iter().copied()).collect();
    let (lo, hi) = tissuefit::geometry::bounding_box(&all).unwrap();
    let grid = VoxelGrid::covering(lo, hi, [step; 3], 2).unwrap();
    let (va, vb) = (voxelize(a, &grid).unwrap(), voxelize(b, &grid).unwrap());
    label_overlap(&va, &vb).unwrap().iter().map(|o| (o.label, o.iou())).collect()
}

#[test]
fn a_multimaterial_mesh_of_boxes_is_retriangulated_into_valid_cells_of_the_same_shape() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("boxes.vtk");
    // Cells 1 and 2 share a face (a seam written once); cell 3 touches cell 1 along an edge only.
    let boxes = [(1, [0, 0, 0], [4, 3, 3]), (2, [4, 0, 0], [7, 3, 3]), (3, [0, 3, 3], [4, 6, 6])];
    std::fs::write(&input, boxes_mm_vtk(&boxes)).unwrap();
    let original =
        read_tissue(&input, &ReadOptions { length_scale: "um".parse().unwrap(), orient: true }).unwrap().tissue;
    assert_eq!(original.len(), 3);
    let out = dir.path().join("new.vtp");
    let o = run_cli(&[
        "--threads",
        "2",
        "mesh",
        input.to_str().unwrap(),
        "--length-unit",
        "um",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("new.report.json")).unwrap()).unwrap();
    assert_eq!(report["retriangulated"]["input_cells"], 3);
    assert_eq!(report["retriangulated"]["odd_rows"], 0, "every input cell surface is closed");
    assert_eq!(report["kept"], 3);
    let l_min = report["l_min"].as_f64().unwrap();
    let new = read_tissue(&out, &ReadOptions::default()).unwrap().tissue;
    assert_eq!(new.cells().iter().map(|c| c.id().0).collect::<Vec<_>>(), [1, 2, 3], "ids are kept");
    for (old, cell) in original.cells().iter().zip(new.cells()) {
        assert_eq!(cell.mesh().validate(), Ok(()), "cell {}", cell.id());
        assert_eq!(cell.kind(), CellKind::Epithelial);
        // The input has 2-triangle unit squares (edges 1–1.4 µm); the new cells have l_min-spaced nodes.
        let old_mean = old.mesh().edge_length_stats().unwrap().mean;
        assert!(cell.mesh().edge_length_stats().unwrap().mean < 0.5 * old_mean, "cell {}: re-triangulated", cell.id());
        let e = cell.mesh().edge_length_stats().unwrap();
        assert!(
            e.max <= 3.0 * l_min * (1.0 + 1e-9) && e.mean >= l_min,
            "cell {}: edges {e:?}, l_min {l_min:e}",
            cell.id()
        );
        // Box corners are rounded by the voxel blur: a few % of volume (module doc of `meshing`).
        let (v0, v1) = (old.mesh().signed_volume(), cell.mesh().signed_volume());
        assert!((v1 / v0 - 1.0).abs() < 0.05, "cell {}: volume {v1:e} vs {v0:e}", cell.id());
    }
    for (label, iou) in tissue_iou(&original, &new, l_min / 2.0) {
        assert!(iou > 0.9, "cell {label}: IoU {iou}");
    }
}

/// A pipeline's `[input] mesh` with `retriangulate = true` is meshed by the same stage as
/// `tissuefit mesh X.vtk`: same tissue and report, byte for byte (wall times aside); without the key
/// the mesh is copied as it is, and the keys that need it are refused by name.
#[test]
fn a_pipeline_retriangulates_its_input_mesh_as_tissuefit_mesh_does() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("boxes.vtk");
    std::fs::write(&input, boxes_mm_vtk(&[(1, [0, 0, 0], [4, 3, 3]), (2, [4, 0, 0], [7, 3, 3])])).unwrap();
    let write_pipeline = |name: &str, input_keys: &str| {
        let path = dir.path().join(name);
        std::fs::write(
            &path,
            format!(
                "[input]\nmesh = {:?}\nlength_unit = \"um\"\n{input_keys}\n[mesh]\nseed = 3\ntarget_nodes = 120\n",
                input.display().to_string()
            ),
        )
        .unwrap();
        path
    };
    let pipeline = write_pipeline("p.toml", "retriangulate = true\nvoxel_size = [2.5e-7, 2.5e-7, 2.5e-7]\n");
    let run = dir.path().join("run");
    let o = run_cli(&["run", pipeline.to_str().unwrap(), "--out", run.to_str().unwrap()]);
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    let cli = dir.path().join("cli");
    std::fs::create_dir_all(&cli).unwrap();
    let o = run_cli(&[
        "mesh",
        input.to_str().unwrap(),
        "--length-unit",
        "um",
        "--voxel-size",
        "0.25um",
        "--seed",
        "3",
        "--target-nodes",
        "120",
        "--out",
        cli.join("tissue.vtp").to_str().unwrap(),
        "--report",
        cli.join("report.json").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for file in ["tissue.vtp", "report.json"] {
        assert_eq!(
            crate::support::run_dirs::normalised_hash(&run.join("mesh").join(file)),
            crate::support::run_dirs::normalised_hash(&cli.join(file)),
            "{file}: the pipeline's differs from tissuefit mesh's"
        );
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("mesh/report.json")).unwrap()).unwrap();
    assert_eq!(report["retriangulated"]["input_cells"], 2, "{report}");
    assert_eq!(report["voxel_size"][0].as_f64().unwrap(), 2.5e-7);
    let new = read_tissue(&run.join("mesh/tissue.vtp"), &ReadOptions::default()).unwrap().tissue;
    let original =
        read_tissue(&input, &ReadOptions { length_scale: "um".parse().unwrap(), orient: true }).unwrap().tissue;
    // Re-triangulated at l_min: the input's nodes lie on the integer µm lattice, the new ones do not.
    let on_lattice = |t: &Tissue| {
        t.cells()
            .iter()
            .flat_map(|c| c.mesh().positions().iter())
            .filter(|p| p.iter().all(|x| (x * 1e6 - (x * 1e6).round()).abs() < 1e-6))
            .count()
    };
    assert_eq!(on_lattice(&original), original.node_count());
    assert!(
        on_lattice(&new) < new.node_count() / 4,
        "{} of {} nodes on the input's lattice",
        on_lattice(&new),
        new.node_count()
    );

    // `tissuefit fit`'s `[observed] tissue` with `retriangulate` starts from that same tissue.
    let fit = tissuefit::inference::FitConfig::from_toml_str(
        &format!(
            "[observed]\ntissue = {:?}\nlength_unit = \"um\"\nretriangulate = true\nvoxel_size = [2.5e-7, 2.5e-7, 2.5e-7]\n\
             [observed.meshing]\nseed = 3\ntarget_nodes = 120\n\
             [parameters.surface_tension]\nbounds = [1e-4, 1e-3]\n",
            input.display().to_string()
        ),
        "fit.toml",
    )
    .unwrap();
    let observed = tissuefit::inference::load_observation(&fit).unwrap().tissue;
    assert_eq!(observed.len(), new.len());
    for (a, b) in observed.cells().iter().zip(new.cells()) {
        assert_eq!(a.mesh().positions(), b.mesh().positions(), "cell {}", a.id());
    }

    // Without the key the mesh is copied (its nodes as they are); the keys that need it are refused.
    let copy = write_pipeline("copy.toml", "");
    let copied = dir.path().join("copied");
    let o = run_cli(&["run", copy.to_str().unwrap(), "--out", copied.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let kept = read_tissue(&copied.join("mesh/tissue.vtp"), &ReadOptions::default()).unwrap().tissue;
    assert_eq!(on_lattice(&kept), original.node_count(), "copied as it is");
    for (keys, expected) in [
        (
            "voxel_size = [2.5e-7, 2.5e-7, 2.5e-7]\n",
            "input.voxel_size: applies to a `labels` input, or to a `mesh` with",
        ),
        ("retriangulate = false\nvoxel_size = [2.5e-7, 2.5e-7, 2.5e-7]\n", "input.voxel_size"),
    ] {
        let bad = write_pipeline("bad.toml", keys);
        let o = run_cli(&["run", bad.to_str().unwrap(), "--out", dir.path().join("bad").to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{keys}");
        assert!(String::from_utf8_lossy(&o.stderr).contains(expected), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let labels_too = dir.path().join("labels.toml");
    std::fs::write(&labels_too, "[input]\ngenerate = { kind = \"sphere\" }\nretriangulate = true\n").unwrap();
    let o = run_cli(&["run", labels_too.to_str().unwrap(), "--out", dir.path().join("bad").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("input.retriangulate: applies to a `mesh` input"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn mesh_refuses_unknown_inputs_and_nuclei_with_a_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("boxes.vtk");
    std::fs::write(&input, boxes_mm_vtk(&[(1, [0, 0, 0], [2, 2, 2])])).unwrap();
    let out = dir.path().join("t.vtp");
    let o = run_cli(&["mesh", input.to_str().unwrap(), "--nuclei", "n.tif", "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--nuclei applies to a label volume"));
    let stl = dir.path().join("x.stl");
    std::fs::write(&stl, "solid x").unwrap();
    let o = run_cli(&["mesh", stl.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains(".tif/.tiff"), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!out.exists());
}

#[test]
#[ignore = "real data, a few s in release: cargo test --release --test integration retriangulate:: -- --ignored"]
fn real_c_elegans_multimaterial_meshes_are_retriangulated_into_four_valid_cells() {
    let real = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real");
    // Coordinates in voxels of unknown size: read as µm (only the scale of the numbers changes).
    for name in ["foambryo-runner__Cshaper_4_cells_min-d-3.vtk", "deltaMic__cell4.vtk"] {
        let input = real.join(name);
        let original =
            read_tissue(&input, &ReadOptions { length_scale: "um".parse().unwrap(), orient: true }).unwrap().tissue;
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("new.vtp");
        let o = run_cli(&["mesh", input.to_str().unwrap(), "--length-unit", "um", "--out", out.to_str().unwrap()]);
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{name}: {stdout}\n{}", String::from_utf8_lossy(&o.stderr));
        println!("{name}: {stdout}");
        let new = read_tissue(&out, &ReadOptions::default()).unwrap().tissue;
        assert_eq!(new.len(), 4, "{name}: every cell re-triangulated");
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join("new.report.json")).unwrap()).unwrap();
        let l_min = report["l_min"].as_f64().unwrap();
        for (old, cell) in original.cells().iter().zip(new.cells()) {
            assert_eq!(old.id(), cell.id());
            assert_eq!(cell.mesh().validate(), Ok(()), "{name} cell {}", cell.id());
            let (v0, v1) = (old.mesh().signed_volume().abs(), cell.mesh().signed_volume());
            assert!((v1 / v0 - 1.0).abs() < 0.05, "{name} cell {}: volume {v1:e} vs {v0:e}", cell.id());
        }
        for (label, iou) in tissue_iou(&original, &new, l_min / 2.0) {
            assert!(iou > 0.9, "{name} cell {label}: IoU {iou}");
        }
    }
}
