//! Direct estimate of every interface's tension and every cell's pressure from the shapes alone:
//! Young–Dupré (Neumann) force balance at the junction lines and Young–Laplace on each interface, in
//! the manner of CellFIT-3D (Veldhuis et al. 2017) and foambryo (Ichbiah et al. 2023), on per-cell
//! closed meshes.
//!
//! **Interfaces.** The contact partition ([`super::face_contacts`]) splits every cell's surface into
//! interfaces: the faces in contact with cell j (interface i–j, seen from both cells) and the free
//! faces (interface i–medium, label 0); on a multi-material mesh, whose faces name the cells on both
//! sides, the partition is read from those labels instead (exact, no δ). Each interface's faces are
//! fitted by one sphere (a surface of constant tension between two constant pressures has constant
//! mean curvature; a sphere is the simplest such surface and fits every Surface Evolver interface we
//! have within a few % of its radius), or by a plane when the sphere is not determined (nearly flat patches). The faces within
//! [`FIT_MARGIN_EDGES`] mean edge lengths of the interface's junction lines are left out of the fit: a
//! mesh rounds its junctions over one or two edges (remeshing, the contact gap, the voxels of a
//! segmentation), and the first triangles' angle is biased by several degrees there.
//!
//! **Junction samples.** Every mesh edge whose two faces belong to different interfaces is a sample of
//! a triple line: on cell i between partners p and q, the line where i, p and q meet (p or q may be the
//! medium), with the three interfaces i–p, i–q and p–q. At the sample point x each interface's fitted
//! surface gives its unit normal n_k (far field: the fit, not the nearest faces); the line direction is
//! the cross product of the two most different normals, and each interface's unit tangent t_k is
//! perpendicular to the line and to n_k, pointing from the line into the interface (towards that
//! interface's faces near x). Force balance gives two equations per sample in the plane normal to the
//! line, Σ_k T_k t_k = 0.
//!
//! **Solve.** The stacked equations A T = 0 are homogeneous: tensions are fixed up to a common factor,
//! the gauge. The estimate minimises |A T|² with the mean of T equal to 1 (one linear constraint, as
//! CellFIT's: T = 1 + Z y over an orthonormal basis Z of the mean-preserving directions; independent of
//! the gauge). Where the samples balance exactly it is the right singular vector of A with the smallest
//! singular value; where they do not, that vector can concentrate on a few weakly tied interfaces and
//! leave the others near 0 (a real crop of dense tissue), which the constraint does not reward. It is
//! then scaled so that the gauge holds:
//! by default the mean of the cell–medium tensions is 1, or a named interface's tension is 1, or either
//! equals a value given in mN/m. Unknowns that share no sample form separate blocks solved separately; a
//! block without a gauge unknown, an interface without a sample, and a block whose second-smallest
//! singular value vanishes (several balancing directions) are *undetermined*: flagged, no number. The
//! condition number is σ_max / σ_second-smallest (how well the samples separate the solution from the
//! other directions); the spectral gap σ_second-smallest / σ_smallest how clearly they single out one
//! map. A median relative sd above [`POOR_RELATIVE_SD`] gets a warning.
//!
//! **Uncertainty.** First-order perturbation of the constrained minimum by the residuals,
//! cluster-robust by junction line (the samples of one line share their fits, so they are not
//! independent): Cov(v) = K (Σ_lines s_l s_lᵀ) K · G/(G − 1), s_l = A_lᵀ r_l the line's score,
//! K = Z (ZᵀAᵀAZ)⁻¹ Zᵀ, G lines, carried through the gauge scaling. It reflects how consistently
//! the junctions balance, not biases shared by all junctions (a systematically rounded rim).
//!
//! **Pressures.** Young–Laplace on every determined interface, p_a − p_b = 2 H_ab T_ab with H_ab the
//! mean curvature of its fitted sphere (positive when the sphere's centre lies on a's side, 0 for a
//! plane), the medium's pressure 0; least squares over all interfaces. A cell with no path of determined
//! interfaces to the medium is undetermined. The pressure's standard deviation combines the tensions'
//! (independent) and the Laplace residual.
//!
//! **Field of view.** A segmentation cuts the cells at the image border: their faces there touch no
//! medium. With [`TensionSettings::field_of_view`] (the imaged box, given for label volumes) a free
//! face whose centre lies within a voxel or a mean edge length of the box's sides belongs to no interface: no tension, no
//! junction along it, grey in the map.
//!
//! Units: lengths in metres as the tissue; tensions in units of the gauge; pressures in gauge tension
//! per metre (the command line prints per µm). Deterministic: every loop runs in a fixed order and the
//! contact partition is thread-independent, so 1 and N threads give identical results.

use super::face_contacts::{FREE, contact_partition};
use super::far_field::fit_sphere;
use super::measure::DEFAULT_CONTACT_DISTANCE_FACTOR;
use crate::geometry::{Real, Vec3};
use crate::mesh::{Adjacency, CellKind, Tissue};
use nalgebra::{DMatrix, DVector};
use std::collections::BTreeMap;

/// Faces within this many mean edge lengths of an interface's junction lines are left out of its fit.
pub const FIT_MARGIN_EDGES: Real = 2.0;
/// Fewest faces for a sphere fit (fewer: a plane, from at least 3).
pub const MIN_SPHERE_FACES: usize = 12;
/// A sphere fit whose radius exceeds this many times the patch's rms extent is a plane.
pub const MAX_RADIUS_OVER_EXTENT: Real = 1e3;
/// Sphere-fit rms above this fraction of the radius is reported in the warnings (the interface is not
/// one sphere: its far-field tangents are approximate).
pub const WARN_FIT_RMS: Real = 0.05;
/// Junction samples farther than this many mean edge lengths from the line where their three fitted
/// surfaces meet are left out (stray contact faces, not a junction).
pub const MAX_JUNCTION_OFFSET_EDGES: Real = 4.0;
/// The three fitted surfaces of a junction sample must pass within this many rounding scales (the
/// voxel on a segmentation, else the mean edge) of the point where they come closest, or the sample
/// is a stray contact face's edge. A label boundary is placed to within half a voxel, so surfaces
/// fitted to three of them can miss each other by that much: on a doublet meshed at 9 voxels per
/// diameter the wall, half a voxel off the caps' mid-plane, misses them by 0.11–0.12 voxel at every
/// sample. (0.1, 0.3, 0.5 and 1 change the Evolver fixtures' medians by ≤ 1.3 points.)
pub const JUNCTION_MEET_SCALES: Real = 0.5;
/// Junction samples within this many mean edge lengths of another junction line are left out.
pub const VERTEX_MARGIN_EDGES: Real = 2.0;
/// A local fit ([`FarField::Local`]) uses the faces within this many rounding scales of the sample.
pub const LOCAL_RADIUS_SCALES: Real = 6.0;
/// The robust pass never drops samples whose imbalance is below this (units of the gauge).
pub const MIN_TRIMMED_IMBALANCE: Real = 0.05;
/// A median relative tension sd above this gets a warning: the map is poorly determined (2–3 % on the
/// Evolver fixtures at 10 voxels per diameter and on the real C. elegans embryo, 21 % on the real
/// PlantSeg ovule crop).
pub const POOR_RELATIVE_SD: Real = 0.10;
/// Relative size (to the largest) below which a second singular value counts as zero.
pub const SINGULAR_TOLERANCE: Real = 1e-10;

/// Which tension fixes the common scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Gauge {
    /// The mean of all cell–medium tensions equals the gauge value.
    MediumMean,
    /// The tension of the interface between these two labels (0 = medium) equals the gauge value.
    Interface(u32, u32),
}

/// Where each junction sample's interface surfaces come from. Measured on the Surface Evolver
/// fixtures (docs/scripts/tensions.sh) `Auto` equals `Global` wherever the global surfaces meet and
/// recovers the samples where they do not; on the real C. elegans embryo it keeps every interface
/// determined and stable across mesh resolutions, where `Global` lost one or another.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FarField {
    /// One sphere (or plane) fitted to all of an interface's faces away from its junctions.
    Global,
    /// Per sample, each interface's faces near it, on a sphere of the interface's global radius.
    Local,
    /// The global fit, and the local one where the global surfaces do not meet near the sample.
    Auto,
}

impl FarField {
    pub const NAMES: [&'static str; 3] = ["global", "local", "auto"];

    pub fn as_str(self) -> &'static str {
        match self {
            FarField::Global => "global",
            FarField::Local => "local",
            FarField::Auto => "auto",
        }
    }
}

impl std::str::FromStr for FarField {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "global" => Ok(FarField::Global),
            "local" => Ok(FarField::Local),
            "auto" => Ok(FarField::Auto),
            _ => Err(format!("`{s}`: the far field is one of {}", FarField::NAMES.join(", "))),
        }
    }
}

/// How to estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct TensionSettings {
    /// Contact distance δ (m); `None`: [`DEFAULT_CONTACT_DISTANCE_FACTOR`] × the mean edge length.
    pub contact_distance: Option<Real>,
    /// One tension shared by every cell–medium interface instead of one per cell.
    pub one_medium_tension: bool,
    pub gauge: Gauge,
    /// The gauge tension's value (1 for relative tensions, or a tension in the user's unit).
    pub gauge_value: Real,
    /// The length (m) over which the input rounds its junctions when it exceeds the mean edge length:
    /// the voxel size of a meshed segmentation. The fit margin, the vertex margin and the junction
    /// tolerances are multiples of max(this, mean edge length). `None`: the mean edge length.
    pub rounding_scale: Option<Real>,
    /// Take the interfaces from the input's interface labels when every cell carries them (a
    /// multi-material mesh, [`crate::mesh::Cell::interface_labels`]) instead of the contact distance.
    pub interface_labels: bool,
    /// The imaged box of a segmentation: free faces on its sides are cut by the border, no interface.
    pub field_of_view: Option<FieldOfView>,
    /// Where the interfaces' surfaces at each junction sample come from.
    pub far_field: FarField,
}

