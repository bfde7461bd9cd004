//! Planar cap of a division cut: the polygon bounded by the cut loop is filled with Poisson-disk points
//! (Bridson 2007, spacing `r`, seeded ChaCha8) and triangulated with spade's constrained Delaunay
//! triangulation, the loop edges being the constraints. Only triangles inside the loop are kept.
//!
//! Everything is computed in plane coordinates scaled by `1/r` (so the spacing is 1 and the robust
//! predicates see numbers of order 1 whatever the units). Interior points keep at least `r` from each
//! other and from the loop nodes, and at least `r/2` from the loop segments, so that no point falls on a
//! constraint (spade would split the constraint there and the cap would no longer match the loop).

use super::divide::DivisionError;
use crate::geometry::{Real, Vec3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Uniform};
use spade::handles::FixedVertexHandle;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// Candidates tried around one active sample before it is retired (Bridson's k).
const CANDIDATES: usize = 30;
/// Uniform darts thrown into the bounding box to seed a new front once the current one is exhausted
/// (reaches regions of a non-convex loop that a narrow neck cut off).
const DARTS: usize = 64;
/// Smallest distance of an interior point from a loop segment, in units of the spacing.
const SEGMENT_CLEARANCE: Real = 0.5;

/// A triangulated planar cap. Node `i < loop_len` is loop node `i`; node `loop_len + k` is `interior[k]`.
pub(super) struct PlanarCap {
    /// Poisson-disk points strictly inside the loop, exactly in the plane (m).
    pub interior: Vec<Vec3>,
    /// Triangles counter-clockwise about the plane normal `n` (their normal points along `+n`).
    pub triangles: Vec<[u32; 3]>,
}

/// Orthonormal in-plane basis `(e1, e2)` with `e1 × e2 = n` (`n` a unit vector).
pub(super) fn plane_basis(n: &Vec3) -> (Vec3, Vec3) {
    // Cross with the coordinate axis least aligned with n: well conditioned for every n.
    let a = n.iamin();
    let mut axis = Vec3::zeros();
    axis[a] = 1.0;
    let e1 = n.cross(&axis).normalize();
    let e2 = n.cross(&e1);
    (e1, e2)
}

/// Fills the loop `loop_positions` (in order, lying in the plane through `origin` with unit normal `n`
/// up to the snapping tolerance) with points at spacing `spacing` and triangulates it.
pub(super) fn triangulate_cap(
    loop_positions: &[Vec3],
    origin: &Vec3,
    n: &Vec3,
    spacing: Real,
    seed: u64,
) -> Result<PlanarCap, DivisionError> {
    let (e1, e2) = plane_basis(n);
    let to_2d = |p: &Vec3| {
        let q = p - origin;
        [q.dot(&e1) / spacing, q.dot(&e2) / spacing]
    };
    let polygon: Vec<[Real; 2]> = loop_positions.iter().map(to_2d).collect();
    let samples = poisson_disk_in_polygon(&polygon, seed);
    let triangles = constrained_triangulation(&polygon, &samples)?;
    let interior = samples.iter().map(|&[u, v]| origin + spacing * (u * e1 + v * e2)).collect();
    Ok(PlanarCap { interior, triangles })
}

/// Uniform grid of unit cells over the polygon's bounding box, holding the points placed so far (loop
/// nodes and samples) and the loop segments near each cell: a point closer than 1 to a stored point lies
/// in the 3×3 block of cells around it, and a segment closer than [`SEGMENT_CLEARANCE`] to a point is
/// registered in the point's cell.
struct Grid {
    lo: [Real; 2],
    nx: usize,
    ny: usize,
    points: Vec<Vec<[Real; 2]>>,
    segments: Vec<Vec<u32>>,
}

