//! `LabelVolume`: one integer label per voxel on a regular, possibly anisotropic grid, plus the
//! per-label queries the mesher needs (label list with bounding boxes, a padded binary mask of one
//! label, whether a label touches the volume border).
//!
//! Coordinate convention (used by every function of this module and by `meshing`):
//! - arrays are indexed `[z, y, x]` (page, row, column, as `tifffile.imread` returns them);
//! - voxel sizes are given in the same order, `[sz, sy, sx]`, in metres;
//! - mesh coordinates are `(x, y, z)` in metres; the **centre** of voxel `[k, j, i]` lies at
//!   `origin + (i·sx, j·sy, k·sz)`, where `origin` is the centre of voxel `[0, 0, 0]`;
//! - voxel `[k, j, i]` covers the box centre ± half a voxel along each axis.

use super::ImagingError;
use super::limits::check_voxel_memory;
use crate::geometry::{Real, Vec3};
use ndarray::{Array3, Axis, Zip, s};
use rayon::prelude::*;
use std::collections::HashMap;

/// A regular grid: shape `[nz, ny, nx]`, voxel size `[sz, sy, sx]` (m) and the position (x, y, z in
/// metres) of the centre of voxel `[0, 0, 0]`.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelGrid {
    pub shape: [usize; 3],
    pub voxel_size: [Real; 3],
    pub origin: Vec3,
}

impl VoxelGrid {
    /// A grid, checked: voxel sizes positive and finite, origin finite, no axis of length 0.
    pub fn new(shape: [usize; 3], voxel_size: [Real; 3], origin: Vec3) -> Result<Self, ImagingError> {
        let grid = Self { shape, voxel_size, origin };
        grid.check()?;
        Ok(grid)
    }

    pub(crate) fn check(&self) -> Result<(), ImagingError> {
        if !self.voxel_size.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(ImagingError::Grid(format!(
                "voxel size {:?} (z,y,x) m must be positive and finite",
                self.voxel_size
            )));
        }
        if !self.origin.iter().all(|c| c.is_finite()) {
            return Err(ImagingError::Grid(format!("origin {:?} must be finite", self.origin.as_slice())));
        }
        if self.shape.contains(&0) {
            return Err(ImagingError::Grid(format!("shape {:?} (z,y,x) has an empty axis", self.shape)));
        }
        self.shape
            .iter()
            .try_fold(1usize, |acc, &n| acc.checked_mul(n))
            .ok_or_else(|| ImagingError::Grid(format!("shape {:?} has too many voxels", self.shape)))?;
        Ok(())
    }

    /// The smallest grid with this voxel size whose voxel centres cover the box `[lo, hi]` (x,y,z m)
    /// with `margin` extra voxels on every side. Voxel centres are aligned to whole multiples of the
    /// voxel size, so grids of one voxel size built around different boxes share their voxel centres.
    pub fn covering(lo: Vec3, hi: Vec3, voxel_size: [Real; 3], margin: usize) -> Result<Self, ImagingError> {
        let size_xyz = [voxel_size[2], voxel_size[1], voxel_size[0]];
        let mut shape_xyz = [0usize; 3];
        let mut origin = Vec3::zeros();
        for a in 0..3 {
            let s = size_xyz[a];
            if !(s.is_finite() && s > 0.0 && lo[a].is_finite() && hi[a].is_finite() && lo[a] <= hi[a]) {
                return Err(ImagingError::Grid(format!(
                    "cannot cover the box {:?}..{:?} with voxel size {voxel_size:?}",
                    lo.as_slice(),
                    hi.as_slice()
                )));
            }
            let first = (lo[a] / s).floor() - margin as Real;
            let last = (hi[a] / s).ceil() + margin as Real;
            let n = last - first + 1.0;
            if !n.is_finite() || n >= 1e9 {
                return Err(ImagingError::Grid(format!(
                    "covering {}..{} m with {s} m voxels needs {n} voxels along one axis",
                    lo[a], hi[a]
                )));
            }
            shape_xyz[a] = n as usize;
            origin[a] = first * s;
        }
        Self::new([shape_xyz[2], shape_xyz[1], shape_xyz[0]], voxel_size, origin)
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    /// Whether the grid has no voxel (never true for a checked grid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Centre (x, y, z m) of voxel `[z, y, x]`; indices may lie outside the grid.
    pub fn voxel_centre(&self, index: [isize; 3]) -> Vec3 {
        let [sz, sy, sx] = self.voxel_size;
        self.origin + Vec3::new(index[2] as Real * sx, index[1] as Real * sy, index[0] as Real * sz)
    }

    /// Volume of one voxel (m³).
    pub fn voxel_volume(&self) -> Real {
        self.voxel_size.iter().product()
    }
}

