//! From a binary mask to the scalar field whose 0.5 level is the cell surface: crop to the mask's
//! bounding box, pad, keep the largest 6-connected component, fill enclosed cavities, blur.

use super::MeshingError;
use crate::geometry::{Real, Vec3};
use ndarray::ArrayView3;

/// A scalar field on a regular grid, stored x-fastest: `values[x + nx·(y + ny·z)]`.
#[derive(Clone, Debug)]
pub(crate) struct Field {
    /// Grid size in (x, y, z).
    pub dims: [usize; 3],
    /// Voxel edge (m) in (x, y, z).
    pub spacing: [Real; 3],
    /// Physical position (m) of the centre of grid point (0, 0, 0).
    pub origin: Vec3,
    pub values: Vec<f32>,
}

impl Field {
    #[inline]
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// Physical position of grid point (x, y, z), fractional coordinates allowed.
    #[inline]
    pub fn position(&self, x: Real, y: Real, z: Real) -> Vec3 {
        self.origin + Vec3::new(x * self.spacing[0], y * self.spacing[1], z * self.spacing[2])
    }

    /// The grid cell holding the physical point `p` (its lowest corner) and the fractional position
    /// inside it; `None` outside the grid or on a grid thinner than two points along an axis.
    fn locate(&self, p: &Vec3) -> Option<([usize; 3], [Real; 3])> {
        let mut cell = [0usize; 3];
        let mut t = [0.0; 3];
        for a in 0..3 {
            let g = (p[a] - self.origin[a]) / self.spacing[a];
            if !(g >= 0.0 && g <= (self.dims[a] - 1) as Real) || self.dims[a] < 2 {
                return None;
            }
            cell[a] = (g.floor() as usize).min(self.dims[a] - 2);
            t[a] = g - cell[a] as Real;
        }
        Some((cell, t))
    }

    /// Trilinearly interpolated value and its gradient (per metre) at the physical point `p`;
    /// `None` outside the grid.
    pub fn sample(&self, p: &Vec3) -> Option<(Real, Vec3)> {
        let (cell, t) = self.locate(p)?;
        let v = |dx: usize, dy: usize, dz: usize| {
            Real::from(self.values[self.index(cell[0] + dx, cell[1] + dy, cell[2] + dz)])
        };
        let lerp = |a: Real, b: Real, s: Real| a + (b - a) * s;
        // Values on the four x-edges, then the two y-lines, then z.
        let e =
            [[v(0, 0, 0), v(1, 0, 0)], [v(0, 1, 0), v(1, 1, 0)], [v(0, 0, 1), v(1, 0, 1)], [v(0, 1, 1), v(1, 1, 1)]];
        let x = e.map(|[a, b]| lerp(a, b, t[0]));
        let dx = e.map(|[a, b]| b - a);
        let (y0, y1) = (lerp(x[0], x[1], t[1]), lerp(x[2], x[3], t[1]));
        let value = lerp(y0, y1, t[2]);
        let gx = lerp(lerp(dx[0], dx[1], t[1]), lerp(dx[2], dx[3], t[1]), t[2]);
        let gy = lerp(x[1] - x[0], x[3] - x[2], t[2]);
        let gz = y1 - y0;
        Some((value, Vec3::new(gx / self.spacing[0], gy / self.spacing[1], gz / self.spacing[2])))
    }

    /// Smooth gradient (per metre) at `p`: central differences at the grid points, interpolated
    /// trilinearly (the trilinear interpolant's own gradient is one-sided at cell faces). `None`
    /// outside the grid.
    pub fn smooth_gradient(&self, p: &Vec3) -> Option<Vec3> {
        let (cell, t) = self.locate(p)?;
        let at = |c: [usize; 3]| Real::from(self.values[self.index(c[0], c[1], c[2])]);
        let mut gradient = Vec3::zeros();
        for corner in 0..8 {
            let c = [0, 1, 2].map(|a| cell[a] + ((corner >> a) & 1));
            let w: Real = (0..3).map(|a| if (corner >> a) & 1 == 1 { t[a] } else { 1.0 - t[a] }).product();
            for a in 0..3 {
                let (mut lo, mut hi) = (c, c);
                lo[a] = c[a].saturating_sub(1);
                hi[a] = (c[a] + 1).min(self.dims[a] - 1);
                let d = (at(hi) - at(lo)) / ((hi[a] - lo[a]) as Real * self.spacing[a]);
                gradient[a] += w * d;
            }
        }
        Some(gradient)
    }