impl Grid {
    fn new(polygon: &[[Real; 2]], lo: [Real; 2], hi: [Real; 2]) -> Self {
        let lo = [lo[0].floor() - 1.0, lo[1].floor() - 1.0];
        let (nx, ny) = ((hi[0] - lo[0]).ceil() as usize + 2, (hi[1] - lo[1]).ceil() as usize + 2);
        let mut grid = Self { lo, nx, ny, points: vec![Vec::new(); nx * ny], segments: vec![Vec::new(); nx * ny] };
        for (k, a) in polygon.iter().enumerate() {
            let b = &polygon[(k + 1) % polygon.len()];
            let (i0, j0) = grid.cell_clamped(&[a[0].min(b[0]) - SEGMENT_CLEARANCE, a[1].min(b[1]) - SEGMENT_CLEARANCE]);
            let (i1, j1) = grid.cell_clamped(&[a[0].max(b[0]) + SEGMENT_CLEARANCE, a[1].max(b[1]) + SEGMENT_CLEARANCE]);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    grid.segments[i + nx * j].push(k as u32);
                }
            }
            grid.insert(*a);
        }
        grid
    }

    fn cell_clamped(&self, p: &[Real; 2]) -> (usize, usize) {
        let i = ((p[0] - self.lo[0]).floor().max(0.0) as usize).min(self.nx - 1);
        let j = ((p[1] - self.lo[1]).floor().max(0.0) as usize).min(self.ny - 1);
        (i, j)
    }

    /// The cell of `p`, `None` outside the grid (and so outside the polygon).
    fn cell(&self, p: &[Real; 2]) -> Option<(usize, usize)> {
        let (x, y) = ((p[0] - self.lo[0]).floor(), (p[1] - self.lo[1]).floor());
        (x >= 0.0 && y >= 0.0 && x < self.nx as Real && y < self.ny as Real).then_some((x as usize, y as usize))
    }

    fn insert(&mut self, p: [Real; 2]) {
        let (i, j) = self.cell(&p).expect("points are inserted inside the grid");
        self.points[i + self.nx * j].push(p);
    }

    /// Whether `p` may be added: inside the grid, at least 1 from every stored point and at least
    /// [`SEGMENT_CLEARANCE`] from every loop segment.
    fn is_free(&self, p: &[Real; 2], polygon: &[[Real; 2]]) -> bool {
        let Some((i, j)) = self.cell(p) else { return false };
        let near_point = (j.saturating_sub(1)..=(j + 1).min(self.ny - 1)).any(|b| {
            (i.saturating_sub(1)..=(i + 1).min(self.nx - 1))
                .any(|a| self.points[a + self.nx * b].iter().any(|q| dist2(p, q) < 1.0))
        });
        let clearance2 = SEGMENT_CLEARANCE * SEGMENT_CLEARANCE;
        !near_point
            && self.segments[i + self.nx * j].iter().all(|&k| {
                let (a, b) = (&polygon[k as usize], &polygon[(k as usize + 1) % polygon.len()]);
                segment_dist2(p, a, b) >= clearance2
            })
    }
}

fn dist2(p: &[Real; 2], q: &[Real; 2]) -> Real {
    (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
}

/// Squared distance from `p` to the segment `a`–`b`.
fn segment_dist2(p: &[Real; 2], a: &[Real; 2], b: &[Real; 2]) -> Real {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 { (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
    dist2(p, &[a[0] + t * dx, a[1] + t * dy])
}

/// Whether `p` lies inside the closed polygon (even–odd rule).
fn inside(p: &[Real; 2], polygon: &[[Real; 2]]) -> bool {
    let mut inside = false;
    for (i, a) in polygon.iter().enumerate() {
        let b = &polygon[(i + 1) % polygon.len()];
        if (a[1] > p[1]) != (b[1] > p[1]) && p[0] < a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]) {
            inside = !inside;
        }
    }
    inside
}

/// Bridson's Poisson-disk sampling with unit spacing inside `polygon`, away from its nodes and edges.
fn poisson_disk_in_polygon(polygon: &[[Real; 2]], seed: u64) -> Vec<[Real; 2]> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut lo, mut hi) = ([Real::INFINITY; 2], [Real::NEG_INFINITY; 2]);
    for p in polygon {
        for k in 0..2 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let (Ok(ux), Ok(uy)) = (Uniform::new_inclusive(lo[0], hi[0]), Uniform::new_inclusive(lo[1], hi[1])) else {
        return Vec::new();
    };
    let unit = Uniform::new(0.0, 1.0).expect("the unit interval is a valid range");
    let mut grid = Grid::new(polygon, lo, hi);
    let acceptable = |p: &[Real; 2], grid: &Grid| grid.is_free(p, polygon) && inside(p, polygon);

    let mut samples: Vec<[Real; 2]> = Vec::new();
    let mut active: Vec<usize> = Vec::new();
    // Seed a front with a dart; stop when no dart lands on free space.
    while let Some(dart) = (0..DARTS).map(|_| [ux.sample(&mut rng), uy.sample(&mut rng)]).find(|p| acceptable(p, &grid))
    {
        grid.insert(dart);
        active.push(samples.len());
        samples.push(dart);
        while !active.is_empty() {
            let slot = (unit.sample(&mut rng) * active.len() as Real) as usize % active.len();
            let centre = samples[active[slot]];
            let found = (0..CANDIDATES)
                .map(|_| {
                    // Uniform in the annulus 1 ≤ ρ ≤ 2.
                    let rho = (1.0 + 3.0 * unit.sample(&mut rng)).sqrt();
                    let phi = std::f64::consts::TAU * unit.sample(&mut rng);
                    [centre[0] + rho * phi.cos(), centre[1] + rho * phi.sin()]
                })
                .find(|p| acceptable(p, &grid));
            match found {
                Some(p) => {
                    grid.insert(p);
                    active.push(samples.len());
                    samples.push(p);
                }
                None => {
                    active.swap_remove(slot);
                }
            }
        }
    }
    samples
}

