//! CellMesh: measures converge to analytic values, and validate() catches every kind of defect.

use tissuefit::geometry::Vec3;
use tissuefit::mesh::shapes::{cuboid, ellipsoid, icosphere};
use tissuefit::mesh::{CellMesh, FaceId, MeshDefect, sphericity};

use std::f64::consts::PI;

/// Observed convergence order from errors at successive refinements (h halves each time).
fn orders(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

#[test]
fn icosphere_volume_and_area_converge_with_order_two() {
    let r = 5e-6;
    let (mut ev, mut ea) = (Vec::new(), Vec::new());
    for n in 1..=5 {
        let m = icosphere(r, n, Vec3::new(1e-5, -2e-5, 3e-5));
        m.validate().unwrap();
        ev.push((m.signed_volume() - 4.0 / 3.0 * PI * r.powi(3)).abs() / (4.0 / 3.0 * PI * r.powi(3)));
        ea.push((m.area() - 4.0 * PI * r * r).abs() / (4.0 * PI * r * r));
    }
    // The inscribed polyhedron's error is O(h²); the observed order tends to 2 from below as the
    // icosahedron's non-uniform refinement settles. Between levels 4 and 5 it is within 0.05 of 2.
    let (ov, oa) = (orders(&ev), orders(&ea));
    for o in ov.iter().chain(&oa).skip(1) {
        assert!((o - 2.0).abs() < 0.15, "orders volume {ov:?} area {oa:?}");
    }
    assert!((ov.last().unwrap() - 2.0).abs() < 0.05 && (oa.last().unwrap() - 2.0).abs() < 0.05, "{ov:?} {oa:?}");
    assert!(ev[4] < 2e-3 && ea[4] < 2e-3);
}

#[test]
fn box_from_quads_has_exact_measures() {
    let m = cuboid(Vec3::new(2.0, 3.0, 4.0), Vec3::new(10.0, 0.0, -5.0));
    m.validate().unwrap();
    assert!((m.signed_volume() - 24.0).abs() < 1e-12);
    assert!((m.area() - 52.0).abs() < 1e-12);
    assert!((m.volume_centroid().unwrap() - Vec3::new(10.0, 0.0, -5.0)).norm() < 1e-12);
}

#[test]
fn sphere_mean_curvature_is_inverse_radius() {
    let r = 3e-6;
    let m = icosphere(r, 4, Vec3::new(2e-6, 0.0, 0.0));
    let h = m.mean_curvature();
    // Cotangent curvature on a near-uniform sphere mesh is accurate to O(h²); at 2562 nodes every
    // node is within 1 % of 1/R.
    for &hi in &h {
        assert!((hi * r - 1.0).abs() < 0.01, "H·R = {}", hi * r);
    }
    // Turning the surface inside out turns the sign.
    let mut inv = m.clone();
    inv.flip_all();
    assert!(inv.mean_curvature().iter().all(|&hi| (hi * r + 1.0).abs() < 0.01));
}

#[test]
fn ellipsoid_principal_axes_match_semi_axes() {
    let semi = Vec3::new(3.0, 2.0, 1.0);
    let m = ellipsoid(semi, 5, Vec3::new(0.5, 0.5, 0.5));
    let pa = m.principal_axes().unwrap();
    // The inscribed mesh is slightly smaller than the ellipsoid (volume error ~3e-4 at 5 levels).
    for (got, want) in pa.semi_axes.iter().zip([3.0, 2.0, 1.0]) {
        assert!((got - want).abs() / want < 2e-3, "semi-axes {:?}", pa.semi_axes);
    }
    assert!(pa.axes[0].x.abs() > 0.999 && pa.axes[1].y.abs() > 0.999 && pa.axes[2].z.abs() > 0.999);
    assert!((pa.centroid - Vec3::new(0.5, 0.5, 0.5)).norm() < 1e-9);
}

#[test]
fn sphericity_is_one_for_sphere_and_lower_for_box() {
    let s = icosphere(1.0, 5, Vec3::zeros());
    assert!((sphericity(s.signed_volume(), s.area()) - 1.0).abs() < 1e-3);
    let c = cuboid(Vec3::new(1.0, 1.0, 1.0), Vec3::zeros());
    let psi = sphericity(c.signed_volume(), c.area());
    assert!((psi - (PI / 6.0).cbrt()).abs() < 1e-12, "cube sphericity {psi}");
}

fn sphere() -> CellMesh {
    icosphere(1e-5, 2, Vec3::zeros())
}

#[test]
fn validate_catches_a_hole() {
    let m = sphere();
    let mut tris = m.triangles().to_vec();
    tris.remove(7);
    let holed = CellMesh::from_triangles(m.positions().to_vec(), tris).unwrap();
    assert!(matches!(holed.validate(), Err(MeshDefect::BoundaryEdge { .. })), "{:?}", holed.validate());
}

#[test]
fn validate_catches_a_flipped_face() {
    let mut m = sphere();
    m.flip_face(FaceId(11));
    match m.validate() {
        Err(MeshDefect::InconsistentOrientation { face_a, face_b, .. }) => {
            assert!(face_a == 11 || face_b == 11)
        }
        other => panic!("expected inconsistent orientation, got {other:?}"),
    }
}

#[test]
fn validate_catches_inside_out_surface() {
    let mut m = sphere();
    m.flip_all();
    assert!(matches!(m.validate(), Err(MeshDefect::NonPositiveVolume { .. })));
}

#[test]
fn validate_catches_a_non_manifold_edge() {
    // A fin: an extra triangle on an existing edge plus a new node.
    let m = sphere();
    let [a, b, _] = m.triangles()[0];
    let mut pos = m.positions().to_vec();
    pos.push(Vec3::new(0.0, 0.0, 3e-5));
    let mut tris = m.triangles().to_vec();
    tris.push([a, b, (pos.len() - 1) as u32]);
    let fin = CellMesh::from_triangles(pos, tris).unwrap();
    let defects = fin.check();
    assert!(defects.iter().any(|d| matches!(d, MeshDefect::NonManifoldEdge { faces: 3, .. })), "{defects:?}");
}

#[test]
fn validate_catches_a_duplicate_face() {
    let m = sphere();
    let mut tris = m.triangles().to_vec();
    let t = tris[3];
    tris.push([t[1], t[2], t[0]]);
    let dup = CellMesh::from_triangles(m.positions().to_vec(), tris).unwrap();
    assert!(matches!(dup.validate(), Err(MeshDefect::DuplicateFace { a: 3, .. })), "{:?}", dup.validate());
}

#[test]
fn validate_catches_a_nan_coordinate() {
    let mut m = sphere();
    m.positions_mut()[5].y = f64::NAN;
    assert_eq!(m.validate(), Err(MeshDefect::NonFiniteCoordinate { node: 5 }));
}

#[test]
fn validate_catches_degenerate_and_pinched_and_disconnected_surfaces() {
    // Degenerate: collapse a node onto its neighbour's position along an edge midpoint line.
    let m = sphere();
    let mut tris = m.triangles().to_vec();
    tris[0] = [tris[0][0], tris[0][0], tris[0][2]];
    let deg = CellMesh::from_triangles(m.positions().to_vec(), tris).unwrap();
    assert!(deg.check().iter().any(|d| matches!(d, MeshDefect::DegenerateFace { face: 0 })));

    // Two spheres: two components.
    let a = icosphere(1.0, 1, Vec3::zeros());
    let b = icosphere(1.0, 1, Vec3::new(5.0, 0.0, 0.0));
    let n = a.node_count() as u32;
    let pos: Vec<Vec3> = a.positions().iter().chain(b.positions()).copied().collect();
    let tris: Vec<[u32; 3]> =
        a.triangles().iter().copied().chain(b.triangles().iter().map(|t| t.map(|i| i + n))).collect();
    let two = CellMesh::from_triangles(pos.clone(), tris.clone()).unwrap();
    assert_eq!(two.validate(), Err(MeshDefect::Disconnected { components: 2 }));

    // Two spheres glued at one node: a pinched (non-manifold) vertex. Merge b's node 0 into a's node 3,
    // after moving b so that the two nodes coincide.
    let shift = a.positions()[3] - b.positions()[0];
    let pos2: Vec<Vec3> = a.positions().iter().copied().chain(b.positions().iter().map(|p| p + shift)).collect();
    let tris2: Vec<[u32; 3]> = tris.iter().map(|t| t.map(|i| if i == n { 3 } else { i })).collect();
    let mut pinched = CellMesh::from_triangles(pos2, tris2).unwrap();
    pinched.remove_unused_nodes();
    assert!(
        pinched.check().iter().any(|d| matches!(d, MeshDefect::NonManifoldVertex { fans: 2, .. })),
        "{:?}",
        pinched.check()
    );
}

#[test]
fn validate_catches_a_torus() {
    // A square torus built from quads: 4×4 grid on the torus, genus 1 (χ = 0).
    let (n, m) = (6usize, 5usize);
    let mut pos = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let (u, v) = (2.0 * PI * i as f64 / n as f64, 2.0 * PI * j as f64 / m as f64);
            pos.push(Vec3::new((3.0 + v.cos()) * u.cos(), (3.0 + v.cos()) * u.sin(), v.sin()));
        }
    }
    let id = |i: usize, j: usize| ((i % n) * m + (j % m)) as u32;
    let quads: Vec<[u32; 4]> =
        (0..n).flat_map(|i| (0..m).map(move |j| [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)])).collect();
    let (torus, _) = CellMesh::from_polygons(pos, &quads).unwrap();
    assert_eq!(torus.validate(), Err(MeshDefect::EulerCharacteristic { chi: 0 }));
}

