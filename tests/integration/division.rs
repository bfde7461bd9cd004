//! Cell division by a plane (`divide_mesh`): valid daughters, exact volume conservation, a cap whose
//! edges respect the remeshing bounds, inherited face types, determinism, and clear errors.

use proptest::prelude::*;
use std::collections::HashMap;
use tissuefit::geometry::Vec3;
use tissuefit::mesh::shapes::{cuboid, ellipsoid, icosphere};
use tissuefit::mesh::{
    CellMesh, Daughter, DivisionError, DivisionPlane, FaceType, SNAP_FRACTION, divide_mesh, division_plane,
    division_plane_normal,
};

const R: f64 = 5e-6;

/// The 642-node icosphere of radius R: edges 0.13–0.16 R, inside [l_min, 3·l_min] for l_min = 0.08 R.
fn sphere() -> (CellMesh, f64) {
    (icosphere(R, 3, Vec3::new(1e-5, -2e-5, 3e-5)), 0.08 * R)
}

/// Direction used to give the mother's faces types: apical where the face normal has a positive
/// component along it, basal otherwise. Cap faces are the only lateral ones.
fn type_direction() -> Vec3 {
    Vec3::new(0.31, 0.52, 0.79).normalize()
}

fn type_of_normal(n: &Vec3) -> FaceType {
    if n.dot(&type_direction()) > 0.0 { FaceType::Apical } else { FaceType::Basal }
}

fn mother_types(mesh: &CellMesh) -> Vec<FaceType> {
    let normals = mesh.face_normals();
    // No face is near the rule's threshold, so round-off in a cut piece's normal cannot change its type.
    assert!(normals.iter().all(|n| n.dot(&type_direction()).abs() > 1e-6));
    normals.iter().map(type_of_normal).collect()
}

/// Whether a daughter face lies in the cutting plane (within the snapping tolerance): a cap face.
fn in_plane(mesh: &CellMesh, f: usize, point: &Vec3, n: &Vec3, l_min: f64) -> bool {
    let t = mesh.triangles()[f];
    t.iter().all(|&i| (mesh.positions()[i as usize] - point).dot(n).abs() <= SNAP_FRACTION * l_min * 1.0001)
}

/// Divides and checks everything that must hold for every successful division; returns the daughters.
fn divide_and_check(mesh: &CellMesh, point: Vec3, normal: Vec3, l_min: f64, seed: u64) -> (Daughter, Daughter) {
    let types = mother_types(mesh);
    let (a, b) = divide_mesh(mesh, &types, point, normal, l_min, seed)
        .unwrap_or_else(|e| panic!("division along {normal:?} through {point:?} failed: {e}"));
    let n = normal.normalize();
    a.mesh.validate().unwrap();
    b.mesh.validate().unwrap();
    // Daughters' faces are the mother's (cut in their own planes) plus one cap counted with both
    // orientations, so the volumes add up exactly but for round-off (~1e-15 relative per face).
    let (va, vb, v) = (a.mesh.signed_volume(), b.mesh.signed_volume(), mesh.signed_volume());
    assert!(((va + vb) - v).abs() <= 1e-9 * v, "V_a + V_b = {:e}, mother {v:e}", va + vb);
    // The first daughter lies on the side the normal points to.
    let (ca, cb) = (a.mesh.volume_centroid().unwrap(), b.mesh.volume_centroid().unwrap());
    assert!((ca - point).dot(&n) > 0.0 && (cb - point).dot(&n) < 0.0);

    let mut inherited_area = 0.0;
    let mut cap_area = [0.0; 2];
    for (k, d) in [&a, &b].into_iter().enumerate() {
        assert_eq!(d.face_types.len(), d.mesh.face_count());
        let normals = d.mesh.face_normals();
        let areas = d.mesh.face_areas();
        for f in 0..d.mesh.face_count() {
            if in_plane(&d.mesh, f, &point, &n, l_min) {
                assert_eq!(d.face_types[f], FaceType::Lateral, "cap face {f} of daughter {k}");
                // Outward: along −n for the positive daughter, +n for the negative one.
                let expected = if k == 0 { -n } else { n };
                assert!(normals[f].dot(&expected) > 0.999, "cap face {f} of daughter {k} points {:?}", normals[f]);
                cap_area[k] += areas[f];
            } else {
                assert_eq!(d.face_types[f], type_of_normal(&normals[f]), "inherited face {f} of daughter {k}");
                inherited_area += areas[f];
            }
        }
    }
    assert!((inherited_area - mesh.area()).abs() <= 1e-9 * mesh.area(), "inherited {inherited_area:e}");
    assert!(cap_area[0] > 0.0 && (cap_area[0] - cap_area[1]).abs() <= 1e-9 * cap_area[0]);
    (a, b)
}