/// Constrained Delaunay triangulation of the polygon's nodes and the interior samples, the polygon's
/// edges as constraints; returns the triangles inside the polygon (counter-clockwise), indexed as in
/// [`PlanarCap`].
fn constrained_triangulation(polygon: &[[Real; 2]], samples: &[[Real; 2]]) -> Result<Vec<[u32; 3]>, DivisionError> {
    let mut cdt: ConstrainedDelaunayTriangulation<Point2<Real>> = ConstrainedDelaunayTriangulation::new();
    let mut handles: Vec<FixedVertexHandle> = Vec::with_capacity(polygon.len() + samples.len());
    for (k, p) in polygon.iter().chain(samples).enumerate() {
        let h = cdt
            .insert(Point2::new(p[0], p[1]))
            .map_err(|e| DivisionError::Triangulation { reason: format!("inserting cap point {k}: {e:?}") })?;
        if h.index() != k {
            // spade merges a point equal to an earlier one.
            return Err(DivisionError::CoincidentLoopNodes { a: h.index(), b: k });
        }
        handles.push(h);
    }
    let l = polygon.len();
    for i in 0..l {
        let (a, b) = (handles[i], handles[(i + 1) % l]);
        if cdt.can_add_constraint(a, b) {
            cdt.add_constraint(a, b);
        }
        if !cdt.exists_constraint(a, b) {
            return Err(DivisionError::LoopEdgeLost { a: i, b: (i + 1) % l });
        }
    }

    // Flood-fill the outside from the faces on the convex hull, never crossing a constraint.
    let mut outside = vec![false; cdt.num_all_faces()];
    let mut stack = Vec::new();
    for face in cdt.inner_faces() {
        let on_hull = face.adjacent_edges().iter().any(|e| !e.is_constraint_edge() && e.rev().face().is_outer());
        if on_hull {
            outside[face.fix().index()] = true;
            stack.push(face.fix());
        }
    }
    while let Some(f) = stack.pop() {
        for e in cdt.face(f).adjacent_edges() {
            if e.is_constraint_edge() {
                continue;
            }
            if let Some(g) = e.rev().face().as_inner()
                && !outside[g.fix().index()]
            {
                outside[g.fix().index()] = true;
                stack.push(g.fix());
            }
        }
    }
    let triangles: Vec<[u32; 3]> = cdt
        .inner_faces()
        .filter(|f| !outside[f.fix().index()])
        .map(|f| f.vertices().map(|v| v.fix().index() as u32))
        .collect();
    // A simple polygon with l nodes and k interior points has l + 2k − 2 triangles: anything else means
    // the loop is not simple in the plane or a point was lost.
    let expected = l + 2 * samples.len() - 2;
    if triangles.len() != expected {
        return Err(DivisionError::CapTriangleCount { expected, found: triangles.len() });
    }
    Ok(triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(side: Real) -> Vec<[Real; 2]> {
        vec![[0.0, 0.0], [side, 0.0], [side, side], [0.0, side]]
    }

    #[test]
    fn samples_are_spaced_inside_and_clear_of_the_boundary() {
        let poly = square(10.0);
        let s = poisson_disk_in_polygon(&poly, 3);
        // A maximal unit-spacing packing of the 9×9 usable square holds roughly 9²/0.7 ≈ 115 points.
        assert!(s.len() > 60 && s.len() < 140, "{}", s.len());
        for (i, p) in s.iter().enumerate() {
            assert!(inside(p, &poly));
            assert!(poly.iter().enumerate().all(|(k, a)| segment_dist2(p, a, &poly[(k + 1) % 4]) >= 0.25));
            for q in &s[..i] {
                assert!(dist2(p, q) >= 1.0);
            }
        }
    }

    #[test]
    fn square_cap_has_the_euler_count_of_triangles() {
        let poly = square(6.0);
        let s = poisson_disk_in_polygon(&poly, 9);
        let t = constrained_triangulation(&poly, &s).unwrap();
        assert_eq!(t.len(), 4 + 2 * s.len() - 2);
        // Counter-clockwise and summing to the square's area.
        let all: Vec<[Real; 2]> = poly.iter().chain(&s).copied().collect();
        let area: Real = t
            .iter()
            .map(|&[a, b, c]| {
                let [a, b, c] = [a, b, c].map(|i| all[i as usize]);
                let twice = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
                assert!(twice > 0.0);
                twice / 2.0
            })
            .sum();
        assert!((area - 36.0).abs() < 1e-9, "{area}");
    }

    #[test]
    fn concave_polygon_keeps_only_inside_triangles() {
        // An L shape: its convex hull holds a notch that must not be capped.
        let poly = vec![[0.0, 0.0], [6.0, 0.0], [6.0, 2.0], [2.0, 2.0], [2.0, 6.0], [0.0, 6.0]];
        let s = poisson_disk_in_polygon(&poly, 1);
        let t = constrained_triangulation(&poly, &s).unwrap();
        assert_eq!(t.len(), poly.len() + 2 * s.len() - 2);
    }
}
