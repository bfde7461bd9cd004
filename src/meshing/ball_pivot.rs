//! The ball-pivoting algorithm (Bernardini, Mittleman, Rushmeier, Silva, Taubin, IEEE TVCG 5(4),
//! 1999) on oriented points.
//!
//! A ball of radius ρ that touches three points and contains no other is a triangle. The ball always
//! sits on the outer side of the surface (the side the point normals point to): for a triangle
//! (a, b, c), wound counter-clockwise seen from outside, its ball centre is the circumcentre plus
//! √(ρ² − r_c²) along the triangle's normal (no ball when the circumradius r_c exceeds ρ).
//!
//! * Seed: for the first unused point `a` (index order), its nearest unused neighbours within 2ρ are
//!   tried in pairs (nearest first); a triangle whose normal agrees with all three point normals and
//!   whose ball is empty starts a front.
//! * Pivot: each front edge i→j of a triangle (i, j, o) rolls the triangle's ball about the edge, away
//!   from o. The ball centre moves on the circle about the edge midpoint m perpendicular to the edge;
//!   for every point k within ρ + |c − m| of m, the ball touching i, j, k (on the outer side of the
//!   candidate (j, i, k)) sits at some angle along that circle; the smallest angle is the first point
//!   hit. The triangle (j, i, k) is added when the edges i→k and k→j are not already used in that
//!   direction (that would break manifoldness or orientation), its normal agrees with the three point
//!   normals, and k is unused, or a front neighbour of i or j (the triangle fills a corner of the
//!   front), or on another piece of the surface (the pieces merge). Otherwise the edge stays open.
//!   A "join" of two parts of one piece's front (k on the front, not next to i or j) splits the front
//!   in two; closing both can wrap a handle around unmeshed surface. Joins are allowed in the first
//!   pass only when asked (`joins`): with the smallest ball they are how the front closes around the
//!   cell, and leave few, small holes. With the larger balls of later passes they bridged concave
//!   folds of real cells into handles, so later passes never join. Without joins, with only grow,
//!   corner and merge steps, every piece stays a topological disk and the closed surface has genus
//!   0 whatever the geometry; the price is a long seam where the front meets itself, left to hole
//!   filling (the fallback of [`super::mesh_mask`] when a surface with joins is not valid).
//! * Radii: a pass with each radius in increasing order. Later passes only pivot from the edges
//!   still open (no new seeds), which closes gaps where the samples are sparse.
//!
//! Merge steps leave pinched vertices (two fans) until the gap between the pieces closes; the repair
//! step removes the smaller fans of those that remain. Decisions never depend on hash order: the front is a FIFO queue, candidates are
//! ranked by (angle, index), so the output is a function of the input points.

use super::point_grid::PointGrid;
use crate::geometry::{Real, Vec3};
use std::collections::{HashMap, VecDeque};

/// What the pivoting did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct PivotStats {
    /// Seed triangles placed.
    pub seeds: usize,
    /// Triangles added in the pass with each radius.
    pub faces_per_radius: Vec<usize>,
}

/// Neighbours tried as seed partners of a point.
const SEED_NEIGHBOURS: usize = 12;

/// Centre of the ball of radius `rho` through `a`, `b`, `c` on the side of the normal
/// `(b − a) × (c − a)`; `None` for a degenerate triangle or a circumradius above `rho`.
pub(crate) fn ball_centre(a: &Vec3, b: &Vec3, c: &Vec3, rho: Real) -> Option<Vec3> {
    let (ab, ac) = (b - a, c - a);
    let n = ab.cross(&ac);
    let n2 = n.norm_squared();
    if n2 <= 1e-14 * ab.norm_squared() * ac.norm_squared() {
        return None;
    }
    let to_centre = (n.cross(&ab) * ac.norm_squared() + ac.cross(&n) * ab.norm_squared()) / (2.0 * n2);
    let h2 = rho * rho - to_centre.norm_squared();
    if h2 < 0.0 {
        return None;
    }
    Some(a + to_centre + n * (h2.sqrt() / n2.sqrt()))
}

struct Pivoting<'a> {
    points: &'a [Vec3],
    normals: &'a [Vec3],
    faces: Vec<[u32; 3]>,
    /// Directed edge → the face that traverses it.
    half: HashMap<(u32, u32), u32>,
    used: Vec<bool>,
    /// Open (boundary) directed edges touching each point.
    open: Vec<u32>,
    /// Union-find parent of each point: points joined by triangles share a root.
    parent: Vec<u32>,
    queue: VecDeque<(u32, u32)>,
    grid: PointGrid,
    scratch: Vec<u32>,
    next_seed: usize,
}