    /// Moves `p` onto the level `level` of the interpolated field by Newton steps along the gradient
    /// (each at most one voxel); returns the point and the unit outward normal (down the smooth
    /// gradient).
    /// `None` when the gradient vanishes, the point leaves the grid or ends more than two voxels away.
    pub fn project_to_level(&self, p: &Vec3, level: Real) -> Option<(Vec3, Vec3)> {
        let largest = self.spacing.iter().copied().fold(0.0, Real::max);
        let smallest = self.spacing.iter().copied().fold(Real::INFINITY, Real::min);
        let mut q = *p;
        for _ in 0..8 {
            let (f, g) = self.sample(&q)?;
            let g2 = g.norm_squared();
            if g2 == 0.0 || !g2.is_finite() {
                return None;
            }
            let mut step = g * ((f - level) / g2);
            let len = step.norm();
            if len > largest {
                step *= largest / len;
            }
            q -= step;
            if len < 1e-6 * smallest {
                break;
            }
        }
        let (f, _) = self.sample(&q)?;
        let close = (f - level).abs() < 1e-4 && (q - p).norm() <= 2.0 * largest;
        let normal = (-self.smooth_gradient(&q)?).try_normalize(0.0)?;
        close.then_some((q, normal))
    }
}

/// What preparing the mask found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct MaskStats {
    /// Voxels of the kept (largest 6-connected) component, before cavity filling.
    pub voxels: usize,
    /// Foreground voxels dropped because they lie in smaller components.
    pub dropped_voxels: usize,
    /// Background voxels enclosed by the cell and filled in.
    pub filled_voxels: usize,
}