/// The box a label volume images (m): from the outer side of its first voxels to that of its last,
/// and which cells the image cuts.
#[derive(Clone, Debug, PartialEq)]
pub struct FieldOfView {
    pub lo: Vec3,
    pub hi: Vec3,
    /// Per axis, how close (m) to a side a face's centre must be to count as cut: one voxel.
    pub margin: Vec3,
    /// The cells (labels) with a voxel on the border: only their faces can be cut. `None`: any cell.
    /// (A cell that stops short of the border has no cut face, however close to it the mesh's
    /// edge length brings its faces.)
    pub cut_cells: Option<std::collections::BTreeSet<u32>>,
}

impl FieldOfView {
    /// The box of `volume`'s grid (voxel `[k, j, i]` centred at origin + (i·sx, j·sy, k·sz)) and the
    /// labels on its border.
    pub fn of_volume(volume: &crate::imaging::LabelVolume) -> Self {
        let grid = volume.grid();
        let [nz, ny, nx] = grid.shape;
        let [sz, sy, sx] = grid.voxel_size;
        let size = Vec3::new(sx, sy, sz);
        let lo = grid.origin - 0.5 * size;
        let hi = grid.origin + Vec3::new(nx as Real * sx, ny as Real * sy, nz as Real * sz) - 0.5 * size;
        Self { lo, hi, margin: size, cut_cells: Some(volume.border_labels()) }
    }

    /// Whether a face of `cell` centred at `x` lies on a side of the box: the cell reaches the border
    /// and the face lies within the margin or `edge` (the mesh's edge length, over which the mesh
    /// rounds the cut) of a side.
    pub fn on_border(&self, cell: u32, x: &Vec3, edge: Real) -> bool {
        self.cut_cells.as_ref().is_none_or(|c| c.contains(&cell))
            && (0..3).any(|k| {
                let m = self.margin[k].max(edge);
                x[k] < self.lo[k] + m || x[k] > self.hi[k] - m
            })
    }
}

/// The key of a face cut by the field of view: no interface.
const CUT: (u32, u32) = (u32::MAX, u32::MAX);

impl Default for TensionSettings {
    fn default() -> Self {
        Self {
            contact_distance: None,
            one_medium_tension: false,
            gauge: Gauge::MediumMean,
            gauge_value: 1.0,
            rounding_scale: None,
            interface_labels: true,
            field_of_view: None,
            far_field: FarField::Auto,
        }
    }
}

/// Why no estimate could be made.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TensionError {
    #[error("the tissue has {cells} cell(s): a force balance needs at least two cells in contact")]
    TooFewCells { cells: usize },
    #[error("cell {cell} has a non-finite node coordinate")]
    NonFinite { cell: u32 },
    #[error("cell id 0 is reserved for the medium; renumber the cells from 1")]
    CellIdZero,
    #[error("contact distance {value:e} m must be finite and positive")]
    InvalidContactDistance { value: Real },
    #[error("cannot derive the contact distance: the tissue has no edge length; give one")]
    NoEdgeLength,
    #[error(
        "no junction lines: no cell touches another within the contact distance δ = {delta:e} m, so there is no \
         force balance to solve (give a larger contact distance if the cells are separated by a gap)"
    )]
    NoJunctions { delta: Real },
    #[error("the gauge value {value} must be finite and positive")]
    InvalidGaugeValue { value: Real },
    #[error("gauge interface {a}-{b} is not an interface of this tissue (labels present: {labels})")]
    UnknownGaugeInterface { a: u32, b: u32, labels: String },
    #[error("the gauge {gauge} has no junction sample: every tension is undetermined")]
    GaugeUndetermined { gauge: String },
}

/// One interface's estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct InterfaceTension {
    /// Cell labels; `cell_b` = 0 for the medium (then `cell_a` is the cell), else `cell_a < cell_b`.
    pub cell_a: u32,
    pub cell_b: u32,
    /// Tension in units of the gauge; `None` when undetermined.
    pub tension: Option<Real>,
    /// Its standard deviation (see the module docs); `None` when undetermined.
    pub tension_sd: Option<Real>,
    pub determined: bool,
    /// Area (m²): the mean of both sides' face areas for a cell–cell interface.
    pub area: Real,
    /// Junction samples that involve this interface.
    pub samples: usize,
    /// Mean curvature (1/m) of the fitted surface, positive when it bulges into `cell_b`; `None` without
    /// a fit.
    pub mean_curvature: Option<Real>,
    /// `sphere`, `plane` or `none`.
    pub fit: &'static str,
    /// Rms distance (m) of the fitted faces from the surface.
    pub fit_rms: Option<Real>,
    /// Faces behind the fit.
    pub fit_faces: usize,
}

/// One cell's pressure.
#[derive(Clone, Debug, PartialEq)]
pub struct CellPressure {
    pub cell: u32,
    /// Pressure relative to the medium, in gauge tension per metre; `None` when undetermined.
    pub pressure: Option<Real>,
    pub pressure_sd: Option<Real>,
    /// `pressure` and `determined` are relative to the medium.
    pub determined: bool,
    /// The pressure minus the mean pressure of the cells that determined interfaces link this one to
    /// (its group, itself included), with its sd: known also where no chain reaches the medium (a
    /// dense crop); `None` for a cell linked to no other.
    pub pressure_relative: Option<Real>,
    pub pressure_relative_sd: Option<Real>,
    /// Mean curvature (1/m) of the fitted free surface; `None` without one.
    pub free_mean_curvature: Option<Real>,
    /// Free area (m²).
    pub free_area: Real,
}

/// The whole estimate.
#[derive(Clone, Debug, PartialEq)]
pub struct TensionMap {
    /// Ascending by (cell_a, cell_b) with the medium interfaces (cell_b = 0) first for each cell.
    pub interfaces: Vec<InterfaceTension>,
    /// In tissue order.
    pub cells: Vec<CellPressure>,
    /// For each tissue cell and face, the index in `interfaces` of the face's interface (`None`: a
    /// face cut by the field of view).
    pub face_interface: Vec<Vec<Option<usize>>>,
    /// Contact distance used (m): the contact rule's δ, or with interface labels only the scale of
    /// the rim search.
    pub contact_distance: Real,
    /// How the interfaces were found.
    pub contact_rule: super::ContactRule,
    /// What fixes the scale, e.g. "the mean cell–medium tension" (or "the mean cell–cell tension"
    /// when no cell has a free surface).
    pub gauge: String,
    /// Junction samples used in the force balance.
    pub samples: usize,
    /// Samples left out (a partner pair that does not touch, or an interface without a fit, or
    /// surfaces that do not meet near the sample).
    pub samples_skipped: usize,
    /// Samples left out within [`VERTEX_MARGIN_EDGES`] mean edge lengths of another junction line
    /// (near a vertex where four interfaces meet, the triple-line geometry does not hold).
    pub samples_near_vertices: usize,
    /// Samples left out by the robust pass (imbalance above [`TRIM_FACTOR`] × the median; never an
    /// interface's last ones).
    pub samples_trimmed: usize,
    /// Of the samples used, those whose interfaces' surfaces were fitted locally ([`FarField`]).
    pub samples_local: usize,
    /// Distinct junction lines (triples of labels).
    pub junction_lines: usize,
    /// Unknown tensions.
    pub unknowns: usize,
    /// σ_max / σ_second-smallest of the force-balance matrix (largest over the blocks).
    pub condition_number: Option<Real>,
    /// σ_second-smallest / σ_smallest of the force-balance matrix (smallest over the blocks): how
    /// clearly the samples single out one map (∞ where they balance exactly).
    pub spectral_gap: Option<Real>,
    /// Rms and median over samples of |Σ T_k t_k| (units of the gauge).
    pub residual_rms: Option<Real>,
    pub residual_median: Option<Real>,
    /// Rms residual of the Young–Laplace fit of the pressures (gauge tension per metre).
    pub pressure_residual_rms: Option<Real>,
    pub warnings: Vec<String>,
}

/// An interface's faces and its fitted surface.
#[derive(Default)]
struct Patch {
    /// Face centroids, both sides.
    centroids: Vec<Vec3>,
    /// Face area per side: [cell_a side, cell_b side].
    area: [Real; 2],
    /// Sum of area-weighted normals pointing from cell_a into cell_b.
    normal_ab: Vec3,
    junction_points: Vec<Vec3>,
    /// The faces the surface was fitted to (the far field), for local fits.
    fit_points: Vec<Vec3>,
    surface: Option<Surface>,
    fit_rms: Option<Real>,
    fit_faces: usize,
}

#[derive(Clone, Copy, Debug)]
enum Surface {
    Sphere { centre: Vec3, radius: Real },
    Plane { point: Vec3, normal: Vec3 },
}

impl Surface {
    fn normal_at(&self, x: &Vec3) -> Option<Vec3> {
        match self {
            Surface::Sphere { centre, .. } => (x - centre).try_normalize(0.0),
            Surface::Plane { normal, .. } => Some(*normal),
        }
    }
}

/// A junction sample: the point, the mesh edge direction and its three interfaces (indices).
struct Sample {
    x: Vec3,
    edge: Vec3,
    interfaces: [usize; 3],
    line: usize,
}

fn key(a: u32, b: u32) -> (u32, u32) {
    match (a, b) {
        (0, c) | (c, 0) => (c, 0),
        (a, b) => (a.min(b), a.max(b)),
    }
}

