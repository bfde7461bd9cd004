//! Measuring label volumes directly (voxels), its agreement with the mesh route on smooth synthetic
//! shapes, and shape comparison (IoU, χ = 1 − IoU).

use crate::support::cli::tissuefit;
use ndarray::{Array3, s};
use std::collections::BTreeSet;
use std::f64::consts::PI;
use std::path::Path;
use tissuefit::geometry::Vec3;
use tissuefit::imaging::{
    LabelPattern, LabelSpec, LabelVolume, LabelWriteOptions, generate_labels, label_overlap, voxelize, write_label_tiff,
};
use tissuefit::mesh::CellKind;
use tissuefit::meshing::{BorderPolicy, LabelMeshingOptions, mesh_labels};
use tissuefit::morphology::{
    LabelMeasureSettings, MeasureSettings, Morphology, compare_shapes, compare_tissues, measure_labels, measure_tissue,
};

/// A ball of radius `r` (m) centred off the grid, on a grid of voxel size `size` (z, y, x m).
fn ball(r: f64, size: [f64; 3]) -> LabelVolume {
    let n = [0, 1, 2].map(|a| (2.0 * r / size[a]).ceil() as usize + 6);
    let c = Vec3::new(n[2] as f64 * size[2], n[1] as f64 * size[1], n[0] as f64 * size[0]) / 2.0
        + Vec3::new(0.43 * size[2], 0.17 * size[1], 0.31 * size[0]);
    let labels = Array3::from_shape_fn(n, |(k, j, i)| {
        let p = Vec3::new(i as f64 * size[2], j as f64 * size[1], k as f64 * size[0]);
        u32::from((p - c).norm() <= r)
    });
    LabelVolume::new(labels, size, Vec3::zeros()).unwrap()
}

fn labels(v: &LabelVolume) -> Morphology {
    measure_labels(v, &LabelMeasureSettings { min_voxels: 1, ..Default::default() }).unwrap().morphology
}

// ---------------------------------------------------------------------------------------------
// The label route alone

/// A voxelised sphere: the voxel-count volume is within 1 % of 4πR³/3 (R ≥ 10 voxels), the projected
/// area within 2 % of 4πR² (measured: +1.1 % isotropic, +0.7–0.9 % with 1.6:1 voxels, at the default
/// σ = 2 voxels), where the plain face count gives +35–50 %; so Ψ lies within 2 % of 1, and the
/// semi-axes of the second moments are R within 1 %.
#[test]
fn a_voxelised_sphere_has_the_area_and_volume_of_the_sphere() {
    for size in [[1e-7; 3], [1.6e-7, 1e-7, 1e-7]] {
        for r in [1e-6, 1.5e-6, 2.5e-6] {
            let m = labels(&ball(r, size));
            assert_eq!(m.cells.len(), 1);
            let c = &m.cells[0];
            let (area, volume) = (c.area / (4.0 * PI * r * r), c.volume / (4.0 / 3.0 * PI * r.powi(3)));
            eprintln!("voxel {size:?} R {r:e}: area {area:.4} volume {volume:.4} Ψ {:.4}", c.sphericity);
            assert!((volume - 1.0).abs() < 0.01, "volume ratio {volume}");
            assert!((area - 1.0).abs() < 0.02, "area ratio {area} (voxel {size:?}, R {r:e})");
            assert!(c.sphericity > 0.98 && c.sphericity < 1.02, "Ψ = {}", c.sphericity);
            for a in [c.semi_axis_1, c.semi_axis_2, c.semi_axis_3] {
                assert!((a / r - 1.0).abs() < 0.01, "semi-axis {a:e} vs R {r:e}");
            }
            assert_eq!((c.neighbours, c.contact_fraction), (0, 0.0));
            assert!((c.free_area - c.area).abs() <= 1e-12 * c.area);
        }
    }
}

