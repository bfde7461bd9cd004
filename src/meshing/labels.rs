//! A whole label volume → a tissue: every label (cell) meshed by [`mesh_mask`], in parallel.
//!
//! Per label, in ascending label order:
//! 1. **Filter**: labels with fewer than [`LabelMeshingOptions::min_voxels`] voxels are segmentation
//!    debris, and with [`BorderPolicy::Drop`] labels whose bounding box reaches the image border are
//!    cut cells: both are reported as dropped, with the reason.
//! 2. **Mesh**: the label's mask (bounding box + [`MASK_MARGIN`] voxels) goes to [`mesh_mask`] with one
//!    l_min for every cell (given, or [`default_l_min`] of the median volume of the labels to mesh, so
//!    that a typical cell gets [`LabelMeshingOptions::target_nodes`] nodes and all cells share one
//!    resolution, as the simulation's remeshing needs) and a seed derived from (seed, label). A
//!    [`MeshingError`] that a finer sampling may cure (the surface did not close, or encloses more
//!    than [`super::MAX_VOLUME_ERROR`] less than the voxels: typically a cell thinner than a few
//!    l_min) is retried at l_min/2, up to [`LabelMeshingOptions::max_refinements`] times; the cell's
//!    report then gives its own l_min and the errors at the coarser ones (on the PlantSeg ovule crop, 4
//!    of 44 cells, 106–606 voxels, need l_min/2 or l_min/4). The simulation's remeshing later brings
//!    such a cell's edges to the shared [l_min, 3·l_min]. A failure at the finest l_min drops that
//!    label with every attempt's error as the reason; it never aborts the others.
//! 3. **Kind**: labels in [`LabelMeshingOptions::lumen_labels`] become [`CellKind::Lumen`]; with
//!    [`BorderPolicy::Static`], border labels become [`CellKind::Static`] (boundary cells of an imaged
//!    patch, which the simulation holds fixed); the others are epithelial. Cell id = label; target
//!    volume = mesh volume; parameter set (`cell_type`) 2 for a lumen, 3 for a nucleus, else 0.
//!
//! 4. **Nuclei** ([`mesh_cells_and_nuclei`], optional): a second label volume on the same grid; each
//!    nucleus is meshed like a cell and becomes a [`CellKind::Nucleus`] cell with id label + the
//!    largest cell label, inside its host (the cell label holding most of its voxels). The
//!    simulation finds a nucleus's host as the cell containing its centroid, so that is checked.
//!
//! Labels are meshed with rayon, one task per label; results are collected in label order, and every
//! cell's mesh depends only on its mask, l_min and its own seed, so the tissue is identical whatever
//! the thread count.

use super::{DEFAULT_TARGET_NODES, MeshedCell, MeshingError, MeshingSettings, default_l_min, mesh_mask};
use crate::geometry::Real;
use crate::imaging::{BorderPolicy, DEFAULT_MIN_VOXELS, LabelInfo, LabelVolume};
use crate::mesh::{Cell, CellId, CellKind, Tissue, TissueError};
use ndarray::Axis;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};

/// Background voxels around each label's bounding box in the mask given to the mesher.
pub const MASK_MARGIN: usize = 2;