/// Estimates every interface's tension and every cell's pressure; see the module docs.
pub fn estimate_tensions(tissue: &Tissue, settings: &TensionSettings) -> Result<TensionMap, TensionError> {
    if !(settings.gauge_value.is_finite() && settings.gauge_value > 0.0) {
        return Err(TensionError::InvalidGaugeValue { value: settings.gauge_value });
    }
    let cells = tissue.cells();
    let participates: Vec<bool> = cells.iter().map(|c| c.kind() != CellKind::Nucleus).collect();
    let n_cells = participates.iter().filter(|&&p| p).count();
    if n_cells < 2 {
        return Err(TensionError::TooFewCells { cells: n_cells });
    }
    for c in cells {
        if c.id().0 == 0 {
            return Err(TensionError::CellIdZero);
        }
        if c.mesh().positions().iter().any(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(TensionError::NonFinite { cell: c.id().0 });
        }
    }
    let h = tissue.mean_edge_length().filter(|h| h.is_finite() && *h > 0.0).ok_or(TensionError::NoEdgeLength)?;
    let delta = match settings.contact_distance {
        Some(d) if d.is_finite() && d > 0.0 => d,
        Some(d) => return Err(TensionError::InvalidContactDistance { value: d }),
        None => DEFAULT_CONTACT_DISTANCE_FACTOR * h,
    };
    let (partitions, contact_rule) = contact_partition(tissue, &participates, delta, settings.interface_labels);
    let ids: Vec<u32> = cells.iter().map(|c| c.id().0).collect();
    let mut warnings = Vec::new();

    // Interfaces and each face's interface.
    let mut patches: BTreeMap<(u32, u32), Patch> = BTreeMap::new();
    let (mut cut_faces, mut cut_cells) = (0usize, std::collections::BTreeSet::new());
    let mut face_key: Vec<Vec<(u32, u32)>> = Vec::with_capacity(cells.len());
    for (i, cell) in cells.iter().enumerate() {
        if !participates[i] {
            face_key.push(Vec::new());
            continue;
        }
        let mesh = cell.mesh();
        let p = mesh.positions();
        let vectors = mesh.face_area_vectors();
        let own = ids[i];
        let centroid = |t: &[u32; 3]| (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0;
        let keys: Vec<(u32, u32)> = partitions[i]
            .partner
            .iter()
            .zip(mesh.triangles())
            .map(|(&b, t)| match b {
                FREE if settings.field_of_view.as_ref().is_some_and(|v| v.on_border(own, &centroid(t), h)) => CUT,
                FREE => key(own, 0),
                b => key(own, ids[b as usize]),
            })
            .collect();
        for (f, t) in mesh.triangles().iter().enumerate() {
            let k = keys[f];
            if k == CUT {
                cut_faces += 1;
                cut_cells.insert(own);
                continue;
            }
            let patch = patches.entry(k).or_default();
            let side = usize::from(k.0 != own);
            patch.centroids.push((p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0);
            patch.area[side] += vectors[f].norm();
            // Outward of cell_a points into b; outward of cell_b points into a.
            patch.normal_ab += if side == 0 { vectors[f] } else { -vectors[f] };
        }
        face_key.push(keys);
    }
    if cut_faces > 0 {
        warnings.push(format!(
            "{cut_faces} faces of {} cell(s) lie on the image border (cut by the field of view): they are no \
             interface, and no junction along them is used",
            cut_cells.len()
        ));
    }
    let index: BTreeMap<(u32, u32), usize> = patches.keys().enumerate().map(|(n, k)| (*k, n)).collect();
    let keys: Vec<(u32, u32)> = patches.keys().copied().collect();
    let mut patches: Vec<Patch> = patches.into_values().collect();

    // Junction samples.
    let mut samples = Vec::new();
    let mut skipped = 0usize;
    let mut lines: BTreeMap<[u32; 3], usize> = BTreeMap::new();
    for (i, cell) in cells.iter().enumerate() {
        if !participates[i] {
            continue;
        }
        let mesh = cell.mesh();
        let p = mesh.positions();
        let adjacency = Adjacency::new(mesh);
        let own = ids[i];
        for (e, &[u, v]) in adjacency.edges().iter().enumerate() {
            let &[f, g] = adjacency.edge_faces(e) else { continue };
            let (kf, kg) = (face_key[i][f as usize], face_key[i][g as usize]);
            if kf == kg || kf == CUT || kg == CUT {
                continue;
            }
            let other = |k: (u32, u32)| if k.0 == own { k.1 } else { k.0 };
            let (pa, pb) = (other(kf), other(kg));
            let Some(&third) = index.get(&key(pa, pb)) else {
                skipped += 1;
                continue;
            };
            let mut triple = [own, pa, pb];
            triple.sort_unstable();
            let next = lines.len();
            let line = *lines.entry(triple).or_insert(next);
            let x = (p[u as usize] + p[v as usize]) / 2.0;
            let interfaces = [index[&kf], index[&kg], third];
            for &k in &interfaces {
                patches[k].junction_points.push(x);
            }
            samples.push(Sample { x, edge: p[v as usize] - p[u as usize], interfaces, line });
        }
    }
    if samples.is_empty() {
        return Err(TensionError::NoJunctions { delta });
    }

    // Fit every interface, leaving out the faces near its junctions.
    // The scale over which a junction is rounded: the mesh's edges, or the segmentation's voxels
    // when they are coarser.
    let scale = settings.rounding_scale.map_or(h, |v| v.max(h));
    let margin = FIT_MARGIN_EDGES * scale;
    let mut not_spheres: Vec<(String, Real)> = Vec::new();
    for (k, patch) in patches.iter_mut().enumerate() {
        let far: Vec<Vec3> = patch
            .centroids
            .iter()
            .filter(|c| patch.junction_points.iter().all(|q| (*c - q).norm_squared() > margin * margin))
            .copied()
            .collect();
        let points = if far.len() >= MIN_SPHERE_FACES { far } else { patch.centroids.clone() };
        let (surface, rms) = fit_surface(&points);
        if let (Some(Surface::Sphere { radius, .. }), Some(rms)) = (surface, rms)
            && rms > WARN_FIT_RMS * radius
        {
            let (a, b) = keys[k];
            not_spheres.push((format!("{a}-{b}"), 100.0 * rms / radius));
        }
        patch.surface = surface;
        patch.fit_rms = rms;
        patch.fit_faces = points.len();
        patch.fit_points = points;
    }
    if !not_spheres.is_empty() {
        let (lo, hi) = not_spheres.iter().fold((Real::MAX, Real::MIN), |(lo, hi), (_, r)| (lo.min(*r), hi.max(*r)));
        let names: Vec<&str> = not_spheres.iter().map(|(n, _)| n.as_str()).collect();
        warnings.push(format!(
            "interface(s) {}: faces not one sphere (rms {lo:.1}–{hi:.1} % of the radius); their tangents are approximate{}",
            names.join(", "),
            if settings.far_field == FarField::Global { "" } else { " where the global fits are used" }
        ));
    }

    // Force-balance rows: per sample, the tangents of its three interfaces in the plane normal to the line.
    let medium_unknown = settings.one_medium_tension;
    let mut unknown_of = vec![usize::MAX; keys.len()];
    let mut unknown_keys: Vec<Vec<usize>> = Vec::new();
    let mut shared_medium = None;
    for (k, &(_, b)) in keys.iter().enumerate() {
        if b == 0 && medium_unknown {
            let u = *shared_medium.get_or_insert_with(|| {
                unknown_keys.push(Vec::new());
                unknown_keys.len() - 1
            });
            unknown_of[k] = u;
            unknown_keys[u].push(k);
        } else {
            unknown_of[k] = unknown_keys.len();
            unknown_keys.push(vec![k]);
        }
    }
    let n = unknown_keys.len();
    let local = 4.0 * scale;
    // (row coefficients as (unknown, value), line) per equation; two equations per sample.
    let mut rows: Vec<Row> = Vec::with_capacity(2 * samples.len());
    let near_vertex = near_other_lines(&samples, VERTEX_MARGIN_EDGES * scale);
    let mut vertex_skipped = 0usize;
    let mut local_sample = vec![false; samples.len()];
    for (si, s) in samples.iter().enumerate() {
        if near_vertex[si] {
            vertex_skipped += 1;
            continue;
        }
        let global: Option<Vec<Surface>> = s.interfaces.iter().map(|&k| patches[k].surface).collect();
        let Some(global) = global else {
            skipped += 1;
            continue;
        };
        // The junction is where the three fitted surfaces meet: the mesh's own junction edge lies
        // inside the rounding of the rim, up to a voxel or more away on a segmentation, and a sphere's
        // normal turns by that offset over its radius. A sample whose surfaces do not meet near it
        // is a stray contact face's edge, not a junction.
        let meets = |surfaces: &[Surface]| {
            let x = snap_to_junction(surfaces, s.x, h);
            ((x - s.x).norm() <= MAX_JUNCTION_OFFSET_EDGES * scale
                && surfaces.iter().all(|f| f.distance(&x) <= JUNCTION_MEET_SCALES * scale))
            .then_some(x)
        };
        let local_fit = || -> Option<Vec<Surface>> {
            s.interfaces
                .iter()
                .zip(&global)
                .map(|(&k, g)| local_surface(&patches[k].fit_points, g, &s.x, scale))
                .collect()
        };
        let chosen = match settings.far_field {
            FarField::Global => meets(&global).map(|x| (global.clone(), x, false)),
            FarField::Local => local_fit().and_then(|l| meets(&l).map(|x| (l, x, true))),
            FarField::Auto => meets(&global)
                .map(|x| (global.clone(), x, false))
                .or_else(|| local_fit().and_then(|l| meets(&l).map(|x| (l, x, true)))),
        };
        let Some((surfaces, x, is_local)) = chosen else {
            skipped += 1;
            continue;
        };
        let normals: Option<Vec<Vec3>> = surfaces.iter().map(|f| f.normal_at(&x)).collect();
        let Some(normals) = normals else {
            skipped += 1;
            continue;
        };
        let Some(line) = line_direction(&normals, &s.edge) else {
            skipped += 1;
            continue;
        };
        let mut tangents = [Vec3::zeros(); 3];
        let mut ok = true;
        for (j, &k) in s.interfaces.iter().enumerate() {
            let Some(t) = line.cross(&normals[j]).try_normalize(1e-12) else {
                ok = false;
                break;
            };
            let near = local_mean(&patches[k].centroids, &x, local);
            let toward = near - x;
            tangents[j] = if t.dot(&toward) >= 0.0 { t } else { -t };
        }
        if !ok {
            skipped += 1;
            continue;
        }
        let u_axis = tangents[0];
        let w_axis = line.cross(&u_axis);
        for axis in [u_axis, w_axis] {
            let mut coefficients: Vec<(usize, Real)> = Vec::with_capacity(3);
            for (j, &k) in s.interfaces.iter().enumerate() {
                let c = tangents[j].dot(&axis);
                match coefficients.iter_mut().find(|(u, _)| *u == unknown_of[k]) {
                    Some(entry) => entry.1 += c,
                    None => coefficients.push((unknown_of[k], c)),
                }
            }
            rows.push(Row { coefficients, line: s.line, sample: si, noise: Vec::new() });
        }
        local_sample[si] = is_local;
    }
    if rows.is_empty() {
        return Err(TensionError::NoJunctions { delta });
    }

    // Gauge vector. A tissue without free surface (a dense crop) has no cell–medium mean: the mean
    // cell–cell tension stands in, said in a warning.
    let mut medium_gauge_fallback = false;
    let gauge_unknowns: Vec<usize> = match settings.gauge {
        Gauge::MediumMean => {
            let mut u: Vec<usize> =
                keys.iter().enumerate().filter(|(_, k)| k.1 == 0).map(|(k, _)| unknown_of[k]).collect();
            u.dedup();
            if u.is_empty() {
                medium_gauge_fallback = true;
                u = keys.iter().enumerate().filter(|(_, k)| k.1 != 0).map(|(k, _)| unknown_of[k]).collect();
                u.dedup();
                warnings.push(
                    "no cell has a free surface (a dense crop?): the gauge is the mean cell–cell tension instead of \
                     the mean cell–medium tension; fix one interface with --gauge A-B for another scale"
                        .to_string(),
                );
            }
            u
        }
        Gauge::Interface(a, b) => match index.get(&key(a, b)) {
            Some(&k) => vec![unknown_of[k]],
            None => {
                return Err(TensionError::UnknownGaugeInterface {
                    a,
                    b,
                    labels: ids.iter().map(u32::to_string).collect::<Vec<_>>().join(", "),
                });
            }
        },
    };
    let gauge_name = match settings.gauge {
        Gauge::MediumMean if medium_gauge_fallback => "the mean cell–cell tension".to_string(),
        Gauge::MediumMean => "the mean cell–medium tension".to_string(),
        Gauge::Interface(a, b) => format!("interface {a}-{b}"),
    };

    // Blocks of unknowns linked by samples (union-find in a fixed order).
    let first = solve_tensions(&rows, n, &gauge_unknowns, &gauge_name, settings.gauge_value)?;
    // One robust pass: samples whose force imbalance exceeds TRIM_FACTOR × the median (a junction
    // mis-read near a vertex, a stray contact patch) are left out and the system solved again.
    let imbalance = sample_imbalance(&rows, &first.tension, settings.gauge_value);
    let mut values: Vec<Real> = imbalance.values().copied().collect();
    let limit = median(&mut values).map(|m| (TRIM_FACTOR * m).max(MIN_TRIMMED_IMBALANCE));
    let outliers = match limit {
        Some(limit) => outliers_to_drop(&imbalance, limit, &rows, &samples, &unknown_of, n),
        None => Vec::new(),
    };
    let solved = if outliers.is_empty() {
        first
    } else {
        let kept: Vec<Row> = rows.into_iter().filter(|r| outliers.binary_search(&r.sample).is_err()).collect();
        rows = kept;
        solve_tensions(&rows, n, &gauge_unknowns, &gauge_name, settings.gauge_value)?
    };
    let trimmed_samples = outliers.len();
    let Solved { tension, tension_sd, condition, gap, sampled, warnings: solve_warnings } = solved;
    warnings.extend(solve_warnings);
    let mut relative_sd: Vec<Real> = tension
        .iter()
        .zip(&tension_sd)
        .filter_map(|(t, sd)| Some(sd.as_ref()? / t.as_ref()?.abs()))
        .filter(|r| r.is_finite())
        .collect();
    if let Some(m) = median(&mut relative_sd).filter(|&m| m > POOR_RELATIVE_SD) {
        let wide = relative_sd.iter().filter(|&&r| r > 0.5).count();
        warnings.push(format!(
            "the tensions are poorly determined: their median relative sd is {:.0} % ({wide} of {} above 50 %; \
             spectral gap σ₂/σ₁ = {}): other sets of tensions balance the junctions almost as well. Expected where the \
             shapes are not set by a force balance (plant cell walls), where the crop cuts most cells (few junctions \
             per interface), or on a mesh too coarse for the smallest interfaces",
            100.0 * m,
            relative_sd.len(),
            gap.map_or("n/a".to_string(), |g| format!("{g:.1}"))
        ));
    }
    let unsampled: Vec<String> = keys
        .iter()
        .enumerate()
        .filter(|(k, _)| !sampled[unknown_of[*k]])
        .map(|(_, (a, b))| format!("{a}-{b}"))
        .collect();
    if !unsampled.is_empty() {
        warnings.push(format!(
            "interface(s) {} have no junction sample: undetermined (flagged, no tension)",
            unsampled.join(", ")
        ));
    }
    let negative: Vec<String> = keys
        .iter()
        .enumerate()
        .filter(|(k, _)| tension[unknown_of[*k]].is_some_and(|t| t <= 0.0))
        .map(|(_, (a, b))| format!("{a}-{b}"))
        .collect();
    if !negative.is_empty() {
        warnings.push(format!(
            "interface(s) {} came out with a tension ≤ 0 (left out of the gauge's mean and of the pressures): the shapes \
             are not at a force balance there, or the mesh is too coarse, or a buried cell shows a spurious free patch",
            negative.join(", ")
        ));
    }

    // Residuals of the force balance.
    let mut per_interface_samples = vec![0usize; keys.len()];
    let (mut used, mut local_samples) = (0usize, 0usize);
    for r in rows.iter().step_by(2) {
        used += 1;
        local_samples += usize::from(local_sample[r.sample]);
        for &k in &samples[r.sample].interfaces {
            per_interface_samples[k] += 1;
        }
    }
    let per_sample: Vec<Real> = sample_imbalance(&rows, &tension, settings.gauge_value).into_values().collect();
    let residual_rms = (!per_sample.is_empty())
        .then(|| (per_sample.iter().map(|r| r * r).sum::<Real>() / per_sample.len() as Real).sqrt());
    let residual_median = median(&mut per_sample.clone());

    // Interfaces.
    let interfaces: Vec<InterfaceTension> = keys
        .iter()
        .enumerate()
        .map(|(k, &(a, b))| {
            let patch = &patches[k];
            let u = unknown_of[k];
            let area = if b == 0 { patch.area[0] } else { (patch.area[0] + patch.area[1]) / 2.0 };
            let (fit, curvature) = match patch.surface {
                Some(Surface::Sphere { centre, radius }) => {
                    let mean = patch.centroids.iter().sum::<Vec3>() / patch.centroids.len() as Real;
                    // Centre on a's side (opposite to the a→b normal): bulges into b, H > 0.
                    let sign = if (centre - mean).dot(&patch.normal_ab) <= 0.0 { 1.0 } else { -1.0 };
                    ("sphere", Some(sign / radius))
                }
                Some(Surface::Plane { .. }) => ("plane", Some(0.0)),
                None => ("none", None),
            };
            InterfaceTension {
                cell_a: a,
                cell_b: b,
                tension: tension[u],
                tension_sd: tension_sd[u],
                determined: tension[u].is_some(),
                area,
                samples: per_interface_samples[k],
                mean_curvature: curvature,
                fit,
                fit_rms: patch.fit_rms,
                fit_faces: patch.fit_faces,
            }
        })
        .collect();

    // Pressures: Young–Laplace on every determined interface with a curvature.
    let cell_index: BTreeMap<u32, usize> =
        ids.iter().enumerate().filter(|(i, _)| participates[*i]).map(|(i, &id)| (id, i)).collect();
    let (pressures, pressure_residual_rms) = solve_pressures(&interfaces, &cell_index, cells.len(), &mut warnings);
    let no_free: Vec<String> = ids
        .iter()
        .enumerate()
        .filter(|(i, id)| participates[*i] && !index.contains_key(&(**id, 0)))
        .map(|(_, id)| id.to_string())
        .collect();
    if !no_free.is_empty() {
        warnings.push(format!(
            "cell(s) {} have no free surface: no cell–medium tension of theirs enters{}",
            no_free.join(", "),
            if matches!(settings.gauge, Gauge::MediumMean) { " the gauge" } else { "" }
        ));
    }
    let cells_out: Vec<CellPressure> = cells
        .iter()
        .enumerate()
        .filter(|(i, _)| participates[*i])
        .map(|(i, c)| {
            let free = index.get(&(c.id().0, 0)).map(|&k| &interfaces[k]);
            let PressureEstimate { absolute, relative } = pressures[i];
            CellPressure {
                cell: c.id().0,
                pressure: absolute.map(|(p, _)| p),
                pressure_sd: absolute.map(|(_, sd)| sd),
                determined: absolute.is_some(),
                pressure_relative: relative.map(|(p, _)| p),
                pressure_relative_sd: relative.map(|(_, sd)| sd),
                free_mean_curvature: free.and_then(|f| f.mean_curvature),
                free_area: free.map_or(0.0, |f| f.area),
            }
        })
        .collect();
    let face_interface =
        face_key.iter().map(|keys| keys.iter().map(|k| index.get(k).copied()).collect::<Vec<_>>()).collect::<Vec<_>>();
    Ok(TensionMap {
        gauge: gauge_name,
        interfaces,
        cells: cells_out,
        face_interface,
        contact_distance: delta,
        contact_rule,
        samples: used,
        samples_skipped: skipped,
        samples_near_vertices: vertex_skipped,
        samples_local: local_samples,
        samples_trimmed: trimmed_samples,
        junction_lines: lines.len(),
        unknowns: n,
        condition_number: condition,
        spectral_gap: gap,
        residual_rms,
        residual_median,
        pressure_residual_rms,
        warnings,
    })
}

/// Per sample (index), |Σ T_k t_k| / gauge over its two rows; samples with an undetermined tension
/// are left out.
fn sample_imbalance(rows: &[Row], tension: &[Option<Real>], value: Real) -> BTreeMap<usize, Real> {
    let mut out: BTreeMap<usize, Real> = BTreeMap::new();
    let mut unknown: Vec<usize> = Vec::new();
    for r in rows {
        let mut sum = 0.0;
        for &(u, c) in &r.coefficients {
            match tension[u] {
                Some(t) => sum += c * t,
                None => unknown.push(r.sample),
            }
        }
        *out.entry(r.sample).or_insert(0.0) += sum * sum;
    }
    for s in unknown {
        out.remove(&s);
    }
    out.values_mut().for_each(|v| *v = v.sqrt() / value);
    out
}

/// The samples the robust pass drops (ascending): those whose imbalance exceeds `limit`, worst first,
/// but never an interface's last samples (that would leave it undetermined, or cut its block off the
/// gauge: a small interface whose few samples all balance poorly is kept, its worse balance then in
/// its sd).
fn outliers_to_drop(
    imbalance: &BTreeMap<usize, Real>,
    limit: Real,
    rows: &[Row],
    samples: &[Sample],
    unknown_of: &[usize],
    unknowns: usize,
) -> Vec<usize> {
    let mut worst: Vec<(usize, Real)> = imbalance.iter().filter(|(_, r)| **r > limit).map(|(s, r)| (*s, *r)).collect();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    // Samples (one per pair of rows) left per unknown.
    let mut left = vec![0usize; unknowns];
    for r in rows.iter().step_by(2) {
        for &k in &samples[r.sample].interfaces {
            left[unknown_of[k]] += 1;
        }
    }
    let mut out = Vec::new();
    for (sample, _) in worst {
        let of_sample = samples[sample].interfaces.map(|k| unknown_of[k]);
        if of_sample.iter().all(|&u| left[u] > of_sample.iter().filter(|&&v| v == u).count()) {
            of_sample.iter().for_each(|&u| left[u] -= 1);
            out.push(sample);
        }
    }
    out.sort_unstable();
    out
}

/// For each sample, whether a sample of another junction line lies within `radius` (a hash grid of
/// cubes of edge `radius`); a line never loses all its samples this way.
fn near_other_lines(samples: &[Sample], radius: Real) -> Vec<bool> {
    let cube = |x: &Vec3| [0, 1, 2].map(|a| (x[a] / radius).floor() as i64);
    let mut grid: std::collections::HashMap<[i64; 3], Vec<usize>> = std::collections::HashMap::new();
    for (i, s) in samples.iter().enumerate() {
        grid.entry(cube(&s.x)).or_default().push(i);
    }
    let mut near: Vec<bool> = samples
        .iter()
        .map(|s| {
            let c = cube(&s.x);
            (-1..=1).any(|dx| {
                (-1..=1).any(|dy| {
                    (-1..=1).any(|dz| {
                        grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]).is_some_and(|list| {
                            list.iter().any(|&j| {
                                samples[j].line != s.line && (samples[j].x - s.x).norm_squared() < radius * radius
                            })
                        })
                    })
                })
            })
        })
        .collect();
    let lines = samples.iter().map(|s| s.line).max().map_or(0, |m| m + 1);
    let mut keeps = vec![false; lines];
    for (s, &n) in samples.iter().zip(&near) {
        keeps[s.line] |= !n;
    }
    for (s, n) in samples.iter().zip(near.iter_mut()) {
        if !keeps[s.line] {
            *n = false;
        }
    }
    near
}

