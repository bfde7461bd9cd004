//! Synthetic label volumes with known geometry, for tests and for trying the pipeline without data.
//!
//! All shapes are centred in the volume; `L` below is the smallest physical extent of the volume
//! (`min(nx·sx, ny·sy, nz·sz)`). A voxel is labelled when its centre is inside the shape.
//! - `sphere`: one ball of radius 0.35·L, label 1.
//! - `ellipsoid`: semi-axes 0.4·L, 0.3·L, 0.2·L along x, y, z, label 1.
//! - `cube`: an axis-aligned cube of edge 0.5·L, label 1.
//! - `doublet`: two balls of radius R, centres 1.5·R apart along x, their union split by the
//!   bisecting plane (a flat interface): label 1 at −x, 2 at +x.
//! - `aggregate`: N cells = Voronoi regions of N seeded random points inside a ball of radius 0.42·L
//!   (seeds at least a packing distance apart, rejection sampling from ChaCha8 seeded with `seed`);
//!   labels 1..=N. With `lumen`, a central ball of radius 0.4·(0.42·L) gets label N+1, reported as
//!   the lumen label, and seeds lie outside it.
//!
//! Deterministic for a seed, whatever the thread count (each voxel is computed independently).

use super::{ImagingError, LabelVolume, VoxelGrid};
use crate::geometry::{Real, Vec3};
use ndarray::{Axis, Zip};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Uniform};
use rayon::prelude::*;
use std::fmt;
use std::str::FromStr;

/// Which synthetic shape to generate.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LabelPattern {
    Sphere,
    Ellipsoid,
    Cube,
    Doublet,
    Aggregate,
}

impl LabelPattern {
    pub const ALL: [LabelPattern; 5] = [
        LabelPattern::Sphere,
        LabelPattern::Ellipsoid,
        LabelPattern::Cube,
        LabelPattern::Doublet,
        LabelPattern::Aggregate,
    ];

    pub fn name(self) -> &'static str {
        match self {
            LabelPattern::Sphere => "sphere",
            LabelPattern::Ellipsoid => "ellipsoid",
            LabelPattern::Cube => "cube",
            LabelPattern::Doublet => "doublet",
            LabelPattern::Aggregate => "aggregate",
        }
    }
}

impl fmt::Display for LabelPattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for LabelPattern {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| format!("unknown pattern `{s}`; one of {}", Self::ALL.map(|p| p.name()).join(", ")))
    }
}

/// What to generate.
#[derive(Clone, Debug, PartialEq)]
pub struct LabelSpec {
    pub pattern: LabelPattern,
    /// `[nz, ny, nx]`.
    pub shape: [usize; 3],
    /// `[sz, sy, sx]` (m).
    pub voxel_size: [Real; 3],
    /// Number of cells of an aggregate (ignored by the other patterns).
    pub cells: usize,
    /// Seed of the aggregate's random seeds.
    pub seed: u64,
    /// Whether an aggregate has a central lumen.
    pub lumen: bool,
}

/// A generated volume and what its labels are.
#[derive(Clone, Debug)]
pub struct GeneratedLabels {
    pub volume: LabelVolume,
    /// Cell labels (lumen excluded), ascending.
    pub cells: Vec<u32>,
    /// The lumen's label, if any.
    pub lumen: Option<u32>,
}

