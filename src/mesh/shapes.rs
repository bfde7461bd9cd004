//! Analytic shapes as cell meshes: icospheres, ellipsoids and boxes, for tests, benchmarks and demos.

use super::CellMesh;
use crate::geometry::{Real, Vec3};
use std::collections::HashMap;

/// Sphere of radius `radius` centred at `centre`: an icosahedron subdivided `subdivisions` times
/// (20·4ⁿ faces, 10·4ⁿ + 2 nodes), nodes projected onto the sphere, faces pointing outward.
pub fn icosphere(radius: Real, subdivisions: u32, centre: Vec3) -> CellMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut pos: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|c| Vec3::new(c[0], c[1], c[2]).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::new();
        let mut mid = |a: u32, b: u32, pos: &mut Vec<Vec3>| {
            *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                pos.push(((pos[a as usize] + pos[b as usize]) / 2.0).normalize());
                (pos.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(tris.len() * 4);
        for &[a, b, c] in &tris {
            let (ab, bc, ca) = (mid(a, b, &mut pos), mid(b, c, &mut pos), mid(c, a, &mut pos));
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    let positions = pos.into_iter().map(|p| centre + radius * p).collect();
    CellMesh::from_triangles(positions, tris).expect("icosphere indices are in range")
}

/// Ellipsoid with semi-axes `semi_axes` along x, y, z: a unit icosphere scaled per axis.
pub fn ellipsoid(semi_axes: Vec3, subdivisions: u32, centre: Vec3) -> CellMesh {
    let mut mesh = icosphere(1.0, subdivisions, Vec3::zeros());
    mesh.scale(semi_axes);
    mesh.positions_mut().iter_mut().for_each(|p| *p += centre);
    mesh
}

/// Axis-aligned box with edge lengths `size` centred at `centre`: 8 nodes, 12 outward triangles.
pub fn cuboid(size: Vec3, centre: Vec3) -> CellMesh {
    let h = size / 2.0;
    let positions = (0..8)
        .map(|i| {
            let s = |bit: u32| if i >> bit & 1 == 1 { 1.0 } else { -1.0 };
            centre + Vec3::new(s(0) * h.x, s(1) * h.y, s(2) * h.z)
        })
        .collect();
    // Node i has x from bit 0, y from bit 1, z from bit 2. Each quad is counter-clockwise from outside.
    let quads: [[u32; 4]; 6] = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let (mesh, _) = CellMesh::from_polygons(positions, &quads).expect("box indices are in range");
    mesh
}