/// Triangulates oriented points (unit outward `normals`) with balls of the given radii (increasing);
/// returns triangles wound outward and what was done. With `joins`, the first pass may join two
/// parts of one piece's front (the original algorithm); later passes never do.
pub(crate) fn ball_pivot(
    points: &[Vec3],
    normals: &[Vec3],
    radii: &[Real],
    joins: bool,
) -> (Vec<[u32; 3]>, PivotStats) {
    let mut stats = PivotStats::default();
    let Some(&largest) = radii.iter().max_by(|a, b| a.total_cmp(b)) else {
        return (Vec::new(), stats);
    };
    let mut grid = PointGrid::new(largest);
    for (i, p) in points.iter().enumerate() {
        grid.insert(p, i as u32);
    }
    let mut state = Pivoting {
        points,
        normals,
        faces: Vec::new(),
        half: HashMap::new(),
        used: vec![false; points.len()],
        open: vec![0; points.len()],
        parent: (0..points.len() as u32).collect(),
        queue: VecDeque::new(),
        grid,
        scratch: Vec::new(),
        next_seed: 0,
    };
    for (pass, &rho) in radii.iter().enumerate() {
        let before = state.faces.len();
        if pass > 0 {
            state.requeue_open_edges();
        }
        loop {
            while let Some((i, j)) = state.queue.pop_front() {
                state.pivot(i, j, rho, joins && pass == 0);
            }
            if pass > 0 || !state.seed(rho) {
                break;
            }
            stats.seeds += 1;
        }
        stats.faces_per_radius.push(state.faces.len() - before);
    }
    (state.faces, stats)
}