/// An ellipsoid's elongation comes out of the second moments of the voxels (semi-axes 0.4, 0.3, 0.2 L).
#[test]
fn a_voxelised_ellipsoid_has_its_semi_axes() {
    let spec = LabelSpec {
        pattern: LabelPattern::Ellipsoid,
        shape: [60, 60, 60],
        voxel_size: [1e-7; 3],
        cells: 1,
        seed: 0,
        lumen: false,
    };
    let g = generate_labels(&spec).unwrap();
    let c = &labels(&g.volume).cells[0];
    let l = 6e-6;
    for (got, want) in [(c.semi_axis_1, 0.4 * l), (c.semi_axis_2, 0.3 * l), (c.semi_axis_3, 0.2 * l)] {
        assert!((got / want - 1.0).abs() < 0.01, "semi-axis {got:e} vs {want:e}");
    }
    assert!((c.elongation - 2.0).abs() < 0.03, "elongation {}", c.elongation);
}

/// Two labels sharing a flat square interface: the contact area is the square exactly (axis-aligned
/// faces have weight 1 away from the rim), φ is the interface over the area, z = 1 each.
#[test]
fn two_boxes_share_their_interface() {
    let mut a = Array3::<u32>::zeros((24, 24, 40));
    a.slice_mut(s![2..22, 2..22, 2..20]).fill(3);
    a.slice_mut(s![2..22, 2..22, 20..38]).fill(9);
    let v = LabelVolume::new(a, [1e-7, 1e-7, 2e-7], Vec3::zeros()).unwrap();
    let m = labels(&v);
    assert_eq!(m.cells.iter().map(|c| c.cell).collect::<Vec<_>>(), vec![3, 9]);
    assert_eq!(m.contacts.len(), 1);
    let contact = &m.contacts[0];
    assert_eq!((contact.cell_a, contact.cell_b, contact.contact_angle_deg, contact.rim_edges), (3, 9, None, 0));
    let square = 20e-7 * 20e-7;
    // Within σ = 2 voxels of the rim the smoothed normal tilts; the interior 16×16 voxels are exact.
    assert!(
        contact.area <= square * (1.0 + 1e-12) && contact.area > square * (16.0 * 16.0) / 400.0,
        "{}",
        contact.area
    );
    for c in &m.cells {
        assert_eq!(c.neighbours, 1);
        assert!((c.contact_fraction - contact.area / c.area).abs() < 0.02, "φ {}", c.contact_fraction);
        assert_eq!((c.apical_area, c.nucleus_volume, c.iou), (None, None, None));
        assert!((c.volume / (20.0 * 20.0 * 18.0 * 2e-21) - 1.0).abs() < 1e-12, "{}", c.volume);
    }
    assert_eq!(m.summary.contact_distance, None);
    assert_eq!(m.summary.cells, 2);
}

