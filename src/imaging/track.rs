//! Labels matched across the time points of a series by overlap: the cell that carries label 5 in
//! one frame and label 2 in the next is one track. Frames must be registered (on one grid, the
//! tissue not moved by more than a fraction of a cell between them).
//!
//! Each pair (previous label, current label) that share voxels is a candidate with its intersection
//! over union; candidates at or above `min_iou` are taken greedily, largest IoU first (ties by
//! label), each label at most once — the one-to-one matching that keeps the best overlaps. A current
//! label left over starts a new track; the previous label it overlaps most (by the fraction of its
//! own voxels) is recorded as its `parent`, which is what a division looks like (the larger
//! daughter continues the mother's track, the other starts one with the mother as parent).

use super::overlap::check_same_grid;
use super::{ImagingError, LabelVolume};
use crate::geometry::Real;
use ndarray::Axis;
use rayon::prelude::*;
use std::collections::{BTreeMap, BTreeSet};

/// One label of the current frame and the track it belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackedLabel {
    /// The label in the current frame's file.
    pub label: u32,
    /// The track: the previous frame's track it continues, or a new id.
    pub track: u32,
    /// The IoU with the previous frame's label it continues (`None` for a new track).
    pub iou: Option<Real>,
    /// For a new track, the previous frame's track overlapping it most (a division's mother, or a
    /// cell too changed to be matched); `None` when it overlaps nothing.
    pub parent: Option<u32>,
    /// Voxels with this label.
    pub voxels: u64,
}

/// The labels of one frame matched against the previous one.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameTracks {
    /// Every label of the current frame, in label order.
    pub labels: Vec<TrackedLabel>,
    /// Tracks of the previous frame that nothing continues (the cell left the field, died, or
    /// changed beyond `min_iou`).
    pub ended: Vec<u32>,
}

impl FrameTracks {
    /// Label of the current frame → its track.
    pub fn relabelling(&self) -> BTreeMap<u32, u32> {
        self.labels.iter().map(|l| (l.label, l.track)).collect()
    }

    /// The first frame of a series: every label is its own track.
    pub fn first(volume: &LabelVolume) -> FrameTracks {
        FrameTracks {
            labels: volume
                .label_stats()
                .into_iter()
                .map(|l| TrackedLabel { label: l.label, track: l.label, iou: None, parent: None, voxels: l.voxels })
                .collect(),
            ended: Vec::new(),
        }
    }
}

/// Matches the labels of `current` to `previous`, whose labels are already track ids (the previous
/// frame relabelled by its [`FrameTracks::relabelling`]). New tracks are numbered from
/// `*next_track` on, which is advanced. Both volumes must lie on one grid.
pub fn match_labels(
    previous: &LabelVolume,
    current: &LabelVolume,
    min_iou: Real,
    next_track: &mut u32,
) -> Result<FrameTracks, ImagingError> {
    if !(min_iou > 0.0 && min_iou <= 1.0) {
        return Err(ImagingError::Tracking(format!("min_iou = {min_iou}: give a value in (0, 1]")));
    }
    check_same_grid(
        previous,
        current,
        "match",
        "the frames of a series must share one grid (crop or resample them alike)",
    )?;
    // Voxels per (previous, current) pair and per label, one z slice at a time, merged in order.
    type Counts = (BTreeMap<(u32, u32), u64>, BTreeMap<u32, u64>, BTreeMap<u32, u64>);
    let per_slice: Vec<Counts> = previous
        .labels()
        .axis_iter(Axis(0))
        .into_par_iter()
        .zip(current.labels().axis_iter(Axis(0)).into_par_iter())
        .map(|(sp, sc)| {
            let (mut pairs, mut p, mut c) = Counts::default();
            for (&lp, &lc) in sp.iter().zip(sc.iter()) {
                if lp != 0 {
                    *p.entry(lp).or_insert(0) += 1;
                }
                if lc != 0 {
                    *c.entry(lc).or_insert(0) += 1;
                }
                if lp != 0 && lc != 0 {
                    *pairs.entry((lp, lc)).or_insert(0) += 1;
                }
            }
            (pairs, p, c)
        })
        .collect();
    let (mut pairs, mut prev_voxels, mut cur_voxels) = Counts::default();
    for (sp, p, c) in per_slice {
        for (k, n) in sp {
            *pairs.entry(k).or_insert(0) += n;
        }
        for (k, n) in p {
            *prev_voxels.entry(k).or_insert(0) += n;
        }
        for (k, n) in c {
            *cur_voxels.entry(k).or_insert(0) += n;
        }
    }
    let mut candidates: Vec<(Real, u32, u32)> = pairs
        .iter()
        .map(|(&(p, c), &shared)| {
            let union = prev_voxels[&p] + cur_voxels[&c] - shared;
            (shared as Real / union as Real, p, c)
        })
        .filter(|(iou, _, _)| *iou >= min_iou)
        .collect();
    candidates.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let (mut taken_prev, mut matched) = (BTreeSet::new(), BTreeMap::new());
    for (iou, p, c) in candidates {
        if !taken_prev.contains(&p) && !matched.contains_key(&c) {
            taken_prev.insert(p);
            matched.insert(c, (p, iou));
        }
    }
    *next_track = (*next_track).max(prev_voxels.keys().next_back().map_or(1, |m| m + 1));
    let labels = cur_voxels
        .iter()
        .map(|(&label, &voxels)| match matched.get(&label) {
            Some(&(track, iou)) => TrackedLabel { label, track, iou: Some(iou), parent: None, voxels },
            None => {
                let parent = pairs
                    .iter()
                    .filter(|((_, c), _)| *c == label)
                    .max_by(|a, b| a.1.cmp(b.1).then(b.0.0.cmp(&a.0.0)))
                    .map(|((p, _), _)| *p);
                let track = *next_track;
                *next_track += 1;
                TrackedLabel { label, track, iou: None, parent, voxels }
            }
        })
        .collect();
    let ended = prev_voxels.keys().filter(|p| !taken_prev.contains(p)).copied().collect();
    Ok(FrameTracks { labels, ended })
}

