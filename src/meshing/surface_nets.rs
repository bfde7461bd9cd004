//! Naive surface nets (Gibson 1998) at level 0.5 of a [`Field`], in physical coordinates.
//!
//! Every grid cube (8 neighbouring grid points) whose corners straddle the level gets one vertex, the
//! mean of the level crossings on its 12 edges (linear interpolation). Every grid edge whose ends
//! straddle the level gets a quad joining the vertices of the 4 cubes around it, wound so that its
//! normal points from the inside (value > 0.5) end to the outside end, and split along its shorter
//! diagonal. The result is closed and outward-oriented; it can have non-manifold vertices where the
//! inside touches itself along a cube edge, which does not matter here: it only guides sampling.

use super::field::Field;
use crate::geometry::{Real, Vec3, triangle_area_vector};

/// A triangle surface with per-vertex unit normals (area-weighted face normals).
#[derive(Clone, Debug, Default)]
pub(crate) struct Surface {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
    pub normals: Vec<Vec3>,
}

impl Surface {
    /// Total area (m²).
    pub fn area(&self) -> Real {
        self.triangles.iter().map(|t| self.face_area_vector(t).norm()).sum()
    }

    /// Enclosed volume (m³), positive for an outward surface.
    pub fn volume(&self) -> Real {
        let o = self.positions.first().copied().unwrap_or_default();
        let p = |i: u32| self.positions[i as usize] - o;
        self.triangles.iter().map(|t| p(t[0]).dot(&p(t[1]).cross(&p(t[2])))).sum::<Real>() / 6.0
    }

    pub fn face_area_vector(&self, t: &[u32; 3]) -> Vec3 {
        let [a, b, c] = t.map(|i| self.positions[i as usize]);
        triangle_area_vector(&a, &b, &c)
    }
}

/// The level the surface is extracted at.
pub(crate) const LEVEL: f32 = 0.5;

/// Extracts the 0.5 level of `field` and keeps its largest connected piece (by area).
pub(crate) fn extract_surface(field: &Field) -> Surface {
    let [nx, ny, nz] = field.dims;
    if nx < 2 || ny < 2 || nz < 2 {
        return Surface::default();
    }
    let inside = |x: usize, y: usize, z: usize| field.values[field.index(x, y, z)] > LEVEL;
    // Cube (x, y, z) has grid points (x..=x+1, y..=y+1, z..=z+1); its vertex index or u32::MAX.
    let cube_index = |x: usize, y: usize, z: usize| x + (nx - 1) * (y + (ny - 1) * z);
    let mut vertex_of = vec![u32::MAX; (nx - 1) * (ny - 1) * (nz - 1)];
    let mut positions = Vec::new();
    const CORNERS: [[usize; 3]; 8] =
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1]];
    const EDGES: [[usize; 2]; 12] =
        [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]];
    for z in 0..nz - 1 {
        for y in 0..ny - 1 {
            for x in 0..nx - 1 {
                let v = CORNERS.map(|c| field.values[field.index(x + c[0], y + c[1], z + c[2])]);
                let count = v.iter().filter(|&&f| f > LEVEL).count();
                if count == 0 || count == 8 {
                    continue;
                }
                let mut sum = Vec3::zeros();
                let mut crossings = 0.0;
                for [a, b] in EDGES {
                    if (v[a] > LEVEL) != (v[b] > LEVEL) {
                        let t = Real::from((LEVEL - v[a]) / (v[b] - v[a]));
                        let pa = Vec3::new(CORNERS[a][0] as Real, CORNERS[a][1] as Real, CORNERS[a][2] as Real);
                        let pb = Vec3::new(CORNERS[b][0] as Real, CORNERS[b][1] as Real, CORNERS[b][2] as Real);
                        sum += pa + (pb - pa) * t;
                        crossings += 1.0;
                    }
                }
                let local = sum / crossings;
                vertex_of[cube_index(x, y, z)] = positions.len() as u32;
                positions.push(field.position(x as Real + local.x, y as Real + local.y, z as Real + local.z));
            }
        }
    }
    let mut triangles = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let here = inside(x, y, z);
                for axis in 0..3 {
                    let mut q = [x, y, z];
                    q[axis] += 1;
                    if q[axis] >= field.dims[axis] || inside(q[0], q[1], q[2]) == here {
                        continue;
                    }
                    // The 4 cubes around the edge: offsets along the two other axes (b, c) with
                    // b × c = axis, taken counter-clockwise seen from +axis.
                    let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
                    let p = [x, y, z];
                    if p[b] == 0 || p[c] == 0 {
                        continue; // cannot happen: the padded border is background
                    }
                    let quad = [[0, 0], [1, 0], [1, 1], [0, 1]].map(|[db, dc]| {
                        let mut cube = p;
                        cube[b] -= db;
                        cube[c] -= dc;
                        vertex_of[cube_index(cube[0], cube[1], cube[2])]
                    });
                    if quad.contains(&u32::MAX) {
                        continue; // cannot happen: each of these cubes straddles the level
                    }
                    let quad = if here { quad } else { [quad[0], quad[3], quad[2], quad[1]] };
                    let d02 = (positions[quad[0] as usize] - positions[quad[2] as usize]).norm_squared();
                    let d13 = (positions[quad[1] as usize] - positions[quad[3] as usize]).norm_squared();
                    if d02 <= d13 {
                        triangles.push([quad[0], quad[1], quad[2]]);
                        triangles.push([quad[0], quad[2], quad[3]]);
                    } else {
                        triangles.push([quad[1], quad[2], quad[3]]);
                        triangles.push([quad[1], quad[3], quad[0]]);
                    }
                }
            }
        }
    }
    keep_largest_piece(Surface { positions, triangles, normals: Vec::new() })
}