/// Builds the field: the indicator of the largest 6-connected component of `mask` (indexed
/// `[z, y, x]`), its enclosed cavities filled, blurred by a Gaussian of standard deviation `sigma`
/// (m; 0 = none), on a grid padded so that the field is below 0.5 on the whole border.
pub(crate) fn prepare_field(
    mask: ArrayView3<bool>,
    voxel_size: [Real; 3],
    origin: Vec3,
    sigma: Real,
) -> Result<(Field, MaskStats), MeshingError> {
    // (x, y, z) order from here on.
    let spacing = [voxel_size[2], voxel_size[1], voxel_size[0]];
    let (sz, sy, sx) = mask.dim();
    let mut lo = [usize::MAX; 3];
    let mut hi = [0usize; 3];
    let mut any = false;
    for ((z, y, x), &v) in mask.indexed_iter() {
        if v {
            any = true;
            for (a, c) in [x, y, z].into_iter().enumerate() {
                lo[a] = lo[a].min(c);
                hi[a] = hi[a].max(c);
            }
        }
    }
    if !any {
        return Err(MeshingError::EmptyMask { shape: [sz, sy, sx] });
    }
    // Padding: the blur kernel's reach plus two voxels of background on every side. The reach is
    // sized in floating point and checked before any cast: on a strongly anisotropic grid σ (a
    // fraction of the largest voxel) spans more grid steps along the fine axes than any grid holds.
    let reach_steps = spacing.map(|s| if sigma > 0.0 { (3.0 * sigma / s).ceil() } else { 0.0 });
    let padded = [0, 1, 2].map(|a| (hi[a] - lo[a] + 1) as Real + 2.0 * (reach_steps[a] + 2.0));
    if !padded.iter().all(|n| n.is_finite()) || padded.iter().product::<Real>() > MAX_GRID_POINTS as Real {
        let axis = (1..3).fold(0, |widest, a| if reach_steps[a] > reach_steps[widest] { a } else { widest });
        return Err(MeshingError::SmoothingTooWide {
            sigma,
            axis: ["x", "y", "z"][axis],
            steps: sigma / spacing[axis],
            fine: spacing[axis],
            coarse: spacing.iter().copied().fold(0.0, Real::max),
            max: MAX_GRID_POINTS,
        });
    }
    let pad = reach_steps.map(|r| r as usize + 2);
    let dims = [0, 1, 2].map(|a| hi[a] - lo[a] + 1 + 2 * pad[a]);
    let cells = dims[0].checked_mul(dims[1]).and_then(|n| n.checked_mul(dims[2]));
    let Some(cells) = cells.filter(|&n| n <= MAX_GRID_POINTS) else {
        return Err(MeshingError::TooLarge { dims, max: MAX_GRID_POINTS });
    };
    let idx = |x: usize, y: usize, z: usize| x + dims[0] * (y + dims[1] * z);
    let mut inside = vec![false; cells];
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                if mask[[z, y, x]] {
                    inside[idx(x - lo[0] + pad[0], y - lo[1] + pad[1], z - lo[2] + pad[2])] = true;
                }
            }
        }
    }
    let total = inside.iter().filter(|&&v| v).count();
    let kept = keep_largest_component(&mut inside, dims);
    let filled = fill_cavities(&mut inside, dims);
    let stats = MaskStats { voxels: kept, dropped_voxels: total - kept, filled_voxels: filled };

    let mut values: Vec<f32> = inside.iter().map(|&v| if v { 1.0 } else { 0.0 }).collect();
    if sigma > 0.0 {
        for (axis, s) in spacing.iter().enumerate() {
            blur_axis(&mut values, dims, axis, sigma / s);
        }
    }
    let first = [0, 1, 2].map(|a| lo[a] as Real - pad[a] as Real);
    let origin = origin + Vec3::new(first[0] * spacing[0], first[1] * spacing[1], first[2] * spacing[2]);
    Ok((Field { dims, spacing, origin, values }, stats))
}

/// Largest grid handled (points after cropping and padding): 512³, 128 Mi floats.
const MAX_GRID_POINTS: usize = 1 << 27;

/// The 6 face neighbours of a grid point, `None` outside the grid.
fn neighbours(i: usize, dims: [usize; 3]) -> impl Iterator<Item = usize> {
    let x = i % dims[0];
    let y = (i / dims[0]) % dims[1];
    let z = i / (dims[0] * dims[1]);
    let (sx, sy) = (1, dims[0]);
    let sz = dims[0] * dims[1];
    [
        (x > 0).then(|| i - sx),
        (x + 1 < dims[0]).then(|| i + sx),
        (y > 0).then(|| i - sy),
        (y + 1 < dims[1]).then(|| i + sy),
        (z > 0).then(|| i - sz),
        (z + 1 < dims[2]).then(|| i + sz),
    ]
    .into_iter()
    .flatten()
}

/// Labels the 6-connected components of `inside` and clears all but the largest (the first found
/// in index order wins a tie). Returns its voxel count.
fn keep_largest_component(inside: &mut [bool], dims: [usize; 3]) -> usize {
    let mut label = vec![u32::MAX; inside.len()];
    let mut sizes: Vec<usize> = Vec::new();
    let mut stack = Vec::new();
    for start in 0..inside.len() {
        if !inside[start] || label[start] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        let mut size = 0;
        label[start] = id;
        stack.push(start);
        while let Some(i) = stack.pop() {
            size += 1;
            for j in neighbours(i, dims) {
                if inside[j] && label[j] == u32::MAX {
                    label[j] = id;
                    stack.push(j);
                }
            }
        }
        sizes.push(size);
    }
    let (best, &size) = sizes.iter().enumerate().max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0))).expect("non-empty");
    for (v, &l) in inside.iter_mut().zip(&label) {
        *v = *v && l == best as u32;
    }
    size
}

