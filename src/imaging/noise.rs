//! Segmentation-like noise on the boundaries of a label volume, to measure how much a fit's answer
//! depends on where a segmenter put the boundaries (`tissuefit generate noise`).
//!
//! Real masks (Cellpose, PlantSeg, watershed) place a boundary within about a voxel of the true
//! interface, and that error varies along the surface. [`perturb_boundaries`] models it as a smooth
//! random displacement field **d**(x): three fields of white Gaussian noise, each blurred by a Gaussian
//! of standard deviation `correlation` voxels and scaled so that its root mean square over the volume is
//! `amplitude` voxels; the voxel at index i takes the label found at the nearest voxel to i + **d**(i).
//! Inside a cell every voxel nearby has the same label, so only the boundaries move: by `amplitude`
//! voxels (RMS) along each axis, with bumps about `correlation` voxels wide (0 = independent from voxel to
//! voxel, salt-and-pepper; 1–2 = the wavy boundaries of a segmentation). Background and cells are treated
//! alike, so cells gain and lose voxels at the medium as at their contacts. The field comes from a seeded
//! ChaCha8 stream: the same volume, settings and seed give the same volume on any thread count.
//!
//! [`denoise_labels`] is the remedy: a Gaussian-weighted majority vote over the labels, applied by the
//! meshing (`denoise_voxels`) to the observed volume and, in a fit, to every simulated tissue's voxels
//! alike.

use super::{ImagingError, LabelVolume, check_voxel_memory};
use crate::geometry::Real;
use ndarray::{Array3, Axis, Zip};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

/// How to perturb a label volume's boundaries (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundaryNoise {
    /// Root-mean-square displacement of the boundaries along each axis, in voxels (≥ 0; 1 = a typical
    /// segmentation's error).
    pub amplitude: Real,
    /// Standard deviation (voxels) of the Gaussian that smooths the displacement field: the width of
    /// the bumps (0 = independent per voxel).
    pub correlation: Real,
    /// Seed of the noise.
    pub seed: u64,
}

impl BoundaryNoise {
    /// Checks that amplitude and correlation are finite and in range.
    pub fn check(&self) -> Result<(), ImagingError> {
        if !(self.amplitude.is_finite() && (0.0..=10.0).contains(&self.amplitude)) {
            return Err(ImagingError::Generate(format!(
                "the noise amplitude {} voxels must lie in [0, 10] (about 1 for a typical segmentation)",
                self.amplitude
            )));
        }
        if !(self.correlation.is_finite() && (0.0..=20.0).contains(&self.correlation)) {
            return Err(ImagingError::Generate(format!(
                "the noise correlation {} voxels must lie in [0, 20] (1–2 for the wavy boundaries of a segmentation)",
                self.correlation
            )));
        }
        Ok(())
    }
}

/// How many voxels changed label, out of how many.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NoiseStats {
    pub changed: usize,
    pub voxels: usize,
}

/// A copy of `volume` with its boundaries displaced by `noise` (see the module documentation); the
/// grid (shape, voxel size, origin) is unchanged.
pub fn perturb_boundaries(
    volume: &LabelVolume,
    noise: &BoundaryNoise,
) -> Result<(LabelVolume, NoiseStats), ImagingError> {
    noise.check()?;
    let labels = volume.labels();
    let dim = labels.dim();
    // Two f64 fields at a time (the field and its blurred copy) plus the three rounded offsets (i8).
    check_voxel_memory(
        Some(labels.len() as u64),
        2 * 8 + 3,
        "the boundary-noise displacement field",
        "crop the volume",
    )?;
    let mut rng = ChaCha8Rng::seed_from_u64(noise.seed);
    let reach = (4.0 * noise.amplitude).ceil() as i64;
    let mut offsets: Vec<Array3<i8>> = Vec::with_capacity(3);
    for _ in 0..3 {
        let white = Array3::from_shape_simple_fn(dim, || StandardNormal.sample(&mut rng));
        let field = gaussian_blur(white, [1.0; 3], noise.correlation);
        let rms = (field.iter().map(|v| v * v).sum::<Real>() / field.len().max(1) as Real).sqrt();
        let scale = if rms > 0.0 { noise.amplitude / rms } else { 0.0 };
        offsets.push(field.mapv(|v| (v * scale).round().clamp(-reach as Real, reach as Real) as i8));
    }
    let (nz, ny, nx) = dim;
    let clamp = |i: usize, d: i8, n: usize| (i as i64 + d as i64).clamp(0, n as i64 - 1) as usize;
    let mut out = labels.clone();
    let mut changed = 0;
    for ((z, y, x), l) in out.indexed_iter_mut() {
        let source = [
            clamp(z, offsets[0][[z, y, x]], nz),
            clamp(y, offsets[1][[z, y, x]], ny),
            clamp(x, offsets[2][[z, y, x]], nx),
        ];
        let new = labels[source];
        if new != *l {
            *l = new;
            changed += 1;
        }
    }
    let stats = NoiseStats { changed, voxels: labels.len() };
    Ok((LabelVolume::new(out, volume.voxel_size(), volume.origin())?, stats))
}