/// Keeps the connected piece (triangles joined through shared vertices) of largest area, drops
/// unused vertices, and computes vertex normals.
fn keep_largest_piece(surface: Surface) -> Surface {
    let n = surface.positions.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn find(parent: &mut [u32], mut i: u32) -> u32 {
        while parent[i as usize] != i {
            parent[i as usize] = parent[parent[i as usize] as usize];
            i = parent[i as usize];
        }
        i
    }
    for t in &surface.triangles {
        for k in 1..3 {
            let (ra, rb) = (find(&mut parent, t[0]), find(&mut parent, t[k]));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
    }
    let mut area = vec![0.0; n];
    for t in &surface.triangles {
        let r = find(&mut parent, t[0]);
        area[r as usize] += surface.face_area_vector(t).norm();
    }
    let Some(best) = (0..n).max_by(|&a, &b| area[a].total_cmp(&area[b]).then(b.cmp(&a))) else {
        return surface;
    };
    let mut new_index = vec![u32::MAX; n];
    let mut out = Surface::default();
    for t in &surface.triangles {
        if find(&mut parent, t[0]) as usize != best {
            continue;
        }
        let t = t.map(|i| {
            if new_index[i as usize] == u32::MAX {
                new_index[i as usize] = out.positions.len() as u32;
                out.positions.push(surface.positions[i as usize]);
            }
            new_index[i as usize]
        });
        out.triangles.push(t);
    }
    let mut normals = vec![Vec3::zeros(); out.positions.len()];
    for t in &out.triangles {
        let a = out.face_area_vector(t);
        t.iter().for_each(|&i| normals[i as usize] += a);
    }
    out.normals = normals.into_iter().map(|v| v.try_normalize(0.0).unwrap_or_else(Vec3::zeros)).collect();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::CellMesh;

    fn ball_field(r: Real, n: usize) -> Field {
        let c = (n as Real - 1.0) / 2.0;
        let mut values = vec![0.0f32; n * n * n];
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let d = ((x as Real - c).powi(2) + (y as Real - c).powi(2) + (z as Real - c).powi(2)).sqrt();
                    values[x + n * (y + n * z)] = if d <= r { 1.0 } else { 0.0 };
                }
            }
        }
        Field { dims: [n; 3], spacing: [1.0, 1.0, 2.0], origin: Vec3::zeros(), values }
    }

    #[test]
    fn surface_of_a_ball_is_closed_and_outward() {
        let s = extract_surface(&ball_field(6.0, 17));
        let mesh = CellMesh::from_triangles(s.positions.clone(), s.triangles.clone()).unwrap();
        // No sign change on a cube edge of a ball mask: a closed 2-manifold surface.
        assert_eq!(mesh.validate(), Ok(()));
        assert!(mesh.signed_volume() > 0.0);
        // Normals point away from the centre (8, 8, 16) in physical coordinates (z spacing 2).
        let c = Vec3::new(8.0, 8.0, 16.0);
        for (p, n) in s.positions.iter().zip(&s.normals) {
            assert!((p - c).dot(n) > 0.0);
        }
    }
}
