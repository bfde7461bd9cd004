//! Ray-casting polarisation (paper mode 2): against an independent geometric ground truth on the
//! SimuCell3D lumen test geometry, and inside simulations (start, interval, divisions).

use crate::support::cli::tissuefit;
use rayon::prelude::*;
use std::path::Path;
use tissuefit::geometry::{Real, Vec3, bounding_box, closest_point_on_triangle};
use tissuefit::io::{ReadOptions, read_tissue};
use tissuefit::mechanics::{
    Parameters, Polarity, RayCastSettings, Simulation, SimulationMode, polarize_by_ray_casting,
};
use tissuefit::mesh::shapes::icosphere;
use tissuefit::mesh::{Cell, CellId, CellKind, FaceType, Tissue};

/// The geometric ground truth of one face of cell `c` of `tissue`, independent of voxels and rays:
/// lateral when a triangle of another cell lies within `d` of the face centre (exact closest-point
/// distance) and faces it (normals at more than 120°, the contact criterion of SimuCell3D: two
/// membranes in contact look at each other, while a neighbour's coplanar outer face at the rim of
/// the interface does not); otherwise apical when the face looks towards the cyst's centre
/// `centre` (the lumen of a closed cyst is around its centre), basal when it looks away.
fn ground_truth(tissue: &Tissue, boxes: &[(Vec3, Vec3)], c: usize, f: usize, centre: &Vec3, d: Real) -> FaceType {
    let mesh = tissue.cells()[c].mesh();
    let [a, b, q] = mesh.corners(tissuefit::mesh::FaceId(f as u32));
    let p = (a + b + q) / 3.0;
    let n = (b - a).cross(&(q - a)).normalize();
    for (o, other) in tissue.cells().iter().enumerate() {
        let (lo, hi) = boxes[o];
        if o == c || (0..3).any(|k| p[k] < lo[k] - d || p[k] > hi[k] + d) {
            continue;
        }
        let x = other.mesh().positions();
        for t in other.mesh().triangles() {
            let hit = closest_point_on_triangle(&p, &x[t[0] as usize], &x[t[1] as usize], &x[t[2] as usize]);
            let normal = (x[t[1] as usize] - x[t[0] as usize]).cross(&(x[t[2] as usize] - x[t[0] as usize]));
            if hit.distance <= d && normal.normalize().dot(&n) <= -0.5 {
                return FaceType::Lateral;
            }
        }
    }
    if n.dot(&(centre - p)) > 0.0 { FaceType::Apical } else { FaceType::Basal }
}

