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

/// Axis-aligned cube of edge `size` centred at `centre`, each face an `n`×`n` grid of squares split
/// into two triangles along alternating diagonals: 6n² + 2 nodes, 12n² faces, outward. A cell far from a sphere, for relaxation tests.
pub fn subdivided_cube(size: Real, n: u32, centre: Vec3) -> CellMesh {
    assert!(n >= 1, "a cube face needs at least one square");
    let n = n as i64;
    let mut index: HashMap<[i64; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut node = |c: [i64; 3], positions: &mut Vec<Vec3>| {
        *index.entry(c).or_insert_with(|| {
            positions.push(
                centre + Vec3::new(c[0] as Real, c[1] as Real, c[2] as Real) * (size / n as Real)
                    - Vec3::repeat(size / 2.0),
            );
            (positions.len() - 1) as u32
        })
    };
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, n] {
            for a in 0..n {
                for b in 0..n {
                    let corner = |du: i64, dv: i64| {
                        let mut c = [0i64; 3];
                        c[axis] = side;
                        c[u] = a + du;
                        c[v] = b + dv;
                        c
                    };
                    // (u, v, axis) is right-handed: counter-clockwise in (u, v) faces +axis. The
                    // squares are split along alternating diagonals (a symmetric pattern), so no
                    // direction is preferred when the cube deforms.
                    let mut q =
                        [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)].map(|c| node(c, &mut positions));
                    if side == 0 {
                        q.reverse();
                    }
                    if (a + b) % 2 == 0 {
                        triangles.extend([[q[0], q[1], q[2]], [q[0], q[2], q[3]]]);
                    } else {
                        triangles.extend([[q[0], q[1], q[3]], [q[1], q[2], q[3]]]);
                    }
                }
            }
        }
    }
    CellMesh::from_triangles(positions, triangles).expect("cube indices are in range")
}

/// Sphere of radius `radius` from an `n`×`n`-subdivided cube projected onto it: 6n² + 2 nodes of
/// nearly uniform spacing (n = 13 gives 1,016 nodes). For benchmarks at a chosen node count.
pub fn cube_sphere(radius: Real, n: u32, centre: Vec3) -> CellMesh {
    let mut mesh = subdivided_cube(1.0, n, Vec3::zeros());
    mesh.positions_mut().iter_mut().for_each(|p| *p = centre + radius * p.normalize());
    mesh
}

/// A sphere of `radius` centred at the origin, meshed for edge lengths in [l_min, 3·l_min] (the
/// remeshing bounds): the finest icosphere whose shortest edge is at least `l_min`, then one
/// remeshing pass (which leaves it alone when it is already within bounds). Used as the single
/// founder cell of growth runs.
pub fn sphere_for_min_edge(radius: Real, l_min: Real) -> Result<CellMesh, super::remesh::RemeshError> {
    let mut subdivisions = 0;
    while subdivisions < 8
        && icosphere(radius, subdivisions + 1, Vec3::zeros()).edge_length_stats().is_some_and(|s| s.min >= l_min)
    {
        subdivisions += 1;
    }
    let mut mesh = icosphere(radius, subdivisions, Vec3::zeros());
    super::remesh::remesh_cell(&mut mesh, None, None, &super::remesh::RemeshSettings::new(l_min))?;
    Ok(mesh)
}
