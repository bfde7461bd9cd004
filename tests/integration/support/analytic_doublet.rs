//! An analytic doublet's cells: spherical caps closed by a flat disc, meshed ring by ring. Shared by
//! `tests/integration/morphology.rs` and `tests/integration/direct_tensions.rs`.

use std::f64::consts::PI;
use tissuefit::geometry::Vec3;
use tissuefit::mesh::CellMesh;

/// A closed surface of revolution around z through `rings` (each a loop of points, first and last
/// closed by a fan to `start` and `end`), oriented outward.
pub fn ring_surface(start: Vec3, rings: &[Vec<Vec3>], end: Vec3) -> CellMesh {
    let m = rings[0].len() as u32;
    let mut positions = vec![start];
    for ring in rings {
        assert_eq!(ring.len() as u32, m);
        positions.extend(ring);
    }
    positions.push(end);
    let ring_node = |r: u32, j: u32| 1 + r * m + j % m;
    let mut triangles = Vec::new();
    for j in 0..m {
        triangles.push([0, ring_node(0, j + 1), ring_node(0, j)]);
    }
    for r in 0..rings.len() as u32 - 1 {
        for j in 0..m {
            let (a, b, c, d) = (ring_node(r, j), ring_node(r, j + 1), ring_node(r + 1, j + 1), ring_node(r + 1, j));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    let last = positions.len() as u32 - 1;
    let r = rings.len() as u32 - 1;
    for j in 0..m {
        triangles.push([last, ring_node(r, j), ring_node(r, j + 1)]);
    }
    let mut mesh = CellMesh::from_triangles(positions, triangles).unwrap();
    mesh.orient_outward();
    assert!(mesh.check().is_empty(), "{:?}", mesh.check());
    mesh
}

/// The part z ≤ 0 of the sphere of radius `radius` whose intersection with z = 0 is the disc of radius
/// `disc` (centre at z = −√(R² − a²)), closed by that disc. `segments` around, `cap_rings` from the pole
/// to the rim, `disc_rings` from the rim to the centre. Mirrored to z ≥ 0 when `upper`.
pub fn cap_cell(radius: f64, disc: f64, segments: u32, cap_rings: u32, disc_rings: u32, upper: bool) -> CellMesh {
    let hc = (radius * radius - disc * disc).sqrt();
    let centre = Vec3::new(0.0, 0.0, -hc);
    let rim_polar = PI - (disc / radius).asin(); // polar angle from −z to the rim
    let around = |j: u32| 2.0 * PI * j as f64 / segments as f64;
    let mut rings: Vec<Vec<Vec3>> = Vec::new();
    for k in 1..cap_rings {
        let alpha = rim_polar * k as f64 / cap_rings as f64;
        rings.push(
            (0..segments)
                .map(|j| {
                    centre
                        + radius * Vec3::new(alpha.sin() * around(j).cos(), alpha.sin() * around(j).sin(), -alpha.cos())
                })
                .collect(),
        );
    }
    for k in (1..=disc_rings).rev() {
        let r = disc * k as f64 / disc_rings as f64;
        rings.push((0..segments).map(|j| Vec3::new(r * around(j).cos(), r * around(j).sin(), 0.0)).collect());
    }
    let mut mesh = ring_surface(centre - Vec3::new(0.0, 0.0, radius), &rings, Vec3::zeros());
    if upper {
        mesh.scale(Vec3::new(1.0, 1.0, -1.0));
    }
    mesh
}