/// How to mesh a label volume: the options of `tissuefit mesh`, the pipeline's `[mesh]` and the
/// fit's `[observed.meshing]` (one struct; its field docs are the configuration reference's text).
#[derive(Clone, Debug, PartialEq, serde::Deserialize, serde::Serialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct LabelMeshingOptions {
    /// Minimum edge length l_min (m) of every cell. Default: chosen from `target_nodes` (the l_min
    /// at which the median-sized cell gets that many nodes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub l_min: Option<Real>,
    /// Nodes of a median-sized cell when l_min is chosen automatically. Default 400.
    pub target_nodes: usize,
    /// Labels with fewer voxels are dropped. Default 100.
    pub min_voxels: u64,
    /// Labels touching the image border: "keep" (default), "static" or "drop".
    pub border: BorderPolicy,
    /// Labels meshed as lumen cells. Default none.
    pub lumen_labels: Vec<u32>,
    /// Sampling seed; each label gets its own stream from (seed, label). Default 0 (in a pipeline:
    /// `input.seed`).
    pub seed: u64,
    /// Retries, each at half the previous l_min, of a cell that cannot be made valid at the shared
    /// l_min. Default 2 (down to l_min/4).
    pub max_refinements: u32,
    /// Denoise the label volume before meshing: each voxel takes the label with the largest
    /// Gaussian-weighted vote within 2σ, σ = this many voxels (of the largest edge). For masks whose
    /// boundaries are off by about a voxel (a segmentation's noise), 2 votes the bumps away while
    /// cells in contact stay in contact. A fit measures its simulated tissues through the same filter
    /// (`forward.measure_like_data`), so its own rounding of the cells cancels. Default: none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub denoise_voxels: Option<Real>,
}

/// Largest [`LabelMeshingOptions::denoise_voxels`]: beyond a few voxels the vote rounds cells of 10
/// voxels across into spheres.
pub const MAX_DENOISE_VOXELS: Real = 5.0;

/// Default of [`LabelMeshingOptions::max_refinements`].
pub const DEFAULT_MAX_REFINEMENTS: u32 = 2;

impl Default for LabelMeshingOptions {
    fn default() -> Self {
        Self {
            l_min: None,
            target_nodes: DEFAULT_TARGET_NODES,
            min_voxels: DEFAULT_MIN_VOXELS,
            border: BorderPolicy::Keep,
            lumen_labels: Vec::new(),
            seed: 0,
            max_refinements: DEFAULT_MAX_REFINEMENTS,
            denoise_voxels: None,
        }
    }
}

/// Errors that stop the whole volume (a single cell's failure is a dropped label instead).
#[derive(Debug, thiserror::Error)]
pub enum LabelMeshingError {
    #[error("l_min = {l_min} must be positive and finite")]
    InvalidLMin { l_min: Real },
    #[error("target_nodes must be at least 1")]
    InvalidTargetNodes,
    #[error(
        "denoise_voxels = {value} must lie in [0, {MAX_DENOISE_VOXELS}] (voxels; 2 for masks with about a voxel of \
         boundary noise)"
    )]
    InvalidDenoise { value: Real },
    #[error("denoising the labels: {0}")]
    Denoise(crate::imaging::ImagingError),
    #[error("the volume has no labels (every voxel is background, 0)")]
    NoLabels,
    #[error(
        "the nuclei volume is on another grid than the cells: {reason}; both must have the same shape, voxel size and origin"
    )]
    NucleiGrid { reason: String },
    #[error("nucleus label {label} + the largest cell label {offset} exceeds the largest cell id {max}")]
    NucleusIdOverflow { label: u32, offset: u32, max: u32 },
    #[error("stopped by the caller before every label was meshed")]
    Stopped,
    #[error(transparent)]
    Tissue(#[from] TissueError),
    #[error(transparent)]
    Anisotropy(#[from] crate::imaging::AnisotropyError),
}

/// What happened to one label.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum LabelStatus {
    /// Meshed as a free cell (epithelial, or lumen).
    Kept,
    /// Meshed as a static cell (border cell with [`BorderPolicy::Static`]).
    Static,
    /// Not in the tissue; see the reason.
    Dropped,
}

impl LabelStatus {
    pub fn name(self) -> &'static str {
        match self {
            LabelStatus::Kept => "kept",
            LabelStatus::Static => "static",
            LabelStatus::Dropped => "dropped",
        }
    }
}