/// Largest ratio of a grid's largest to its smallest voxel edge that meshing and measuring accept
/// ([`VoxelGrid::check_anisotropy`]). Both smooth the label masks isotropically in space over a
/// fraction of the *largest* edge (mesh σ = 0.35 ×, measure σ = 2 ×), so along the fine axes the
/// smoothing spans that ratio times as many voxels: at 20:1 the measure's σ is 40 fine voxels, about
/// the radius of a typical cell there. Beyond it the results are not merely less accurate but wrong
/// (the demo doublet measured with z stretched: sphericity 0.83 at 5:1, 0.90 at 20:1, 1.12 at 50:1,
/// above the bound of 1 that no shape exceeds; `mesh` finds no surface from 20:1 on). Resample
/// such a stack to more isotropic voxels first.
pub const MAX_ANISOTROPY: Real = 20.0;

/// A grid whose voxels are more anisotropic than [`MAX_ANISOTROPY`].
#[derive(Clone, Debug, PartialEq)]
pub struct AnisotropyError {
    /// `[sz, sy, sx]` m.
    pub voxel_size: [Real; 3],
    /// Largest edge / smallest edge.
    pub ratio: Real,
}

impl std::fmt::Display for AnisotropyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [z, y, x] = self.voxel_size.map(|s| {
            let um = s * 1e6;
            if (1e-3..1e6).contains(&um) { format!("{um:.4}") } else { format!("{um:.4e}") }
        });
        let ratio = if self.ratio < 1e6 { format!("{:.1}", self.ratio) } else { format!("{:.1e}", self.ratio) };
        write!(
            f,
            "voxel size {z} × {y} × {x} µm (z,y,x): the largest edge is {ratio} times the smallest, more than the \
             {MAX_ANISOTROPY} that meshing and measuring resolve (their smoothing, a fraction of the largest edge, \
             would span a whole cell along the finer axes); check the voxel size (--voxel-size, or the TIFF's \
             metadata) or resample the volume to more isotropic voxels"
        )
    }
}

impl std::error::Error for AnisotropyError {}

impl VoxelGrid {
    /// Largest voxel edge / smallest voxel edge (1 for cubic voxels).
    pub fn anisotropy(&self) -> Real {
        let largest = self.voxel_size.iter().copied().fold(0.0, Real::max);
        let smallest = self.voxel_size.iter().copied().fold(Real::INFINITY, Real::min);
        largest / smallest
    }

    /// Errs when [`VoxelGrid::anisotropy`] exceeds [`MAX_ANISOTROPY`] (or is not a number): the one
    /// check of `mesh` and `measure` on label volumes.
    pub fn check_anisotropy(&self) -> Result<(), AnisotropyError> {
        let ratio = self.anisotropy();
        if ratio <= MAX_ANISOTROPY {
            return Ok(());
        }
        Err(AnisotropyError { voxel_size: self.voxel_size, ratio })
    }
}

/// One label of a volume: how many voxels it has and its bounding box (inclusive voxel indices, z,y,x).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LabelInfo {
    pub label: u32,
    pub voxels: u64,
    pub min: [usize; 3],
    pub max: [usize; 3],
}

impl LabelInfo {
    /// Whether the bounding box reaches the border of a volume of this shape (the object is cut by the
    /// image boundary, so its surface there is not a real cell surface).
    pub fn touches_border(&self, shape: [usize; 3]) -> bool {
        (0..3).any(|a| self.min[a] == 0 || self.max[a] + 1 == shape[a])
    }

    fn merge(&mut self, other: &LabelInfo) {
        self.voxels += other.voxels;
        for a in 0..3 {
            self.min[a] = self.min[a].min(other.min[a]);
            self.max[a] = self.max[a].max(other.max[a]);
        }
    }
}

/// A binary mask of one label, cropped to its bounding box plus a margin (the margin may extend past
/// the volume; voxels there are `false`). What the mesher turns into a closed surface.
///
/// `mask[[k, j, i]]` is the voxel whose centre is `origin + (i·sx, j·sy, k·sz)` with
/// `voxel_size = [sz, sy, sx]`; it is voxel `offset + [k, j, i]` of the source volume.
#[derive(Clone, Debug, PartialEq)]
pub struct LabelMask {
    pub label: u32,
    pub mask: Array3<bool>,
    /// `[sz, sy, sx]` in metres.
    pub voxel_size: [Real; 3],
    /// Centre (x, y, z m) of mask voxel `[0, 0, 0]`.
    pub origin: Vec3,
    /// Index (z, y, x) in the source volume of mask voxel `[0, 0, 0]` (negative when the margin
    /// extends past the volume).
    pub offset: [isize; 3],
}

