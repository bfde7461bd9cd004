//! Meshing binary masks: synthetic shapes built here (spheres, ellipsoid, cube, anisotropic voxels, a
//! dumbbell, masks touching the crop border), bad input, determinism, and the real C. elegans cells.
//!
//! Volume tolerance (3 %): the voxel count × voxel volume is the reference. The 0.5 level of a
//! binary mask runs through the outer faces of the boundary voxels where the boundary is flat, so it
//! encloses the voxel-count volume there; where it is curved, the level cuts across the staircase
//! corners and encloses less (the relative deficit shrinks like 1/R in voxels). The Gaussian blur
//! (σ = 0.35 voxel) pulls a convex level inward by ≈ σ²/R, and the final triangles are chords of
//! that level, ≈ 3·r_c²/(4R²) less again (r_c the triangle circumradius, ≈ 1.5 % at 400 nodes).
//! For the shapes here (radii of curvature ≥ 8 voxels, ~400 nodes) these add up to 1.9–2.2 %
//! (over 40 seeds the ellipsoid stays within 1.9–2.6 %), hence the 3 % bound.

use ndarray::Array3;
use std::collections::HashSet;
use tissuefit::geometry::{Real, Vec3};
use tissuefit::mesh::CellMesh;
use tissuefit::meshing::{DEFAULT_TARGET_NODES, MeshedCell, MeshingError, MeshingSettings, default_l_min, mesh_mask};

/// A mask of `shape` (z, y, x) with voxel size `voxel` (z, y, x): voxel set where `inside(p)` holds
/// for its centre p = (x·sx, y·sy, z·sz).
fn mask_of(shape: [usize; 3], voxel: [Real; 3], inside: impl Fn(Vec3) -> bool) -> Array3<bool> {
    Array3::from_shape_fn((shape[0], shape[1], shape[2]), |(z, y, x)| {
        inside(Vec3::new(x as Real * voxel[2], y as Real * voxel[1], z as Real * voxel[0]))
    })
}

fn voxel_count(mask: &Array3<bool>) -> usize {
    mask.iter().filter(|&&v| v).count()
}

/// Fraction of the mesh's edges with length in [l_min, 3·l_min].
fn edges_in_range(mesh: &CellMesh, l_min: Real) -> Real {
    let mut edges = HashSet::new();
    for t in mesh.triangles() {
        for s in 0..3 {
            let (a, b) = (t[s], t[(s + 1) % 3]);
            edges.insert((a.min(b), a.max(b)));
        }
    }
    let p = mesh.positions();
    let ok = edges
        .iter()
        .filter(|&&(a, b)| {
            let l = (p[a as usize] - p[b as usize]).norm();
            (l_min * (1.0 - 1e-9)..=3.0 * l_min * (1.0 + 1e-9)).contains(&l)
        })
        .count();
    ok as Real / edges.len() as Real
}

/// Meshes `mask` at the default resolution and checks the contract: valid, volume within 3 % of the
/// voxel volume, ≥ 95 % of edges in range, a few hundred nodes.
fn mesh_and_check(name: &str, mask: &Array3<bool>, voxel: [Real; 3]) -> MeshedCell {
    let volume = voxel_count(mask) as Real * voxel.iter().product::<Real>();
    let l_min = default_l_min(volume, DEFAULT_TARGET_NODES).unwrap();
    let settings = MeshingSettings::new(l_min, voxel);
    let cell = mesh_mask(mask.view(), voxel, Vec3::new(1e-6, -2e-6, 3e-6), &settings)
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let mesh = &cell.mesh;
    assert_eq!(mesh.validate(), Ok(()), "{name}");
    assert!((cell.voxel_volume - volume).abs() <= 1e-12 * volume, "{name}: no voxel dropped or filled");
    let ratio = mesh.signed_volume() / volume;
    let in_range = edges_in_range(mesh, l_min);
    eprintln!(
        "{name}: nodes {} samples {} unused {} seeds {} faces/radius {:?} holes {} (largest {}) removed {} \
         volume ratio {ratio:.4} (surface {:.4}) edges in range {in_range:.3} remesh splits {} collapses {} flips {}",
        mesh.node_count(),
        cell.samples,
        cell.unused_samples,
        cell.seeds,
        cell.faces_per_radius,
        cell.holes_filled,
        cell.largest_hole,
        cell.removed_faces,
        cell.surface_volume / volume,
        cell.remesh.splits,
        cell.remesh.collapses,
        cell.remesh.flips,
    );
    assert!((ratio - 1.0).abs() < 0.03, "{name}: mesh volume / voxel volume = {ratio}");
    assert!(in_range >= 0.95, "{name}: only {in_range} of the edges lie in [l_min, 3·l_min]");
    assert!((200..=800).contains(&mesh.node_count()), "{name}: {} nodes", mesh.node_count());
    cell
}