/// One force-balance equation: coefficients per unknown, its junction line and sample.
pub(super) struct Row {
    pub(super) coefficients: Vec<(usize, Real)>,
    pub(super) line: usize,
    pub(super) sample: usize,
    /// How the row's coefficients move with the input's vertex coordinates, as (unknown, coordinate,
    /// ∂coefficient/∂coordinate): where given (the 2.5-D sheet), the sds propagate an isotropic
    /// vertex noise estimated from the residuals instead of clustering by line.
    pub(super) noise: Vec<(usize, usize, Real)>,
}

/// The tensions solved block by block (see the module docs).
pub(super) struct Solved {
    pub(super) tension: Vec<Option<Real>>,
    pub(super) tension_sd: Vec<Option<Real>>,
    pub(super) condition: Option<Real>,
    pub(super) gap: Option<Real>,
    pub(super) sampled: Vec<bool>,
    pub(super) warnings: Vec<String>,
}

pub(super) fn solve_tensions(
    rows: &[Row],
    n: usize,
    gauge_unknowns: &[usize],
    gauge_name: &str,
    value: Real,
) -> Result<Solved, TensionError> {
    let mut warnings = Vec::new();
    let mut parent: Vec<usize> = (0..n).collect();
    for Row { coefficients, .. } in rows {
        for w in coefficients.windows(2) {
            join(&mut parent, w[0].0, w[1].0);
        }
    }
    let root: Vec<usize> = (0..n).map(|u| group_root(&mut parent, u)).collect();
    let mut sampled = vec![false; n];
    for Row { coefficients, .. } in rows {
        for &(u, _) in coefficients {
            sampled[u] = true;
        }
    }
    let mut tension: Vec<Option<Real>> = vec![None; n];
    let mut tension_sd: Vec<Option<Real>> = vec![None; n];
    let mut condition: Option<Real> = None;
    let mut gap: Option<Real> = None;
    let mut blocks: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for u in 0..n {
        if sampled[u] {
            blocks.entry(root[u]).or_default().push(u);
        }
    }
    let gauge_blocks: Vec<usize> = {
        let mut b: Vec<usize> = gauge_unknowns.iter().filter(|&&u| sampled[u]).map(|&u| root[u]).collect();
        b.sort_unstable();
        b.dedup();
        b
    };
    if gauge_blocks.is_empty() {
        return Err(TensionError::GaugeUndetermined { gauge: gauge_name.to_string() });
    }
    if gauge_blocks.len() > 1 {
        warnings.push(format!(
            "the junctions form {} unconnected groups with a gauge tension each; each group is scaled by its own \
             gauge ({gauge_name}), so tensions compare only within a group",
            gauge_blocks.len()
        ));
    }
    for (&block_root, members) in &blocks {
        if !gauge_blocks.contains(&block_root) {
            warnings.push(format!(
                "{} tension(s) share no junction with the gauge ({gauge_name}): undetermined",
                members.len()
            ));
            continue;
        }
        let local_of: BTreeMap<usize, usize> = members.iter().enumerate().map(|(l, &u)| (u, l)).collect();
        let m = members.len();
        let block_rows: Vec<&Row> = rows.iter().filter(|r| local_of.contains_key(&r.coefficients[0].0)).collect();
        let mut a = DMatrix::<Real>::zeros(block_rows.len(), m);
        for (r, Row { coefficients, .. }) in block_rows.iter().enumerate() {
            for &(u, c) in coefficients {
                a[(r, local_of[&u])] += c;
            }
        }
        let gauge: Vec<usize> = gauge_unknowns.iter().filter_map(|u| local_of.get(u).copied()).collect();
        let noise: Vec<Vec<(usize, usize, Real)>> = block_rows
            .iter()
            .map(|r| r.noise.iter().filter_map(|&(u, c, d)| Some((*local_of.get(&u)?, c, d))).collect())
            .collect();
        let lines: Vec<usize> = block_rows.iter().map(|r| r.line).collect();
        match solve_block(&a, &lines, &noise, &gauge, value) {
            Some(solution) => {
                for (l, &u) in members.iter().enumerate() {
                    tension[u] = Some(solution.tension[l]);
                    tension_sd[u] = Some(solution.sd[l]);
                }
                if let Some(c) = solution.condition {
                    condition = Some(condition.map_or(c, |x: Real| x.max(c)));
                }
                if let Some(g) = solution.gap {
                    gap = Some(gap.map_or(g, |x: Real| x.min(g)));
                }
            }
            None => warnings.push(format!(
                "{m} tension(s) linked to the gauge are not determined by the junctions (several force-balancing \
                 directions): undetermined"
            )),
        }
    }
    Ok(Solved { tension, tension_sd, condition, gap, sampled, warnings })
}