impl LabelMask {
    /// Number of `true` voxels.
    pub fn count(&self) -> usize {
        self.mask.iter().filter(|&&b| b).count()
    }
}

/// A label volume: `labels[[z, y, x]]`, 0 = background, on a [`VoxelGrid`].
#[derive(Clone, Debug, PartialEq)]
pub struct LabelVolume {
    labels: Array3<u32>,
    voxel_size: [Real; 3],
    origin: Vec3,
}

impl LabelVolume {
    /// A volume from labels indexed `[z, y, x]`, voxel size `[sz, sy, sx]` (m) and the centre of
    /// voxel `[0, 0, 0]` (x, y, z m).
    pub fn new(labels: Array3<u32>, voxel_size: [Real; 3], origin: Vec3) -> Result<Self, ImagingError> {
        let (nz, ny, nx) = labels.dim();
        VoxelGrid::new([nz, ny, nx], voxel_size, origin)?;
        let labels = if labels.is_standard_layout() { labels } else { labels.as_standard_layout().into_owned() };
        Ok(Self { labels, voxel_size, origin })
    }

    /// An all-background volume on `grid`.
    pub fn zeros(grid: &VoxelGrid) -> Result<Self, ImagingError> {
        grid.check()?;
        let [nz, ny, nx] = grid.shape;
        check_voxel_memory(
            Some(grid.len() as u64),
            4,
            &format!("a label volume of {nz} × {ny} × {nx} voxels (z,y,x)"),
            "choose a coarser voxel size or a smaller grid",
        )?;
        Ok(Self { labels: Array3::zeros(grid.shape), voxel_size: grid.voxel_size, origin: grid.origin })
    }

    /// `32x128x128 (z,y,x), voxel 0.235 x 0.15 x 0.15 µm`, for messages.
    pub fn describe_grid(&self) -> String {
        let [nz, ny, nx] = self.shape();
        let [sz, sy, sx] = self.voxel_size().map(|s| s * 1e6);
        format!("{nz}x{ny}x{nx} (z,y,x), voxel {sz:.6} x {sy:.6} x {sx:.6} µm")
    }

    pub fn labels(&self) -> &Array3<u32> {
        &self.labels
    }
    pub fn labels_mut(&mut self) -> &mut Array3<u32> {
        &mut self.labels
    }
    pub fn into_labels(self) -> Array3<u32> {
        self.labels
    }
    /// `[nz, ny, nx]`.
    pub fn shape(&self) -> [usize; 3] {
        let (nz, ny, nx) = self.labels.dim();
        [nz, ny, nx]
    }
    /// `[sz, sy, sx]` in metres.
    pub fn voxel_size(&self) -> [Real; 3] {
        self.voxel_size
    }
    /// Centre (x, y, z m) of voxel `[0, 0, 0]`.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }
    /// Changes the voxel size (e.g. a caller's override of the file's metadata).
    pub fn set_voxel_size(&mut self, voxel_size: [Real; 3]) -> Result<(), ImagingError> {
        VoxelGrid::new(self.shape(), voxel_size, self.origin)?;
        self.voxel_size = voxel_size;
        Ok(())
    }
    /// Moves the grid.
    pub fn set_origin(&mut self, origin: Vec3) -> Result<(), ImagingError> {
        VoxelGrid::new(self.shape(), self.voxel_size, origin)?;
        self.origin = origin;
        Ok(())
    }
    /// The grid of this volume.
    pub fn grid(&self) -> VoxelGrid {
        VoxelGrid { shape: self.shape(), voxel_size: self.voxel_size, origin: self.origin }
    }
    /// Volume of one voxel (m³).
    pub fn voxel_volume(&self) -> Real {
        self.voxel_size.iter().product()
    }
    /// Largest label (0 for an all-background volume).
    pub fn max_label(&self) -> u32 {
        self.labels.as_slice().map_or(0, |s| s.par_iter().copied().max().unwrap_or(0))
    }

