//! Voxel-grid kernels in grid units (voxel edge 1, voxel (i, j, k) = [i, i+1)×[j, j+1)×[k, k+1)):
//! the walk of a ray through the voxels it crosses, and the exact triangle–box overlap test used to
//! rasterise surfaces conservatively.
//!
//! # Ray walk
//! [`VoxelWalk`] is the 3-D DDA of Amanatides & Woo ("A fast voxel traversal algorithm for ray
//! tracing", Eurographics 1987): from the voxel holding the start point, step each time into the
//! neighbour across the voxel face the ray reaches first. Per axis it keeps `t_max`, the ray
//! parameter at the next face crossing on that axis, and `t_delta = 1/|d|`, the parameter between
//! two crossings. A positive component crosses the upper face of the current voxel first, a negative
//! one the lower face (the reference program swaps the two); a zero component never crosses (t_max
//! = ∞). Ties step the lowest axis first, so the walk is 6-connected even through voxel edges and
//! corners. The walk stops when it leaves the grid.
//!
//! # Triangle–box overlap
//! [`triangle_box_overlap`] is the separating-axis test of Akenine-Möller ("Fast 3D triangle-box
//! overlap testing", 2001): a triangle and an axis-aligned box are disjoint exactly when one of 13
//! axes separates them (the 3 box axes, the triangle normal, and the 9 cross products of box axes
//! with triangle edges). Touching counts as overlap, so with a box enlarged by a small margin the
//! rasterisation is conservative: every voxel the surface touches is marked.

use super::{Real, Vec3};

/// The voxels a ray crosses, in order, with the ray parameter at which it enters each one. See the
/// module documentation.
#[derive(Clone, Debug)]
pub struct VoxelWalk {
    voxel: [i64; 3],
    dims: [usize; 3],
    step: [i64; 3],
    t_max: [Real; 3],
    t_delta: [Real; 3],
    t: Real,
    done: bool,
}

impl VoxelWalk {
    /// A walk from `start` (grid units) along `direction` (any length; a zero vector visits only
    /// the start voxel) through a grid of `dims` = [nx, ny, nz] voxels. A start outside the grid or
    /// not finite gives an empty walk.
    pub fn new(start: Vec3, direction: Vec3, dims: [usize; 3]) -> Self {
        let mut walk = Self {
            voxel: [0; 3],
            dims,
            step: [0; 3],
            t_max: [Real::INFINITY; 3],
            t_delta: [Real::INFINITY; 3],
            t: 0.0,
            done: false,
        };
        for axis in 0..3 {
            let (s, d) = (start[axis], direction[axis]);
            if !(s.is_finite() && d.is_finite()) || s < 0.0 || s >= dims[axis] as Real {
                walk.done = true;
                return walk;
            }
            let cell = s.floor();
            walk.voxel[axis] = cell as i64;
            if d > 0.0 {
                walk.step[axis] = 1;
                walk.t_max[axis] = (cell + 1.0 - s) / d;
                walk.t_delta[axis] = 1.0 / d;
            } else if d < 0.0 {
                walk.step[axis] = -1;
                walk.t_max[axis] = (s - cell) / -d;
                walk.t_delta[axis] = -1.0 / d;
            }
        }
        walk
    }
}

impl Iterator for VoxelWalk {
    /// The voxel [i, j, k] and the ray parameter at which the ray enters it (0 for the start voxel).
    type Item = ([usize; 3], Real);

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let current = (self.voxel.map(|v| v as usize), self.t);
        // The axis whose next face crossing comes first; ties take the lowest axis.
        let mut axis = 0;
        for a in 1..3 {
            if self.t_max[a] < self.t_max[axis] {
                axis = a;
            }
        }
        if self.t_max[axis].is_infinite() {
            self.done = true; // a zero direction: only the start voxel
        } else {
            self.t = self.t_max[axis];
            self.t_max[axis] += self.t_delta[axis];
            self.voxel[axis] += self.step[axis];
            let v = self.voxel[axis];
            if v < 0 || v >= self.dims[axis] as i64 {
                self.done = true;
            }
        }
        Some(current)
    }
}