#[test]
fn orient_outward_repairs_flipped_and_inside_out_faces() {
    let reference = icosphere(2e-6, 3, Vec3::new(1e-6, 0.0, 0.0));
    let mut m = reference.clone();
    for f in [0u32, 5, 6, 100, 101, 102, 999] {
        m.flip_face(FaceId(f));
    }
    assert!(m.validate().is_err());
    assert_eq!(m.orient_outward(), 7);
    assert_eq!(m, reference);
    m.flip_all();
    assert_eq!(m.orient_outward(), m.face_count());
    assert_eq!(m.validate(), Ok(()));
    // A hole does not stop the repair of the rest.
    let mut tris = reference.triangles().to_vec();
    tris.remove(50);
    tris[7].swap(1, 2);
    let mut holed = CellMesh::from_triangles(reference.positions().to_vec(), tris).unwrap();
    assert_eq!(holed.orient_outward(), 1);
    // Only the hole remains: three boundary edges, and χ = 1 of a disc.
    let defects = holed.check();
    assert!(
        defects
            .iter()
            .all(|d| matches!(d, MeshDefect::BoundaryEdge { .. } | MeshDefect::EulerCharacteristic { chi: 1 })),
        "{defects:?}"
    );
}

#[test]
fn subdivided_cube_is_a_valid_closed_cube() {
    let m = tissuefit::mesh::shapes::subdivided_cube(2.0, 5, Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(m.validate(), Ok(()));
    assert_eq!((m.node_count(), m.face_count()), (6 * 25 + 2, 12 * 25));
    assert!((m.signed_volume() - 8.0).abs() < 1e-12 && (m.area() - 24.0).abs() < 1e-12);
}