/// One label's outcome (a row of `report.json`). Volumes in m³.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LabelReport {
    pub label: u32,
    pub status: LabelStatus,
    /// Why the label was dropped (or, for a static cell, why it is static); `None` for kept cells.
    pub reason: Option<String>,
    /// Cell kind in the tissue; `None` when dropped.
    pub kind: Option<CellKind>,
    /// Nodes of the mesh (0 when dropped).
    pub nodes: usize,
    /// Faces of the mesh (0 when dropped).
    pub faces: usize,
    /// Volume enclosed by the mesh; `None` when dropped.
    pub volume: Option<Real>,
    /// Voxels of the label × voxel volume (for a meshed cell: of its largest 6-connected component with
    /// enclosed cavities filled, the volume the mesh represents).
    pub voxel_volume: Real,
    /// Voxels of the label in the volume.
    pub voxels: u64,
    /// Whether the label's bounding box reaches the image border.
    pub touches_border: bool,
    /// Voxels of the label outside its largest 6-connected component (left out of the mesh).
    pub dropped_voxels: usize,
    /// The l_min (m) this cell was meshed with: the shared l_min, or a finer one when the cell could
    /// not be made valid at the shared one (see `refined_because`); `None` when not meshed.
    pub l_min: Option<Real>,
    /// Why the cell was retried at a finer l_min (the error at each coarser l_min); `None` when the
    /// shared l_min worked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub refined_because: Option<String>,
    /// Id of the cell in the tissue (the label for cells; the label + [`LabelMeshing::nucleus_id_offset`]
    /// for nuclei); `None` when dropped.
    pub cell_id: Option<u32>,
    /// For a nucleus: the label of the cell holding most of its voxels (its host); `None` for cells
    /// and for nuclei outside every cell.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub host: Option<u32>,
    /// For a kept nucleus: its nodes outside its host's surface (0 for a nucleus well inside; a few
    /// where the segmented nucleus touches the cell's membrane, which the contact model then pushes in).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nodes_outside_host: Option<usize>,
}

/// A meshed volume: the tissue (cells in ascending label order) and one report per label.
#[derive(Clone, Debug)]
pub struct LabelMeshing {
    pub tissue: Tissue,
    /// One entry per label of the volume, ascending.
    pub report: Vec<LabelReport>,
    /// The l_min (m) shared by the cells; `None` when no label passed the filters (and so no l_min was
    /// needed). A cell retried at a finer l_min reports its own in [`LabelReport::l_min`].
    pub l_min: Option<Real>,
    /// One entry per label of the nuclei volume, ascending (empty without one). Kept nuclei are
    /// [`CellKind::Nucleus`] cells of the tissue, after the cells, with id label + `nucleus_id_offset`.
    pub nuclei: Vec<LabelReport>,
    /// The largest label of the cell volume: nucleus ids start above it, so they never collide.
    pub nucleus_id_offset: u32,
}

impl LabelMeshing {
    /// Labels with this status.
    pub fn count(&self, status: LabelStatus) -> usize {
        self.report.iter().filter(|r| r.status == status).count()
    }
}