/// Removes boundary noise from a label volume by a Gaussian-weighted vote: each voxel takes the label
/// (background included) with the largest sum of weights exp(−r²/2σ²) over the voxels within 2σ of it,
/// r measured in metres, σ = `sigma_voxels` × the largest voxel edge (so anisotropic voxels are
/// smoothed isotropically in space). A voxel keeps its label on a tie. The result is still a partition
/// of the grid, so two cells in contact stay in contact (blurring each cell's mask on its own opens a
/// gap between them where they meet the medium); bumps narrower than about σ are voted away, and a
/// convex free surface moves inward by about σ²/R, as under any smoothing. Returns the volume and how
/// many voxels changed label. `sigma_voxels = 0` is the identity.
pub fn denoise_labels(volume: &LabelVolume, sigma_voxels: Real) -> Result<(LabelVolume, usize), ImagingError> {
    if !(sigma_voxels.is_finite() && (0.0..=5.0).contains(&sigma_voxels)) {
        return Err(ImagingError::Generate(format!(
            "the denoising σ {sigma_voxels} voxels must lie in [0, 5] (about 2 for a voxel of boundary noise)"
        )));
    }
    let labels = volume.labels();
    if sigma_voxels == 0.0 {
        return Ok((volume.clone(), 0));
    }
    let size = volume.voxel_size();
    let sigma = sigma_voxels * size.iter().copied().fold(0.0, Real::max);
    let reach: [isize; 3] = std::array::from_fn(|a| (2.0 * sigma / size[a]).floor() as isize);
    // The stencil: offsets within 2σ and their weights.
    let mut stencil: Vec<([isize; 3], Real)> = Vec::new();
    for dz in -reach[0]..=reach[0] {
        for dy in -reach[1]..=reach[1] {
            for dx in -reach[2]..=reach[2] {
                let r2 =
                    (dz as Real * size[0]).powi(2) + (dy as Real * size[1]).powi(2) + (dx as Real * size[2]).powi(2);
                if r2 <= 4.0 * sigma * sigma {
                    stencil.push(([dz, dy, dx], (-r2 / (2.0 * sigma * sigma)).exp()));
                }
            }
        }
    }
    let (nz, ny, nx) = labels.dim();
    let n = [nz as isize, ny as isize, nx as isize];
    let rows: Vec<(Vec<u32>, usize)> = (0..nz)
        .into_par_iter()
        .map(|z| {
            let mut row = Vec::with_capacity(ny * nx);
            let mut changed = 0;
            let mut votes: Vec<(u32, Real)> = Vec::new();
            for y in 0..ny {
                for x in 0..nx {
                    let own = labels[[z, y, x]];
                    votes.clear();
                    let mut uniform = true;
                    for (d, w) in &stencil {
                        let p = [z as isize + d[0], y as isize + d[1], x as isize + d[2]];
                        if (0..3).any(|a| p[a] < 0 || p[a] >= n[a]) {
                            continue;
                        }
                        let l = labels[[p[0] as usize, p[1] as usize, p[2] as usize]];
                        uniform &= l == own;
                        match votes.iter_mut().find(|v| v.0 == l) {
                            Some(v) => v.1 += w,
                            None => votes.push((l, *w)),
                        }
                    }
                    let mut best = own;
                    if !uniform {
                        let own_weight = votes.iter().find(|v| v.0 == own).map_or(0.0, |v| v.1);
                        let mut top = own_weight;
                        for &(l, w) in &votes {
                            if w > top {
                                (best, top) = (l, w);
                            }
                        }
                    }
                    changed += usize::from(best != own);
                    row.push(best);
                }
            }
            (row, changed)
        })
        .collect();
    let changed = rows.iter().map(|r| r.1).sum();
    let flat: Vec<u32> = rows.into_iter().flat_map(|r| r.0).collect();
    let out = Array3::from_shape_vec((nz, ny, nx), flat).expect("one row per z slice");
    Ok((LabelVolume::new(out, size, volume.origin())?, changed))
}