/// Border labels: kept as cells by default (as `mesh`), flagged static and left out of the statistics,
/// or dropped; debris below min_voxels is dropped; lumen labels count layers.
#[test]
fn border_debris_and_lumen_labels_follow_the_mesh_route() {
    let spec = LabelSpec {
        pattern: LabelPattern::Aggregate,
        shape: [48, 48, 48],
        voxel_size: [0.5e-6; 3],
        cells: 12,
        seed: 5,
        lumen: true,
    };
    let g = generate_labels(&spec).unwrap();
    let lumen = g.lumen.unwrap();
    let mut v = g.volume.clone();
    v.labels_mut()[[0, 0, 0]] = 77; // a one-voxel debris label on the border
    let settings = LabelMeasureSettings { lumen_labels: vec![lumen], ..Default::default() };
    let r = measure_labels(&v, &settings).unwrap();
    assert_eq!(r.dropped.iter().map(|d| d.label).collect::<Vec<_>>(), vec![77]);
    let m = &r.morphology;
    assert_eq!(m.cells.len(), 13);
    assert!(m.cells.iter().all(|c| c.kind != CellKind::Static));
    let lumen_row = m.cells.iter().find(|c| c.cell == lumen).unwrap();
    assert_eq!((lumen_row.kind, lumen_row.in_statistics), (CellKind::Lumen, false));
    // Voronoi cells of a shell around the lumen: N(c) = 1 exactly for the cells touching both the lumen
    // and the exterior, ≥ 2 for the others.
    assert!(m.summary.lumen_facing_cells > 0);
    for c in m.cells.iter().filter(|c| c.kind == CellKind::Epithelial) {
        assert_eq!(c.layer == Some(1), c.lumen_facing && c.exterior_facing, "cell {}: {:?}", c.cell, c.layer);
    }
    assert!(m.summary.layers.is_some_and(|n| n >= 1));

    // Cut the volume: labels on the cut are static (and left out) or dropped.
    let cut = LabelVolume::new(v.labels().slice(s![.., .., 20..]).to_owned(), v.voxel_size(), Vec3::zeros()).unwrap();
    let on_border: BTreeSet<u32> =
        cut.label_stats().iter().filter(|i| i.touches_border(cut.shape())).map(|i| i.label).collect();
    let frozen =
        measure_labels(&cut, &LabelMeasureSettings { border: BorderPolicy::Static, ..Default::default() }).unwrap();
    let statics: BTreeSet<u32> = frozen.morphology.cells.iter().filter(|c| c.is_static).map(|c| c.cell).collect();
    assert!(!statics.is_empty());
    assert!(statics.iter().all(|l| on_border.contains(l)));
    assert!(frozen.morphology.cells.iter().filter(|c| c.is_static).all(|c| !c.in_statistics));
    let dropped =
        measure_labels(&cut, &LabelMeasureSettings { border: BorderPolicy::Drop, ..Default::default() }).unwrap();
    assert!(dropped.morphology.cells.iter().all(|c| !on_border.contains(&c.cell)));
    assert!(statics.iter().all(|l| dropped.dropped.iter().any(|d| d.label == *l)));
}

// ---------------------------------------------------------------------------------------------
// Mesh route vs label route

struct Agreement {
    volume: f64,
    contact_area: f64,
}

/// Contacts of at least this many voxel faces (a disc of radius ≥ 8 voxels) are held to the 10 %
/// threshold; see [`routes_agree`].
const RESOLVED_CONTACT_FACES: f64 = 200.0;

/// Meshes `volume` (about `nodes` nodes per median cell), measures both routes and checks the issue's
/// thresholds: volume within 2 %, neighbours identical, contact areas within 10 %. Returns the worst
/// relative differences (volume; contact area over the resolved contacts).
///
/// Contact areas differ by a rim band: the mesh route's surfaces are rounded within about a third of a
/// voxel of the contact rim (the mesher's blur σ = 0.35 voxel), the label route counts voxel faces up to
/// the rim, so |ΔA| ≈ perimeter × 0.35 voxel, i.e. 2·0.35/r relative for a disc of radius r voxels:
/// below 10 % from r ≈ 7 voxels. Contacts of at least [`RESOLVED_CONTACT_FACES`] voxel faces are held to
/// the 10 % threshold; smaller ones (corners of Voronoi cells) to |ΔA| < perimeter × 1 voxel of the disc
/// of the same area.
fn routes_agree(volume: &LabelVolume, nodes: usize) -> Agreement {
    let options = LabelMeshingOptions { target_nodes: nodes, seed: 1, ..Default::default() };
    let meshed = mesh_labels(volume, &options).unwrap();
    let by_mesh = measure_tissue(&meshed.tissue, &MeasureSettings::default()).unwrap();
    let by_voxels = measure_labels(volume, &LabelMeasureSettings::default()).unwrap().morphology;
    assert_eq!(
        by_mesh.cells.iter().map(|c| c.cell).collect::<Vec<_>>(),
        by_voxels.cells.iter().map(|c| c.cell).collect::<Vec<_>>()
    );
    let mut worst = Agreement { volume: 0.0, contact_area: 0.0 };
    for (m, v) in by_mesh.cells.iter().zip(&by_voxels.cells) {
        let dv = m.volume / v.volume - 1.0;
        eprintln!(
            "cell {}: volume {dv:+.4}, area {:+.4}, Ψ {:.4} / {:.4}, φ {:.3} / {:.3}, z {} / {}",
            m.cell,
            m.area / v.area - 1.0,
            m.sphericity,
            v.sphericity,
            m.contact_fraction,
            v.contact_fraction,
            m.neighbours,
            v.neighbours
        );
        worst.volume = worst.volume.max(dv.abs());
    }
    let pairs = |m: &Morphology| m.contacts.iter().map(|c| (c.cell_a, c.cell_b)).collect::<BTreeSet<_>>();
    assert_eq!(pairs(&by_mesh), pairs(&by_voxels), "contact graphs differ");
    let voxel = volume.voxel_size()[2];
    let face = voxel * voxel;
    for (m, v) in by_mesh.contacts.iter().zip(&by_voxels.contacts) {
        let da = m.area / v.area - 1.0;
        let faces = v.area / face;
        eprintln!("contact {}–{}: {faces:.0} voxel faces, area mesh/voxels − 1 = {da:+.4}", m.cell_a, m.cell_b);
        if faces >= RESOLVED_CONTACT_FACES {
            worst.contact_area = worst.contact_area.max(da.abs());
        } else {
            let band = 2.0 * (PI * v.area).sqrt() * voxel;
            assert!((m.area - v.area).abs() < band, "contact {}–{}: {da:+.4} of {faces:.0} faces", m.cell_a, m.cell_b);
        }
    }
    for (m, v) in by_mesh.cells.iter().zip(&by_voxels.cells) {
        assert_eq!(m.neighbours, v.neighbours, "cell {}", m.cell);
    }
    assert!(worst.volume < 0.02, "volume differs by {:.4}", worst.volume);
    assert!(worst.contact_area < 0.10, "contact area differs by {:.4}", worst.contact_area);
    worst
}

