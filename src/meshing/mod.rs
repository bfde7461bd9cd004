//! From one cell's binary voxel mask to a closed triangle surface at a chosen resolution (paper,
//! Methods "Initial triangulation", Fig. S1): surface extraction → Poisson-disk sampling with minimum
//! spacing l_min → ball pivoting → hole filling → edge-length clean-up.
//!
//! [`mesh_mask`] runs, for one cell:
//!
//! 1. **Field** (`field.rs`): crop the mask (indexed `[z, y, x]`) to its bounding box, pad it (so
//!    cells touching the crop border get closed surfaces), keep the largest 6-connected component,
//!    fill enclosed cavities (a cell surface is genus 0 with nothing inside), and blur the 0/1
//!    indicator with a Gaussian of standard deviation [`MeshingSettings::smoothing`] (metres, so
//!    anisotropic voxels are blurred isotropically in space).
//! 2. **Surface** (`surface_nets.rs`): naive surface nets at level 0.5, in physical coordinates
//!    (voxel `(z, y, x)` centre = `origin + (x·sx, y·sy, z·sz)`), keeping the largest piece. It only
//!    guides sampling (where candidates are drawn, with what area weight).
//! 3. **Sampling** (`poisson.rs`): area-weighted dart throwing with minimum spacing l_min, seeded
//!    (ChaCha8) by [`MeshingSettings::seed`]; about 0.7 samples per l_min² of area. Each candidate
//!    is first projected by Newton steps onto the 0.5 level of the trilinearly interpolated field
//!    (the surface-nets facets are chords of it, ~1 % volume inside on a 10-voxel sphere), and takes
//!    the field's normal −∇f/|∇f|; the spacing test comes after the projection.
//! 4. **Ball pivoting** (`ball_pivot.rs`, Bernardini et al. 1999) on the oriented samples with radii
//!    [`MeshingSettings::ball_radii`] × l_min (default 1.2, 1.6, 2.2, 3.0; the reference program uses
//!    1.2·l_min): triangles have edges ≥ l_min because the samples are that far apart.
//! 5. **Repair** (`repair.rs`): remove pinched fans and stray pieces, fill the holes left (minimum
//!    angle ear clipping), orient outward, validate. If that fails (typically a handle: V − E + F = 0),
//!    steps 4–5 run again with pivoting that never joins two parts of one front, which keeps every
//!    piece a disk and so guarantees genus 0, at the price of a longer seam to fill
//!    ([`MeshedCell::without_joins`]).
//! 6. **Clean-up**: [`crate::mesh::remesh::remesh_cell`] with l_max = 3·l_min splits the long edges of
//!    hole fillings and flips slivers; the result must pass [`CellMesh::validate`].
//!
//! [`mesh_labels`] (`labels.rs`) runs this for every label of a volume, in parallel, and builds the tissue
//! (with [`mesh_cells_and_nuclei`], also nuclei from a second volume); [`retriangulate`]
//! (`retriangulate.rs`) voxelises a tissue read from a file and meshes it the same way.
//!
//! A cell that cannot be made valid is an `Err` naming the stage and the defect, never a silently
//! wrong mesh; so is a valid surface whose volume is more than [`MAX_VOLUME_ERROR`] off the voxel
//! volume. The function is deterministic (same mask, settings and seed → identical mesh) and
//! single-threaded: callers run cells in parallel with one seed per cell.
//!
//! Volume: the 0.5 level of a binary mask passes through the faces of the boundary voxels on flat
//! parts, so it encloses about the voxel-count volume; on curved parts it cuts the staircase corners
//! (smaller volume), and the Gaussian blur moves the level inward where the surface is convex (by
//! about σ²/R for mean curvature radius R). The samples lie on that level; the pivoted surface's
//! flat triangles are chords of it, which loses about 3·r_c²/(4R²) of the volume (r_c the triangle
//! circumradius): ≈ 1.5 % for a sphere with 400 nodes. Measured (tests/integration/meshing.rs) at ~400 nodes:
//! 97.8–98.1 % of the voxel-count volume for 8–17-voxel shapes, 98.4 % for a 40-voxel sphere
//! (99.7 % with 1800 nodes), 98.2–98.5 % for real C. elegans cells. Concave creases narrower than
//! the ball are bridged, not followed (random unions of 4–9-voxel balls: 95.8–97.9 %).

mod ball_pivot;
mod field;
mod generate;
mod interfaces;
mod labels;
mod point_grid;
mod poisson;
mod repair;
mod retriangulate;
mod surface_nets;