/// Sphere or plane through the points (see the module docs): each fitted, refitted once without the
/// points farther than [`TRIM_FACTOR`] × the median distance (stray contact faces far from the
/// interface), and the sphere kept only when it fits clearly better than the plane (rms at most
/// [`SPHERE_OVER_PLANE_RMS`] of the plane's; on a nearly flat, noisy patch a sphere fits the noise).
fn fit_surface(points: &[Vec3]) -> (Option<Surface>, Option<Real>) {
    if points.len() < 3 {
        return (None, None);
    }
    let plane = trimmed(points, fit_plane);
    let sphere = if points.len() >= MIN_SPHERE_FACES { trimmed(points, fit_sphere_surface) } else { None };
    match (sphere, plane) {
        (Some((Surface::Sphere { centre, radius }, rms_s, extent)), Some((_, rms_p, _)))
            if radius < MAX_RADIUS_OVER_EXTENT * extent && rms_s <= SPHERE_OVER_PLANE_RMS * rms_p =>
        {
            (Some(Surface::Sphere { centre, radius }), Some(rms_s))
        }
        (_, Some((plane, rms_p, _))) => (Some(plane), Some(rms_p)),
        _ => (None, None),
    }
}

/// Points farther than this many median distances from a first fit are left out of the second.
pub const TRIM_FACTOR: Real = 3.0;
/// A sphere replaces the plane when its rms distance is at most this fraction of the plane's.
pub const SPHERE_OVER_PLANE_RMS: Real = 0.5;

impl Surface {
    fn distance(&self, x: &Vec3) -> Real {
        match self {
            Surface::Sphere { centre, radius } => ((x - centre).norm() - radius).abs(),
            Surface::Plane { point, normal } => (x - point).dot(normal).abs(),
        }
    }
}