/// Whether triangle (a, b, c) and the axis-aligned box of centre `centre` and half extents `half`
/// overlap (touching included). Separating-axis test; see the module documentation.
pub fn triangle_box_overlap(a: &Vec3, b: &Vec3, c: &Vec3, centre: &Vec3, half: &Vec3) -> bool {
    // Work relative to the box centre.
    let v = [a - centre, b - centre, c - centre];
    // Box axes: the triangle's bounding box against the box.
    for axis in 0..3 {
        let lo = v[0][axis].min(v[1][axis]).min(v[2][axis]);
        let hi = v[0][axis].max(v[1][axis]).max(v[2][axis]);
        if lo > half[axis] || hi < -half[axis] {
            return false;
        }
    }
    let edges = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    // The triangle's plane (first: it rejects most boxes of a triangle's bounding box).
    if separated(&v, &edges[0].cross(&edges[1]), half) {
        return false;
    }
    // The nine cross products of the box axes with the edges.
    for edge in &edges {
        for axis in 0..3 {
            let mut l = Vec3::zeros();
            l[axis] = 1.0;
            if separated(&v, &l.cross(edge), half) {
                return false;
            }
        }
    }
    true
}

/// Whether axis `l` separates the triangle `v` (relative to the box centre) from the box.
fn separated(v: &[Vec3; 3], l: &Vec3, half: &Vec3) -> bool {
    let p = [v[0].dot(l), v[1].dot(l), v[2].dot(l)];
    let radius = half.x * l.x.abs() + half.y * l.y.abs() + half.z * l.z.abs();
    let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
    lo > radius || hi < -radius
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn walk(start: Vec3, direction: Vec3, dims: [usize; 3]) -> Vec<([usize; 3], Real)> {
        VoxelWalk::new(start, direction, dims).collect()
    }

    #[test]
    fn axis_aligned_walks_step_one_voxel_at_a_time_in_both_senses() {
        let dims = [5, 4, 3];
        let up: Vec<[usize; 3]> = walk(Vec3::new(1.5, 2.5, 0.5), Vec3::x(), dims).into_iter().map(|v| v.0).collect();
        assert_eq!(up, [[1, 2, 0], [2, 2, 0], [3, 2, 0], [4, 2, 0]]);
        let down: Vec<([usize; 3], Real)> = walk(Vec3::new(1.5, 2.5, 2.25), -2.0 * Vec3::z(), dims);
        assert_eq!(down.iter().map(|v| v.0).collect::<Vec<_>>(), [[1, 2, 2], [1, 2, 1], [1, 2, 0]]);
        // Entry parameters: the lower face of voxel k = 2 is 0.25 away at speed 2.
        assert_eq!(down.iter().map(|v| v.1).collect::<Vec<_>>(), [0.0, 0.125, 0.625]);
        assert_eq!(walk(Vec3::new(0.5, 0.5, 0.5), Vec3::zeros(), dims).len(), 1);
        assert!(walk(Vec3::new(5.5, 0.5, 0.5), Vec3::x(), dims).is_empty());
    }

    #[test]
    fn a_diagonal_through_a_voxel_corner_stays_six_connected() {
        let path: Vec<[usize; 3]> =
            walk(Vec3::new(0.5, 0.5, 0.5), Vec3::new(1.0, 1.0, 1.0), [3, 3, 3]).into_iter().map(|v| v.0).collect();
        assert_eq!(path.first(), Some(&[0, 0, 0]));
        assert_eq!(path.last(), Some(&[2, 2, 2]));
        assert_eq!(path.len(), 7);
    }

    #[test]
    fn triangle_box_overlap_separates_on_every_kind_of_axis() {
        let (centre, half) = (Vec3::zeros(), Vec3::repeat(0.5));
        let t = |a: [Real; 3], b: [Real; 3], c: [Real; 3]| {
            triangle_box_overlap(&Vec3::from(a), &Vec3::from(b), &Vec3::from(c), &centre, &half)
        };
        // A large triangle cutting through the box (no vertex inside).
        assert!(t([-5.0, -5.0, 0.1], [5.0, -5.0, 0.1], [0.0, 5.0, 0.1]));
        // Box axis separates.
        assert!(!t([0.6, -1.0, -1.0], [0.6, 1.0, -1.0], [0.6, 0.0, 1.0]));
        // Touching a face counts.
        assert!(t([0.5, -1.0, -1.0], [0.5, 1.0, -1.0], [0.5, 0.0, 1.0]));
        // The triangle's plane separates: x + y + z = 1.6 passes beside the corner (sum 1.5).
        assert!(!t([1.6, 0.0, 0.0], [0.0, 1.6, 0.0], [0.0, 0.0, 1.6]));
        assert!(t([1.4, 0.0, 0.0], [0.0, 1.4, 0.0], [0.0, 0.0, 1.4]));
        // A vertical triangle in x + y = 1.05 passes beside the box's vertical edge (x + y ≤ 1).
        assert!(!t([0.0, 1.05, -2.0], [1.05, 0.0, -2.0], [1.05, 0.0, 2.0]));
        assert!(t([0.0, 0.95, -2.0], [0.95, 0.0, -2.0], [0.95, 0.0, 2.0]));
    }

    fn direction() -> impl Strategy<Value = Vec3> {
        // Components from a small set that includes zeros, so axis-aligned and planar rays occur.
        let component = prop_oneof![Just(0.0), -1.0..1.0f64, Just(1.0), Just(-1.0)];
        (component.clone(), component.clone(), component)
            .prop_filter("non-zero", |(x, y, z)| x * x + y * y + z * z > 1e-6)
            .prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    proptest! {
        /// The walk is 6-connected, and every sample point of the ray inside the grid lies in a
        /// visited voxel, entered no later than the sample's parameter.
        #[test]
        fn walk_is_six_connected_and_covers_the_ray(
            sx in 0.0..7.0f64, sy in 0.0..5.0f64, sz in 0.0..6.0f64,
            d in direction(),
            samples in proptest::collection::vec(0.0..20.0f64, 32),
        ) {
            let dims = [7, 5, 6];
            let start = Vec3::new(sx, sy, sz);
            let path = walk(start, d, dims);
            prop_assert!(!path.is_empty());
            prop_assert_eq!(path[0].0, [sx.floor() as usize, sy.floor() as usize, sz.floor() as usize]);
            for pair in path.windows(2) {
                let steps: i64 = (0..3).map(|a| (pair[0].0[a] as i64 - pair[1].0[a] as i64).abs()).sum();
                prop_assert_eq!(steps, 1, "{:?} → {:?}", pair[0], pair[1]);
                prop_assert!(pair[1].1 >= pair[0].1);
            }
            for t in samples {
                let p = start + t * d;
                if (0..3).any(|a| p[a] < 0.0 || p[a] >= dims[a] as Real) {
                    continue;
                }
                let v = [p.x.floor() as usize, p.y.floor() as usize, p.z.floor() as usize];
                // A sample within rounding of a voxel face may sit in either neighbour.
                let near_face = (0..3).any(|a| (p[a] - p[a].round()).abs() < 1e-9);
                let hit = path.iter().position(|(w, _)| *w == v);
                prop_assert!(hit.is_some() || near_face, "sample {p:?} (voxel {v:?}) not visited");
                if let Some(i) = hit {
                    prop_assert!(path[i].1 <= t + 1e-9);
                }
            }
        }

        /// Every voxel whose centre lies on the triangle overlaps it, and a box far from the
        /// triangle's plane does not.
        #[test]
        fn overlap_agrees_with_points_on_and_off_the_triangle(
            a in proptest::array::uniform3(-3.0..3.0f64),
            b in proptest::array::uniform3(-3.0..3.0f64),
            c in proptest::array::uniform3(-3.0..3.0f64),
            u in 0.0..1.0f64, v in 0.0..1.0f64,
        ) {
            let (a, b, c) = (Vec3::from(a), Vec3::from(b), Vec3::from(c));
            let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
            let p = a + u * (b - a) + v * (c - a);
            let half = Vec3::repeat(0.25);
            prop_assert!(triangle_box_overlap(&a, &b, &c, &p, &half));
            if let Some(n) = (b - a).cross(&(c - a)).try_normalize(1e-9) {
                // A box centred 0.5 from the plane, half-diagonal 0.25·√3 < 0.5: disjoint.
                prop_assert!(!triangle_box_overlap(&a, &b, &c, &(p + 0.5 * n), &half));
            }
        }
    }
}