pub use generate::{
    BodyRow, ECM_GAP_PER_L_MIN, GenerateError, GeneratedTissue, GenerationSummary, KindCount, Penetration,
    TissueGeometry, TissueKind, TissueSpec, generate_tissue, max_penetration,
};
pub use labels::{
    DEFAULT_MAX_REFINEMENTS, LabelMeshing, LabelMeshingError, LabelMeshingOptions, LabelReport, LabelStatus,
    MASK_MARGIN, MAX_DENOISE_VOXELS, label_seed, mesh_cells_and_nuclei, mesh_labels, mesh_labels_with_progress,
};
// Which labels count as cells is `imaging`'s (measuring a label volume applies the same rules);
// re-exported here next to the meshing options that use it.
pub use crate::imaging::{BorderPolicy, DEFAULT_MIN_VOXELS};
pub use interfaces::label_interfaces;
pub use poisson::SurfaceSamples;
pub use retriangulate::{RetriangulateError, Retriangulation, VOXELS_PER_L_MIN, retriangulate};

use crate::geometry::{Real, Vec3};
use crate::mesh::remesh::{RemeshError, RemeshReport, RemeshSettings, remesh_cell};
use crate::mesh::{CellMesh, MeshDefect, MeshError};
use ndarray::ArrayView3;

