//! Triangulation of the planar (or nearly planar) polygons found in input files.
//!
//! Ear clipping in the polygon's best-fit plane (Newell normal), so non-convex polygons are handled and
//! no nodes are added; the triangles keep the polygon's winding. A polygon with no ear (self-intersecting
//! or degenerate) falls back to a fan from its first vertex, which `validate()` will then judge.

use crate::geometry::{Real, Vec3};

/// Appends the triangles of polygon `poly` (indices into `positions`) to `out`.
/// Precondition: `poly.len() >= 3` and every index is in range (checked by the caller).
pub(crate) fn triangulate_polygon(positions: &[Vec3], poly: &[u32], out: &mut Vec<[u32; 3]>) {
    match poly.len() {
        3 => {
            out.push([poly[0], poly[1], poly[2]]);
            return;
        }
        0..=2 => return,
        _ => {}
    }
    let p = |i: u32| positions[i as usize];
    // Newell normal: robust plane normal of a polygon, oriented by its winding.
    let mut normal = Vec3::zeros();
    for (k, &a) in poly.iter().enumerate() {
        let (pa, pb) = (p(a), p(poly[(k + 1) % poly.len()]));
        normal +=
            Vec3::new((pa.y - pb.y) * (pa.z + pb.z), (pa.z - pb.z) * (pa.x + pb.x), (pa.x - pb.x) * (pa.y + pb.y));
    }
    if normal.norm() == 0.0 || !normal.iter().all(|c| c.is_finite()) {
        fan(poly, out);
        return;
    }
    // Orthonormal frame (u, v) of the plane, with u × v along the normal, so that the polygon is
    // counter-clockwise in (u, v) coordinates.
    let n = normal.normalize();
    let helper = if n.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() };
    let u = n.cross(&helper).normalize();
    let v = n.cross(&u);
    let pts: Vec<[Real; 2]> = poly.iter().map(|&i| [p(i).dot(&u), p(i).dot(&v)]).collect();
    let cross =
        |a: [Real; 2], b: [Real; 2], c: [Real; 2]| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);

    let mut remaining: Vec<usize> = (0..poly.len()).collect();
    let start = out.len();
    while remaining.len() > 3 {
        let m = remaining.len();
        let ear = (0..m).find(|&k| {
            let (a, b, c) = (remaining[(k + m - 1) % m], remaining[k], remaining[(k + 1) % m]);
            if cross(pts[a], pts[b], pts[c]) <= 0.0 {
                return false; // reflex or degenerate corner
            }
            remaining.iter().all(|&q| {
                q == a
                    || q == b
                    || q == c
                    || cross(pts[a], pts[b], pts[q]) < 0.0
                    || cross(pts[b], pts[c], pts[q]) < 0.0
                    || cross(pts[c], pts[a], pts[q]) < 0.0
            })
        });
        match ear {
            Some(k) => {
                let (a, b, c) = (remaining[(k + m - 1) % m], remaining[k], remaining[(k + 1) % m]);
                out.push([poly[a], poly[b], poly[c]]);
                remaining.remove(k);
            }
            None => {
                out.truncate(start);
                fan(poly, out);
                return;
            }
        }
    }
    out.push([poly[remaining[0]], poly[remaining[1]], poly[remaining[2]]]);
}

fn fan(poly: &[u32], out: &mut Vec<[u32; 3]>) {
    for k in 1..poly.len() - 1 {
        out.push([poly[0], poly[k], poly[k + 1]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area_sum(pos: &[Vec3], tris: &[[u32; 3]]) -> Vec3 {
        tris.iter()
            .map(|t| {
                crate::geometry::triangle_area_vector(&pos[t[0] as usize], &pos[t[1] as usize], &pos[t[2] as usize])
            })
            .sum()
    }

    #[test]
    fn non_convex_polygon_is_clipped_without_flipped_triangles() {
        // An L-shaped hexagon in the z = 1 plane, counter-clockwise seen from +z: area 3.
        let pos: Vec<Vec3> = [[0., 0.], [2., 0.], [2., 1.], [1., 1.], [1., 2.], [0., 2.]]
            .iter()
            .map(|p| Vec3::new(p[0], p[1], 1.0))
            .collect();
        let mut tris = Vec::new();
        triangulate_polygon(&pos, &[0, 1, 2, 3, 4, 5], &mut tris);
        assert_eq!(tris.len(), 4);
        for t in &tris {
            let a =
                crate::geometry::triangle_area_vector(&pos[t[0] as usize], &pos[t[1] as usize], &pos[t[2] as usize]);
            assert!(a.z > 0.0, "triangle {t:?} is flipped");
        }
        assert!((area_sum(&pos, &tris).z - 3.0).abs() < 1e-12);
    }

    #[test]
    fn winding_is_preserved_for_clockwise_polygon() {
        let pos: Vec<Vec3> =
            [[0., 0.], [1., 0.], [1., 1.], [0., 1.]].iter().map(|p| Vec3::new(p[0], p[1], 0.0)).collect();
        let mut tris = Vec::new();
        triangulate_polygon(&pos, &[3, 2, 1, 0], &mut tris);
        assert_eq!(tris.len(), 2);
        assert!((area_sum(&pos, &tris).z + 1.0).abs() < 1e-12);
    }
}