/// The generated doublet (two balls of radius 16 voxels, flat interface): both routes agree.
#[test]
fn mesh_and_label_routes_agree_on_a_doublet() {
    let spec = LabelSpec {
        pattern: LabelPattern::Doublet,
        shape: [40, 40, 64],
        voxel_size: [0.25e-6; 3],
        cells: 2,
        seed: 0,
        lumen: false,
    };
    let g = generate_labels(&spec).unwrap();
    let w = routes_agree(&g.volume, 1500);
    assert!(w.contact_area > 0.0, "the disc (~350 voxel faces) is a resolved contact");
    eprintln!("doublet: worst volume {:.4}, contact area {:.4}", w.volume, w.contact_area);
}

/// Generated 6-cell aggregates (Voronoi cells in a ball, ~20 voxels across): volumes within 2 %,
/// identical contact graphs, resolved contact areas within 10 % (smaller ones within a one-voxel rim
/// band, see [`routes_agree`]). Precondition checked here: the smallest contact of the label route
/// spans at least 8 voxel faces (the next test shows one that does not).
#[test]
fn mesh_and_label_routes_agree_on_an_aggregate() {
    for seed in [3, 4] {
        let spec = LabelSpec {
            pattern: LabelPattern::Aggregate,
            shape: [64, 64, 64],
            voxel_size: [0.25e-6; 3],
            cells: 6,
            seed,
            lumen: false,
        };
        let g = generate_labels(&spec).unwrap();
        let smallest = labels(&g.volume).contacts.iter().map(|c| c.area).fold(f64::INFINITY, f64::min);
        eprintln!("seed {seed}: smallest contact {:.1} voxel faces", smallest / 0.0625e-12);
        assert!(smallest >= 8.0 * 0.0625e-12, "seed {seed}: a contact of {smallest:e} m² is narrower than a voxel");
        let w = routes_agree(&g.volume, 1500);
        eprintln!("aggregate seed {seed}: worst volume {:.4}, contact area {:.4}", w.volume, w.contact_area);
    }
}

