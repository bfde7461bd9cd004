//! Overlap of two label volumes on one grid, label by label: the intersection over union (IoU) of the
//! voxel sets that carry the same label in both, and χ = 1 − IoU (the paper's cell deformation).
//! This is how a simulated tissue is compared with a segmentation (voxelise the tissue on the
//! segmentation's grid, then compare), and how meshing is checked (labels → mesh → voxelise).

use super::{ImagingError, LabelVolume};
use crate::geometry::Real;
use ndarray::Axis;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// The overlap of one label between a reference volume `a` and a volume `b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LabelOverlap {
    pub label: u32,
    /// Voxels with this label in `a`.
    pub voxels_a: u64,
    /// Voxels with this label in `b`.
    pub voxels_b: u64,
    /// Voxels with this label in both.
    pub shared: u64,
}

impl LabelOverlap {
    /// |A ∩ B| / |A ∪ B|; 0 when the label is in neither.
    pub fn iou(&self) -> Real {
        let union = self.voxels_a + self.voxels_b - self.shared;
        if union == 0 { 0.0 } else { self.shared as Real / union as Real }
    }

    /// Deformation χ = 1 − IoU.
    pub fn chi(&self) -> Real {
        1.0 - self.iou()
    }
}

/// An error unless `a` and `b` lie on the same grid (shape, voxel size and origin); `what` is the
/// verb the message uses ("compare", "match"), `remedy` what to do.
pub(crate) fn check_same_grid(a: &LabelVolume, b: &LabelVolume, what: &str, remedy: &str) -> Result<(), ImagingError> {
    let (ga, gb) = (a.grid(), b.grid());
    let same_origin = (ga.origin - gb.origin).norm() <= 1e-9 * ga.voxel_size.iter().copied().fold(0.0, Real::max);
    let same_size = ga.voxel_size.iter().zip(&gb.voxel_size).all(|(x, y)| (x - y).abs() <= 1e-9 * x.abs());
    if ga.shape != gb.shape || !same_origin || !same_size {
        return Err(ImagingError::Grid(format!(
            "cannot {what} label volumes on different grids: shape {:?} vs {:?}, voxel size {:?} vs {:?} m, origin {:?} vs {:?} m; {remedy}",
            ga.shape,
            gb.shape,
            ga.voxel_size,
            gb.voxel_size,
            ga.origin.as_slice(),
            gb.origin.as_slice()
        )));
    }
    Ok(())
}

/// Per-label overlap of every non-zero label found in `a` or `b`, sorted by label. Both volumes must
/// be on the same grid (shape, voxel size and origin); compare on a common grid by voxelising.
/// The count is one pass over both volumes, z slices in parallel, merged in order (thread-independent).
pub fn label_overlap(a: &LabelVolume, b: &LabelVolume) -> Result<Vec<LabelOverlap>, ImagingError> {
    check_same_grid(a, b, "compare", "voxelise one tissue on the other's grid first (`tissuefit voxelize --like`)")?;
    let per_slice: Vec<BTreeMap<u32, [u64; 3]>> = a
        .labels()
        .axis_iter(Axis(0))
        .into_par_iter()
        .zip(b.labels().axis_iter(Axis(0)).into_par_iter())
        .map(|(sa, sb)| {
            let mut counts: BTreeMap<u32, [u64; 3]> = BTreeMap::new();
            for (&la, &lb) in sa.iter().zip(sb.iter()) {
                if la != 0 {
                    counts.entry(la).or_default()[0] += 1;
                }
                if lb != 0 {
                    counts.entry(lb).or_default()[1] += 1;
                }
                if la != 0 && la == lb {
                    counts.entry(la).or_default()[2] += 1;
                }
            }
            counts
        })
        .collect();
    let mut total: BTreeMap<u32, [u64; 3]> = BTreeMap::new();
    for slice in per_slice {
        for (label, c) in slice {
            let t = total.entry(label).or_default();
            for i in 0..3 {
                t[i] += c[i];
            }
        }
    }
    Ok(total
        .into_iter()
        .map(|(label, [voxels_a, voxels_b, shared])| LabelOverlap { label, voxels_a, voxels_b, shared })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use ndarray::Array3;

    fn volume(labels: Array3<u32>) -> LabelVolume {
        LabelVolume::new(labels, [1e-6; 3], Vec3::zeros()).unwrap()
    }

    #[test]
    fn overlap_counts_shared_voxels_per_label() {
        let mut a = Array3::zeros((2, 2, 4));
        let mut b = Array3::zeros((2, 2, 4));
        // Label 1: 4 voxels in a, 4 in b, 2 shared → IoU 2/6. Label 2 only in b.
        a.slice_mut(ndarray::s![0, .., 0..2]).fill(1);
        b.slice_mut(ndarray::s![0, 0, 0..4]).fill(1);
        b[[1, 1, 3]] = 2;
        let o = label_overlap(&volume(a), &volume(b)).unwrap();
        assert_eq!(o.len(), 2);
        assert_eq!(o[0], LabelOverlap { label: 1, voxels_a: 4, voxels_b: 4, shared: 2 });
        assert!((o[0].iou() - 2.0 / 6.0).abs() < 1e-15);
        assert_eq!(o[1], LabelOverlap { label: 2, voxels_a: 0, voxels_b: 1, shared: 0 });
        assert_eq!(o[1].chi(), 1.0);
    }

    #[test]
    fn identical_volumes_have_iou_one_and_different_grids_are_refused() {
        let mut a = Array3::zeros((3, 3, 3));
        a[[1, 1, 1]] = 7;
        a[[0, 0, 0]] = 3;
        let va = volume(a.clone());
        assert!(label_overlap(&va, &va).unwrap().iter().all(|o| o.iou() == 1.0));
        let shifted = LabelVolume::new(a, [1e-6; 3], Vec3::new(1e-6, 0.0, 0.0)).unwrap();
        let err = label_overlap(&va, &shifted).unwrap_err().to_string();
        assert!(err.contains("different grids"), "{err}");
    }
}