/// `fit` on the points, then again on those within [`TRIM_FACTOR`] median distances of the first
/// fit: (surface, rms distance of the kept points, their rms extent about their mean).
fn trimmed(points: &[Vec3], fit: fn(&[Vec3]) -> Option<Surface>) -> Option<(Surface, Real, Real)> {
    let first = fit(points)?;
    let mut d: Vec<Real> = points.iter().map(|p| first.distance(p)).collect();
    let limit = TRIM_FACTOR * median(&mut d.clone()).unwrap_or(0.0);
    d.clear();
    let kept: Vec<Vec3> = points.iter().filter(|p| first.distance(p) <= limit).copied().collect();
    let (surface, kept) = if kept.len() >= 3 && kept.len() < points.len() {
        match fit(&kept) {
            Some(s) => (s, kept),
            None => (first, points.to_vec()),
        }
    } else {
        (first, points.to_vec())
    };
    let n = kept.len() as Real;
    let rms = (kept.iter().map(|p| surface.distance(p).powi(2)).sum::<Real>() / n).sqrt();
    let mean = kept.iter().sum::<Vec3>() / n;
    let extent = (kept.iter().map(|p| (p - mean).norm_squared()).sum::<Real>() / n).sqrt();
    Some((surface, rms, extent))
}

fn fit_sphere_surface(points: &[Vec3]) -> Option<Surface> {
    if points.len() < MIN_SPHERE_FACES {
        return None;
    }
    let (cap, _) = fit_sphere(points)?;
    cap.radius.is_finite().then_some(Surface::Sphere { centre: cap.centre, radius: cap.radius })
}

fn fit_plane(points: &[Vec3]) -> Option<Surface> {
    if points.len() < 3 {
        return None;
    }
    let plane = super::far_field::least_squares_plane(points)?;
    Some(Surface::Plane { point: plane.centroid, normal: plane.normal })
}

/// An interface's surface near a junction sample at `x0`: the sphere of the interface's own (global)
/// radius — its mean curvature, constant over an interface at equilibrium — placed to fit the far-field
/// faces within [`LOCAL_RADIUS_SCALES`] rounding scales of `x0` (the radius doubled until
/// [`MIN_SPHERE_FACES`] faces are in), or the plane through them for a plane. For interfaces that are
/// not one sphere (cells pressed by a shell or by many neighbours), whose global fit misses the
/// junction. `None` when too few faces lie near.
fn local_surface(points: &[Vec3], global: &Surface, x0: &Vec3, scale: Real) -> Option<Surface> {
    let mut radius = LOCAL_RADIUS_SCALES * scale;
    let near = loop {
        let near: Vec<Vec3> = points.iter().filter(|p| (*p - x0).norm_squared() <= radius * radius).copied().collect();
        if near.len() >= MIN_SPHERE_FACES || near.len() == points.len() || !radius.is_finite() {
            break near;
        }
        radius *= 2.0;
    };
    let Surface::Plane { point, normal } = fit_plane(&near)? else { return None };
    let Surface::Sphere { centre: global_centre, radius: r } = *global else {
        return Some(Surface::Plane { point, normal });
    };
    // The centre on the side of the global one, at distance r from the faces: Gauss–Newton on
    // Σ (|p − c| − r)² from the plane's point offset by r along its normal.
    let side = if (global_centre - point).dot(&normal) >= 0.0 { 1.0 } else { -1.0 };
    let mut c = point + normal * (side * r);
    for _ in 0..20 {
        let mut jtj = nalgebra::Matrix3::<Real>::zeros();
        let mut jtf = Vec3::zeros();
        for p in &near {
            let u = (c - p).try_normalize(0.0)?;
            let f = (c - p).norm() - r;
            jtj += u * u.transpose();
            jtf += u * f;
        }
        let step = jtj.lu().solve(&jtf)?;
        c -= step;
        if step.norm() < 1e-9 * r {
            break;
        }
    }
    c.iter().all(|v| v.is_finite()).then_some(Surface::Sphere { centre: c, radius: r })
}

/// The point nearest to `x0` on all three surfaces: Gauss–Newton on Σ_k d_k(x)² + λ|x − x0|² (the
/// surfaces meet along a line, so the small λ = 10⁻³ only fixes the position along it), from `x0`.
fn snap_to_junction(surfaces: &[Surface], x0: Vec3, h: Real) -> Vec3 {
    let lambda = 1e-3;
    let mut x = x0;
    for _ in 0..20 {
        let mut jtj = nalgebra::Matrix3::<Real>::identity() * lambda;
        let mut jtf = (x - x0) * lambda;
        for f in surfaces {
            let (value, gradient) = match f {
                Surface::Sphere { centre, radius } => {
                    let Some(n) = (x - centre).try_normalize(0.0) else { return x0 };
                    ((x - centre).norm() - radius, n)
                }
                Surface::Plane { point, normal } => ((x - point).dot(normal), *normal),
            };
            jtj += gradient * gradient.transpose();
            jtf += gradient * value;
        }
        let Some(step) = jtj.lu().solve(&jtf) else { return x0 };
        x -= step;
        if step.norm() < 1e-9 * h {
            break;
        }
    }
    x
}

/// The junction line's direction: the cross product of the two most different interface normals, or
/// the mesh edge where all three are nearly parallel (a junction with a vanishing angle).
fn line_direction(normals: &[Vec3], edge: &Vec3) -> Option<Vec3> {
    let mut best = Vec3::zeros();
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let c = normals[a].cross(&normals[b]);
        if c.norm_squared() > best.norm_squared() {
            best = c;
        }
    }
    if best.norm() > 0.1 {
        let l = best.normalize();
        return Some(if l.dot(edge) >= 0.0 { l } else { -l });
    }
    edge.try_normalize(0.0)
}

/// Mean of the points within `radius` of `x`, or of all points when none is that close.
fn local_mean(points: &[Vec3], x: &Vec3, radius: Real) -> Vec3 {
    let (sum, count) = points
        .iter()
        .filter(|p| (*p - x).norm_squared() <= radius * radius)
        .fold((Vec3::zeros(), 0usize), |(s, c), p| (s + p, c + 1));
    if count > 0 { sum / count as Real } else { points.iter().sum::<Vec3>() / points.len().max(1) as Real }
}

pub(super) fn median(values: &mut [Real]) -> Option<Real> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(|a, b| a.total_cmp(b));
    let n = values.len();
    Some(if n % 2 == 1 { values[n / 2] } else { (values[n / 2 - 1] + values[n / 2]) / 2.0 })
}

struct BlockSolution {
    tension: Vec<Real>,
    sd: Vec<Real>,
    condition: Option<Real>,
    /// σ_second-smallest / σ_smallest: how far the best-balancing direction stands apart from the next.
    gap: Option<Real>,
}

/// The tensions that balance the samples best for their mean, `min |A T|²` with `mean(T) = 1`
/// (see the module docs), scaled so that the mean over `gauge` is `value`, and their cluster-robust
/// standard deviations; `None` when the samples leave several balancing directions (the two smallest
/// singular values of `a` coincide).
fn solve_block(
    a: &DMatrix<Real>,
    line_of_row: &[usize],
    noise: &[Vec<(usize, usize, Real)>],
    gauge: &[usize],
    value: Real,
) -> Option<BlockSolution> {
    let m = a.ncols();
    if m == 1 {
        // A single unknown (all samples on one shared tension): only the gauge fixes it.
        return Some(BlockSolution { tension: vec![value], sd: vec![0.0], condition: None, gap: None });
    }
    let normal = a.transpose() * a;
    let mut sigma2: Vec<Real> = normal.clone().symmetric_eigenvalues().iter().copied().collect();
    sigma2.sort_by(|x, y| y.total_cmp(x));
    let (largest, second, lowest) = (sigma2[0], sigma2[m - 2], sigma2[m - 1].max(0.0));
    if largest.is_nan() || largest <= 0.0 || second - lowest <= SINGULAR_TOLERANCE * largest {
        return None;
    }
    // Z: an orthonormal basis of the directions that keep the mean (columns 1.. of the Householder
    // reflection taking 1/√m to −e₀). T = 1 + Z y with y minimising |A(1 + Z y)|².
    let mut w = DVector::<Real>::from_element(m, 1.0 / (m as Real).sqrt());
    w[0] += 1.0;
    let householder = DMatrix::<Real>::identity(m, m) - &w * w.transpose() * (2.0 / w.norm_squared());
    let z = householder.columns(1, m - 1).into_owned();
    let reduced = z.transpose() * &normal * &z;
    let reduced_inverse = reduced.try_inverse()?;
    // K = Z (ZᵀMZ)⁻¹ Zᵀ: the response of the constrained minimum to a perturbation of M.
    let k = &z * reduced_inverse * z.transpose();
    let ones = DVector::<Real>::from_element(m, 1.0);
    let v: DVector<Real> = &ones - &k * (&normal * &ones);
    if v.iter().any(|x| !x.is_finite()) {
        return None;
    }
    let mean = |entries: &[usize]| entries.iter().map(|&k| v[k]).sum::<Real>() / entries.len().max(1) as Real;
    let mut g = mean(gauge);
    if g == 0.0 || !g.is_finite() {
        return None;
    }
    // Gauge tensions that come out ≤ 0 (a spurious free patch of a buried cell, a mis-read
    // junction) are left out of the gauge's mean: one such value would rescale every tension.
    let positive: Vec<usize> = gauge.iter().copied().filter(|&k| v[k] / g > 0.0).collect();
    let gauge: &[usize] = if !positive.is_empty() && positive.len() < gauge.len() {
        g = mean(&positive);
        &positive
    } else {
        gauge
    };
    // x · value / g, not x · (value / g): a gauge tension comes out exactly `value`.
    let tension: DVector<Real> = v.map(|x| x * value / g);
    // First-order response to the samples' errors, estimated by the residuals r = A v: δv = −K Aᵀ r,
    // clustered by line; or, where the rows say how they move with the vertices, from an isotropic
    // vertex noise σ² estimated from the residuals (see `vertex_noise_meat`).
    let residual = a * &v;
    let cov_v = match vertex_noise_meat(a, &v, &residual, &k, noise) {
        Some(meat) => &k * meat * &k,
        None => {
            let mut scores: BTreeMap<usize, DVector<Real>> = BTreeMap::new();
            for (r, &line) in line_of_row.iter().enumerate() {
                let row: DVector<Real> = a.row(r).transpose();
                *scores.entry(line).or_insert_with(|| DVector::zeros(m)) += row * residual[r];
            }
            let groups = scores.len() as Real;
            let mut meat = DMatrix::<Real>::zeros(m, m);
            for s in scores.values() {
                meat += s * s.transpose();
            }
            let correction = if groups > 1.0 { groups / (groups - 1.0) } else { 1.0 };
            &k * meat * &k * correction
        }
    };
    // T = value · v / g(v): J = (value / g) (I − v gᵀ / g), g = mean over the gauge entries.
    let mut gvec = DVector::<Real>::zeros(m);
    for &k in gauge {
        gvec[k] += 1.0 / gauge.len() as Real;
    }
    let j = (DMatrix::<Real>::identity(m, m) - &v * gvec.transpose() / g) * (value / g);
    let cov_t = &j * cov_v * j.transpose();
    let sd = (0..m).map(|k| cov_t[(k, k)].max(0.0).sqrt()).collect();
    let gap = if lowest > 0.0 { (second / lowest).sqrt() } else { Real::INFINITY };
    Some(BlockSolution {
        tension: tension.iter().copied().collect(),
        sd,
        condition: Some((largest / second).sqrt()),
        gap: Some(gap),
    })
}