/// Fills background not 6-connected to the grid border (cavities inside the cell); returns how many
/// voxels were filled. The border is background because of the padding.
fn fill_cavities(inside: &mut [bool], dims: [usize; 3]) -> usize {
    let mut outside = vec![false; inside.len()];
    let mut stack = vec![0usize];
    outside[0] = true;
    while let Some(i) = stack.pop() {
        for j in neighbours(i, dims) {
            if !inside[j] && !outside[j] {
                outside[j] = true;
                stack.push(j);
            }
        }
    }
    let mut filled = 0;
    for (v, &o) in inside.iter_mut().zip(&outside) {
        if !*v && !o {
            *v = true;
            filled += 1;
        }
    }
    filled
}

/// Convolves along one axis with a normalised Gaussian of standard deviation `sigma` grid steps,
/// truncated at 3σ. Outside the grid counts as 0 (the padding keeps the cell away from the border).
/// The kernel never reaches further than the axis is long (taps beyond it never meet a grid point;
/// [`prepare_field`] pads by the full reach, so there it is never shortened), and a σ of no finite
/// positive width leaves the values as they are.
fn blur_axis(values: &mut [f32], dims: [usize; 3], axis: usize, sigma: Real) {
    let n = dims[axis];
    let steps = (3.0 * sigma).ceil();
    // NaN fails the comparison: no finite positive width, no blur.
    if steps.is_nan() || steps < 1.0 || n < 2 {
        return;
    }
    let reach = steps.min((n - 1) as Real) as isize;
    let mut kernel: Vec<f32> =
        (-reach..=reach).map(|d| (-(d * d) as Real / (2.0 * sigma * sigma)).exp() as f32).collect();
    let sum: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= sum);
    let stride = [1, dims[0], dims[0] * dims[1]][axis];
    let mut line = vec![0.0f32; n];
    for start in 0..values.len() {
        // Visit each line once, from the grid point whose coordinate along `axis` is 0.
        if !(start / stride).is_multiple_of(n) {
            continue;
        }
        for (k, l) in line.iter_mut().enumerate() {
            *l = values[start + k * stride];
        }
        for k in 0..n {
            let mut acc = 0.0f32;
            for (t, w) in kernel.iter().enumerate() {
                let j = k as isize + t as isize - reach;
                if (0..n as isize).contains(&j) {
                    acc += w * line[j as usize];
                }
            }
            values[start + k * stride] = acc;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;

    #[test]
    fn keeps_the_largest_component_and_fills_cavities() {
        let mut m = Array3::from_elem((9, 9, 9), false);
        // A hollow 5³ box (27-voxel cavity... the inner 3³) and a lone voxel far away.
        for z in 1..6 {
            for y in 1..6 {
                for x in 1..6 {
                    let shell = [x, y, z].iter().any(|&c| c == 1 || c == 5);
                    m[[z, y, x]] = shell;
                }
            }
        }
        m[[8, 8, 8]] = true;
        let (f, stats) = prepare_field(m.view(), [1.0; 3], Vec3::zeros(), 0.0).unwrap();
        assert_eq!(stats.voxels, 125 - 27);
        assert_eq!(stats.dropped_voxels, 1);
        assert_eq!(stats.filled_voxels, 27);
        assert_eq!(f.values.iter().filter(|&&v| v > 0.5).count(), 125);
        // Border of the padded grid is background.
        assert_eq!(f.values[0], 0.0);
    }

    #[test]
    fn blur_preserves_mass_and_origin_is_physical() {
        let mut m = Array3::from_elem((4, 5, 6), false);
        m[[2, 3, 4]] = true;
        let (f, _) = prepare_field(m.view(), [0.3, 0.2, 0.1], Vec3::new(1.0, 2.0, 3.0), 0.2).unwrap();
        let mass: f32 = f.values.iter().sum();
        assert!((mass - 1.0).abs() < 1e-4, "mass {mass}");
        // The voxel's centre in physical coordinates: origin + (4·0.1, 3·0.2, 2·0.3).
        let (best, _) = f.values.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap();
        let (x, y, z) = (best % f.dims[0], (best / f.dims[0]) % f.dims[1], best / (f.dims[0] * f.dims[1]));
        let p = f.position(x as Real, y as Real, z as Real);
        assert!((p - Vec3::new(1.4, 2.6, 3.6)).norm() < 1e-12, "{p}");
    }

    #[test]
    fn projection_lands_on_the_level_with_an_outward_normal() {
        let n = 21;
        let mut m = Array3::from_elem((n, n, n), false);
        let c = 10.0;
        for ((z, y, x), v) in m.indexed_iter_mut() {
            *v = ((x as Real - c).powi(2) + (y as Real - c).powi(2) + (z as Real - c).powi(2)).sqrt() <= 7.0;
        }
        let (f, _) = prepare_field(m.view(), [1.0; 3], Vec3::zeros(), 0.5).unwrap();
        let centre = Vec3::repeat(c);
        for dir in [Vec3::x(), Vec3::new(1.0, 1.0, 0.0).normalize(), Vec3::new(-1.0, 2.0, -2.0).normalize()] {
            let (q, normal) = f.project_to_level(&(centre + dir * 6.0), 0.5).unwrap();
            assert!((f.sample(&q).unwrap().0 - 0.5).abs() < 1e-4);
            assert!(((q - centre).norm() - 7.0).abs() < 0.6, "radius {}", (q - centre).norm());
            assert!(normal.dot(&dir) > 0.9, "normal {normal} vs {dir}: {}", normal.dot(&dir));
        }
        // Far outside the grid: no projection.
        assert!(f.project_to_level(&Vec3::repeat(-100.0), 0.5).is_none());
    }

    /// Regression: one voxel edge 10²⁰ times the others (a TIFF's `spacing=1e30`, a typo in
    /// `--voxel-size`) made σ span ~10²⁰ steps along the fine axes, and the kernel allocation
    /// panicked with "capacity overflow".
    #[test]
    fn smoothing_wider_than_any_grid_is_an_error_not_a_panic() {
        let m = Array3::from_elem((3, 3, 3), true);
        let voxel_size = [1e14, 4e-7, 4e-7];
        let sigma = 0.35 * 1e14;
        let err = prepare_field(m.view(), voxel_size, Vec3::zeros(), sigma).unwrap_err();
        assert!(matches!(err, MeshingError::SmoothingTooWide { axis: "x", .. }), "{err}");
        let text = err.to_string();
        assert!(text.contains("--voxel-size") && text.contains("1.000e14"), "{text}");
    }

    #[test]
    fn blur_kernel_is_bounded_by_the_axis() {
        // σ of 10¹⁸ steps on a 5-point axis: no allocation of 10¹⁸ taps; the kernel is cut at
        // the axis length (±4 steps, 9 equal taps) and the values stay finite.
        let dims = [5, 1, 1];
        let mut values = vec![0.0, 0.0, 1.0, 0.0, 0.0];
        blur_axis(&mut values, dims, 0, 1e18);
        assert!(values.iter().all(|v| (*v - 1.0 / 9.0).abs() < 1e-6), "{values:?}");
        // No width (0, NaN, negative, infinite) or a one-point axis: unchanged.
        for (sigma, n) in [(0.0, 3), (Real::NAN, 3), (-1.0, 3), (Real::INFINITY, 1)] {
            let mut values = vec![0.0, 1.0, 0.0][..n].to_vec();
            let before = values.clone();
            blur_axis(&mut values, [n, 1, 1], 0, sigma);
            assert_eq!(values, before, "σ = {sigma}");
        }
    }

    #[test]
    fn empty_mask_is_an_error() {
        let m = Array3::from_elem((3, 3, 3), false);
        assert!(matches!(prepare_field(m.view(), [1.0; 3], Vec3::zeros(), 0.0), Err(MeshingError::EmptyMask { .. })));
    }
}