/// Errors of meshing one cell.
#[derive(Debug, thiserror::Error)]
pub enum MeshingError {
    #[error("invalid meshing settings: {reason}")]
    InvalidSettings { reason: String },
    #[error("voxel size {voxel_size:?} (z, y, x) must be positive and finite")]
    InvalidVoxelSize { voxel_size: [Real; 3] },
    #[error("origin {origin:?} must be finite")]
    InvalidOrigin { origin: [Real; 3] },
    #[error("the mask of shape {shape:?} (z, y, x) has no voxel set")]
    EmptyMask { shape: [usize; 3] },
    #[error("the padded grid {dims:?} (x, y, z) exceeds {max} points")]
    TooLarge { dims: [usize; 3], max: usize },
    #[error(
        "the smoothing σ = {sigma:.3e} m spans {steps:.3e} voxels of {fine:.3e} m along {axis}, more than a grid \
         of {max} points holds: the voxel sizes ({coarse:.3e} m along the coarsest axis) differ by too much; \
         check the voxel size (--voxel-size, or the TIFF's metadata)"
    )]
    SmoothingTooWide { sigma: Real, axis: &'static str, steps: Real, fine: Real, coarse: Real, max: usize },
    #[error("the cell has {voxels} voxels; at least {min} are needed to mesh it")]
    TooFewVoxels { voxels: usize, min: usize },
    #[error("surface extraction found no surface")]
    NoSurface,
    #[error("only {samples} samples at spacing l_min = {l_min:e} m (need {min}): l_min is too large for this cell")]
    TooFewSamples { samples: usize, min: usize, l_min: Real },
    #[error("l_min = {l_min:e} m would give about {expected} nodes (at most {max}): choose a larger l_min")]
    ResolutionTooFine { l_min: Real, expected: usize, max: usize },
    #[error("ball pivoting produced no triangle from {samples} samples")]
    NoTriangles { samples: usize },
    #[error("closing the pivoted surface failed: {reason}")]
    Repair { reason: String },
    #[error(
        "the mesh encloses {mesh_volume:e} m³ but the voxels {voxel_volume:e} m³ (off by more than {max_error}): \
         l_min is too coarse for this shape"
    )]
    VolumeMismatch { mesh_volume: Real, voxel_volume: Real, max_error: Real },
    #[error("the mesh after {stage} is not a valid cell surface: {defect}")]
    InvalidMesh { stage: &'static str, defect: MeshDefect },
    #[error(transparent)]
    Remesh(#[from] RemeshError),
    #[error(transparent)]
    Mesh(#[from] MeshError),
}

/// Parameters of meshing one cell. Lengths in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshingSettings {
    /// Minimum edge length l_min (m) = minimum sample spacing; edges end in [l_min, 3·l_min]. No
    /// default: see [`default_l_min`].
    pub l_min: Real,
    /// Seed of the sampling stream. Default 0; give each cell its own (e.g. seed ⊕ label).
    pub seed: u64,
    /// Standard deviation (m) of the Gaussian blur of the mask before extraction; 0 = none. Default
    /// (from [`MeshingSettings::new`]) the larger of 0.35 × the largest voxel edge and
    /// [`SMOOTHING_PER_L_MIN`] × l_min. 0.35 voxel is enough to round the staircase (smooth normals,
    /// fewer pivoting holes on real cells) without moving flat boundaries; the inward shift of convex
    /// parts (≈ σ²/R) costs ~0.3 % of volume at R = 10 voxels, 0.5 × would cost ~0.7 %. When l_min
    /// spans many voxels, the samples still follow the voxel staircase of a slanted interface while
    /// the triangles between them do not, so two abutting cells cross each other by up to a voxel
    /// and more (real C. elegans cells, l_min 3–8 voxels: 1.05–1.44 voxels); blurring over a fixed
    /// fraction of l_min removes that (0.74 voxels) for ~0.3 % of volume. Away from the background,
    /// the blurred masks of two abutting cells sum to 1, so their 0.5 levels still coincide.
    pub smoothing: Real,
    /// Ball radii of the pivoting passes, in units of l_min, increasing. Default [1.2, 1.6, 2.2, 3.0].
    pub ball_radii: Vec<Real>,
    /// Sampling candidates per l_min² of surface area. Default 20 (more: closer to a maximal
    /// sampling, slower).
    pub candidates_per_area: Real,
}

impl MeshingSettings {
    /// Defaults for a given `l_min` (m) and voxel size (m, z, y, x).
    pub fn new(l_min: Real, voxel_size: [Real; 3]) -> Self {
        let largest = voxel_size.iter().copied().fold(0.0, Real::max);
        Self {
            l_min,
            seed: 0,
            smoothing: (0.35 * largest).max(SMOOTHING_PER_L_MIN * l_min),
            ball_radii: vec![1.2, 1.6, 2.2, 3.0],
            candidates_per_area: 20.0,
        }
    }

    /// Checks the documented ranges.
    pub fn check(&self) -> Result<(), MeshingError> {
        let reason = if !(self.l_min.is_finite() && self.l_min > 0.0) {
            format!("l_min = {} must be positive and finite", self.l_min)
        } else if !(self.smoothing.is_finite() && self.smoothing >= 0.0) {
            format!("smoothing = {} must be finite and ≥ 0", self.smoothing)
        } else if self.ball_radii.is_empty()
            || self.ball_radii.iter().any(|r| !(r.is_finite() && *r >= 0.5))
            || self.ball_radii.windows(2).any(|w| w[1] <= w[0])
        {
            format!("ball_radii = {:?} must be increasing, finite and ≥ 0.5 (units of l_min)", self.ball_radii)
        } else if !(self.candidates_per_area.is_finite() && (1.0..=1000.0).contains(&self.candidates_per_area)) {
            format!("candidates_per_area = {} must lie in [1, 1000]", self.candidates_per_area)
        } else {
            return Ok(());
        };
        Err(MeshingError::InvalidSettings { reason })
    }
}

/// Default blur per l_min: see [`MeshingSettings::smoothing`].
pub const SMOOTHING_PER_L_MIN: Real = 0.15;

/// Samples (and so, nodes) per l_min² of surface area of the dart-throwing sampler (random
/// sequential adsorption of disks of diameter l_min covers ≈ 55 % of the plane: 0.547·4/π ≈ 0.70).
pub const NODES_PER_LMIN2: Real = 0.70;

/// Nodes a typical cell should get by default: a few hundred, as in the paper's simulations.
pub const DEFAULT_TARGET_NODES: usize = 400;

/// An l_min (m) giving about `target_nodes` nodes to a cell of volume `volume` (m³), from the area
/// of the sphere of that volume, A = (36π V²)^(1/3), and nodes ≈ 0.70·A/l_min². Elongated or
/// irregular cells have more area, hence more nodes. `None` for a non-positive volume or target.
pub fn default_l_min(volume: Real, target_nodes: usize) -> Option<Real> {
    if !(volume.is_finite() && volume > 0.0) || target_nodes == 0 {
        return None;
    }
    let area = (36.0 * std::f64::consts::PI * volume * volume).cbrt();
    Some((NODES_PER_LMIN2 * area / target_nodes as Real).sqrt())
}

/// One meshed cell and how it was made.
#[derive(Clone, Debug)]
pub struct MeshedCell {
    /// The closed, outward, genus-0 surface (metres), passing [`CellMesh::validate`].
    pub mesh: CellMesh,
    /// Volume (m³) of the kept voxels (largest component, cavities filled) × voxel volume.
    pub voxel_volume: Real,
    /// Voxels of the largest 6-connected component.
    pub voxels: usize,
    /// Foreground voxels dropped (smaller components).
    pub dropped_voxels: usize,
    /// Enclosed background voxels filled in.
    pub filled_voxels: usize,
    /// Vertices of the extracted (surface-nets) surface.
    pub surface_vertices: usize,
    /// Volume (m³) enclosed by the extracted surface (the level set the samples lie on).
    pub surface_volume: Real,
    /// Poisson-disk samples.
    pub samples: usize,
    /// Seed triangles of the ball pivoting.
    pub seeds: usize,
    /// Triangles added by the pivoting pass with each radius.
    pub faces_per_radius: Vec<usize>,
    /// Passes after the first (larger radii) that added triangles.
    pub radius_escalations: usize,
    /// Samples left out of the surface (not reached by any ball, or on a removed piece).
    pub unused_samples: usize,
    /// Whether the surface came from the fallback pivoting without joins (the first attempt's
    /// surface could not be closed into a valid cell).
    pub without_joins: bool,
    /// Faces removed as pinched fans or stray pieces.
    pub removed_faces: usize,
    /// Holes filled, their largest boundary (edges), and the faces added.
    pub holes_filled: usize,
    pub largest_hole: usize,
    pub hole_faces: usize,
    /// What the final remeshing did.
    pub remesh: RemeshReport,
}

/// Ball pivoting, repair and validation of the sampled surface (steps 4–5 of the module doc).
fn pivot_and_close(
    samples: &SurfaceSamples,
    radii: &[Real],
    joins: bool,
) -> Result<(CellMesh, ball_pivot::PivotStats, repair::RepairStats), MeshingError> {
    let (faces, pivot) = ball_pivot::ball_pivot(&samples.points, &samples.normals, radii, joins);
    if faces.is_empty() {
        return Err(MeshingError::NoTriangles { samples: samples.points.len() });
    }
    let (faces, repair) = repair::close_surface(&samples.points, &samples.normals, faces)?;
    let mut mesh = CellMesh::from_triangles(samples.points.clone(), faces)?;
    mesh.remove_unused_nodes();
    mesh.orient_outward();
    mesh.validate().map_err(|defect| MeshingError::InvalidMesh { stage: "ball pivoting and hole filling", defect })?;
    Ok((mesh, pivot, repair))
}

/// Fewest voxels meshed: smaller masks are segmentation debris, not cells.
pub const MIN_VOXELS: usize = 8;
/// Largest relative difference between the mesh volume and the voxel volume accepted: beyond it
/// the surface, although valid, does not represent the cell (typically l_min too coarse for it;
/// at the default resolution the difference is 1–5 %).
pub const MAX_VOLUME_ERROR: Real = 0.25;
/// Most nodes per cell: a guard against an l_min far too small for the cell (memory, time).
pub const MAX_NODES: usize = 1_000_000;
/// Fewest samples for ball pivoting to make a closed surface (an octahedron has 6 corners).
pub const MIN_SAMPLES: usize = 12;

/// Meshes one cell's binary mask (see the module doc). `mask` is indexed `[z, y, x]`,
/// `voxel_size` is (z, y, x) in metres, `origin` the (x, y, z) position (m) of voxel `[0, 0, 0]`'s centre.
pub fn mesh_mask(
    mask: ArrayView3<bool>,
    voxel_size: [Real; 3],
    origin: Vec3,
    settings: &MeshingSettings,
) -> Result<MeshedCell, MeshingError> {
    settings.check()?;
    if !voxel_size.iter().all(|s| s.is_finite() && *s > 0.0) {
        return Err(MeshingError::InvalidVoxelSize { voxel_size });
    }
    if !origin.iter().all(|c| c.is_finite()) {
        return Err(MeshingError::InvalidOrigin { origin: [origin.x, origin.y, origin.z] });
    }
    let (field, mask_stats) = field::prepare_field(mask, voxel_size, origin, settings.smoothing)?;
    if mask_stats.voxels < MIN_VOXELS {
        return Err(MeshingError::TooFewVoxels { voxels: mask_stats.voxels, min: MIN_VOXELS });
    }
    let voxel_volume = (mask_stats.voxels + mask_stats.filled_voxels) as Real * voxel_size.iter().product::<Real>();
    let surface = surface_nets::extract_surface(&field);
    if surface.triangles.is_empty() {
        return Err(MeshingError::NoSurface);
    }
    let expected = NODES_PER_LMIN2 * surface.area() / (settings.l_min * settings.l_min);
    if expected.is_nan() || expected > MAX_NODES as Real {
        let expected = if expected.is_finite() { expected as usize } else { usize::MAX };
        return Err(MeshingError::ResolutionTooFine { l_min: settings.l_min, expected, max: MAX_NODES });
    }
    let level = Real::from(surface_nets::LEVEL);
    let samples =
        poisson::poisson_disk_sample(&surface, settings.l_min, settings.candidates_per_area, settings.seed, |p| {
            field.project_to_level(p, level)
        });
    if samples.points.len() < MIN_SAMPLES {
        return Err(MeshingError::TooFewSamples {
            samples: samples.points.len(),
            min: MIN_SAMPLES,
            l_min: settings.l_min,
        });
    }
    let radii: Vec<Real> = settings.ball_radii.iter().map(|r| r * settings.l_min).collect();
    // First with joins in the first pass (few, small holes); if that surface cannot be closed into a
    // valid cell (a handle), again without joins (genus 0 by construction, longer seams to fill).
    let (mut mesh, pivot, repair, without_joins) = match pivot_and_close(&samples, &radii, true) {
        Ok((m, p, r)) => (m, p, r, false),
        Err(MeshingError::InvalidMesh { .. } | MeshingError::Repair { .. }) => {
            let (m, p, r) = pivot_and_close(&samples, &radii, false)?;
            (m, p, r, true)
        }
        Err(e) => return Err(e),
    };
    let unused_samples = samples.points.len() - mesh.node_count();
    let remesh = remesh_cell(&mut mesh, None, None, &RemeshSettings::new(settings.l_min))?;
    mesh.validate().map_err(|defect| MeshingError::InvalidMesh { stage: "remeshing", defect })?;
    let mesh_volume = mesh.signed_volume();
    let error = (mesh_volume / voxel_volume - 1.0).abs();
    if error.is_nan() || error > MAX_VOLUME_ERROR {
        return Err(MeshingError::VolumeMismatch { mesh_volume, voxel_volume, max_error: MAX_VOLUME_ERROR });
    }
    Ok(MeshedCell {
        mesh,
        voxel_volume,
        voxels: mask_stats.voxels,
        dropped_voxels: mask_stats.dropped_voxels,
        filled_voxels: mask_stats.filled_voxels,
        surface_vertices: surface.positions.len(),
        surface_volume: surface.volume(),
        samples: samples.points.len(),
        seeds: pivot.seeds,
        radius_escalations: pivot.faces_per_radius.iter().skip(1).filter(|&&n| n > 0).count(),
        faces_per_radius: pivot.faces_per_radius,
        unused_samples,
        without_joins,
        removed_faces: repair.removed_faces,
        holes_filled: repair.holes,
        largest_hole: repair.largest_hole,
        hole_faces: repair.hole_faces,
        remesh,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ndarray::Array3;

    /// Samples of a dumbbell mask (two overlapping balls), as `mesh_mask` makes them.
    fn dumbbell_samples(l_min: Real, seed: u64) -> SurfaceSamples {
        let mask = Array3::from_shape_fn((25, 25, 39), |(z, y, x)| {
            let p = Vec3::new(x as Real, y as Real, z as Real);
            (p - Vec3::new(11.0, 12.0, 12.0)).norm() <= 9.0 || (p - Vec3::new(27.0, 12.0, 12.0)).norm() <= 9.0
        });
        let (field, _) = field::prepare_field(mask.view(), [1.0; 3], Vec3::zeros(), 0.5).unwrap();
        let surface = surface_nets::extract_surface(&field);
        poisson::poisson_disk_sample(&surface, l_min, 20.0, seed, |p| field.project_to_level(p, 0.5))
    }

    #[test]
    fn the_fallback_without_joins_closes_surfaces_of_genus_0() {
        // The fallback is only taken when the first attempt fails, so exercise it directly: over
        // several seeds and resolutions, pivoting without joins must always give a valid cell.
        for (l_min, seed) in [(1.5, 1), (1.5, 2), (2.0, 3), (2.5, 4)] {
            let samples = dumbbell_samples(l_min, seed);
            let radii: Vec<Real> = [1.2, 1.6, 2.2, 3.0].iter().map(|r| r * l_min).collect();
            let (mesh, pivot, _) = pivot_and_close(&samples, &radii, false).unwrap();
            assert_eq!(mesh.validate(), Ok(()));
            assert_eq!(pivot.seeds, 1);
            assert!(mesh.node_count() + 10 >= samples.points.len(), "most samples are used");
        }
    }
}