/// Why the routes can differ in z: the seed-2 aggregate has cells 3 and 4 meeting in a contact of about
/// 3 voxel faces (0.19 µm²) at the aggregate's surface. Each label is meshed on its own, and its level
/// set curves away from the neighbour within about a voxel of the line where the two cells and the
/// medium meet, so a contact narrower than a voxel is lost by the mesh route at any mesh resolution
/// (also with l_min = 0.6 voxel). The label route reports every voxel face. This test pins that
/// difference: everything else agrees, and the only extra contact is that sub-voxel one.
#[test]
fn a_contact_narrower_than_a_voxel_is_seen_only_by_the_label_route() {
    let spec = LabelSpec {
        pattern: LabelPattern::Aggregate,
        shape: [64, 64, 64],
        voxel_size: [0.25e-6; 3],
        cells: 6,
        seed: 2,
        lumen: false,
    };
    let g = generate_labels(&spec).unwrap();
    let meshed =
        mesh_labels(&g.volume, &LabelMeshingOptions { target_nodes: 1500, seed: 1, ..Default::default() }).unwrap();
    let by_mesh = measure_tissue(&meshed.tissue, &MeasureSettings::default()).unwrap();
    let by_voxels = labels(&g.volume);
    let mesh_pairs: BTreeSet<(u32, u32)> = by_mesh.contacts.iter().map(|c| (c.cell_a, c.cell_b)).collect();
    let extra: Vec<_> = by_voxels.contacts.iter().filter(|c| !mesh_pairs.contains(&(c.cell_a, c.cell_b))).collect();
    assert_eq!(extra.iter().map(|c| (c.cell_a, c.cell_b)).collect::<Vec<_>>(), vec![(3, 4)]);
    assert!(extra[0].area < 4.0 * 0.0625e-12, "{:e}", extra[0].area);
    assert_eq!(by_mesh.contacts.len() + 1, by_voxels.contacts.len());
}

// ---------------------------------------------------------------------------------------------
// Shape comparison

/// Labels → mesh → compare with the labels: every cell's IoU is high; the tissue against itself is 1;
/// a displaced tissue has a lower IoU.
#[test]
fn compare_shapes_matches_cells_by_label() {
    let spec = LabelSpec {
        pattern: LabelPattern::Aggregate,
        shape: [40, 40, 40],
        voxel_size: [0.25e-6; 3],
        cells: 4,
        seed: 1,
        lumen: false,
    };
    let g = generate_labels(&spec).unwrap();
    let tissue = mesh_labels(&g.volume, &LabelMeshingOptions::default()).unwrap().tissue;
    let overlaps = compare_shapes(&tissue, &g.volume).unwrap();
    assert_eq!(overlaps.iter().map(|o| o.label).collect::<Vec<_>>(), g.cells);
    for o in &overlaps {
        assert!(o.iou() > 0.9 && o.iou() < 1.0, "label {}: IoU {}", o.label, o.iou());
        assert!((o.chi() - (1.0 - o.iou())).abs() < 1e-15);
    }
    // The same as voxelising by hand and counting.
    let by_hand = label_overlap(&g.volume, &voxelize(&tissue, &g.volume.grid()).unwrap()).unwrap();
    assert_eq!(overlaps, by_hand);
    let same = compare_tissues(&tissue, &tissue, [0.2e-6; 3]).unwrap();
    assert!(same.iter().all(|o| o.iou() == 1.0 && o.voxels_a > 0));
    let mut moved = tissue.clone();
    for c in moved.cells_mut() {
        for p in c.positions_mut() {
            p.x += 1e-6;
        }
    }
    let shifted = compare_tissues(&tissue, &moved, [0.2e-6; 3]).unwrap();
    for (a, b) in overlaps.iter().zip(&shifted) {
        assert!(b.iou() < a.iou() - 0.1, "label {}: shifted IoU {} vs {}", a.label, b.iou(), a.iou());
    }
    // set_overlap fills iou/chi and the summary's mean χ.
    let mut m = measure_tissue(&tissue, &MeasureSettings::default()).unwrap();
    m.set_overlap(&overlaps);
    let mean = overlaps.iter().map(|o| o.chi()).sum::<f64>() / overlaps.len() as f64;
    assert!((m.summary.mean_chi.unwrap() - mean).abs() < 1e-12);
    assert!(m.cells.iter().all(|c| c.iou.is_some()));
}

// ---------------------------------------------------------------------------------------------
// CLI