const UM: Real = 1e-6;

#[test]
fn sphere() {
    let v = [0.2 * UM; 3];
    let c = Vec3::repeat(15.0 * v[0]);
    let mask = mask_of([31, 31, 31], v, |p| (p - c).norm() <= 12.0 * v[0]);
    mesh_and_check("sphere", &mask, v);
}

#[test]
fn ellipsoid() {
    let v = [0.2 * UM; 3];
    let c = Vec3::new(20.0, 15.0, 12.0) * v[0];
    let axes = Vec3::new(17.0, 11.0, 8.0) * v[0];
    let mask = mask_of([25, 31, 41], v, |p| (p - c).component_div(&axes).norm() <= 1.0);
    mesh_and_check("ellipsoid", &mask, v);
}

#[test]
fn cube() {
    let v = [0.2 * UM; 3];
    let mask = mask_of([26, 26, 26], v, |p| p.iter().all(|&x| (3.0 * v[0]..=22.5 * v[0]).contains(&x)));
    mesh_and_check("cube", &mask, v);
}

#[test]
fn sphere_on_anisotropic_voxels() {
    let v = [0.235 * UM, 0.15 * UM, 0.15 * UM];
    let c = Vec3::new(22.0 * v[2], 22.0 * v[1], 15.0 * v[0]);
    let mask = mask_of([31, 45, 45], v, |p| (p - c).norm() <= 3.0 * UM);
    let cell = mesh_and_check("anisotropic sphere", &mask, v);
    // Round in space, not in voxels: the z extent equals the x extent.
    let p = cell.mesh.positions();
    let extent = |a: usize| {
        p.iter().map(|q| q[a]).fold(Real::NEG_INFINITY, Real::max)
            - p.iter().map(|q| q[a]).fold(Real::INFINITY, Real::min)
    };
    assert!((extent(2) / extent(0) - 1.0).abs() < 0.05, "z extent {} vs x extent {}", extent(2), extent(0));
}

#[test]
fn dumbbell_of_two_overlapping_balls() {
    let v = [0.2 * UM; 3];
    let (a, b) = (Vec3::new(11.0, 12.0, 12.0) * v[0], Vec3::new(27.0, 12.0, 12.0) * v[0]);
    let r = 9.0 * v[0];
    let mask = mask_of([25, 25, 39], v, |p| (p - a).norm() <= r || (p - b).norm() <= r);
    let cell = mesh_and_check("dumbbell", &mask, v);
    // The neck is narrower than the balls: the surface has nodes near the waist plane at a radius
    // clearly below the balls' radius.
    let waist = cell
        .mesh
        .positions()
        .iter()
        .filter(|p| (p.x - 19.0 * v[0] - 1e-6).abs() < 1.0 * v[0])
        .map(|p| ((p.y + 2e-6 - 12.0 * v[0]).powi(2) + (p.z - 3e-6 - 12.0 * v[0]).powi(2)).sqrt())
        .fold(Real::INFINITY, Real::min);
    assert!(waist < 0.8 * r, "waist radius {waist} vs ball radius {r}");
}