#[test]
#[ignore = "needs ../shared/data/real"]
fn lumen_geometry_polarises_apical_towards_the_lumen_lateral_between_cells_basal_outside() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real/simucell3d__lumen_geometry.vtk");
    let options = ReadOptions { length_scale: "m".parse().unwrap(), orient: false };
    let mut tissue = read_tissue(&path, &options).expect("reads").tissue;
    assert_eq!(tissue.len(), 26);
    // Mean edge length 0.65 µm, shortest 0.5 µm (the file's l_min): the default voxel, 1.5·l_min.
    let h: Real = RayCastSettings::DEFAULT_VOXELS_PER_MIN_EDGE * 0.5e-6;
    let report = polarize_by_ray_casting(&mut tissue, &RayCastSettings::new(h)).expect("polarises");
    eprintln!("{report:?}");
    assert_eq!((report.cytoplasm_clusters, report.exterior_clusters, report.lumen_clusters), (26, 1, 1), "{report:?}");
    assert!(report.cells_without_cytoplasm.is_empty());

    let boxes: Vec<(Vec3, Vec3)> = tissue.cells().iter().map(|c| bounding_box(c.mesh().positions()).unwrap()).collect();
    let centre = tissue.cells().iter().map(|c| c.mesh().volume_centroid().unwrap()).sum::<Vec3>() / 26.0;
    // d: the contact gap of this geometry. Cells in contact sit about one l_min (0.5 µm) apart; d is
    // one mean edge length (0.65 µm), so faces in contact count while rim faces that merely look at
    // a neighbour across the lumen or the medium (several µm) do not.
    let d = 0.65e-6;
    let faces: Vec<(usize, usize)> = tissue
        .cells()
        .iter()
        .enumerate()
        .flat_map(|(c, cell)| (0..cell.face_types().len()).map(move |f| (c, f)))
        .collect();
    let truth: Vec<FaceType> =
        faces.par_iter().map(|&(c, f)| ground_truth(&tissue, &boxes, c, f, &centre, d)).collect();
    // confusion[truth][ray]
    let mut confusion = [[0usize; 3]; 3];
    for (&(c, f), t) in faces.iter().zip(&truth) {
        confusion[t.code() as usize][tissue.cells()[c].face_types()[f].code() as usize] += 1;
    }
    let total: usize = confusion.iter().flatten().sum();
    let agree: usize = (0..3).map(|k| confusion[k][k]).sum();
    for t in FaceType::ALL {
        let row = confusion[t.code() as usize];
        let n: usize = row.iter().sum();
        eprintln!(
            "ground truth {:>7}: {n:>6} faces, ray casting agrees on {:.1} % (as apical/lateral/basal: {row:?})",
            t.name(),
            100.0 * row[t.code() as usize] as Real / n.max(1) as Real
        );
    }
    eprintln!("overall agreement {:.2} % of {total} faces", 100.0 * agree as Real / total as Real);
    assert!(agree as Real >= 0.9 * total as Real, "{confusion:?}");
    for t in FaceType::ALL {
        let row = confusion[t.code() as usize];
        let n: usize = row.iter().sum();
        assert!(n > 1000, "every face type is present: {confusion:?}");
        // Measured 99.7 / 99.1 / 100 %; what disagrees sits on the rims of interfaces, where a
        // face one voxel from a junction is ambiguous to both methods.
        assert!(row[t.code() as usize] as Real >= 0.95 * n as Real, "{}: {row:?}", t.name());
    }
}

fn time_params(l_min: Real) -> Parameters {
    let mut p = Parameters::default();
    p.numerics.min_edge_length = l_min;
    p.numerics.contact_cutoff = 0.8 * l_min;
    p.numerics.polarity = Polarity::RayCasting;
    p.simulation.mode = SimulationMode::Time;
    p.cell_types[0].growth_rate = 0.0;
    p.cell_types[0].min_volume = 0.0;
    p
}

/// Whether the tissue's face types are what a polarisation of its current geometry gives.
fn freshly_polarised(tissue: &Tissue, p: &Parameters) -> bool {
    let mut copy = tissue.clone();
    polarize_by_ray_casting(&mut copy, &RayCastSettings::from_numerics(&p.numerics)).unwrap().changed == 0
}

/// Two touching cells: polarised at the start and every `polarity_interval` steps, not in between;
/// the interface is lateral, the rest basal.
#[test]
fn ray_casting_polarises_at_the_start_and_every_interval() {
    let mut p = time_params(6e-7);
    p.numerics.polarity_interval = 3;
    p.cell_types[0].division_volume = Real::INFINITY;
    let cells = [-1.0, 1.0].map(|side| {
        let mesh = icosphere(3e-6, 2, Vec3::new(side * 2.9e-6, 0.0, 0.0));
        let v = mesh.signed_volume();
        Cell::new(CellId(if side < 0.0 { 1 } else { 2 }), CellKind::Epithelial, 0, mesh).with_target_volume(v)
    });
    let mut sim = Simulation::new(Tissue::from_cells(cells.to_vec()).unwrap(), &p).unwrap();
    sim.start().unwrap();
    assert_eq!(sim.polarizations(), 1);
    for cell in sim.tissue().cells() {
        let count = |t: FaceType| cell.face_types().iter().filter(|x| **x == t).count();
        assert!(count(FaceType::Lateral) > 0 && count(FaceType::Basal) > count(FaceType::Lateral), "{}", cell.id());
        assert_eq!(count(FaceType::Apical), 0);
    }
    let mut counts = Vec::new();
    for _ in 0..7 {
        sim.time_step().unwrap();
        counts.push(sim.polarizations());
    }
    // Steps 1..=7: polarised at steps 3 and 6.
    assert_eq!(counts, [1, 1, 2, 2, 2, 3, 3]);
    assert!(sim.tissue().cells().iter().all(|c| c.mesh().validate().is_ok()));
}

