//! Property tests (proptest) of the local remeshing operations on random meshes: any sequence of
//! splits, collapses and flips keeps the surface valid, and each accepted operation changes the
//! enclosed volume only by its own geometric change (zero for a split, at most l·A_ring/3 for a
//! collapse of an edge of length l whose ring of faces has area A_ring, the tetrahedron a, b, c, d for
//! a flip). Refused operations leave the mesh untouched.

use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Uniform};
use tissuefit::geometry::{Real, Vec3};
use tissuefit::mesh::remesh::{RemeshError, RemeshSettings, collapse_edge, flip_edge, remesh_cell, split_edge};
use tissuefit::mesh::shapes::{ellipsoid, icosphere, subdivided_cube};
use tissuefit::mesh::{Adjacency, CellMesh, NodeId};

/// A base shape moved node by node by up to `amplitude` mean edge lengths (a valid result is kept;
/// perturbations that fold the surface are redrawn).
fn random_mesh(shape: u8, level: u32, amplitude: Real, seed: u64) -> CellMesh {
    let base = match shape {
        0 => icosphere(1.0, level, Vec3::zeros()),
        1 => subdivided_cube(1.0, level + 1, Vec3::zeros()),
        _ => ellipsoid(Vec3::new(2.0, 1.0, 0.7), level, Vec3::zeros()),
    };
    let step = amplitude * base.edge_length_stats().unwrap().mean;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let u = Uniform::new(-1.0, 1.0).unwrap();
    for _ in 0..50 {
        let mut mesh = base.clone();
        for p in mesh.positions_mut() {
            *p += step * Vec3::new(u.sample(&mut rng), u.sample(&mut rng), u.sample(&mut rng));
        }
        if mesh.validate().is_ok() {
            return mesh;
        }
    }
    base
}

fn euler(mesh: &CellMesh) -> i64 {
    mesh.node_count() as i64 - Adjacency::new(mesh).edges().len() as i64 + mesh.face_count() as i64
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn random_operation_sequences_keep_the_surface_valid_with_bounded_volume_change(
        shape in 0u8..3,
        level in 1u32..3,
        amplitude in 0.0..0.35f64,
        seed in any::<u64>(),
        ops in prop::collection::vec((0u8..3, 0.0..1.0f64), 1..40),
    ) {
        let mut mesh = random_mesh(shape, level, amplitude, seed);
        prop_assert_eq!(mesh.validate(), Ok(()));
        for (op, pick) in ops {
            let edges = Adjacency::new(&mesh).edges().to_vec();
            let [a, b] = edges[((pick * edges.len() as f64) as usize).min(edges.len() - 1)];
            let (na, nb) = (NodeId(a), NodeId(b));
            let v0 = mesh.signed_volume();
            let l = (mesh.position(na) - mesh.position(nb)).norm();
            let ring: Real = mesh
                .triangles()
                .iter()
                .zip(mesh.face_areas())
                .filter(|(t, _)| t.contains(&a) || t.contains(&b))
                .map(|(_, s)| s)
                .sum();
            let apexes: Vec<u32> = mesh
                .triangles()
                .iter()
                .filter(|t| t.contains(&a) && t.contains(&b))
                .flat_map(|t| t.iter().copied().filter(|&n| n != a && n != b))
                .collect();
            let [pa, pb, pc, pd] = [a, b, apexes[0], apexes[1]].map(|n| mesh.position(NodeId(n)));
            let tetrahedron = (pb - pa).dot(&(pc - pa).cross(&(pd - pa))).abs() / 6.0;
            let before = mesh.clone();
            let (result, expected, tolerance) = match op {
                0 => (split_edge(&mut mesh, na, nb, None, None).map(|_| ()), 0.0, 1e-12 * v0),
                1 => (collapse_edge(&mut mesh, na, nb, None, None).map(|_| ()), 0.0, l * ring / 3.0 * (1.0 + 1e-9)),
                _ => (flip_edge(&mut mesh, na, nb, None), tetrahedron, 1e-12 * v0),
            };
            match result {
                Ok(()) => {
                    prop_assert_eq!(mesh.validate(), Ok(()));
                    prop_assert_eq!(euler(&mesh), 2);
                    let dv = (mesh.signed_volume() - v0).abs();
                    prop_assert!((dv - expected).abs() <= tolerance, "op {}: |ΔV| = {:e}, expected {:e}", op, dv, expected);
                }
                Err(RemeshError::Refused(_)) => prop_assert_eq!(&mesh, &before),
                Err(e) => prop_assert!(false, "unexpected error {}", e),
            }
        }
    }

    /// A strongly stretched random cell (up to 6:1) comes back to [l_min, 3·l_min] in one pass.
    #[test]
    fn a_stretched_cell_is_remeshed_into_the_edge_bounds(stretch in 2.0..6.0f64, seed in any::<u64>()) {
        let mut mesh = random_mesh(0, 2, 0.15, seed);
        let l_min = 0.5 * mesh.edge_length_stats().unwrap().mean;
        mesh.scale(Vec3::new(stretch, 1.0, 1.0));
        let settings = RemeshSettings::new(l_min);
        let report = remesh_cell(&mut mesh, None, None, &settings).unwrap();
        prop_assert_eq!(mesh.validate(), Ok(()));
        prop_assert_eq!((report.long_edges, report.short_edges), (0, 0), "{:?}", report);
        let stats = mesh.edge_length_stats().unwrap();
        prop_assert!(stats.min >= l_min && stats.max <= 3.0 * l_min, "{:?}", stats);
    }
}