/// How rough a label volume's boundaries are: the voxels that a vote of σ = 2 voxels
/// ([`denoise_labels`]) gives another label, per boundary voxel (one with a face neighbour of
/// another label, background included). A smooth boundary loses only the voxels its curvature
/// rounds off (about σ²/R deep); boundary noise adds its bumps, about in proportion to its
/// amplitude (a vote of σ = 1 saturates above half a voxel of noise). The value depends on the
/// cells' size as much as on the noise, so it says something only next to the same statistic of
/// shapes of the same size (a fit calibrates `forward.roughen_voxels` with it on its own relaxed
/// tissue). `None` for a volume without boundaries.
pub fn boundary_roughness(volume: &LabelVolume) -> Result<Option<Real>, ImagingError> {
    let labels = volume.labels();
    let (nz, ny, nx) = labels.dim();
    let boundary: usize = (0..nz)
        .into_par_iter()
        .map(|z| {
            let mut count = 0;
            for y in 0..ny {
                for x in 0..nx {
                    let own = labels[[z, y, x]];
                    let differs = |p: [usize; 3]| labels[p] != own;
                    let edge = (z > 0 && differs([z - 1, y, x]))
                        || (z + 1 < nz && differs([z + 1, y, x]))
                        || (y > 0 && differs([z, y - 1, x]))
                        || (y + 1 < ny && differs([z, y + 1, x]))
                        || (x > 0 && differs([z, y, x - 1]))
                        || (x + 1 < nx && differs([z, y, x + 1]));
                    count += usize::from(edge);
                }
            }
            count
        })
        .sum();
    if boundary == 0 {
        return Ok(None);
    }
    let (_, changed) = denoise_labels(volume, 2.0)?;
    Ok(Some(changed as Real / boundary as Real))
}