/// Generates a synthetic label volume; see the module documentation. Errors when the grid is invalid
/// or too coarse for every cell to get a voxel.
pub fn generate_labels(spec: &LabelSpec) -> Result<GeneratedLabels, ImagingError> {
    let grid = VoxelGrid::new(spec.shape, spec.voxel_size, Vec3::zeros())?;
    let [nz, ny, nx] = spec.shape;
    let [sz, sy, sx] = spec.voxel_size;
    let extent = Vec3::new(nx as Real * sx, ny as Real * sy, nz as Real * sz);
    let centre = grid.voxel_centre([nz as isize - 1, ny as isize - 1, nx as isize - 1]) / 2.0;
    let l = extent.min();
    let mut volume = LabelVolume::zeros(&grid)?;
    let mut lumen = None;
    let cells: Vec<u32> = match spec.pattern {
        LabelPattern::Sphere => {
            let r2 = (0.35 * l).powi(2);
            fill(&mut volume, |p| if (p - centre).norm_squared() <= r2 { 1 } else { 0 });
            vec![1]
        }
        LabelPattern::Ellipsoid => {
            let semi = Vec3::new(0.4, 0.3, 0.2) * l;
            fill(&mut volume, |p| if (p - centre).component_div(&semi).norm_squared() <= 1.0 { 1 } else { 0 });
            vec![1]
        }
        LabelPattern::Cube => {
            let h = 0.25 * l;
            fill(&mut volume, |p| if (p - centre).amax() <= h { 1 } else { 0 });
            vec![1]
        }
        LabelPattern::Doublet => {
            let r = (0.9 * extent.x / 3.5).min(0.4 * extent.y.min(extent.z));
            let half = Vec3::new(0.75 * r, 0.0, 0.0);
            let (c1, c2, r2) = (centre - half, centre + half, r * r);
            fill(&mut volume, |p| {
                let inside = (p - c1).norm_squared() <= r2 || (p - c2).norm_squared() <= r2;
                match (inside, p.x < centre.x) {
                    (false, _) => 0,
                    (true, true) => 1,
                    (true, false) => 2,
                }
            });
            vec![1, 2]
        }
        LabelPattern::Aggregate => {
            let n = spec.cells;
            if n == 0 || n > 1_000_000 {
                return Err(ImagingError::Generate(format!("an aggregate needs 1 to 1000000 cells, not {n}")));
            }
            let outer = 0.42 * l;
            let inner = if spec.lumen { 0.4 * outer } else { 0.0 };
            let seeds = seeds_in_shell(n, centre, inner, outer, spec.seed)?;
            let lumen_label = (n + 1) as u32;
            let (outer2, inner2) = (outer * outer, inner * inner);
            fill(&mut volume, |p| {
                let d2 = (p - centre).norm_squared();
                if d2 > outer2 {
                    0
                } else if d2 < inner2 {
                    lumen_label
                } else {
                    nearest(&seeds, &p) as u32 + 1
                }
            });
            if spec.lumen {
                lumen = Some(lumen_label);
            }
            (1..=n as u32).collect()
        }
    };
    // Every requested label must own a voxel.
    let present = volume.label_stats();
    let missing: Vec<u32> = cells
        .iter()
        .chain(lumen.iter())
        .copied()
        .filter(|l| present.binary_search_by_key(l, |i| i.label).is_err())
        .collect();
    if !missing.is_empty() {
        return Err(ImagingError::Generate(format!(
            "the grid {:?} is too coarse: {} of {} labels got no voxel (e.g. {}); use a larger shape or fewer cells",
            spec.shape,
            missing.len(),
            cells.len() + lumen.iter().count(),
            missing[0]
        )));
    }
    Ok(GeneratedLabels { volume, cells, lumen })
}

