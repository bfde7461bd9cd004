//! An incremental hash grid over points for fixed-radius neighbour queries (sampling and ball
//! pivoting insert points one at a time, which the rebuild-only [`crate::geometry::SpatialGrid`]
//! does not do). Queries visit cubes in a fixed order and points in insertion order, so results do
//! not depend on hashing.
//!
//! A cube's three integer coordinates are packed into one `u64` (21 bits each, wrapping) and hashed
//! by a multiply-xorshift mix instead of SipHash over 24 bytes: a Poisson-disk candidate visits 27
//! cubes, and SipHash was most of the sampling's time. Cubes 2²¹ apart share a key; a query then
//! sees their points too, which is harmless, since every caller tests the distance (queries return
//! a superset of the points within reach) and no surface spans 2²¹ sample spacings.

use crate::geometry::{Real, Vec3};
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Hashes a packed cube key ([`PointGrid::key`]); only `write_u64` is used.
#[derive(Default)]
struct CubeHasher(u64);

impl Hasher for CubeHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, x: u64) {
        // SplitMix64's finaliser: every input bit moves the high bits (the table's control bytes)
        // and the low bits (its bucket).
        let mut z = (self.0 ^ x).wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        self.0 = z ^ (z >> 31);
    }

    fn finish(&self) -> u64 {
        self.0
    }
}

#[derive(Clone, Debug)]
pub(crate) struct PointGrid {
    inv: Real,
    cells: HashMap<u64, Vec<u32>, BuildHasherDefault<CubeHasher>>,
}

impl PointGrid {
    /// An empty grid of cubes with edge `cell_size` (> 0, finite; checked by the callers' settings).
    pub fn new(cell_size: Real) -> Self {
        Self { inv: 1.0 / cell_size, cells: HashMap::default() }
    }

    /// The integer coordinates of the cube holding `p`.
    fn cube(&self, p: &Vec3) -> [i64; 3] {
        [0, 1, 2].map(|a| (p[a] * self.inv).floor() as i64)
    }

    /// The hash key of a cube: its coordinates' low 21 bits each (see the module doc).
    fn key(c: [i64; 3]) -> u64 {
        const MASK: u64 = (1 << 21) - 1;
        ((c[0] as u64 & MASK) << 42) | ((c[1] as u64 & MASK) << 21) | (c[2] as u64 & MASK)
    }

    pub fn insert(&mut self, p: &Vec3, id: u32) {
        self.cells.entry(Self::key(self.cube(p))).or_default().push(id);
    }

    /// Calls `f(id)` for every inserted id whose cube overlaps the ball of radius `r` around `p`
    /// (a superset of the points within `r`; callers test the distance).
    pub fn for_each_near(&self, p: &Vec3, r: Real, mut f: impl FnMut(u32)) {
        let lo = self.cube(&(p - Vec3::repeat(r)));
        let hi = self.cube(&(p + Vec3::repeat(r)));
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    if let Some(ids) = self.cells.get(&Self::key([x, y, z])) {
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