#[test]
fn masks_touching_the_crop_border() {
    let v = [0.2 * UM; 3];
    // A ball that touches all six faces of its array.
    let c = Vec3::repeat(11.0 * v[0]);
    let touching = mask_of([23, 23, 23], v, |p| (p - c).norm() <= 11.4 * v[0]);
    assert!(touching[[0, 11, 11]] && touching[[22, 11, 11]] && touching[[11, 11, 0]]);
    mesh_and_check("ball touching the border", &touching, v);
    // A ball cut by the array: the cut face is a flat side of the cell.
    let c = Vec3::new(12.0, 12.0, 4.0) * v[0];
    let cut = mask_of([20, 25, 25], v, |p| (p - c).norm() <= 12.0 * v[0]);
    mesh_and_check("ball cut by the border", &cut, v);
}

#[test]
fn same_seed_same_mesh_other_seed_other_mesh() {
    let v = [0.2 * UM; 3];
    let c = Vec3::repeat(11.0 * v[0]);
    let mask = mask_of([23, 23, 23], v, |p| (p - c).norm() <= 9.0 * v[0]);
    let mut settings = MeshingSettings::new(0.5 * UM, v);
    settings.seed = 42;
    let a = mesh_mask(mask.view(), v, Vec3::zeros(), &settings).unwrap();
    let b = mesh_mask(mask.view(), v, Vec3::zeros(), &settings).unwrap();
    assert_eq!(a.mesh, b.mesh);
    settings.seed = 43;
    let c = mesh_mask(mask.view(), v, Vec3::zeros(), &settings).unwrap();
    assert_ne!(a.mesh, c.mesh);
    assert_eq!(c.mesh.validate(), Ok(()));
}

#[test]
fn default_l_min_gives_a_few_hundred_nodes() {
    let v = [0.25 * UM; 3];
    let c = Vec3::repeat(20.0 * v[0]);
    let mask = mask_of([41, 41, 41], v, |p| (p - c).norm() <= 18.0 * v[0]);
    for target in [200, 600] {
        let volume = voxel_count(&mask) as Real * v[0].powi(3);
        let l_min = default_l_min(volume, target).unwrap();
        let cell = mesh_mask(mask.view(), v, Vec3::zeros(), &MeshingSettings::new(l_min, v)).unwrap();
        let n = cell.mesh.node_count() as Real;
        assert!((n / target as Real - 1.0).abs() < 0.25, "target {target}: {n} nodes");
    }
    assert_eq!(default_l_min(0.0, 100), None);
    assert_eq!(default_l_min(1.0, 0), None);
}