/// A nuclei volume for `cells`: for every label in `labels`, a ball around the label's voxel centroid
/// with radius `radius_fraction` × the radius of the sphere of the label's volume, but at most the
/// distance from the centroid to the nearest voxel of the label's boundary less 2.5 voxels (so the
/// nucleus stays clear of the cell's surface, as a nucleus inside its cell must, also once both are
/// meshed at a coarse l_min whose flat triangles cut the cell's corners); nucleus label =
/// cell label. Errors when `radius_fraction` is not in (0, 1), a listed label is absent, or a cell
/// is too thin around its centroid to hold a nucleus of one voxel.
pub fn generate_nuclei(
    cells: &LabelVolume,
    labels: &[u32],
    radius_fraction: Real,
) -> Result<LabelVolume, ImagingError> {
    if !(radius_fraction > 0.0 && radius_fraction < 1.0) {
        return Err(ImagingError::Generate(format!(
            "the nucleus radius fraction {radius_fraction} must lie in (0, 1)"
        )));
    }
    let grid = cells.grid();
    // Per label: sum of voxel centres and count, z slices in parallel, merged in order.
    let per_slice: Vec<std::collections::BTreeMap<u32, (Vec3, u64)>> = cells
        .labels()
        .axis_iter(Axis(0))
        .into_par_iter()
        .enumerate()
        .map(|(k, slice)| {
            let mut sums = std::collections::BTreeMap::new();
            for ((j, i), &l) in slice.indexed_iter() {
                if l != 0 {
                    let e = sums.entry(l).or_insert((Vec3::zeros(), 0u64));
                    e.0 += grid.voxel_centre([k as isize, j as isize, i as isize]);
                    e.1 += 1;
                }
            }
            sums
        })
        .collect();
    let mut total: std::collections::BTreeMap<u32, (Vec3, u64)> = std::collections::BTreeMap::new();
    for slice in per_slice {
        for (l, (s, n)) in slice {
            let e = total.entry(l).or_insert((Vec3::zeros(), 0));
            e.0 += s;
            e.1 += n;
        }
    }
    let voxel_volume = grid.voxel_volume();
    let mut centroids: std::collections::HashMap<u32, (Vec3, Real)> = std::collections::HashMap::new();
    for &l in labels {
        let (sum, n) =
            total.get(&l).copied().ok_or_else(|| ImagingError::Generate(format!("label {l} is not in the volume")))?;
        let r = radius_fraction * (3.0 * n as Real * voxel_volume / (4.0 * std::f64::consts::PI)).cbrt();
        centroids.insert(l, (sum / n as Real, r));
    }
    // Distance from each centroid to the nearest boundary voxel of its label (a voxel with a
    // 6-neighbour of another label, or on the volume's border), z slices in parallel.
    let source = cells.labels();
    let [nz, ny, nx] = cells.shape();
    let per_slice: Vec<std::collections::BTreeMap<u32, Real>> = (0..nz)
        .into_par_iter()
        .map(|k| {
            let mut nearest: std::collections::BTreeMap<u32, Real> = std::collections::BTreeMap::new();
            for j in 0..ny {
                for i in 0..nx {
                    let l = source[[k, j, i]];
                    let Some((c, _)) = centroids.get(&l) else { continue };
                    let other = |dk: isize, dj: isize, di: isize| {
                        let (a, b, e) = (k as isize + dk, j as isize + dj, i as isize + di);
                        a < 0
                            || b < 0
                            || e < 0
                            || a >= nz as isize
                            || b >= ny as isize
                            || e >= nx as isize
                            || source[[a as usize, b as usize, e as usize]] != l
                    };
                    let boundary = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
                        .into_iter()
                        .any(|(a, b, e)| other(a, b, e));
                    if boundary {
                        let dist = (grid.voxel_centre([k as isize, j as isize, i as isize]) - c).norm();
                        let entry = nearest.entry(l).or_insert(Real::INFINITY);
                        *entry = entry.min(dist);
                    }
                }
            }
            nearest
        })
        .collect();
    let mut nearest: std::collections::HashMap<u32, Real> = std::collections::HashMap::new();
    for slice in per_slice {
        for (l, d) in slice {
            let entry = nearest.entry(l).or_insert(Real::INFINITY);
            *entry = entry.min(d);
        }
    }
    let largest_voxel = grid.voxel_size.iter().copied().fold(0.0, Real::max);
    let mut balls: std::collections::HashMap<u32, (Vec3, Real)> = std::collections::HashMap::new();
    for &l in labels {
        let (c, r) = centroids[&l];
        let room = nearest.get(&l).copied().unwrap_or(Real::INFINITY) - 2.5 * largest_voxel;
        let r = r.min(room);
        if r < 0.5 * largest_voxel {
            return Err(ImagingError::Generate(format!(
                "cell {l} is too thin around its centroid to hold a nucleus ({:.3} µm of room)",
                room * 1e6
            )));
        }
        balls.insert(l, (c, r * r));
    }
    let mut nuclei = LabelVolume::zeros(&grid)?;
    nuclei.labels_mut().axis_iter_mut(Axis(0)).into_par_iter().enumerate().for_each(|(k, mut slice)| {
        Zip::indexed(&mut slice).for_each(|(j, i), v| {
            let l = source[[k, j, i]];
            if let Some((c, r2)) = balls.get(&l)
                && (grid.voxel_centre([k as isize, j as isize, i as isize]) - c).norm_squared() <= *r2
            {
                *v = l;
            }
        });
    });
    Ok(nuclei)
}