/// A division re-polarises at once, whatever the interval: the daughters' shared cut is lateral,
/// and the types are those of a polarisation of the new geometry.
#[test]
fn ray_casting_repolarises_after_a_division() {
    let mut p = time_params(6e-7);
    p.numerics.polarity_interval = 1000;
    let mesh = icosphere(3e-6, 2, Vec3::zeros());
    let volume = mesh.signed_volume();
    p.cell_types[0].division_volume = 0.5 * volume;
    let mother = Cell::new(CellId(5), CellKind::Epithelial, 0, mesh).with_target_volume(1.1 * volume);
    let mut sim = Simulation::new(Tissue::from_cells(vec![mother]).unwrap(), &p).unwrap();
    sim.start().unwrap();
    assert_eq!(sim.polarizations(), 1);
    assert!(sim.tissue().cells()[0].face_types().iter().all(|t| *t == FaceType::Basal), "a lone cell is basal");
    sim.time_step().unwrap();
    assert_eq!(sim.tissue().len(), 2, "the cell divided");
    assert_eq!(sim.polarizations(), 2, "the division was polarised at its step");
    assert!(freshly_polarised(sim.tissue(), &p));
    for cell in sim.tissue().cells() {
        assert!(cell.mesh().validate().is_ok());
        let lateral = cell.face_types().iter().filter(|t| **t == FaceType::Lateral).count();
        assert!(lateral > 0 && lateral < cell.face_types().len() / 2, "cell {}: {lateral} lateral", cell.id());
    }
    for _ in 0..5 {
        sim.time_step().unwrap();
    }
    assert_eq!(sim.polarizations(), 2, "no division, no interval: no polarisation");
    assert!(sim.tissue().cells().iter().all(|c| c.mesh().validate().is_ok()));
}

fn demo() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/cell_quartet.vtk")
}

fn count(tissue: &Tissue, t: FaceType) -> usize {
    tissue.cells().iter().map(|c| c.face_types().iter().filter(|x| **x == t).count()).sum()
}