/// `volume` with every label replaced by `map[label]` (labels not in `map` kept).
pub fn relabel(volume: &LabelVolume, map: &BTreeMap<u32, u32>) -> LabelVolume {
    let mut out = volume.clone();
    out.labels_mut().par_mapv_inplace(|l| if l == 0 { 0 } else { map.get(&l).copied().unwrap_or(l) });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use ndarray::{Array3, s};

    fn volume(labels: Array3<u32>) -> LabelVolume {
        LabelVolume::new(labels, [1e-6; 3], Vec3::zeros()).unwrap()
    }

    /// Three cubes side by side along x (labels 1, 2, 3), each 4 voxels wide, shifted by `dx`.
    fn three(labels: [u32; 3], dx: usize) -> LabelVolume {
        let mut a = Array3::zeros((4, 4, 16));
        for (k, l) in labels.iter().enumerate() {
            a.slice_mut(s![.., .., dx + 4 * k..dx + 4 * k + 4]).fill(*l);
        }
        volume(a)
    }

    #[test]
    fn permuted_and_shifted_labels_are_matched_to_their_tracks() {
        let prev = three([1, 2, 3], 0);
        // The same cells moved by one voxel and renumbered 3 → 7, 1 → 3, 2 → 1.
        let cur = three([3, 1, 7], 1);
        let mut next = 4;
        let t = match_labels(&prev, &cur, 0.3, &mut next).unwrap();
        assert_eq!(t.relabelling(), BTreeMap::from([(1, 2), (3, 1), (7, 3)]));
        // A shift of a quarter of a cell: IoU 3/5.
        assert!(t.labels.iter().all(|l| (l.iou.unwrap() - 0.6).abs() < 1e-12), "{t:?}");
        assert!(t.ended.is_empty());
        assert_eq!(next, 4);
        let tracked = relabel(&cur, &t.relabelling());
        assert_eq!(tracked.labels()[[0, 0, 1]], 1);
        assert_eq!(tracked.labels()[[0, 0, 12]], 3);
        assert_eq!(tracked.labels()[[0, 0, 0]], 0);
    }

    #[test]
    fn a_division_continues_the_mother_in_its_larger_daughter_and_a_lost_cell_ends() {
        let prev = three([1, 2, 3], 0);
        let mut cur = three([1, 2, 0], 0);
        // Cell 2 divides: 3 of its 4 columns keep label 2, one becomes 9. Cell 3 is gone.
        cur.labels_mut().slice_mut(s![.., .., 7..8]).fill(9);
        let mut next = 4;
        let t = match_labels(&prev, &cur, 0.5, &mut next).unwrap();
        let by_label: BTreeMap<u32, &TrackedLabel> = t.labels.iter().map(|l| (l.label, l)).collect();
        assert_eq!(by_label[&2].track, 2);
        assert_eq!((by_label[&9].track, by_label[&9].parent, by_label[&9].iou), (4, Some(2), None));
        assert_eq!(t.ended, vec![3]);
        assert_eq!(next, 5);
        // Below min_iou the continuing daughter is a new track too (IoU 3/4 < 0.8).
        let mut next = 4;
        let strict = match_labels(&prev, &cur, 0.8, &mut next).unwrap();
        assert!(strict.labels.iter().filter(|l| l.label != 1).all(|l| l.iou.is_none() && l.parent == Some(2)));
        assert_eq!(strict.ended, vec![2, 3]);
    }

    #[test]
    fn frames_on_different_grids_and_bad_thresholds_are_refused() {
        let prev = three([1, 2, 3], 0);
        let other = volume(Array3::zeros((4, 4, 17)));
        let e = match_labels(&prev, &other, 0.3, &mut 4).unwrap_err().to_string();
        assert!(e.contains("cannot match") && e.contains("share one grid"), "{e}");
        let e = match_labels(&prev, &prev, 0.0, &mut 4).unwrap_err().to_string();
        assert!(e.contains("min_iou"), "{e}");
        let e = match_labels(&prev, &prev, Real::NAN, &mut 4).unwrap_err().to_string();
        assert!(e.contains("min_iou"), "{e}");
    }
}