/// Sets every voxel to `f(centre)`, z slices in parallel.
fn fill(volume: &mut LabelVolume, f: impl Fn(Vec3) -> u32 + Sync) {
    let grid = volume.grid();
    volume.labels_mut().axis_iter_mut(Axis(0)).into_par_iter().enumerate().for_each(|(k, mut slice)| {
        Zip::indexed(&mut slice).for_each(|(j, i), v| *v = f(grid.voxel_centre([k as isize, j as isize, i as isize])));
    });
}

/// Index of the seed nearest to `p` (lowest index on ties).
fn nearest(seeds: &[Vec3], p: &Vec3) -> usize {
    let mut best = (Real::INFINITY, 0);
    for (i, s) in seeds.iter().enumerate() {
        let d = (s - p).norm_squared();
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

/// `n` points uniform in the shell `inner < r < outer` around `centre`, kept apart by a distance that
/// starts at 0.8× the mean spacing and shrinks when placement stalls.
fn seeds_in_shell(n: usize, centre: Vec3, inner: Real, outer: Real, seed: u64) -> Result<Vec<Vec3>, ImagingError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let unit = Uniform::new_inclusive(-1.0, 1.0).map_err(|e| ImagingError::Generate(e.to_string()))?;
    let shell = 4.0 / 3.0 * std::f64::consts::PI * (outer.powi(3) - inner.powi(3));
    let mut min_dist = 0.8 * (shell / n as Real).cbrt();
    let mut seeds: Vec<Vec3> = Vec::with_capacity(n);
    let mut failures = 0;
    while seeds.len() < n {
        let q = Vec3::new(unit.sample(&mut rng), unit.sample(&mut rng), unit.sample(&mut rng));
        let r = q.norm();
        if r > 1.0 || r * outer <= inner {
            continue;
        }
        let p = centre + q * outer;
        if seeds.iter().all(|s| (s - p).norm_squared() >= min_dist * min_dist) {
            seeds.push(p);
            failures = 0;
        } else {
            failures += 1;
            if failures > 1000 {
                min_dist *= 0.95;
                failures = 0;
            }
        }
    }
    Ok(seeds)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(pattern: LabelPattern) -> LabelSpec {
        LabelSpec { pattern, shape: [40, 48, 56], voxel_size: [1e-6, 0.5e-6, 0.5e-6], cells: 12, seed: 7, lumen: false }
    }

    #[test]
    fn sphere_volume_matches_the_ball() {
        let g =
            generate_labels(&LabelSpec { shape: [64, 64, 64], voxel_size: [1e-6; 3], ..spec(LabelPattern::Sphere) })
                .unwrap();
        let n = g.volume.label_stats()[0].voxels as Real;
        let r = 0.35 * 64.0;
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        // Voxel counting of a ball of radius 22.4 voxels: error well under 1 %.
        assert!((n - exact).abs() < 0.01 * exact, "{n} vs {exact}");
        assert!(!g.volume.touches_border(1));
    }

    #[test]
    fn doublet_has_a_flat_interface_and_two_equal_cells() {
        let g = generate_labels(&spec(LabelPattern::Doublet)).unwrap();
        let s = g.volume.label_stats();
        assert_eq!(g.cells, vec![1, 2]);
        assert_eq!(s.len(), 2);
        // Mirror images of each other about the bisecting plane (56 columns: the plane lies between
        // columns 27 and 28).
        assert_eq!(s[0].voxels, s[1].voxels);
        assert_eq!(s[0].max[2] + 1, s[1].min[2]);
    }

    #[test]
    fn aggregate_is_deterministic_and_marks_the_lumen() {
        let mut sp = spec(LabelPattern::Aggregate);
        sp.lumen = true;
        let a = generate_labels(&sp).unwrap();
        let b = generate_labels(&sp).unwrap();
        assert_eq!(a.volume.labels(), b.volume.labels());
        assert_eq!(a.lumen, Some(13));
        assert_eq!(a.cells, (1..=12).collect::<Vec<_>>());
        assert_eq!(a.volume.label_stats().len(), 13);
        sp.seed = 8;
        let c = generate_labels(&sp).unwrap();
        assert_ne!(a.volume.labels(), c.volume.labels());
        // Too coarse: 200 cells in a 6³ grid cannot all get a voxel.
        sp.shape = [6, 6, 6];
        sp.cells = 200;
        assert!(matches!(generate_labels(&sp), Err(ImagingError::Generate(_))));
    }
}