/// Σ_c s_c s_cᵀ σ² for an isotropic noise σ² of the input's vertex coordinates: the residual of row
/// i moves with coordinate c by g_ic = Σ_u v_u ∂A_iu/∂x_c, the solution by K s_c with s_c = Σ_i A_iᵀ
/// g_ic, and E|r|² = σ² (Σ_ic g_ic² − Σ_c s_cᵀ K s_c) gives σ². Rows sharing a vertex (a wall seen at
/// both its junctions) are correlated through it. `None` where no row carries a noise loading.
fn vertex_noise_meat(
    a: &DMatrix<Real>,
    v: &DVector<Real>,
    residual: &DVector<Real>,
    k: &DMatrix<Real>,
    noise: &[Vec<(usize, usize, Real)>],
) -> Option<DMatrix<Real>> {
    if noise.iter().all(|n| n.is_empty()) {
        return None;
    }
    let m = a.ncols();
    // g_ic per coordinate, then s_c.
    let mut g: BTreeMap<usize, Vec<(usize, Real)>> = BTreeMap::new();
    for (i, loadings) in noise.iter().enumerate() {
        let mut by_coordinate: BTreeMap<usize, Real> = BTreeMap::new();
        for &(u, c, d) in loadings {
            *by_coordinate.entry(c).or_default() += v[u] * d;
        }
        for (c, value) in by_coordinate {
            g.entry(c).or_default().push((i, value));
        }
    }
    let mut total = 0.0;
    let mut explained = 0.0;
    let mut meat = DMatrix::<Real>::zeros(m, m);
    for entries in g.values() {
        // s_c is sparse: the unknowns of the few rows that coordinate c enters.
        let mut s: BTreeMap<usize, Real> = BTreeMap::new();
        for &(i, value) in entries {
            total += value * value;
            for (u, &x) in a.row(i).iter().enumerate() {
                if x != 0.0 {
                    *s.entry(u).or_default() += x * value;
                }
            }
        }
        for (&p, &sp) in &s {
            for (&q, &sq) in &s {
                explained += sp * k[(p, q)] * sq;
                meat[(p, q)] += sp * sq;
            }
        }
    }
    let dof = total - explained;
    if dof.is_nan() || dof <= 0.0 {
        return None;
    }
    let sigma2 = residual.norm_squared() / dof;
    Some(meat * sigma2)
}

