//! An incremental hash grid over points for fixed-radius neighbour queries (sampling and ball
//! pivoting insert points one at a time, which the rebuild-only [`crate::geometry::SpatialGrid`]
//! does not do). Queries visit cubes in a fixed order and points in insertion order, so results do
//! not depend on hashing.

use crate::geometry::{Real, Vec3};
use std::collections::HashMap;

#[derive(Clone, Debug)]
pub(crate) struct PointGrid {
    inv: Real,
    cells: HashMap<[i64; 3], Vec<u32>>,
}

impl PointGrid {
    /// An empty grid of cubes with edge `cell_size` (> 0, finite; checked by the callers' settings).
    pub fn new(cell_size: Real) -> Self {
        Self { inv: 1.0 / cell_size, cells: HashMap::new() }
    }

    fn key(&self, p: &Vec3) -> [i64; 3] {
        [0, 1, 2].map(|a| (p[a] * self.inv).floor() as i64)
    }

    pub fn insert(&mut self, p: &Vec3, id: u32) {
        self.cells.entry(self.key(p)).or_default().push(id);
    }

    /// Calls `f(id)` for every inserted id whose cube overlaps the ball of radius `r` around `p`
    /// (a superset of the points within `r`; callers test the distance).
    pub fn for_each_near(&self, p: &Vec3, r: Real, mut f: impl FnMut(u32)) {
        let lo = self.key(&(p - Vec3::repeat(r)));
        let hi = self.key(&(p + Vec3::repeat(r)));
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    if let Some(ids) = self.cells.get(&[x, y, z]) {
                        ids.iter().for_each(|&i| f(i));
                    }
                }
            }
        }
    }

    /// Ids of the points of `points` within distance `r` of `p` (closed ball), ascending.
    pub fn within(&self, points: &[Vec3], p: &Vec3, r: Real, out: &mut Vec<u32>) {
        out.clear();
        let r2 = r * r;
        self.for_each_near(p, r, |i| {
            if (points[i as usize] - p).norm_squared() <= r2 {
                out.push(i);
            }
        });
        out.sort_unstable();
    }

    /// Whether some point of `points` lies strictly closer than `r` to `p`.
    pub fn any_closer(&self, points: &[Vec3], p: &Vec3, r: Real) -> bool {
        let r2 = r * r;
        let mut found = false;
        self.for_each_near(p, r, |i| found |= (points[i as usize] - p).norm_squared() < r2);
        found
    }
}