    /// Every non-zero label with its voxel count and bounding box, sorted by label; one pass over the
    /// volume (z slices in parallel, merged in z order, so the result does not depend on threads).
    pub fn label_stats(&self) -> Vec<LabelInfo> {
        let per_slice: Vec<HashMap<u32, LabelInfo>> = self
            .labels
            .axis_iter(Axis(0))
            .into_par_iter()
            .enumerate()
            .map(|(z, slice)| {
                let mut map: HashMap<u32, LabelInfo> = HashMap::new();
                for (y, row) in slice.outer_iter().enumerate() {
                    // Runs of one label cost one map update.
                    let mut run: Option<(u32, usize)> = None;
                    let close = |map: &mut HashMap<u32, LabelInfo>, label: u32, start: usize, end: usize| {
                        if label != 0 {
                            let info = LabelInfo {
                                label,
                                voxels: (end - start) as u64,
                                min: [z, y, start],
                                max: [z, y, end - 1],
                            };
                            map.entry(label).and_modify(|e| e.merge(&info)).or_insert(info);
                        }
                    };
                    for (x, &label) in row.iter().enumerate() {
                        match run {
                            Some((l, _)) if l == label => {}
                            Some((l, start)) => {
                                close(&mut map, l, start, x);
                                run = Some((label, x));
                            }
                            None => run = Some((label, x)),
                        }
                    }
                    if let Some((l, start)) = run {
                        close(&mut map, l, start, row.len());
                    }
                }
                map
            })
            .collect();
        let mut all: HashMap<u32, LabelInfo> = HashMap::new();
        for map in per_slice {
            for (label, info) in map {
                all.entry(label).and_modify(|e| e.merge(&info)).or_insert(info);
            }
        }
        let mut list: Vec<LabelInfo> = all.into_values().collect();
        list.sort_unstable_by_key(|i| i.label);
        list
    }

    /// The volume's six outer voxel layers.
    fn border_sides(&self) -> [ndarray::ArrayView2<'_, u32>; 6] {
        let [nz, ny, nx] = self.shape();
        let l = &self.labels;
        [
            l.slice(s![0, .., ..]),
            l.slice(s![nz - 1, .., ..]),
            l.slice(s![.., 0, ..]),
            l.slice(s![.., ny - 1, ..]),
            l.slice(s![.., .., 0]),
            l.slice(s![.., .., nx - 1]),
        ]
    }

    /// Whether any voxel of `label` lies on the border of the volume (scans only the six faces).
    pub fn touches_border(&self, label: u32) -> bool {
        self.border_sides().iter().any(|v| v.iter().any(|&x| x == label))
    }

    /// Every label (not 0) with a voxel on the border of the volume: the cells the image cuts.
    pub fn border_labels(&self) -> std::collections::BTreeSet<u32> {
        self.border_sides().iter().flat_map(|v| v.iter().copied()).filter(|&x| x != 0).collect()
    }

    /// Binary mask of `label` cropped to its bounding box plus `margin` voxels on every side;
    /// `None` when the label is absent. Scans the volume once; with many labels, call
    /// [`LabelVolume::label_stats`] once and then [`LabelVolume::mask_of`] per label.
    pub fn mask(&self, label: u32, margin: usize) -> Option<LabelMask> {
        let info = self.bounding_box(label)?;
        Some(self.mask_of(&info, margin))
    }

    /// Binary mask of `info.label` over `info`'s bounding box plus `margin` voxels on every side.
    pub fn mask_of(&self, info: &LabelInfo, margin: usize) -> LabelMask {
        let shape = self.shape();
        let m = margin as isize;
        let offset = [info.min[0] as isize - m, info.min[1] as isize - m, info.min[2] as isize - m];
        let dims = [0, 1, 2].map(|a| info.max[a] - info.min[a] + 1 + 2 * margin);
        let mut mask = Array3::from_elem(dims, false);
        // Part of the mask inside the volume, in volume and in mask indices.
        let lo = [0, 1, 2].map(|a| offset[a].max(0) as usize);
        let hi = [0, 1, 2].map(|a| ((offset[a] + dims[a] as isize) as usize).min(shape[a]));
        let src = self.labels.slice(s![lo[0]..hi[0], lo[1]..hi[1], lo[2]..hi[2]]);
        let mlo = [0, 1, 2].map(|a| (lo[a] as isize - offset[a]) as usize);
        let mhi = [0, 1, 2].map(|a| mlo[a] + hi[a] - lo[a]);
        let label = info.label;
        Zip::from(mask.slice_mut(s![mlo[0]..mhi[0], mlo[1]..mhi[1], mlo[2]..mhi[2]]))
            .and(&src)
            .for_each(|m, &l| *m = l == label);
        let origin = self.grid().voxel_centre(offset);
        LabelMask { label, mask, voxel_size: self.voxel_size, origin, offset }
    }