/// Separable Gaussian blur of standard deviation `sigma` (m) on a grid of voxel size `size` (z, y, x),
/// kernel truncated at 3σ, zero outside the array, and never longer than the axis (taps beyond it
/// never meet a voxel; an unbounded kernel on a strongly anisotropic grid did not fit in memory).
/// `sigma = 0` returns the field unchanged.
pub fn gaussian_blur(mut field: Array3<Real>, size: [Real; 3], sigma: Real) -> Array3<Real> {
    if sigma.is_nan() || sigma <= 0.0 {
        return field;
    }
    for (a, s) in size.iter().enumerate() {
        let longest = field.len_of(Axis(a)).saturating_sub(1) as Real;
        let radius = (3.0 * sigma / s).ceil().min(longest).max(0.0) as isize;
        let kernel: Vec<Real> =
            (-radius..=radius).map(|k| (-(k as Real * s).powi(2) / (2.0 * sigma * sigma)).exp()).collect();
        let total: Real = kernel.iter().sum();
        let kernel: Vec<Real> = kernel.iter().map(|w| w / total).collect();
        let mut out = Array3::<Real>::zeros(field.dim());
        Zip::from(out.lanes_mut(Axis(a))).and(field.lanes(Axis(a))).for_each(|mut o, f| {
            let n = f.len() as isize;
            for x in 0..n {
                let mut acc = 0.0;
                for (w, k) in kernel.iter().zip(-radius..=radius) {
                    let y = x + k;
                    if (0..n).contains(&y) {
                        acc += w * f[y as usize];
                    }
                }
                o[x as usize] = acc;
            }
        });
        field = out;
    }
    field
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;

    #[test]
    fn blur_preserves_mass_away_from_the_edges_and_zero_sigma_is_identity() {
        // Kernel radii: 3 voxels along z and y, 5 along x (3σ/s rounded up).
        let mut f = Array3::<Real>::zeros((13, 13, 13));
        f[[6, 6, 6]] = 1.0;
        let b = gaussian_blur(f.clone(), [1.0, 1.0, 0.5], 0.7);
        assert!((b.sum() - 1.0).abs() < 1e-12);
        assert!(b[[6, 6, 6]] < 1.0 && b[[6, 6, 7]] > b[[6, 7, 6]]);
        assert_eq!((b[[6, 6, 12]], b[[6, 10, 6]]), (0.0, 0.0));
        assert_eq!(gaussian_blur(f.clone(), [1.0; 3], 0.0), f);
    }

    #[test]
    fn roughness_grows_with_the_noise_and_a_flat_boundary_has_none() {
        let ball = Array3::from_shape_fn((28, 28, 28), |(z, y, x)| {
            let r2 = [z, y, x].iter().map(|&i| (i as Real - 13.5).powi(2)).sum::<Real>();
            u32::from(r2 <= 81.0)
        });
        let ball = LabelVolume::new(ball, [1e-6; 3], Vec3::zeros()).unwrap();
        let clean = boundary_roughness(&ball).unwrap().unwrap();
        let rough = |amplitude| {
            let (v, _) = perturb_boundaries(&ball, &BoundaryNoise { amplitude, correlation: 1.5, seed: 1 }).unwrap();
            boundary_roughness(&v).unwrap().unwrap()
        };
        let (half, one, two) = (rough(0.5), rough(1.0), rough(2.0));
        assert!(clean < half && half < one && one < two, "{clean} {half} {one} {two}");
        assert_eq!(boundary_roughness(&halves()).unwrap(), Some(0.0));
        let empty = LabelVolume::new(Array3::zeros((4, 4, 4)), [1e-6; 3], Vec3::zeros()).unwrap();
        assert_eq!(boundary_roughness(&empty).unwrap(), None);
    }

    /// Two half-spaces (labels 1 | 2) in a 24³ box.
    fn halves() -> LabelVolume {
        let labels = Array3::from_shape_fn((24, 24, 24), |(_, _, x)| if x < 12 { 1 } else { 2 });
        LabelVolume::new(labels, [1e-6; 3], Vec3::zeros()).unwrap()
    }

    #[test]
    fn only_boundaries_move_by_about_the_amplitude_and_the_seed_decides() {
        let v = halves();
        let noise = BoundaryNoise { amplitude: 1.0, correlation: 1.5, seed: 3 };
        let (a, stats) = perturb_boundaries(&v, &noise).unwrap();
        // Voxels more than 4 amplitudes from the interface keep their label.
        for ((_, _, x), l) in a.labels().indexed_iter() {
            if x < 8 {
                assert_eq!(*l, 1);
            } else if x >= 16 {
                assert_eq!(*l, 2);
            }
        }
        // The interface, one plane of 24² voxels, moves by ~1 voxel RMS: about 0.8 voxels changed per
        // column (E|round(N(0,1))| ≈ 0.76), so between 0.4 and 1.2 × 576.
        let per_column = stats.changed as Real / 576.0;
        assert!((0.4..1.2).contains(&per_column), "{per_column} changed voxels per column");
        assert_eq!(perturb_boundaries(&v, &noise).unwrap().0.labels(), a.labels());
        let other = perturb_boundaries(&v, &BoundaryNoise { seed: 4, ..noise }).unwrap().0;
        assert_ne!(other.labels(), a.labels());
        let none = perturb_boundaries(&v, &BoundaryNoise { amplitude: 0.0, ..noise }).unwrap();
        assert_eq!((none.0.labels(), none.1.changed), (v.labels(), 0));
    }

    #[test]
    fn the_vote_removes_specks_and_bumps_but_keeps_flat_boundaries_and_contacts() {
        let clean = halves();
        // A flat boundary is a fixed point.
        assert_eq!(denoise_labels(&clean, 1.0).unwrap().1, 0);
        let mut speckled = clean.clone();
        speckled.labels_mut()[[12, 12, 5]] = 2; // a speck inside cell 1
        speckled.labels_mut()[[12, 12, 12]] = 1; // a one-voxel bump into cell 2
        speckled.labels_mut()[[3, 3, 3]] = 0; // a hole of background
        let (voted, changed) = denoise_labels(&speckled, 1.0).unwrap();
        assert_eq!((voted.labels(), changed), (clean.labels(), 3));
        // Salt-and-pepper noise on the interface: the vote brings most of it back.
        let noise = BoundaryNoise { amplitude: 1.0, correlation: 0.0, seed: 7 };
        let (noisy, _) = perturb_boundaries(&clean, &noise).unwrap();
        let wrong = |v: &LabelVolume| v.labels().iter().zip(clean.labels()).filter(|(a, b)| a != b).count();
        let (voted, _) = denoise_labels(&noisy, 1.5).unwrap();
        assert!(
            wrong(&voted) * 4 < wrong(&noisy),
            "{} voxels wrong after the vote, {} before",
            wrong(&voted),
            wrong(&noisy)
        );
        // No background appears between the two cells: the result is still a partition into 1 and 2.
        assert!(voted.labels().iter().all(|&l| l == 1 || l == 2));
        assert!(denoise_labels(&clean, Real::NAN).unwrap_err().to_string().contains("denoising"));
    }

    #[test]
    fn amplitudes_and_correlations_out_of_range_are_refused() {
        let v = halves();
        for (amplitude, correlation) in [(Real::NAN, 1.0), (-1.0, 1.0), (11.0, 1.0), (1.0, Real::INFINITY), (1.0, -0.5)]
        {
            let e = perturb_boundaries(&v, &BoundaryNoise { amplitude, correlation, seed: 0 }).unwrap_err();
            assert!(e.to_string().contains("noise"), "{e}");
        }
    }
}