/// The seed of `label`'s sampling stream: a SplitMix64 mix of (seed, label), so neighbouring labels and
/// seeds give unrelated streams.
pub fn label_seed(seed: u64, label: u32) -> u64 {
    fn splitmix64(mut z: u64) -> u64 {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    splitmix64(seed ^ splitmix64(u64::from(label)))
}

/// Meshes every label of `volume`; see the module documentation.
pub fn mesh_labels(volume: &LabelVolume, options: &LabelMeshingOptions) -> Result<LabelMeshing, LabelMeshingError> {
    mesh_cells_and_nuclei(volume, None, options, &|_| true)
}

/// [`mesh_labels`], calling `on_label(label)` (from a worker thread) as each label is finished; when
/// it returns `false` the labels not yet started are left and the meshing ends with
/// [`LabelMeshingError::Stopped`].
pub fn mesh_labels_with_progress(
    volume: &LabelVolume,
    options: &LabelMeshingOptions,
    on_label: &(dyn Fn(u32) -> bool + Sync),
) -> Result<LabelMeshing, LabelMeshingError> {
    mesh_cells_and_nuclei(volume, None, options, on_label)
}

/// [`mesh_labels`] plus, with `nuclei` (a second label volume on the same grid), one
/// [`CellKind::Nucleus`] cell per nucleus label assigned to its host: the cell label holding most of
/// the nucleus's voxels. A nucleus is dropped, with the reason, when it has fewer than
/// `min_voxels` voxels, when most of it lies in background, when its host was not meshed or is not a
/// cell (a lumen), when it cannot be meshed, or when its mesh's centroid is not inside the host's
/// surface (the simulation finds a nucleus's host by that centroid). Nuclei use the cells' l_min (and
/// the same refinement); their seeds differ from the cells'. `on_label` is called for cells and nuclei;
/// its `false` stops the meshing ([`LabelMeshingError::Stopped`]).
pub fn mesh_cells_and_nuclei(
    volume: &LabelVolume,
    nuclei: Option<&LabelVolume>,
    options: &LabelMeshingOptions,
    on_label: &(dyn Fn(u32) -> bool + Sync),
) -> Result<LabelMeshing, LabelMeshingError> {
    if let Some(l_min) = options.l_min
        && !(l_min.is_finite() && l_min > 0.0)
    {
        return Err(LabelMeshingError::InvalidLMin { l_min });
    }
    if options.l_min.is_none() && options.target_nodes == 0 {
        return Err(LabelMeshingError::InvalidTargetNodes);
    }
    let denoised;
    let volume = match options.denoise_voxels {
        Some(value) if !(value.is_finite() && (0.0..=MAX_DENOISE_VOXELS).contains(&value)) => {
            return Err(LabelMeshingError::InvalidDenoise { value });
        }
        Some(value) if value > 0.0 => {
            denoised = crate::imaging::denoise_labels(volume, value).map_err(LabelMeshingError::Denoise)?.0;
            &denoised
        }
        _ => volume,
    };
    volume.grid().check_anisotropy()?;
    if let Some(n) = nuclei {
        check_same_grid(volume, n)?;
    }
    let shape = volume.shape();
    let voxel_volume = volume.voxel_volume();
    let mut stats = volume.label_stats();
    stats.sort_by_key(|s| s.label);
    if stats.is_empty() {
        return Err(LabelMeshingError::NoLabels);
    }
    let skip_reason = |info: &LabelInfo| -> Option<String> {
        if info.voxels < options.min_voxels {
            Some(format!("{} voxels, fewer than the minimum {}", info.voxels, options.min_voxels))
        } else if options.border == BorderPolicy::Drop && info.touches_border(shape) {
            Some("touches the image border (--border drop)".into())
        } else {
            None
        }
    };
    let mut to_mesh: Vec<u64> = stats.iter().filter(|s| skip_reason(s).is_none()).map(|s| s.voxels).collect();
    let l_min = match options.l_min {
        Some(l) => Some(l),
        None if to_mesh.is_empty() => None,
        None => {
            to_mesh.sort_unstable();
            let median = to_mesh[to_mesh.len() / 2] as Real * voxel_volume;
            default_l_min(median, options.target_nodes)
        }
    };

    let go_on = AtomicBool::new(true);
    let results: Vec<Option<(LabelReport, Option<Cell>)>> = stats
        .par_iter()
        .map(|info| {
            if !go_on.load(Ordering::Relaxed) {
                return None;
            }
            let result = mesh_one(volume, info, options, skip_reason(info), l_min);
            if !on_label(info.label) {
                go_on.store(false, Ordering::Relaxed);
            }
            Some(result)
        })
        .collect();
    if !go_on.load(Ordering::Relaxed) {
        return Err(LabelMeshingError::Stopped);
    }
    let mut cells = Vec::new();
    let mut report = Vec::with_capacity(results.len());
    for (r, cell) in results.into_iter().flatten() {
        report.push(r);
        cells.extend(cell);
    }
    let offset = stats.last().map_or(0, |s| s.label);
    let mut nucleus_reports = Vec::new();
    if let Some(nuclei) = nuclei {
        let (reports, nucleus_cells) = mesh_nuclei(volume, nuclei, &cells, options, l_min, offset, on_label)?;
        nucleus_reports = reports;
        cells.extend(nucleus_cells);
    }
    Ok(LabelMeshing {
        tissue: Tissue::from_cells(cells)?,
        report,
        l_min,
        nuclei: nucleus_reports,
        nucleus_id_offset: offset,
    })
}

fn check_same_grid(cells: &LabelVolume, nuclei: &LabelVolume) -> Result<(), LabelMeshingError> {
    let (a, b) = (cells.grid(), nuclei.grid());
    let um = |v: [Real; 3]| v.map(|x| x * 1e6);
    let reason = if a.shape != b.shape {
        format!("shape {:?} (z,y,x) vs {:?} for the cells", b.shape, a.shape)
    } else if a.voxel_size.iter().zip(&b.voxel_size).any(|(x, y)| (x - y).abs() > 1e-6 * x.abs()) {
        format!("voxel size {:?} µm (z,y,x) vs {:?} µm for the cells", um(b.voxel_size), um(a.voxel_size))
    } else if (a.origin - b.origin).norm() > 1e-6 * a.voxel_size.iter().copied().fold(0.0, Real::max) {
        format!("origin {:?} m vs {:?} m for the cells", b.origin.as_slice(), a.origin.as_slice())
    } else {
        return Ok(());
    };
    Err(LabelMeshingError::NucleiGrid { reason })
}

/// For every nucleus label: the cell labels under its voxels and how many, most frequent first
/// (ties: lower label first). One pass, z slices in parallel, merged in order.
fn host_votes(cells: &LabelVolume, nuclei: &LabelVolume) -> BTreeMap<u32, Vec<(u32, u64)>> {
    let per_slice: Vec<BTreeMap<(u32, u32), u64>> = nuclei
        .labels()
        .axis_iter(Axis(0))
        .into_par_iter()
        .zip(cells.labels().axis_iter(Axis(0)).into_par_iter())
        .map(|(n, c)| {
            let mut counts = BTreeMap::new();
            for (&nl, &cl) in n.iter().zip(c.iter()) {
                if nl != 0 {
                    *counts.entry((nl, cl)).or_insert(0u64) += 1;
                }
            }
            counts
        })
        .collect();
    let mut total: BTreeMap<(u32, u32), u64> = BTreeMap::new();
    for slice in per_slice {
        for (k, v) in slice {
            *total.entry(k).or_insert(0) += v;
        }
    }
    let mut votes: BTreeMap<u32, Vec<(u32, u64)>> = BTreeMap::new();
    for ((n, c), v) in total {
        votes.entry(n).or_default().push((c, v));
    }
    for list in votes.values_mut() {
        list.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
    }
    votes
}

fn mesh_nuclei(
    volume: &LabelVolume,
    nuclei: &LabelVolume,
    cells: &[Cell],
    options: &LabelMeshingOptions,
    l_min: Option<Real>,
    offset: u32,
    on_label: &(dyn Fn(u32) -> bool + Sync),
) -> Result<(Vec<LabelReport>, Vec<Cell>), LabelMeshingError> {
    let mut stats = nuclei.label_stats();
    stats.sort_by_key(|s| s.label);
    for s in &stats {
        if s.label.checked_add(offset).is_none_or(|id| id == u32::MAX) {
            return Err(LabelMeshingError::NucleusIdOverflow { label: s.label, offset, max: u32::MAX - 1 });
        }
    }
    let votes = host_votes(volume, nuclei);
    let nucleus_options = LabelMeshingOptions { seed: !options.seed, ..options.clone() };
    let go_on = AtomicBool::new(true);
    let results: Vec<Option<(LabelReport, Option<Cell>)>> = stats
        .par_iter()
        .map(|info| {
            if !go_on.load(Ordering::Relaxed) {
                return None;
            }
            let ranked = votes.get(&info.label).map(Vec::as_slice).unwrap_or(&[]);
            let (host_label, host_voxels) = ranked.first().copied().unwrap_or((0, 0));
            let share = host_voxels as Real / info.voxels.max(1) as Real;
            let host = cells.iter().find(|c| c.id() == CellId(host_label));
            let skip = if info.voxels < options.min_voxels {
                Some(format!("{} voxels, fewer than the minimum {}", info.voxels, options.min_voxels))
            } else if host_label == 0 {
                Some(format!("not inside any cell: {:.0} % of its voxels are background", 100.0 * share))
            } else if host.is_none() {
                Some(format!("inside label {host_label} ({:.0} % of its voxels), which was not meshed", 100.0 * share))
            } else if host.is_some_and(|h| !h.kind().is_cell()) {
                Some(format!("inside label {host_label}, a {} and not a cell", host.map_or("?", |h| h.kind().name())))
            } else {
                None
            };
            let (mut report, cell) = mesh_one(nuclei, info, &nucleus_options, skip, l_min);
            if !on_label(info.label) {
                go_on.store(false, Ordering::Relaxed);
            }
            report.kind = report.kind.map(|_| CellKind::Nucleus);
            if host_label != 0 {
                report.host = Some(host_label);
            }
            let Some(cell) = cell else { return Some((report, None)) };
            let host = host.expect("a meshed nucleus has a host");
            let centroid = cell.mesh().volume_centroid();
            if !centroid.is_some_and(|c| host.mesh().winding_number(&c) > 0.5) {
                drop_meshed(
                    &mut report,
                    format!("its centroid is not inside the surface of its host, label {host_label}"),
                );
                return Some((report, None));
            }
            let id = CellId(info.label + offset);
            report.nodes_outside_host =
                Some(cell.mesh().positions().iter().filter(|p| host.mesh().winding_number(p) <= 0.5).count());
            report.cell_id = Some(id.0);
            report.status = LabelStatus::Kept;
            report.reason = None;
            Some((report, Some(Cell::new(id, CellKind::Nucleus, cell_type_of(CellKind::Nucleus), cell.mesh().clone()))))
        })
        .collect();
    if !go_on.load(Ordering::Relaxed) {
        return Err(LabelMeshingError::Stopped);
    }
    let mut reports = Vec::with_capacity(results.len());
    let mut kept = Vec::new();
    for (r, cell) in results.into_iter().flatten() {
        reports.push(r);
        kept.extend(cell);
    }
    Ok((reports, kept))
}

/// Marks a meshed label as dropped after all, keeping its measured numbers.
fn drop_meshed(report: &mut LabelReport, reason: String) {
    report.status = LabelStatus::Dropped;
    report.reason = Some(reason);
    report.kind = None;
    report.cell_id = None;
}

/// Whether meshing at a finer l_min can cure this error: the sampled surface did not close into a
/// valid cell or does not represent the voxels (too few samples across a thin part).
fn finer_may_help(e: &MeshingError) -> bool {
    matches!(
        e,
        MeshingError::TooFewSamples { .. }
            | MeshingError::NoTriangles { .. }
            | MeshingError::Repair { .. }
            | MeshingError::VolumeMismatch { .. }
            | MeshingError::InvalidMesh { .. }
            | MeshingError::Remesh(_)
            | MeshingError::Mesh(_)
    )
}

fn mesh_one(
    volume: &LabelVolume,
    info: &LabelInfo,
    options: &LabelMeshingOptions,
    skip: Option<String>,
    l_min: Option<Real>,
) -> (LabelReport, Option<Cell>) {
    let touches_border = info.touches_border(volume.shape());
    let mut report = LabelReport {
        label: info.label,
        status: LabelStatus::Dropped,
        reason: None,
        kind: None,
        nodes: 0,
        faces: 0,
        volume: None,
        voxel_volume: info.voxels as Real * volume.voxel_volume(),
        voxels: info.voxels,
        touches_border,
        dropped_voxels: 0,
        l_min: None,
        refined_because: None,
        cell_id: None,
        host: None,
        nodes_outside_host: None,
    };
    if let Some(reason) = skip {
        report.reason = Some(reason);
        return (report, None);
    }
    let Some(l_min) = l_min else {
        // Unreachable in practice: l_min is only missing when no label is meshed.
        report.reason = Some("no l_min could be chosen".into());
        return (report, None);
    };
    let mask = volume.mask_of(info, MASK_MARGIN);
    let mut settings = MeshingSettings::new(l_min, volume.voxel_size());
    settings.seed = label_seed(options.seed, info.label);
    let mut failures: Vec<String> = Vec::new();
    let meshed: Result<MeshedCell, MeshingError> = loop {
        match mesh_mask(mask.mask.view(), mask.voxel_size, mask.origin, &settings) {
            Err(e) if finer_may_help(&e) && failures.len() < options.max_refinements as usize => {
                failures.push(format!("at l_min {:.4} µm: {e}", settings.l_min * 1e6));
                settings.l_min /= 2.0;
            }
            other => break other,
        }
    };
    match meshed {
        Err(e) => {
            failures.push(format!("at l_min {:.4} µm: {e}", settings.l_min * 1e6));
            report.reason = Some(format!("meshing failed {}", failures.join("; then ")));
            (report, None)
        }
        Ok(m) => {
            let kind = if options.lumen_labels.contains(&info.label) {
                CellKind::Lumen
            } else if options.border == BorderPolicy::Static && touches_border {
                CellKind::Static
            } else {
                CellKind::Epithelial
            };
            report.status = if kind == CellKind::Static { LabelStatus::Static } else { LabelStatus::Kept };
            if kind == CellKind::Static {
                report.reason = Some("touches the image border (--border static)".into());
            }
            report.kind = Some(kind);
            report.nodes = m.mesh.node_count();
            report.faces = m.mesh.face_count();
            report.volume = Some(m.mesh.signed_volume());
            report.voxel_volume = m.voxel_volume;
            report.dropped_voxels = m.dropped_voxels;
            report.l_min = Some(settings.l_min);
            report.cell_id = Some(info.label);
            if !failures.is_empty() {
                report.refined_because = Some(failures.join("; "));
            }
            let cell = Cell::new(CellId(info.label), kind, cell_type_of(kind), m.mesh);
            (report, Some(cell))
        }
    }
}

/// The parameter set (`[[cell_types]]` index) a meshed body gets. Lumens and nuclei get their kind's
/// code, as SimuCell3D inputs do and as the default parameter list is ordered (0 epithelial, 1 ECM,
/// 2 lumen, 3 nucleus, 4 static): a lumen with the cells' adhesion and tension, or a nucleus with the
/// cytoplasm's, would be silently wrong physics, and a parameter file without those sets is refused
/// by name instead. Static cells keep set 0: they do not move, and their surfaces should adhere like the
/// cells they stand in for.
fn cell_type_of(kind: CellKind) -> u32 {
    match kind {
        CellKind::Lumen | CellKind::Nucleus => kind.code(),
        CellKind::Epithelial | CellKind::Static | CellKind::Ecm => 0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_seeds_differ_between_labels_and_seeds() {
        let a = label_seed(0, 1);
        assert_ne!(a, label_seed(0, 2));
        assert_ne!(a, label_seed(1, 1));
        assert_eq!(a, label_seed(0, 1));
    }
}