fn column(path: &Path, name: &str) -> Vec<String> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let i = r.headers().unwrap().iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}"));
    r.records().map(|row| row.unwrap()[i].to_string()).collect()
}

/// `measure LABELS.tif` writes the same files and columns as for a tissue, cell ids = labels, empty
/// contact angles; `--compare` adds IoU and χ; one and two threads write identical files.
#[test]
fn measure_cli_measures_a_label_tiff_and_compares_it_with_its_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let spec = LabelSpec {
        pattern: LabelPattern::Doublet,
        shape: [32, 32, 48],
        voxel_size: [0.3e-6, 0.2e-6, 0.2e-6],
        cells: 2,
        seed: 0,
        lumen: false,
    };
    let mut volume = generate_labels(&spec).unwrap().volume;
    for l in volume.labels_mut().iter_mut() {
        *l *= 7; // labels 7 and 14
    }
    let tif = dir.path().join("doublet.tif");
    write_label_tiff(&tif, &volume, &LabelWriteOptions::default()).unwrap();
    let tissue = dir.path().join("doublet.vtp");
    let run = tissuefit(&["mesh", tif.to_str().unwrap(), "--out", tissue.to_str().unwrap()]);
    assert_eq!(run.status.code(), Some(0), "{}", String::from_utf8_lossy(&run.stderr));

    let mut outputs = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("m{threads}"));
        let run = tissuefit(&[
            "measure",
            tif.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--compare",
            tissue.to_str().unwrap(),
            "--threads",
            threads,
        ]);
        assert_eq!(run.status.code(), Some(0), "{}", String::from_utf8_lossy(&run.stderr));
        assert!(String::from_utf8_lossy(&run.stdout).contains("2 cells measured"));
        let cells = std::fs::read_to_string(out.join("cells.csv")).unwrap();
        assert!(cells.starts_with("cell,kind,static,volume,area,sphericity,neighbours,contact_fraction,"));
        assert_eq!(column(&out.join("cells.csv"), "cell"), vec!["7", "14"]);
        assert_eq!(column(&out.join("cells.csv"), "neighbours"), vec!["1", "1"]);
        assert_eq!(column(&out.join("cells.csv"), "apical_area"), vec!["", ""]);
        for iou in column(&out.join("cells.csv"), "iou") {
            let iou: f64 = iou.parse().unwrap();
            assert!(iou > 0.85 && iou < 1.0, "IoU {iou}");
        }
        assert_eq!(column(&out.join("contacts.csv"), "contact_angle_deg"), vec![""]);
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        assert_eq!(summary["input"], "labels");
        assert_eq!(summary["cells"], 2);
        assert_eq!(summary["compared_cells"], 2);
        assert!(summary["contact_distance"].is_null());
        let chi = summary["mean_chi"].as_f64().unwrap();
        assert!(chi > 0.0 && chi < 0.15, "⟨χ⟩ = {chi}");
        outputs.push((std::fs::read(out.join("cells.csv")).unwrap(), std::fs::read(out.join("contacts.csv")).unwrap()));
    }
    assert!(outputs[0] == outputs[1], "1 and 2 threads differ");

    // The tissue route compared with the labels gives the same IoU per cell (same grid, same voxels).
    let out = dir.path().join("t");
    let run = tissuefit(&[
        "measure",
        tissue.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--compare",
        tif.to_str().unwrap(),
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", String::from_utf8_lossy(&run.stderr));
    assert_eq!(column(&out.join("cells.csv"), "iou"), column(&dir.path().join("m1/cells.csv"), "iou"));

    // Label-only options on a tissue, and a contact distance on labels, are refused.
    let bad = tissuefit(&["measure", tissue.to_str().unwrap(), "--out", out.to_str().unwrap(), "--border", "static"]);
    assert_eq!(bad.status.code(), Some(2));
    let bad =
        tissuefit(&["measure", tif.to_str().unwrap(), "--out", out.to_str().unwrap(), "--contact-distance", "0.1um"]);
    assert_eq!(bad.status.code(), Some(2));
}