/// Lengths of the cap's interior edges (both faces in the plane), in units of l_min.
fn cap_interior_edges(d: &Daughter, point: &Vec3, n: &Vec3, l_min: f64) -> Vec<f64> {
    let mesh = &d.mesh;
    let mut cap_faces_per_edge: HashMap<(u32, u32), usize> = HashMap::new();
    for f in (0..mesh.face_count()).filter(|&f| in_plane(mesh, f, point, n, l_min)) {
        let t = mesh.triangles()[f];
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *cap_faces_per_edge.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let p = mesh.positions();
    cap_faces_per_edge
        .iter()
        .filter(|&(_, &count)| count == 2)
        .map(|(&(a, b), _)| (p[a as usize] - p[b as usize]).norm() / l_min)
        .collect()
}

fn orientations() -> Vec<Vec3> {
    vec![
        Vec3::z(), // through icosahedron vertices and edges (the plane z = 0 holds whole edges)
        Vec3::x(),
        Vec3::y(),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(1.0, 2.0, 3.0),
        Vec3::new(-0.3, 0.1, 0.95),
    ]
}

#[test]
fn sphere_divides_into_valid_volume_conserving_halves_along_many_planes() {
    let (mesh, l_min) = sphere();
    let c = mesh.volume_centroid().unwrap();
    let mut nodes_on_plane = 0;
    for n in orientations() {
        nodes_on_plane += mesh.positions().iter().filter(|p| (*p - c).dot(&n.normalize()).abs() < 1e-18).count();
        let (a, b) = divide_and_check(&mesh, c, n, l_min, 7);
        // Through the centre of a sphere: halves within 2 % (the icosphere is not exactly symmetric
        // about an arbitrary plane).
        let (va, vb) = (a.mesh.signed_volume(), b.mesh.signed_volume());
        assert!((va - vb).abs() < 0.02 * (va + vb), "{va:e} {vb:e}");
        // Off-centre planes too.
        divide_and_check(&mesh, c + 0.4 * R * n.normalize(), n, l_min, 7);
        divide_and_check(&mesh, c - 0.7 * R * n.normalize(), n, l_min, 7);
    }
    // The z = 0 plane passes exactly through existing nodes, so that case was exercised.
    assert!(nodes_on_plane >= 4, "{nodes_on_plane}");
}

#[test]
fn ellipsoid_cut_perpendicular_to_its_longest_axis_gives_equal_halves() {
    let mesh = ellipsoid(Vec3::new(2.0 * R, R, 0.8 * R), 3, Vec3::new(-3e-6, 4e-6, 1e-6));
    let l_min = 0.08 * R;
    let (point, normal) = division_plane(&mesh, DivisionPlane::LongestAxis).unwrap();
    assert!(normal.x.abs() > 0.999, "longest axis {normal:?}");
    let (a, b) = divide_and_check(&mesh, point, normal, l_min, 11);
    let (va, vb) = (a.mesh.signed_volume(), b.mesh.signed_volume());
    assert!((va - vb).abs() < 0.01 * (va + vb) / 2.0, "{va:e} vs {vb:e}");
    for n in orientations() {
        divide_and_check(&mesh, point, n, l_min, 11);
    }
}

#[test]
fn cuboid_divides_along_faces_edges_and_corners() {
    let mesh = cuboid(Vec3::new(2e-6, 3e-6, 4e-6), Vec3::new(1e-6, 0.0, -5e-6));
    let c = mesh.volume_centroid().unwrap();
    let l_min = 0.3e-6;
    // Axis planes cross faces and their diagonals; (1,1,1) cuts a hexagon.
    for n in
        [Vec3::x(), Vec3::y(), Vec3::z(), Vec3::new(1.0, 1.5, 0.0), Vec3::new(1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 1.0)]
    {
        let (a, b) = divide_and_check(&mesh, c, n, l_min, 3);
        if n.iter().filter(|x| **x != 0.0).count() == 1 {
            // A box cut through its centre parallel to a face: two equal boxes, exactly.
            let (va, vb) = (a.mesh.signed_volume(), b.mesh.signed_volume());
            assert!((va - vb).abs() < 1e-12 * va, "{va:e} {vb:e}");
        }
    }
    // 3x = 2y passes along two opposite vertical edges of the 2×3 box: whole mother edges and corner
    // nodes lie in the plane.
    divide_and_check(&mesh, c, Vec3::new(3.0, -2.0, 0.0), l_min, 3);
}

#[test]
fn cap_interior_edges_lie_within_the_remeshing_bounds() {
    let (sphere, l_sphere) = sphere();
    let ell = ellipsoid(Vec3::new(2.0 * R, R, 0.8 * R), 3, Vec3::zeros());
    let mut lengths = Vec::new();
    for (mesh, l_min) in [(&sphere, l_sphere), (&ell, 0.08 * R)] {
        let c = mesh.volume_centroid().unwrap();
        for (k, n) in orientations().into_iter().enumerate() {
            let (a, b) = divide_and_check(mesh, c, n, l_min, k as u64);
            let ea = cap_interior_edges(&a, &c, &n.normalize(), l_min);
            let eb = cap_interior_edges(&b, &c, &n.normalize(), l_min);
            let (mut sa, mut sb) = (ea.clone(), eb.clone());
            sa.sort_by(f64::total_cmp);
            sb.sort_by(f64::total_cmp);
            // The same cap in both daughters.
            assert_eq!(sa, sb);
            assert!(ea.len() > 50, "{} interior cap edges", ea.len());
            lengths.extend(ea);
        }
    }
    let inside = lengths.iter().filter(|&&l| (1.0..=3.0).contains(&l)).count();
    let fraction = inside as f64 / lengths.len() as f64;
    let min = lengths.iter().copied().fold(f64::INFINITY, f64::min);
    let max = lengths.iter().copied().fold(0.0, f64::max);
    eprintln!("cap interior edges: {:.1} % in [l_min, 3 l_min], range {min:.3}..{max:.3} l_min", 100.0 * fraction);
    assert!(fraction >= 0.9, "only {:.1} % of {} cap edges in bounds", 100.0 * fraction, lengths.len());
}

#[test]
fn same_seed_gives_identical_daughters_and_another_seed_another_cap() {
    let (mesh, l_min) = sphere();
    let types = mother_types(&mesh);
    let c = mesh.volume_centroid().unwrap();
    let n = Vec3::new(1.0, 2.0, 3.0);
    let first = divide_mesh(&mesh, &types, c, n, l_min, 42).unwrap();
    let again = divide_mesh(&mesh, &types, c, n, l_min, 42).unwrap();
    assert_eq!(first, again);
    let other = divide_mesh(&mesh, &types, c, n, l_min, 43).unwrap();
    assert_ne!(first.0.mesh, other.0.mesh);
}

#[test]
fn division_plane_follows_hertwig_or_a_seeded_random_direction() {
    let mesh = ellipsoid(Vec3::new(R, 0.7 * R, 1.6 * R), 3, Vec3::zeros());
    let n = division_plane_normal(&mesh, DivisionPlane::LongestAxis).unwrap();
    assert!(n.z.abs() > 0.999 && (n.norm() - 1.0).abs() < 1e-12, "{n:?}");
    let r1 = division_plane_normal(&mesh, DivisionPlane::Random(5)).unwrap();
    let r2 = division_plane_normal(&mesh, DivisionPlane::Random(5)).unwrap();
    let r3 = division_plane_normal(&mesh, DivisionPlane::Random(6)).unwrap();
    assert_eq!(r1, r2);
    assert_ne!(r1, r3);
    assert!((r1.norm() - 1.0).abs() < 1e-12);
    // Uniform on the sphere: the mean of many draws is near zero, and each axis is covered both ways.
    let draws: Vec<Vec3> = (0..2000).map(|s| division_plane_normal(&mesh, DivisionPlane::Random(s)).unwrap()).collect();
    let mean = draws.iter().sum::<Vec3>() / draws.len() as f64;
    // Standard error of each component is sqrt(1/3/2000) ≈ 0.013; 0.06 is over 4 of them.
    assert!(mean.norm() < 0.06, "{mean:?}");
}

#[test]
fn a_plane_missing_the_cell_is_a_clear_error() {
    let (mesh, l_min) = sphere();
    let types = mother_types(&mesh);
    let c = mesh.volume_centroid().unwrap();
    let err = divide_mesh(&mesh, &types, c + Vec3::new(0.0, 0.0, 2.0 * R), Vec3::z(), l_min, 1).unwrap_err();
    assert_eq!(err, DivisionError::PlaneMissesCell { above: 0, below: mesh.face_count() });
    assert!(err.to_string().contains("misses"));
}

#[test]
fn a_plane_grazing_a_node_gives_a_valid_result_or_a_clear_error() {
    let (mesh, l_min) = sphere();
    let types = mother_types(&mesh);
    let c = mesh.volume_centroid().unwrap();
    let mut valid = 0;
    for node in [0usize, 17, 200, 641] {
        let p = mesh.positions()[node];
        let n = (p - c).normalize();
        // Tangent at the node: the node is on the plane, everything else below.
        let err = divide_mesh(&mesh, &types, p, n, l_min, 1).unwrap_err();
        assert!(matches!(err, DivisionError::PlaneMissesCell { above: 0, .. }), "{err}");
        // Just below the node (inside and outside the snapping tolerance), slicing off a tiny cap.
        for depth in [0.5 * SNAP_FRACTION * l_min, 2.0 * SNAP_FRACTION * l_min, 0.01 * l_min, 0.3 * l_min] {
            match divide_mesh(&mesh, &types, p - depth * n, n, l_min, 1) {
                Ok((a, b)) => {
                    a.mesh.validate().unwrap();
                    b.mesh.validate().unwrap();
                    let v = mesh.signed_volume();
                    assert!((a.mesh.signed_volume() + b.mesh.signed_volume() - v).abs() <= 1e-9 * v);
                    valid += 1;
                }
                Err(e) => assert!(!e.to_string().is_empty()),
            }
        }
    }
    // The deeper slices have a real loop of cut nodes and must succeed.
    assert!(valid >= 4, "{valid}");
}

#[test]
fn a_plane_along_a_face_of_a_box_is_a_clear_error() {
    let mesh = cuboid(Vec3::new(2.0, 3.0, 4.0), Vec3::zeros());
    let types = vec![FaceType::Basal; mesh.face_count()];
    let err = divide_mesh(&mesh, &types, Vec3::new(1.0, 0.0, 0.0), Vec3::x(), 0.3, 1).unwrap_err();
    assert!(matches!(err, DivisionError::FaceInPlane { .. }), "{err}");
}

#[test]
fn a_plane_cutting_a_banana_twice_reports_two_loops() {
    // An ellipsoid bent into a U: the plane y = 2 crosses both arms.
    let mut mesh = ellipsoid(Vec3::new(3.0, 0.5, 0.5), 3, Vec3::zeros());
    mesh.positions_mut().iter_mut().for_each(|p| p.y += 0.4 * p.x * p.x);
    mesh.validate().unwrap();
    let types = vec![FaceType::Apical; mesh.face_count()];
    let err = divide_mesh(&mesh, &types, Vec3::new(0.0, 2.0, 0.0), Vec3::y(), 0.05, 1).unwrap_err();
    assert_eq!(err, DivisionError::CutLoops { loops: 2 });
    // Across the arms instead, it divides.
    divide_mesh(&mesh, &types, Vec3::zeros(), Vec3::x(), 0.05, 1).unwrap();
}

#[test]
fn bad_arguments_are_errors() {
    let (mesh, l_min) = sphere();
    let types = mother_types(&mesh);
    let c = mesh.volume_centroid().unwrap();
    assert!(matches!(
        divide_mesh(&mesh, &types, c, Vec3::zeros(), l_min, 1),
        Err(DivisionError::InvalidArgument { .. })
    ));
    assert!(matches!(divide_mesh(&mesh, &types, c, Vec3::x(), 0.0, 1), Err(DivisionError::InvalidArgument { .. })));
    assert!(matches!(
        divide_mesh(&mesh, &types[1..], c, Vec3::x(), l_min, 1),
        Err(DivisionError::FaceTypeCount { .. })
    ));
    let mut broken = mesh.clone();
    broken.flip_face(tissuefit::mesh::FaceId(3));
    assert!(matches!(divide_mesh(&broken, &types, c, Vec3::x(), l_min, 1), Err(DivisionError::InvalidMother { .. })));
}

#[test]
fn remeshing_a_daughter_removes_short_cut_edges_and_keeps_it_valid() {
    let (mesh, l_min) = sphere();
    let c = mesh.volume_centroid().unwrap();
    // An off-centre plane that passes close to many nodes leaves short edges next to the cut.
    let (mut a, _) = divide_and_check(&mesh, c + 0.05 * R * Vec3::z(), Vec3::new(0.05, -0.02, 1.0), l_min, 2);
    let short = |d: &Daughter| d.mesh.edge_length_stats().unwrap().min < l_min;
    let before = a.mesh.signed_volume();
    if short(&a) {
        let report = a.remesh(l_min).unwrap();
        assert!(report.collapses > 0, "{report:?}");
    }
    a.mesh.validate().unwrap();
    assert_eq!(a.face_types.len(), a.mesh.face_count());
    // Collapses move nodes by at most l_min/2 on a surface of radius 12.5 l_min: a small change.
    assert!((a.mesh.signed_volume() - before).abs() < 0.02 * before);
}

#[test]
fn time_to_divide_a_642_node_icosphere() {
    let (mesh, l_min) = sphere();
    assert_eq!(mesh.node_count(), 642);
    let types = mother_types(&mesh);
    let c = mesh.volume_centroid().unwrap();
    let runs = 20;
    let start = std::time::Instant::now();
    for s in 0..runs {
        let n = division_plane_normal(&mesh, DivisionPlane::Random(s)).unwrap();
        divide_mesh(&mesh, &types, c, n, l_min, s).unwrap();
    }
    let per = start.elapsed().as_secs_f64() / runs as f64;
    eprintln!("divide_mesh on a 642-node icosphere: {:.3} ms per division", per * 1e3);
    assert!(per < 0.5, "{per} s per division");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn random_planes_through_the_centroid_give_valid_volume_conserving_daughters(
        x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0, seed in 0u64..1000,
    ) {
        let n = Vec3::new(x, y, z);
        prop_assume!(n.norm() > 1e-3);
        let mesh = icosphere(R, 2, Vec3::new(2e-6, 0.0, -1e-6));
        let types = vec![FaceType::Apical; mesh.face_count()];
        let c = mesh.volume_centroid().unwrap();
        let (a, b) = divide_mesh(&mesh, &types, c, n, 0.15 * R, seed).unwrap();
        prop_assert!(a.mesh.validate().is_ok() && b.mesh.validate().is_ok());
        let v = mesh.signed_volume();
        prop_assert!((a.mesh.signed_volume() + b.mesh.signed_volume() - v).abs() <= 1e-9 * v);
        prop_assert!(a.face_types.iter().chain(&b.face_types).any(|t| *t == FaceType::Lateral));
    }
}