/// Union–find over `parent` (each entry its own root at first): the root of `i`'s group, halving the
/// path on the way.
fn group_root(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// Merges the groups of `a` and `b`; the smaller root stays the root (groups in order of their
/// smallest member).
fn join(parent: &mut [usize], a: usize, b: usize) {
    let (ra, rb) = (group_root(parent, a), group_root(parent, b));
    parent[ra.max(rb)] = ra.min(rb);
}

/// A cell's pressure relative to the medium and relative to the mean of its group (the cells that
/// determined interfaces connect it to), each with its standard deviation.
#[derive(Clone, Copy, Debug, Default)]
struct PressureEstimate {
    absolute: Option<(Real, Real)>,
    relative: Option<(Real, Real)>,
}

/// One Young–Laplace equation p_a − p_b = value (b `None`: the medium, pressure 0) with the variance
/// that the interface's tension sd gives it.
struct LaplaceRow {
    a: usize,
    b: Option<usize>,
    value: Real,
    variance: Real,
}

/// [`laplace_least_squares`] over rows `(a, b, value, variance)`: p_a − p_b = value between two cells.
pub(super) fn laplace_least_squares_rows(
    rows: &[(usize, usize, Real, Real)],
    unknowns: &[usize],
) -> Option<(DVector<Real>, DMatrix<Real>, Real)> {
    let rows: Vec<LaplaceRow> =
        rows.iter().map(|&(a, b, value, variance)| LaplaceRow { a, b: Some(b), value, variance }).collect();
    laplace_least_squares(&rows.iter().collect::<Vec<_>>(), unknowns)
}

/// Least squares over `rows` in the `unknowns` (tissue indices): the minimum-norm solution (where only
/// differences are fixed, the one with mean 0), its covariance (the rows' variances through the
/// pseudo-inverse plus the residual scatter) and the residual's sum of squares with its row count.
fn laplace_least_squares(rows: &[&LaplaceRow], unknowns: &[usize]) -> Option<(DVector<Real>, DMatrix<Real>, Real)> {
    let local: BTreeMap<usize, usize> = unknowns.iter().enumerate().map(|(l, &i)| (i, l)).collect();
    let (m, n) = (rows.len(), unknowns.len());
    let mut a = DMatrix::<Real>::zeros(m, n);
    let mut b = DVector::<Real>::zeros(m);
    for (r, e) in rows.iter().enumerate() {
        a[(r, local[&e.a])] += 1.0;
        if let Some(j) = e.b {
            a[(r, local[&j])] -= 1.0;
        }
        b[r] = e.value;
    }
    let svd = a.clone().svd(true, true);
    let p = svd.solve(&b, 1e-12).ok()?;
    let residual = &a * &p - &b;
    let rank = svd.singular_values.iter().filter(|&&s| s > 1e-12).count();
    let pinv = svd.pseudo_inverse(1e-12).ok()?;
    let var_b = DMatrix::<Real>::from_diagonal(&DVector::from_iterator(m, rows.iter().map(|e| e.variance)));
    let mut cov = &pinv * var_b * pinv.transpose();
    if m > rank {
        cov += &pinv * pinv.transpose() * (residual.norm_squared() / (m - rank) as Real);
    }
    Some((p, cov, residual.norm_squared()))
}

/// Least-squares pressures (per tissue index) from Young–Laplace on the determined interfaces, and the
/// rms residual. Relative to the medium where a chain of determined interfaces reaches it; relative to
/// the mean of its group for every cell that determined interfaces connect to another (a dense crop
/// with no free surface has only these).
fn solve_pressures(
    interfaces: &[InterfaceTension],
    cell_index: &BTreeMap<u32, usize>,
    n_cells: usize,
    warnings: &mut Vec<String>,
) -> (Vec<PressureEstimate>, Option<Real>) {
    let mut out = vec![PressureEstimate::default(); n_cells];
    let mut equations: Vec<LaplaceRow> = Vec::new();
    for f in interfaces {
        let (Some(t), Some(h)) = (f.tension, f.mean_curvature) else { continue };
        if t <= 0.0 {
            continue;
        }
        let (Some(&a), b) = (cell_index.get(&f.cell_a), cell_index.get(&f.cell_b).copied()) else { continue };
        let sd = f.tension_sd.unwrap_or(0.0);
        equations.push(LaplaceRow { a, b, value: 2.0 * h * t, variance: (2.0 * h * sd).powi(2) });
    }
    // Groups of cells linked by cell–cell equations (union–find), and those reaching the medium.
    let mut parent: Vec<usize> = (0..n_cells).collect();
    for e in &equations {
        if let Some(b) = e.b {
            join(&mut parent, e.a, b);
        }
    }
    let group: Vec<usize> = (0..n_cells).map(|i| group_root(&mut parent, i)).collect();
    let mut in_equation = vec![false; n_cells];
    let mut reaches_medium = vec![false; n_cells];
    for e in &equations {
        in_equation[e.a] = true;
        if let Some(b) = e.b {
            in_equation[b] = true;
        } else {
            reaches_medium[group[e.a]] = true;
        }
    }
    let mut members: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for i in (0..n_cells).filter(|&i| in_equation[i]) {
        members.entry(group[i]).or_default().push(i);
    }
    let unreached: Vec<(u32, usize)> =
        cell_index.iter().filter(|(_, i)| !reaches_medium[group[**i]]).map(|(&id, &i)| (id, i)).collect();
    let relative_only = unreached.iter().filter(|(_, i)| members.get(&group[*i]).is_some_and(|m| m.len() > 1)).count();
    if !unreached.is_empty() {
        let ids: Vec<String> = unreached.iter().map(|(id, _)| id.to_string()).collect();
        warnings.push(format!(
            "cell(s) {}: no determined interface links them to the medium, so their pressure is undetermined{}",
            ids.join(", "),
            if relative_only > 0 {
                format!(
                    "; {relative_only} of them have a pressure relative to the cells they are linked to \
                     (pressure_relative: the cell's pressure minus its group's mean)"
                )
            } else {
                String::new()
            }
        ));
    }
    // Relative to the medium: every cell of the groups that reach it, in one least squares.
    let (mut squares, mut count) = (0.0, 0usize);
    let reached: Vec<usize> = (0..n_cells).filter(|&i| in_equation[i] && reaches_medium[group[i]]).collect();
    let mut groups_cov: Vec<(Vec<usize>, DVector<Real>, DMatrix<Real>)> = Vec::new();
    if !reached.is_empty() {
        let rows: Vec<&LaplaceRow> = equations.iter().filter(|e| reaches_medium[group[e.a]]).collect();
        if let Some((p, cov, ss)) = laplace_least_squares(&rows, &reached) {
            squares += ss;
            count += rows.len();
            for (l, &i) in reached.iter().enumerate() {
                out[i].absolute = Some((p[l], cov[(l, l)].max(0.0).sqrt()));
            }
            // Each group's block, for its relative pressures below.
            let local: BTreeMap<usize, usize> = reached.iter().enumerate().map(|(l, &i)| (i, l)).collect();
            for cells in members.values().filter(|c| reaches_medium[group[c[0]]]) {
                let idx: Vec<usize> = cells.iter().map(|i| local[i]).collect();
                let sub_p = DVector::from_iterator(idx.len(), idx.iter().map(|&l| p[l]));
                let sub_cov = DMatrix::from_fn(idx.len(), idx.len(), |r, c| cov[(idx[r], idx[c])]);
                groups_cov.push((cells.clone(), sub_p, sub_cov));
            }
        }
    }
    // Relative to the group's mean only: each group that does not reach the medium, on its own.
    for cells in members.values().filter(|c| !reaches_medium[group[c[0]]] && c.len() > 1) {
        let rows: Vec<&LaplaceRow> = equations.iter().filter(|e| group[e.a] == group[cells[0]]).collect();
        if let Some((p, cov, ss)) = laplace_least_squares(&rows, cells) {
            squares += ss;
            count += rows.len();
            groups_cov.push((cells.clone(), p, cov));
        }
    }
    // Relative pressures: p − mean(p) over the group, covariance C Σ Cᵀ with C the centring matrix.
    for (cells, p, cov) in groups_cov.into_iter().filter(|(c, _, _)| c.len() > 1) {
        let k = cells.len();
        let centring = DMatrix::<Real>::identity(k, k) - DMatrix::<Real>::from_element(k, k, 1.0 / k as Real);
        let rel = &centring * p;
        let rel_cov = &centring * cov * centring.transpose();
        for (l, &i) in cells.iter().enumerate() {
            out[i].relative = Some((rel[l], rel_cov[(l, l)].max(0.0).sqrt()));
        }
    }
    let rms = (count > 0).then(|| (squares / count as Real).sqrt());
    (out, rms)
}

/// The map as per-cell parameters of the model: each cell's free tension (its interface with the
/// medium) and a lateral tension a_i such that every cell–cell interface pulls with T_ij ≈ a_i + a_j
/// (what coupled contacts make of two cells' lateral tensions), by least squares over the determined
/// cell–cell interfaces of each connected group of cells. A group whose interfaces do not fix every
/// a_i (two cells: one equation, two unknowns; more generally a group without a cycle of odd
/// length) leaves its cells' lateral tensions undetermined rather than splitting T arbitrarily.
#[derive(Clone, Debug, PartialEq)]
pub struct PerCellTensions {
    /// In the order of [`TensionMap::cells`].
    pub cells: Vec<PerCellTension>,
    /// Rms over the determined cell–cell interfaces of the groups solved of (a_i + a_j − T_ij)/T_ij:
    /// how far the map is from additive (0 for a map that per-cell tensions reproduce exactly);
    /// `None` when no group was solved.
    pub additive_residual_rms: Option<Real>,
}

/// One cell of [`PerCellTensions`], in units of the gauge.
#[derive(Clone, Debug, PartialEq)]
pub struct PerCellTension {
    pub cell: u32,
    /// The tension of the cell's interface with the medium; `None` when it has none or it is
    /// undetermined.
    pub free: Option<Real>,
    /// a_i; `None` when undetermined.
    pub lateral: Option<Real>,
}

/// Decomposes `map` into per-cell tensions ([`PerCellTensions`]).
pub fn per_cell_tensions(map: &TensionMap) -> PerCellTensions {
    let index: std::collections::HashMap<u32, usize> = map.cells.iter().enumerate().map(|(i, c)| (c.cell, i)).collect();
    let pairs: Vec<(usize, usize, Real)> = map
        .interfaces
        .iter()
        .filter(|f| f.cell_b != 0)
        .filter_map(|f| Some((*index.get(&f.cell_a)?, *index.get(&f.cell_b)?, f.tension?)))
        .collect();
    // Connected groups of cells over the determined interfaces (union–find).
    let n = map.cells.len();
    let mut parent: Vec<usize> = (0..n).collect();
    for &(a, b, _) in &pairs {
        join(&mut parent, a, b);
    }
    // Each group's cells and interfaces, in one pass (groups in order of their smallest cell).
    let roots: Vec<usize> = (0..n).map(|i| group_root(&mut parent, i)).collect();
    type Group = (Vec<usize>, Vec<(usize, usize, Real)>);
    let mut groups: std::collections::BTreeMap<usize, Group> = Default::default();
    for (i, &r) in roots.iter().enumerate() {
        groups.entry(r).or_default().0.push(i);
    }
    for &pair in &pairs {
        groups.entry(roots[pair.0]).or_default().1.push(pair);
    }
    let mut lateral: Vec<Option<Real>> = vec![None; n];
    let mut column = vec![0; n];
    let mut relative = Vec::new();
    for (members, rows) in groups.values().filter(|(_, rows)| !rows.is_empty()) {
        for (k, &i) in members.iter().enumerate() {
            column[i] = k;
        }
        let mut a = DMatrix::<Real>::zeros(rows.len(), members.len());
        let mut t = DVector::<Real>::zeros(rows.len());
        for (r, &(i, j, tension)) in rows.iter().enumerate() {
            a[(r, column[i])] = 1.0;
            a[(r, column[j])] = 1.0;
            t[r] = tension;
        }
        let svd = a.clone().svd(true, true);
        let largest = svd.singular_values.max();
        let rank = svd.singular_values.iter().filter(|&&s| s > 1e-9 * largest).count();
        if rank < members.len() {
            continue;
        }
        let Ok(x) = svd.solve(&t, 1e-12 * largest) else { continue };
        for (k, &i) in members.iter().enumerate() {
            lateral[i] = Some(x[k]);
        }
        let fitted = &a * &x;
        relative.extend(rows.iter().enumerate().map(|(r, row)| (fitted[r] - row.2) / row.2));
    }
    let free: std::collections::HashMap<u32, Real> =
        map.interfaces.iter().filter(|f| f.cell_b == 0).filter_map(|f| Some((f.cell_a, f.tension?))).collect();
    PerCellTensions {
        cells: map
            .cells
            .iter()
            .zip(lateral)
            .map(|(c, lateral)| PerCellTension { cell: c.cell, free: free.get(&c.cell).copied(), lateral })
            .collect(),
        additive_residual_rms: (!relative.is_empty())
            .then(|| (relative.iter().map(|r| r * r).sum::<Real>() / relative.len() as Real).sqrt()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points of a sphere of radius 10 about the origin within 30° of +z.
    fn cap() -> Vec<Vec3> {
        let mut points = Vec::new();
        for i in 1..=6 {
            let polar = (i as Real) * 5.0_f64.to_radians();
            for j in 0..24 {
                let azimuth = (j as Real) * std::f64::consts::TAU / 24.0;
                points.push(10.0 * Vec3::new(polar.sin() * azimuth.cos(), polar.sin() * azimuth.sin(), polar.cos()));
            }
        }
        points
    }

    /// The block solve is the least squares |A T|² with mean(T) = 1 (then scaled to the gauge): on a
    /// random inconsistent system it equals the Lagrange solution T ∝ (AᵀA)⁻¹ 1.
    #[test]
    fn the_block_solve_is_the_mean_constrained_least_squares() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (rows, m) = (24, 5);
        let a = DMatrix::<Real>::from_fn(rows, m, |_, _| rng.random::<Real>() * 2.0 - 1.0);
        let lines: Vec<usize> = (0..rows).map(|r| r / 2).collect();
        let gauge = [1, 3];
        let got = solve_block(&a, &lines, &vec![Vec::new(); lines.len()], &gauge, 2.0).unwrap();
        let lagrange = (a.transpose() * &a).try_inverse().unwrap() * DVector::<Real>::from_element(m, 1.0);
        let scale = 2.0 / ((lagrange[1] + lagrange[3]) / 2.0);
        for k in 0..m {
            assert!(
                (got.tension[k] - lagrange[k] * scale).abs() < 1e-10,
                "{k}: {} vs {}",
                got.tension[k],
                lagrange[k] * scale
            );
        }
        assert!((got.tension[1] + got.tension[3] - 4.0).abs() < 1e-12);
        assert!(got.sd.iter().all(|s| s.is_finite() && *s > 0.0));
        assert!(got.gap.is_some_and(|g| g > 1.0 && g.is_finite()));
    }

    #[test]
    fn a_local_fit_places_the_global_radius_through_the_faces_near_the_sample() {
        let points = cap();
        // The global fit: the right radius, its centre off by 2 (an interface that is not one sphere).
        let global = Surface::Sphere { centre: Vec3::new(2.0, 0.0, 0.0), radius: 10.0 };
        let x0 = points[0];
        let Some(Surface::Sphere { centre, radius }) = local_surface(&points, &global, &x0, 0.5) else {
            panic!("no local sphere")
        };
        assert_eq!(radius, 10.0);
        assert!(centre.norm() < 1e-6, "centre {centre:?}");
        // A plane stays a plane.
        let plane = Surface::Plane { point: Vec3::zeros(), normal: Vec3::z() };
        assert!(matches!(local_surface(&points, &plane, &x0, 0.5), Some(Surface::Plane { .. })));
        // Non-finite faces end the search (no endless widening), and too few faces give nothing.
        let broken = vec![Vec3::repeat(Real::NAN); 20];
        assert!(local_surface(&broken, &global, &x0, 0.5).is_none());
        assert!(local_surface(&points[..2], &global, &x0, 0.5).is_none());
    }

    #[test]
    fn only_cells_on_the_border_list_are_cut() {
        let fov = FieldOfView {
            lo: Vec3::zeros(),
            hi: Vec3::repeat(10.0),
            margin: Vec3::repeat(1.0),
            cut_cells: Some([3].into()),
        };
        let near_side = Vec3::new(0.5, 5.0, 5.0);
        assert!(fov.on_border(3, &near_side, 0.1));
        assert!(!fov.on_border(4, &near_side, 0.1));
        assert!(!fov.on_border(3, &Vec3::repeat(5.0), 0.1));
        let any = FieldOfView { cut_cells: None, ..fov };
        assert!(any.on_border(4, &near_side, 0.1));
    }
}