impl Pivoting<'_> {
    fn normals_agree(&self, t: [u32; 3]) -> bool {
        let [a, b, c] = t.map(|i| self.points[i as usize]);
        let n = (b - a).cross(&(c - a));
        t.iter().all(|&i| n.dot(&self.normals[i as usize]) > 0.0)
    }

    fn root(&mut self, mut i: u32) -> u32 {
        while self.parent[i as usize] != i {
            let up = self.parent[self.parent[i as usize] as usize];
            self.parent[i as usize] = up;
            i = up;
        }
        i
    }

    fn add_face(&mut self, t: [u32; 3]) {
        for k in 1..3 {
            let (a, b) = (self.root(t[0]), self.root(t[k]));
            self.parent[a.max(b) as usize] = a.min(b);
        }
        let f = self.faces.len() as u32;
        self.faces.push(t);
        for s in 0..3 {
            let (a, b) = (t[s], t[(s + 1) % 3]);
            self.half.insert((a, b), f);
            self.used[a as usize] = true;
            if self.half.contains_key(&(b, a)) {
                self.open[a as usize] -= 1;
                self.open[b as usize] -= 1;
            } else {
                self.open[a as usize] += 1;
                self.open[b as usize] += 1;
                self.queue.push_back((a, b));
            }
        }
    }

    fn requeue_open_edges(&mut self) {
        for t in &self.faces {
            for s in 0..3 {
                let (a, b) = (t[s], t[(s + 1) % 3]);
                if !self.half.contains_key(&(b, a)) {
                    self.queue.push_back((a, b));
                }
            }
        }
    }

    /// Looks for a seed triangle among unused points from the seed cursor on; adds it and returns
    /// true, or returns false when no unused point has one.
    fn seed(&mut self, rho: Real) -> bool {
        let mut near = std::mem::take(&mut self.scratch);
        while self.next_seed < self.points.len() {
            let a = self.next_seed as u32;
            self.next_seed += 1;
            if self.used[a as usize] {
                continue;
            }
            let pa = self.points[a as usize];
            self.grid.within(self.points, &pa, 2.0 * rho, &mut near);
            near.retain(|&k| k != a && !self.used[k as usize]);
            near.sort_by(|&x, &y| {
                let dx = (self.points[x as usize] - pa).norm_squared();
                let dy = (self.points[y as usize] - pa).norm_squared();
                dx.total_cmp(&dy).then(x.cmp(&y))
            });
            near.truncate(SEED_NEIGHBOURS);
            for (q, &b) in near.iter().enumerate() {
                for &c in &near[q + 1..] {
                    let [pb, pc] = [b, c].map(|k| self.points[k as usize]);
                    let n = (pb - pa).cross(&(pc - pa));
                    let sum = self.normals[a as usize] + self.normals[b as usize] + self.normals[c as usize];
                    let t = if n.dot(&sum) >= 0.0 { [a, b, c] } else { [a, c, b] };
                    if !self.normals_agree(t) {
                        continue;
                    }
                    let [p0, p1, p2] = t.map(|k| self.points[k as usize]);
                    let Some(centre) = ball_centre(&p0, &p1, &p2, rho) else { continue };
                    if self.grid_ball_occupied(&centre, rho, t) {
                        continue;
                    }
                    self.add_face(t);
                    self.scratch = near;
                    return true;
                }
            }
        }
        self.scratch = near;
        false
    }

    /// Whether a point other than those of `t` lies inside the ball (with a relative margin).
    fn grid_ball_occupied(&self, centre: &Vec3, rho: Real, t: [u32; 3]) -> bool {
        let r2 = (rho * (1.0 - 1e-7)).powi(2);
        let mut occupied = false;
        self.grid.for_each_near(centre, rho, |k| {
            occupied |= !t.contains(&k) && (self.points[k as usize] - centre).norm_squared() < r2;
        });
        occupied
    }

    /// Pivots the ball of the face on the open edge i→j; adds the triangle found, if any.
    fn pivot(&mut self, i: u32, j: u32, rho: Real, joins: bool) {
        if self.half.contains_key(&(j, i)) {
            return; // closed since it was queued
        }
        let Some(&f) = self.half.get(&(i, j)) else { return };
        let t = self.faces[f as usize];
        let o = t.into_iter().find(|&k| k != i && k != j).expect("a face has three nodes");
        let [p0, p1, p2] = t.map(|k| self.points[k as usize]);
        let Some(old) = ball_centre(&p0, &p1, &p2, rho) else { return };
        let (pi, pj) = (self.points[i as usize], self.points[j as usize]);
        let m = (pi + pj) * 0.5;
        let e = (pj - pi).normalize();
        let Some(u) = (old - m).try_normalize(1e-300) else { return };
        let w = e.cross(&u);
        let reach = rho + (old - m).norm();
        let mut near = std::mem::take(&mut self.scratch);
        self.grid.within(self.points, &m, reach, &mut near);
        let mut best: Option<(Real, u32)> = None;
        for &k in &near {
            if k == i || k == j || k == o {
                continue;
            }
            let Some(c) = ball_centre(&pj, &pi, &self.points[k as usize], rho) else { continue };
            let v = c - m;
            let mut angle = v.dot(&w).atan2(v.dot(&u));
            // A point on the old ball itself (angle 0 up to rounding) is hit first, not last.
            if angle < -1e-9 {
                angle += std::f64::consts::TAU;
            }
            let angle = angle.max(0.0);
            if best.is_none_or(|(a, _)| angle < a) {
                best = Some((angle, k));
            }
        }
        self.scratch = near;
        let Some((_, k)) = best else { return };
        if self.half.contains_key(&(i, k)) || self.half.contains_key(&(k, j)) {
            return;
        }
        // A used k must be the front neighbour of i or j (the triangle fills a corner of the front)
        // or lie on another piece (the pieces merge at k): joining two parts of the same piece's
        // front would split its boundary and could close a handle around unmeshed surface.
        if self.used[k as usize] {
            let corner = self.half.contains_key(&(k, i)) || self.half.contains_key(&(j, k));
            let interior = self.open[k as usize] == 0;
            if interior || (!joins && !corner && self.root(k) == self.root(i)) {
                return;
            }
        }
        let t = [j, i, k];
        if self.normals_agree(t) {
            self.add_face(t);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::CellMesh;
    use crate::mesh::shapes::icosphere;

    #[test]
    fn ball_centre_is_at_distance_rho_on_the_normal_side() {
        let (a, b, c) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
        let centre = ball_centre(&a, &b, &c, 1.0).unwrap();
        for p in [a, b, c] {
            assert!(((centre - p).norm() - 1.0).abs() < 1e-12);
        }
        assert!(centre.z > 0.0);
        assert!(ball_centre(&a, &c, &b, 1.0).unwrap().z < 0.0);
        assert!(ball_centre(&a, &b, &c, 0.7).is_none()); // circumradius √2/2 ≈ 0.707
    }

    #[test]
    fn pivoting_the_nodes_of_an_icosphere_closes_it() {
        // Points of a subdivided icosahedron: the ball through each triangle's corners is empty, so
        // a radius a little above the largest circumradius rebuilds a closed surface.
        let sphere = icosphere(1.0, 3, Vec3::zeros());
        let pts = sphere.positions().to_vec();
        let normals: Vec<Vec3> = pts.iter().map(|p| p.normalize()).collect();
        let (faces, stats) = ball_pivot(&pts, &normals, &[0.12], true);
        assert_eq!(stats.seeds, 1);
        let mesh = CellMesh::from_triangles(pts, faces).unwrap();
        assert_eq!(mesh.validate(), Ok(()));
        assert_eq!(mesh.face_count(), sphere.face_count());
    }
}