#[test]
fn bad_input_is_a_clear_error() {
    let v = [0.2 * UM; 3];
    let settings = MeshingSettings::new(0.5 * UM, v);
    let empty = Array3::from_elem((5, 5, 5), false);
    let err = mesh_mask(empty.view(), v, Vec3::zeros(), &settings).unwrap_err();
    assert!(matches!(err, MeshingError::EmptyMask { shape: [5, 5, 5] }), "{err}");
    let mut one = empty.clone();
    one[[2, 2, 2]] = true;
    let err = mesh_mask(one.view(), v, Vec3::zeros(), &settings).unwrap_err();
    assert!(matches!(err, MeshingError::TooFewVoxels { voxels: 1, .. }), "{err}");
    let zero = Array3::from_elem((0, 4, 4), false);
    assert!(matches!(mesh_mask(zero.view(), v, Vec3::zeros(), &settings), Err(MeshingError::EmptyMask { .. })));
    // A 3³ block is too small for l_min = 0.5 µm (block edge 0.6 µm).
    let mut block = Array3::from_elem((5, 5, 5), false);
    block.slice_mut(ndarray::s![1..4, 1..4, 1..4]).fill(true);
    let err = mesh_mask(block.view(), v, Vec3::zeros(), &settings).unwrap_err();
    assert!(matches!(err, MeshingError::TooFewSamples { .. }), "{err}");
    assert!(err.to_string().contains("l_min"), "{err}");
    let err =
        mesh_mask(block.view(), v, Vec3::zeros(), &MeshingSettings { l_min: 1e-12, ..settings.clone() }).unwrap_err();
    assert!(matches!(err, MeshingError::ResolutionTooFine { .. }), "{err}");
    // A 10-voxel ball at l_min = 0.8·R gets ~14 samples: a valid polyhedron with ~60 % of the
    // volume, refused rather than returned.
    let c = Vec3::repeat(11.0 * v[0]);
    let ball = mask_of([23, 23, 23], v, |p| (p - c).norm() <= 10.0 * v[0]);
    let coarse = MeshingSettings { l_min: 1.6 * UM, ..settings.clone() };
    let err = mesh_mask(ball.view(), v, Vec3::zeros(), &coarse).unwrap_err();
    assert!(matches!(err, MeshingError::VolumeMismatch { .. }), "{err}");
    let err = mesh_mask(block.view(), [0.2 * UM, 0.0, 0.2 * UM], Vec3::zeros(), &settings).unwrap_err();
    assert!(matches!(err, MeshingError::InvalidVoxelSize { .. }), "{err}");
    let err = mesh_mask(block.view(), v, Vec3::new(Real::NAN, 0.0, 0.0), &settings).unwrap_err();
    assert!(matches!(err, MeshingError::InvalidOrigin { .. }), "{err}");
    for bad in [
        MeshingSettings { l_min: Real::NAN, ..settings.clone() },
        MeshingSettings { l_min: -1.0, ..settings.clone() },
        MeshingSettings { smoothing: -1.0, ..settings.clone() },
        MeshingSettings { ball_radii: vec![], ..settings.clone() },
        MeshingSettings { ball_radii: vec![2.0, 1.5], ..settings.clone() },
        MeshingSettings { candidates_per_area: 0.0, ..settings.clone() },
    ] {
        let err = mesh_mask(block.view(), v, Vec3::zeros(), &bad).unwrap_err();
        assert!(matches!(err, MeshingError::InvalidSettings { .. }), "{err}");
    }
}