    fn bounding_box(&self, label: u32) -> Option<LabelInfo> {
        let mut info: Option<LabelInfo> = None;
        for ((z, y, x), &l) in self.labels.indexed_iter() {
            if l == label {
                let one = LabelInfo { label, voxels: 1, min: [z, y, x], max: [z, y, x] };
                match &mut info {
                    Some(i) => i.merge(&one),
                    None => info = Some(one),
                }
            }
        }
        info
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn volume() -> LabelVolume {
        let mut a = Array3::<u32>::zeros((4, 5, 6));
        a[[1, 1, 1]] = 7;
        a[[1, 2, 1]] = 7;
        a[[2, 2, 3]] = 7;
        a[[0, 4, 5]] = 3;
        a[[3, 0, 0]] = 3;
        LabelVolume::new(a, [2e-6, 1e-6, 0.5e-6], Vec3::new(10e-6, 20e-6, 30e-6)).unwrap()
    }

    #[test]
    fn label_stats_count_voxels_and_bound_them() {
        let v = volume();
        let stats = v.label_stats();
        assert_eq!(
            stats,
            vec![
                LabelInfo { label: 3, voxels: 2, min: [0, 0, 0], max: [3, 4, 5] },
                LabelInfo { label: 7, voxels: 3, min: [1, 1, 1], max: [2, 2, 3] },
            ]
        );
        assert!(stats[0].touches_border(v.shape()) && !stats[1].touches_border(v.shape()));
        assert!(v.touches_border(3) && !v.touches_border(7) && !v.touches_border(99));
        assert!(v.border_labels().contains(&3) && !v.border_labels().contains(&7));
        assert!(!v.border_labels().contains(&0));
        assert_eq!(v.max_label(), 7);
    }

    #[test]
    fn mask_is_padded_and_placed_on_the_voxel_centres() {
        let v = volume();
        let m = v.mask(7, 1).unwrap();
        assert_eq!(m.mask.dim(), (4, 4, 5));
        assert_eq!(m.offset, [0, 0, 0]);
        assert_eq!(m.count(), 3);
        assert!(m.mask[[1, 1, 1]] && m.mask[[1, 2, 1]] && m.mask[[2, 2, 3]]);
        // Mask voxel [k,j,i] = volume voxel offset + [k,j,i]; centres agree.
        assert_eq!(m.origin, v.grid().voxel_centre([0, 0, 0]));
        // A border label: the margin reaches outside the volume and is false there.
        let m = v.mask(3, 2).unwrap();
        assert_eq!(m.offset, [-2, -2, -2]);
        assert_eq!(m.mask.dim(), (8, 9, 10));
        assert_eq!(m.count(), 2);
        assert!(m.mask[[2, 6, 7]] && m.mask[[5, 2, 2]]);
        let c = v.grid().voxel_centre([-2, -2, -2]);
        assert!((m.origin - c).norm() < 1e-18);
        assert!((c - Vec3::new(10e-6 - 1e-6, 20e-6 - 2e-6, 30e-6 - 4e-6)).norm() < 1e-15);
        assert!(v.mask(99, 1).is_none());
    }

    #[test]
    fn covering_grid_contains_the_box_with_margin() {
        let g = VoxelGrid::covering(Vec3::new(0.1, -0.3, 2.0), Vec3::new(1.05, 0.3, 2.0), [0.5, 0.2, 0.1], 2).unwrap();
        let lo = g.voxel_centre([0, 0, 0]);
        let hi = g.voxel_centre([g.shape[0] as isize - 1, g.shape[1] as isize - 1, g.shape[2] as isize - 1]);
        assert!(lo.x <= 0.1 - 0.2 + 1e-12 && hi.x >= 1.05 + 0.2 - 1e-12, "{lo} {hi}");
        assert!(lo.y <= -0.3 - 0.4 + 1e-12 && hi.y >= 0.3 + 0.4 - 1e-12);
        assert!(lo.z <= 2.0 - 1.0 + 1e-12 && hi.z >= 2.0 + 1.0 - 1e-12);
        assert!(VoxelGrid::new([1, 0, 1], [1.0; 3], Vec3::zeros()).is_err());
        assert!(VoxelGrid::new([1, 1, 1], [1.0, -1.0, 1.0], Vec3::zeros()).is_err());
    }
}