/// `tissuefit polarize` writes a .vtp whose face types are those it reports, and those of the
/// library call; bad input exits 2.
#[test]
fn polarize_command_writes_the_face_types_it_reports() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("polarised.vtp");
    let o = tissuefit(&["polarize", demo().to_str().unwrap(), "--out", out.to_str().unwrap(), "--json"]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let written = tissuefit::io::read_vtp(&out).unwrap();
    for t in FaceType::ALL {
        assert_eq!(report[t.name()].as_u64(), Some(count(&written, t) as u64), "{t:?}: {report}");
    }
    // The four touching demo cells have interfaces, and faces towards the medium.
    assert!(count(&written, FaceType::Lateral) > 0 && count(&written, FaceType::Basal) > 0, "{report}");
    // Where the cells meet, two small enclosed pockets open between them: gaps, not lumens, so no
    // face is apical; counted as lumens (threshold 0) they make the faces around them apical.
    assert_eq!((report["gap_clusters"].as_u64(), report["lumen_clusters"].as_u64()), (Some(2), Some(0)), "{report}");
    assert_eq!(count(&written, FaceType::Apical), 0, "{report}");
    let o = tissuefit(&[
        "polarize",
        demo().to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
        "--min-lumen-fraction",
        "0",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let pockets: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(pockets["lumen_clusters"].as_u64(), Some(2), "{pockets}");
    assert!(count(&tissuefit::io::read_vtp(&out).unwrap(), FaceType::Apical) > 0, "{pockets}");
    let o =
        tissuefit(&["polarize", demo().to_str().unwrap(), "--out", out.to_str().unwrap(), "--min-lumen-fraction=-1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--min-lumen-fraction"));
    let mut tissue = read_tissue(&demo(), &ReadOptions::default()).unwrap().tissue;
    let h = report["voxel_size"].as_f64().unwrap();
    let out = dir.path().join("polarised.vtp");
    let o = tissuefit(&["polarize", demo().to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0));
    polarize_by_ray_casting(&mut tissue, &RayCastSettings::new(h)).unwrap();
    for (a, b) in tissue.cells().iter().zip(written.cells()) {
        assert_eq!(a.face_types(), b.face_types(), "cell {}", a.id());
    }
    let o = tissuefit(&["polarize", demo().to_str().unwrap(), "--out", out.to_str().unwrap(), "--voxel-size=0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--voxel-size"));
    let o = tissuefit(&["polarize", demo().to_str().unwrap(), "--out", out.to_str().unwrap(), "--mode", "rays"]);
    assert_eq!(o.status.code(), Some(2));
}

/// A simulation with `polarity = "ray_casting"` writes the face types into its ParaView frames.
#[test]
fn simulate_writes_ray_cast_face_types_into_its_frames() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("config.toml");
    std::fs::write(&config, "[numerics]\nmin_edge_length = 6e-7\npolarity = \"ray_casting\"\npolarity_interval = 2\n")
        .unwrap();
    let out = dir.path().join("run");
    let o = tissuefit(&[
        "simulate",
        demo().to_str().unwrap(),
        "--config",
        config.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--max-steps",
        "4",
    ]);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", String::from_utf8_lossy(&o.stderr));
    let mut frames: Vec<_> = std::fs::read_dir(out.join("frames")).unwrap().map(|e| e.unwrap().path()).collect();
    frames.sort();
    let last = tissuefit::io::read_vtp(frames.last().unwrap()).unwrap();
    assert!(count(&last, FaceType::Lateral) > 0 && count(&last, FaceType::Basal) > 0);
    // The input file has every face apical (SimuCell3D's type 0): the frames show the new types.
    let input = read_tissue(&demo(), &ReadOptions::default()).unwrap().tissue;
    assert_eq!(count(&input, FaceType::Apical), input.face_count());
}

/// A run with ray-casting polarity stopped between two polarisations and resumed ends exactly as
/// the uninterrupted run: the face types travel in the checkpoint, and the schedule follows the
/// step count.
#[test]
fn a_ray_casting_run_stopped_and_resumed_matches_the_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("config.toml");
    std::fs::write(&config, "[numerics]\nmin_edge_length = 6e-7\npolarity = \"ray_casting\"\npolarity_interval = 6\n")
        .unwrap();
    let (reference, split) = (dir.path().join("reference"), dir.path().join("split"));
    let run = |out: &Path, extra: &[&str]| {
        let (demo, config, out) = (demo(), config.clone(), out.to_path_buf());
        let mut args: Vec<String> = ["--threads", "2", "simulate"].map(String::from).to_vec();
        for a in [demo.to_str().unwrap(), "--config", config.to_str().unwrap(), "--out", out.to_str().unwrap()] {
            args.push(a.to_owned());
        }
        args.extend(["--max-steps", "40"].map(String::from));
        args.extend(extra.iter().map(|a| a.to_string()));
        tissuefit(&args.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let full = run(&reference, &[]);
    assert!(matches!(full.status.code(), Some(0 | 1)), "{}", String::from_utf8_lossy(&full.stderr));
    let stopped = run(&split, &["--stop-at-step", "20"]);
    assert_eq!(stopped.status.code(), Some(130), "{}", String::from_utf8_lossy(&stopped.stderr));
    let resumed = tissuefit(&["--threads", "2", "simulate", "--resume", split.to_str().unwrap()]);
    assert_eq!(resumed.status.code(), full.status.code(), "{}", String::from_utf8_lossy(&resumed.stderr));
    for name in ["final.vtk", "stats.csv"] {
        let (a, b) = (std::fs::read(reference.join(name)).unwrap(), std::fs::read(split.join(name)).unwrap());
        assert!(a == b, "{name} differs between the uninterrupted and the resumed run");
    }
}