/// Ray-parity voxelisation of a closed surface (test-only): voxel centres at `origin + step·(x, y, z)`
/// on a grid covering the mesh with a 2-voxel margin; a centre is inside when a ray along +x from it
/// crosses the surface an odd number of times. Rays are offset by a tiny irrational fraction of a
/// voxel so that they never pass exactly through a vertex or an edge of the input.
fn voxelise(mesh: &CellMesh, step: Real) -> (Array3<bool>, Vec3) {
    let p = mesh.positions();
    let lo = p.iter().fold(Vec3::repeat(Real::INFINITY), |a, q| a.inf(q));
    let hi = p.iter().fold(Vec3::repeat(Real::NEG_INFINITY), |a, q| a.sup(q));
    let origin = (lo / step).map(|c| c.floor() - 2.0) * step;
    let dims = ((hi - origin) / step).map(|c| c.ceil() as usize + 3);
    let (nx, ny, nz) = (dims.x, dims.y, dims.z);
    let (jy, jz) = (1.234_567e-4 * step, 2.345_678e-4 * step);
    let mut columns: Vec<Vec<Real>> = vec![Vec::new(); ny * nz];
    for t in mesh.triangles() {
        let [a, b, c] = t.map(|i| p[i as usize]);
        let ymin = ((a.y.min(b.y).min(c.y) - origin.y - jy) / step).floor().max(0.0) as usize;
        let ymax = (((a.y.max(b.y).max(c.y) - origin.y - jy) / step).ceil() as usize).min(ny - 1);
        let zmin = ((a.z.min(b.z).min(c.z) - origin.z - jz) / step).floor().max(0.0) as usize;
        let zmax = (((a.z.max(b.z).max(c.z) - origin.z - jz) / step).ceil() as usize).min(nz - 1);
        let det = (b.y - a.y) * (c.z - a.z) - (c.y - a.y) * (b.z - a.z);
        if det == 0.0 {
            continue;
        }
        for k in zmin..=zmax {
            for j in ymin..=ymax {
                let (y, z) = (origin.y + j as Real * step + jy, origin.z + k as Real * step + jz);
                let u = ((y - a.y) * (c.z - a.z) - (c.y - a.y) * (z - a.z)) / det;
                let v = ((b.y - a.y) * (z - a.z) - (y - a.y) * (b.z - a.z)) / det;
                if u > 0.0 && v > 0.0 && u + v < 1.0 {
                    columns[j + ny * k].push(a.x + u * (b.x - a.x) + v * (c.x - a.x));
                }
            }
        }
    }
    let mut mask = Array3::from_elem((nz, ny, nx), false);
    for k in 0..nz {
        for j in 0..ny {
            let xs = &mut columns[j + ny * k];
            assert!(xs.len().is_multiple_of(2), "a ray crossed the closed surface an odd number of times");
            xs.sort_by(|a, b| a.total_cmp(b));
            for pair in xs.chunks(2) {
                for i in 0..nx {
                    let x = origin.x + i as Real * step;
                    if pair[0] < x && x < pair[1] {
                        mask[[k, j, i]] = true;
                    }
                }
            }
        }
    }
    (mask, origin)
}

#[test]
#[ignore = "needs ../shared/data/real"]
fn real_c_elegans_cells_are_remeshed_from_their_voxelisation() {
    // The 4-cell C. elegans embryo (CShaper segmentation, delaunay-watershed mesh), coordinates in
    // voxel units: each cell voxelised at 1 unit (as in the DERIVED label TIFF), then meshed. This
    // also re-triangulates a multi-material mesh at a chosen resolution.
    use tissuefit::io::{ReadOptions, read_tissue};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/real/foambryo-runner__Cshaper_4_cells_min-d-3.vtk");
    assert!(path.exists(), "{} is missing", path.display());
    let tissue = read_tissue(&path, &ReadOptions::default()).unwrap().tissue;
    assert_eq!(tissue.len(), 4);
    for cell in tissue.cells() {
        let source_volume = cell.mesh().signed_volume();
        let (mask, origin) = voxelise(cell.mesh(), 1.0);
        let voxels = voxel_count(&mask) as Real;
        assert!((voxels / source_volume - 1.0).abs() < 0.01, "cell {}: voxelisation off", cell.id());
        let l_min = default_l_min(voxels, DEFAULT_TARGET_NODES).unwrap();
        let settings = MeshingSettings::new(l_min, [1.0; 3]);
        let start = std::time::Instant::now();
        let meshed =
            mesh_mask(mask.view(), [1.0; 3], origin, &settings).unwrap_or_else(|e| panic!("cell {}: {e}", cell.id()));
        let seconds = start.elapsed().as_secs_f64();
        let mesh = &meshed.mesh;
        assert_eq!(mesh.validate(), Ok(()), "cell {}", cell.id());
        let ratio = mesh.signed_volume() / source_volume;
        let in_range = edges_in_range(mesh, l_min);
        eprintln!(
            "cell {}: {} voxels, {} nodes (source {}), {seconds:.3} s, volume ratio {ratio:.4}, edges in range \
             {in_range:.3}, holes {} (largest {}), removed faces {}, unused samples {}, faces/radius {:?}, without joins {}",
            cell.id(),
            voxels,
            mesh.node_count(),
            cell.mesh().node_count(),
            meshed.holes_filled,
            meshed.largest_hole,
            meshed.removed_faces,
            meshed.unused_samples,
            meshed.faces_per_radius,
            meshed.without_joins,
        );
        assert!((ratio - 1.0).abs() < 0.03, "cell {}: mesh / source volume = {ratio}", cell.id());
        assert!(in_range >= 0.95, "cell {}: {in_range} of the edges in range", cell.id());
    }
}

#[test]
#[ignore = "timing figure for the report; run with --release -- --ignored --nocapture"]
fn timing_of_a_40_voxel_sphere() {
    let v = [0.2 * UM; 3];
    let c = Vec3::repeat(43.0 * v[0]);
    let mask = mask_of([87, 87, 87], v, |p| (p - c).norm() <= 40.0 * v[0]);
    let volume = voxel_count(&mask) as Real * v[0].powi(3);
    for target in [DEFAULT_TARGET_NODES, 2000] {
        let l_min = default_l_min(volume, target).unwrap();
        let start = std::time::Instant::now();
        let cell = mesh_mask(mask.view(), v, Vec3::zeros(), &MeshingSettings::new(l_min, v)).unwrap();
        let seconds = start.elapsed().as_secs_f64();
        assert_eq!(cell.mesh.validate(), Ok(()));
        let ratio = cell.mesh.signed_volume() / volume;
        eprintln!(
            "40-voxel sphere, target {target}: {} nodes, {seconds:.3} s, volume ratio {ratio:.4}, edges in range {:.3}",
            cell.mesh.node_count(),
            edges_in_range(&cell.mesh, l_min)
        );
        assert!((ratio - 1.0).abs() < 0.03);
    }
}

#[test]
fn random_blobs_are_meshed_into_valid_cells() {
    // Irregular shapes: unions of 2–5 random balls (radii 4–9 voxels), some touching the border.
    // Every one must give a valid mesh close to its voxel volume; the no-join fallback may be used.
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2026);
    let v = [0.2 * UM; 3];
    let mut fallbacks = 0;
    for case in 0..12 {
        let balls: Vec<(Vec3, Real)> = (0..rng.random_range(2..=5))
            .map(|_| {
                let c =
                    Vec3::new(rng.random_range(8.0..22.0), rng.random_range(8.0..22.0), rng.random_range(8.0..22.0));
                (c * v[0], rng.random_range(4.0..9.0) * v[0])
            })
            .collect();
        let mask = mask_of([30, 30, 30], v, |p| balls.iter().any(|(c, r)| (p - c).norm() <= *r));
        let volume = voxel_count(&mask) as Real * v[0].powi(3);
        let l_min = default_l_min(volume, 300).unwrap();
        let mut settings = MeshingSettings::new(l_min, v);
        settings.seed = case;
        let cell = mesh_mask(mask.view(), v, Vec3::zeros(), &settings).unwrap_or_else(|e| panic!("blob {case}: {e}"));
        assert_eq!(cell.mesh.validate(), Ok(()), "blob {case}");
        // Compared with the kept voxels (a ball may be a separate, dropped piece). Looser than the
        // 3 % of the smooth shapes: balls of 4–5 voxels radius lose more to chords (the deficit
        // grows like (l_min/R)²), and the creases where balls meet are concave, which a ball of
        // radius ≥ 1.2·l_min rolling outside cannot enter: it bridges them (measured 2–4.2 %).
        let ratio = cell.mesh.signed_volume() / cell.voxel_volume;
        assert!((ratio - 1.0).abs() < 0.08, "blob {case}: volume ratio {ratio}");
        assert!(edges_in_range(&cell.mesh, l_min) >= 0.95, "blob {case}");
        fallbacks += usize::from(cell.without_joins);
        eprintln!(
            "blob {case}: {} nodes, ratio {ratio:.4}, holes {}, without joins {}",
            cell.mesh.node_count(),
            cell.holes_filled,
            cell.without_joins
        );
    }
    eprintln!("{fallbacks} of 12 blobs used the no-join fallback");
}
