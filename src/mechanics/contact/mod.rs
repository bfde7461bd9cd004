//! Contacts between cells: the spring model of the paper (Methods, "Intercellular contacts", Eq. 2),
//! written as an energy so that its forces are exact gradients and overdamped runs never gain energy.
//!
//! **Model.** Every node p of a cell A that lies within the cutoff c of another cell B's surface
//! carries the energy a_p·Φ(d), where d is the signed distance from p to B's surface (positive
//! outside B), Φ the energy density of Eq. 2 ([`contact_energy_density`], dΦ/dd = σ) and a_p the
//! area of p (a third of its faces' areas). The paper multiplies σ by a face area; using the node's
//! own area instead makes the energy continuous when the closest face of B changes, so it is a true
//! potential. The distance is to B's whole surface (its closest face, found through a spatial grid),
//! with the inside/outside sign taken from the pseudo-normal of the closest feature (face normal,
//! sum of the two face normals of an edge, angle-weighted normal of a vertex: Bærentzen & Aanæs
//! 2005), so the sign flips only where p crosses B's surface, where σ = 0. Pairs deeper than −c
//! (where Eq. 2's stress vanishes) are ignored.
//!
//! **Several cells within the cutoff.** Φ splits into the repulsion R(d) ≥ 0 and the adhesion well
//! A(d) ∈ [−W, 0], W = ωc²/4. A node near several cells pays every repulsion but adheres with one
//! well at most: its energy density is Σ_k R(d_k) − W·(1 − Π_k(1 − A(d_k)/(−W))), which is Eq. 2's Φ
//! for a single pair (see `combine_wells`). The area term −Φ·∇a_p below acts as a surface tension Φ
//! added to the node's γ, so summing the wells would give a node near k cells the net tension γ − kW:
//! negative once kW > γ, and the surface then crumples without bound (measured at the paper's
//! ω̃ = ωl/K = 1 with c = l_min = 1.6 µm, where W = γ/2). With one well the net tension stays
//! ≥ γ − W; a configuration with W ≥ γ (complete wetting) has no equilibrium, and validation flags
//! W ≥ 0.7γ (see `FaceParams::MAX_ADHESION_TENSION_RATIO`).
//!
//! **Quadrature.** The sum over nodes is the default (`numerics.contact_quadrature = "vertices"`).
//! With `"faces"` the energy is Σ_f A_f·Φ_f instead, Φ_f the exact mean of Φ over face f with d
//! linear between its corners ([`face_quadrature`]): the energy then no longer changes when nodes
//! slide along an unchanged surface, which moves a doublet's contact line to Young–Dupré (docs:
//! design note "Spring contacts and Young–Dupré"). Pairs are then searched out to c plus the
//! longest edge, and kept down to that depth.
//!
//! **Forces** (exact: the distance's gradient is the unit separation û for p and −w_i·û for the
//! vertices of B's closest face, w the barycentric weights): p gets −a_p σ û, the vertices of the face
//! get +a_p σ w_i û (equal and opposite), and the faces around p get −Φ·∇a_p (the area term).
//!
//! **Two face types.** A node uses the ω and ξ of its own cell, averaged over the faces around it
//! (constants of the configuration, so the energy stays a smooth potential; taking the other side's
//! closest face instead would make ω jump whenever the closest face changes type). Since both
//! surfaces' nodes sense each other, a contact between a lateral face of A and an apical face of B
//! is governed by both sides' values, each on its own nodes.
//!
//! **Enclosing bodies.** A cell inside the ECM lies inside the ECM's closed surface, so for nodes of
//! other cells the sign of the distance to an ECM surface is flipped: adhesion from the inside,
//! repulsion when pushed out through it.
//!
//! Nuclei lie inside their host cell (the cell containing the nucleus's centroid, found at every
//! evaluation): for a nucleus node the distance to its host's surface is flipped the same way, so
//! the host's membrane holds the nucleus in. A nucleus's adhesion is its own: nodes of other bodies
//! near a nucleus adhere with the nucleus type's ω (its mean over face types) where it is below their
//! own, as in the reference program (which takes k_adh from the face's side) and the paper's
//! Application 2 (non-adhesive nuclei, ω_n = 0); otherwise a host's membrane would stick to its
//! nucleus with the host's ω. Capping it at the node's own ω keeps every well within the node's own
//! depth, which [`combine_wells`] assumes (a deeper well would be clipped there, and a node of ω = 0
//! would adhere through one pair but not through two).
//!
//! **Search.** Each node's candidate faces (those of other cells whose bounding box, padded by the
//! search radius and a skin, holds the node) are found through a spatial grid and kept across
//! evaluations until some node may have moved by half the skin; when a few cells' triangles change
//! (remeshing) only the entries involving those cells are searched again (Verlet lists,
//! [`CandidateLists`]). Every evaluation tests the candidates exactly as an
//! exhaustive search would, so keeping them changes no result, only the cost: near equilibrium the
//! grid is rebuilt a few times per thousand steps instead of at every step.
//!
//! **Determinism.** Pairs are found in parallel per cell (read-only), then forces are applied in a
//! fixed order (cell, node), so results do not depend on the thread count.

mod candidates;
mod coupling;
mod face_quadrature;
mod spring;

pub use coupling::{CoupledPair, CouplingWorkspace};
pub use spring::{
    adhesion_energy_density, adhesion_stress, contact_energy_density, contact_stress, repulsion_energy_density,
    repulsion_stress,
};

use super::CellForces;
use super::{CellTypeParams, ContactModel, ContactQuadrature};
use crate::geometry::{Real, SpatialGrid, TriangleRegion, Vec3, closest_point_on_triangle, triangle_area_gradients};
use crate::mesh::{Adjacency, Cell, CellKind, FaceType, Tissue};
use candidates::{CandidateLists, Refresh};
use rayon::prelude::*;
use std::sync::OnceLock;

/// Topology of one cell needed by contacts, cached until its triangles change.
#[derive(Clone, Debug, Default)]
struct CellTopology {
    generation: u64,
    node_face_offsets: Vec<u32>,
    node_faces: Vec<u32>,
    /// The face across each side of each face (u32::MAX at a boundary or non-manifold edge).
    face_neighbours: Vec<[u32; 3]>,
}

impl CellTopology {
    fn update(&mut self, mesh: &crate::mesh::CellMesh) {
        if self.generation == mesh.topology_generation() && !self.node_face_offsets.is_empty() {
            return;
        }
        let adj = Adjacency::new(mesh);
        self.node_face_offsets.clear();
        self.node_faces.clear();
        self.node_face_offsets.push(0);
        for n in 0..mesh.node_count() {
            self.node_faces.extend_from_slice(adj.node_faces(n));
            self.node_face_offsets.push(self.node_faces.len() as u32);
        }
        self.face_neighbours = (0..mesh.face_count())
            .map(|f| {
                adj.face_edges(f).map(|e| match adj.edge_faces(e as usize) {
                    [a, b] => {
                        if *a as usize == f {
                            *b
                        } else {
                            *a
                        }
                    }
                    _ => u32::MAX,
                })
            })
            .collect();
        self.generation = mesh.topology_generation();
    }

    fn faces_of(&self, node: u32) -> &[u32] {
        &self.node_faces
            [self.node_face_offsets[node as usize] as usize..self.node_face_offsets[node as usize + 1] as usize]
    }
}

/// One node of cell A within the cutoff of cell B's surface.
#[derive(Clone, Copy, Debug)]
struct Pair {
    node: u32,
    other: u32,
    face: u32,
    weights: [Real; 3],
    /// ∂d/∂p: unit vector from B's closest point towards p, signed so that d grows along it.
    direction: Vec3,
    /// Node area a_p (m²); 0 with the face quadrature, which weights faces instead (as are `phi`,
    /// `sigma`, `well` and `well_slope`).
    area: Real,
    /// Signed distance d (m).
    distance: Real,
    /// This pair's share of the node's energy density (J/m²) and ∂Φ_p/∂d (Pa) (see [`combine_wells`]).
    phi: Real,
    sigma: Real,
    /// The pair's own adhesion well A(d) (J/m²) and its slope dA/dd (Pa), before combining.
    well: Real,
    well_slope: Real,
    /// Largest ω this pair may adhere with (Pa/m): 0 between two coupling cells, the nucleus's own
    /// mean ω towards a nucleus, unbounded otherwise. Used by the face quadrature.
    adhesion_cap: Real,
    /// ∂E/∂d of the face quadrature (J/m): the sum over the faces around the node of A_f·∂Φ_f/∂d.
    coefficient: Real,
}

/// Combines the pairs of one node (all other cells within the cutoff) into the node's energy density
///
///   Φ_p = Σ_k R(d_k) − W·(1 − Π_k (1 − s_k)),   s_k = A(d_k)/(−W) ∈ [0, 1],
///
/// W = ωc²/4 the well depth of the node's own ω. Repulsions R add up; the adhesion wells saturate at
/// one well: a patch of membrane adheres to one surface at a time, so a node within the cutoff of
/// several cells (near a junction, or on a coarse mesh whose cutoff spans several surfaces) gains at
/// most the adhesion energy W per unit area. Summing the wells instead gives a node near k surfaces
/// −k·W; with kW > γ its net surface tension γ + Φ_p is negative and the energy decreases without
/// bound as the surface crumples (measured on the 24-cell vesicle at ωc²/4 = γ/2: the contact energy
/// outgrew the tension energy until a surface folded at step 136). With one pair Φ_p = R + A, Eq. 2's
/// energy. On entry `phi`, `sigma` hold R(d_k) and R'(d_k); on return, each pair's share of Φ_p (the
/// shares sum to Φ_p) and ∂Φ_p/∂d_k = R'(d_k) + A'(d_k)·Π_{j≠k}(1 − s_j).
fn combine_wells(pairs: &mut [Pair], depth: Real) {
    if let [pair] = pairs {
        pair.phi += pair.well;
        pair.sigma += pair.well_slope;
        return;
    }
    if depth <= 0.0 {
        return;
    }
    let fraction = |p: &Pair| (-p.well / depth).clamp(0.0, 1.0);
    let free: Real = pairs.iter().map(|p| 1.0 - fraction(p)).product();
    let covered: Real = pairs.iter().map(fraction).sum();
    let total = -depth * (1.0 - free);
    for k in 0..pairs.len() {
        let others: Real = pairs.iter().enumerate().filter(|&(j, _)| j != k).map(|(_, p)| 1.0 - fraction(p)).product();
        let s = fraction(&pairs[k]);
        let pair = &mut pairs[k];
        pair.sigma += pair.well_slope * others;
        if covered > 0.0 {
            pair.phi += total * s / covered;
        }
    }
}

/// The face quadrature's version of [`combine_wells`]: for the partners of one face (their face
/// means, [`face_quadrature::FaceTerm`]), Φ_f = Σ_k R̄_k − W·(1 − Π_k (1 − s_k)), s_k = Ā_k/(−W),
/// W the face's well depth, and ∂Φ_f/∂d at the three corners for each partner. With one partner
/// Φ_f = R̄ + Ā exactly.
fn combine_face_wells(terms: &[face_quadrature::FaceTerm], depth: Real) -> (Real, Vec<[Real; 3]>) {
    if let [t] = terms {
        let g = std::array::from_fn(|k| t.repulsion_grad[k] + t.well_grad[k]);
        return (t.repulsion + t.well, vec![g]);
    }
    let mut phi: Real = terms.iter().map(|t| t.repulsion).sum();
    if depth <= 0.0 {
        return (phi, terms.iter().map(|t| t.repulsion_grad).collect());
    }
    let free = |t: &face_quadrature::FaceTerm| 1.0 - (-t.well / depth).clamp(0.0, 1.0);
    let all_free: Real = terms.iter().map(free).product();
    phi -= depth * (1.0 - all_free);
    let slopes = (0..terms.len())
        .map(|k| {
            let others: Real = terms.iter().enumerate().filter(|&(j, _)| j != k).map(|(_, t)| free(t)).product();
            std::array::from_fn(|c| terms[k].repulsion_grad[c] + terms[k].well_grad[c] * others)
        })
        .collect();
    (phi, slopes)
}

/// Reusable buffers of the contact stage.
#[derive(Default)]
pub struct ContactWorkspace {
    grid: Option<SpatialGrid>,
    /// Every face's bounding box padded by the search radius, cell after cell.
    boxes: Vec<(Vec3, Vec3)>,
    /// Where each cell's faces start in `boxes` (global face index = offset + local index).
    face_offsets: Vec<u32>,
    /// Candidate faces of every node, kept across evaluations.
    candidates: CandidateLists,
    /// How many times the candidate lists were rebuilt since this workspace was created.
    pub candidate_rebuilds: usize,
    /// How many times they were brought up to date for a few remeshed cells instead.
    pub candidate_updates: usize,
    topology: Vec<CellTopology>,
    pairs: Vec<Vec<Pair>>,
    /// Per cell, the closest face found for each (node, other cell) at the last evaluation, and the
    /// buffer the current one fills (see [`ClosestHints`]).
    hints: Vec<ClosestHints>,
    /// Number of node–surface pairs in the last evaluation.
    pub pair_count: usize,
    /// Which contact model the springs serve: with [`ContactModel::Coupling`], two coupling cells
    /// (epithelial or static) only repel each other (their adhesion is the coupling).
    model: ContactModel,
    /// How the energy density is integrated over the surface (default: at the nodes).
    quadrature: ContactQuadrature,
    /// The cutoff of the last evaluation (pairs are searched farther with the face quadrature).
    cutoff: Real,
    /// Per cell, the face quadrature's energy density Φ_f of every face (J/m²).
    face_density: Vec<Vec<Real>>,
    /// Per cell, whether each face folds against a neighbour at this evaluation ([`fold_flags`]),
    /// computed the first time a node's closest feature on that cell is asked about.
    folds: Vec<OnceLock<Vec<bool>>>,
    /// Time spent in the last evaluation, per phase.
    pub timings: ContactTimings,
}

/// Wall time of the phases of one contact evaluation.
#[derive(Clone, Copy, Debug, Default)]
pub struct ContactTimings {
    /// Topology caches, face boxes, cell prefilter and grid rebuild (includes `lists`).
    pub broad: std::time::Duration,
    /// Of `broad`: rebuilding the candidate lists (zero when they were reused).
    pub lists: std::time::Duration,
    /// Closest faces and pair records, in parallel over cells.
    pub narrow: std::time::Duration,
    /// Applying the pair forces in a fixed order.
    pub apply: std::time::Duration,
}

/// Appends the bounding box of every face of `mesh`, padded by `pad`, to `out`.
fn padded_face_boxes(mesh: &crate::mesh::CellMesh, pad: Real, out: &mut Vec<(Vec3, Vec3)>) {
    let p = mesh.positions();
    out.extend(mesh.triangles().iter().map(|t| {
        let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
        (a.inf(&b).inf(&c).add_scalar(-pad), a.sup(&b).sup(&c).add_scalar(pad))
    }));
}

/// Each cell's box: the union of its faces' boxes (`offsets` as in `ContactWorkspace::face_offsets`).
fn cell_boxes(boxes: &[(Vec3, Vec3)], offsets: &[u32]) -> Vec<(Vec3, Vec3)> {
    offsets
        .windows(2)
        .map(|w| {
            boxes[w[0] as usize..w[1] as usize]
                .iter()
                .fold((Vec3::repeat(Real::INFINITY), Vec3::repeat(Real::NEG_INFINITY)), |(lo, hi), (a, b)| {
                    (lo.inf(a), hi.sup(b))
                })
        })
        .collect()
}

fn boxes_overlap(a: &(Vec3, Vec3), b: &(Vec3, Vec3)) -> bool {
    (0..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k])
}

/// The closest face found for each (node, other cell index, face index) of one cell at the last
/// evaluation, nodes ascending: the narrow phase starts each search with that face's exact
/// distance as its bound, so that the box test skips the exact computation for almost every other
/// candidate. Only a bound: a face within the search radius is always among the candidates (see
/// [`CandidateLists`]), so the face the search selects, ties included, is the one it selects without
/// the hint (the first candidate at the least distance), bit for bit; a stale hint (remeshed cell,
/// another tissue) is just a looser bound.
#[derive(Clone, Debug, Default)]
struct ClosestHints {
    last: Vec<(u32, u32, u32)>,
    next: Vec<(u32, u32, u32)>,
}

/// Relative safety margin (of the cutoff) of the narrow phase's pruning: a face is skipped only if
/// the distance from the node to its bounding box exceeds the best distance so far (or the cutoff)
/// by `PRUNE_MARGIN · cutoff`. Rounding errors of the box and closest-point distances are about
/// 1e-21 m at µm-scale coordinates, so the margin (5e-16 m for the benchmark's 0.5 µm cutoff) only
/// skips faces that cannot be selected: the closest face, ties included, is the one an exhaustive
/// search picks, bit for bit.
const PRUNE_MARGIN: Real = 1e-9;

/// Squared distance from `p` to a face's bounding box, given the box padded by `cutoff`: a lower
/// bound of the squared distance from `p` to the face. Lets the narrow phase skip the exact
/// closest-point computation for faces that cannot be the closest one.
#[inline]
fn box_distance_squared(p: &Vec3, padded: &(Vec3, Vec3), cutoff: Real) -> Real {
    let mut d2 = 0.0;
    for k in 0..3 {
        let e = ((padded.0[k] + cutoff) - p[k]).max(p[k] - (padded.1[k] - cutoff)).max(0.0);
        d2 += e * e;
    }
    d2
}

/// Angle-weighted normal of a vertex (its pseudo-normal: Bærentzen & Aanæs 2005), from the unit
/// face normals; only needed when a node's closest point on another cell is that vertex.
fn vertex_pseudo_normal(mesh: &crate::mesh::CellMesh, topo: &CellTopology, vertex: u32, normals: &[Vec3]) -> Vec3 {
    let p = mesh.positions();
    let mut sum = Vec3::zeros();
    for &f in topo.faces_of(vertex) {
        let t = mesh.triangles()[f as usize];
        let k = t.iter().position(|&x| x == vertex).expect("the vertex is a corner of its faces");
        let (u, v) = (p[t[(k + 1) % 3] as usize] - p[vertex as usize], p[t[(k + 2) % 3] as usize] - p[vertex as usize]);
        sum += u.cross(&v).norm().atan2(u.dot(&v)) * normals[f as usize];
    }
    sum
}

/// +1 if `p` lies outside the closed surface `mesh`, −1 inside, from its closest point `q` on face
/// `f`: the angle-weighted pseudo-normal of the closest feature (exact for a surface without
/// self-overlap, Bærentzen & Aanæs 2005), or the winding number where the surface folds back on
/// itself there ([`folded_feature`]) and `p` lies farther than `tie` from it. A point on the
/// surface (a coupled node tied to a junction, d = 0) has no side, and its winding number is the
/// solid angle of the corner it sits on (0.13…0.93 measured at the 12-cell ball's junctions), so
/// there the pseudo-normal decides, as everywhere else.
fn outside_sign(
    mesh: &crate::mesh::CellMesh,
    topo: &CellTopology,
    f: u32,
    q: &crate::geometry::PointTriangle,
    p: &Vec3,
    faces: FaceFrames,
    tie: Real,
) -> Real {
    let FaceFrames { normals, folds } = faces;
    let t = mesh.triangles()[f as usize];
    if q.distance > tie && folded_feature(topo, t, f, q.region, folds.get_or_init(|| fold_flags(topo, normals))) {
        return if mesh.winding_number(p) > 0.5 { -1.0 } else { 1.0 };
    }
    let separation = p - q.point;
    if separation == Vec3::zeros() {
        // On the feature itself (a coupled node tied to the other cell's node): the product below is
        // 0 whatever the pseudo-normal, so +1 without computing it (a vertex's costs one atan2 per
        // face around it, and with coupling contacts nearly every closest feature is such a vertex).
        return 1.0;
    }
    let pseudo = match q.region {
        TriangleRegion::Face => normals[f as usize],
        TriangleRegion::Edge(s) => {
            let g = topo.face_neighbours[f as usize][s as usize];
            normals[f as usize] + if g == u32::MAX { Vec3::zeros() } else { normals[g as usize] }
        }
        TriangleRegion::Vertex(v) => vertex_pseudo_normal(mesh, topo, t[v as usize], normals),
    };
    if separation.dot(&pseudo) < 0.0 { -1.0 } else { 1.0 }
}

/// A cell's unit face normals at this evaluation and its faces' fold flags ([`fold_flags`]), made
/// from the normals when first needed (with coupling contacts most closest features are a tied node
/// at distance 0, which never asks).
#[derive(Clone, Copy)]
struct FaceFrames<'a> {
    normals: &'a [Vec3],
    folds: &'a OnceLock<Vec<bool>>,
}

/// Below this fraction of the cutoff a node counts as on the other surface for [`outside_sign`]
/// (the winding number is not asked).
const SIGN_TIE: Real = 1e-3;

/// Cosine of the angle between two adjacent faces' normals beyond which the surface is taken to
/// fold back on itself (120°: sharper than any crease of a cell at a contact rim or junction, whose
/// normals turn by at most about 90°).
const FOLD_COS: Real = -0.5;

/// For each face of a cell (unit `normals`): whether its normal is more than 120° from a
/// neighbour's (computed at most once per evaluation for [`folded_feature`]).
fn fold_flags(topo: &CellTopology, normals: &[Vec3]) -> Vec<bool> {
    topo.face_neighbours
        .iter()
        .zip(normals)
        .map(|(across, n)| across.iter().any(|&h| h != u32::MAX && n.dot(&normals[h as usize]) < FOLD_COS))
        .collect()
}

/// Whether the surface folds back on itself at the closest feature (`region` of face `f`, corners
/// `tri`): a face holding the feature whose normal is more than 120° from a neighbour's (`folds`,
/// from [`fold_flags`]). The sign of the
/// distance from a pseudo-normal is exact for a surface without self-overlap; at a fold (an inverted
/// sliver at a sharp contact rim, a few nanometres high) it is arbitrary, and a node far away whose
/// closest point lands there would be read as deep inside the other cell: a jump of the contact
/// energy by the whole repulsion, at fixed geometry (issue 20: the w/(2γ) = 0.5 doublets).
fn folded_feature(topo: &CellTopology, tri: [u32; 3], f: u32, region: TriangleRegion, flags: &[bool]) -> bool {
    // Each face holding the feature against the faces across its three sides.
    let folds = |g: u32| g != u32::MAX && flags[g as usize];
    match region {
        TriangleRegion::Face => folds(f),
        TriangleRegion::Edge(s) => folds(f) || folds(topo.face_neighbours[f as usize][s as usize]),
        TriangleRegion::Vertex(v) => topo.faces_of(tri[v as usize]).iter().any(|&g| folds(g)),
    }
}

/// Mean of ω and ξ over the faces around a node.
fn node_contact_parameters(faces: &[u32], face_types: &[FaceType], p: &CellTypeParams) -> (Real, Real) {
    let (mut w, mut x) = (0.0, 0.0);
    for &f in faces {
        let fp = p.faces.get(face_types[f as usize]);
        w += fp.adhesion;
        x += fp.repulsion;
    }
    let n = faces.len().max(1) as Real;
    (w / n, x / n)
}

impl ContactWorkspace {
    /// Sets the contact model the springs serve (default [`ContactModel::Spring`]).
    pub fn set_model(&mut self, model: ContactModel) {
        self.model = model;
    }

    /// Sets how the contact energy is integrated over the surface (default
    /// [`ContactQuadrature::Vertices`]).
    pub fn set_quadrature(&mut self, quadrature: ContactQuadrature) {
        self.quadrature = quadrature;
    }

    /// For each node of cell `cell` within the cutoff of another cell's surface at the last
    /// evaluation: (node, index of the other cell, signed distance d), one entry per other cell,
    /// nodes ascending.
    pub fn node_contacts(&self, cell: usize) -> impl Iterator<Item = (u32, u32, Real)> + '_ {
        let cutoff = self.cutoff;
        self.pairs
            .get(cell)
            .into_iter()
            .flatten()
            .filter(move |p| p.distance.abs() <= cutoff)
            .map(|p| (p.node, p.other, p.distance))
    }

    /// The stiffness of the contact law along each pair of cell `a`'s nodes at the last
    /// evaluation, for a minimiser's preconditioner: (node, ∂d/∂p, k) with k = a_p·|dσ/dd| (N/m),
    /// a_p the node's area (a third of its faces' `areas`) and σ Eq. 2's stress with the node's mean
    /// ξ and ω (capped like the pair): ξ inside the other cell down to −c, ω in the well, nothing
    /// elsewhere. The face quadrature's face means bend no more sharply than the law itself.
    pub fn pair_stiffnesses<'s>(
        &'s self,
        a: usize,
        cell: &'s Cell,
        params: &'s CellTypeParams,
        areas: &'s [Real],
    ) -> impl Iterator<Item = (u32, Vec3, Real)> + 's {
        let cutoff = self.cutoff;
        let topology = self.topology.get(a);
        self.pairs.get(a).into_iter().flatten().filter_map(move |p| {
            if !(-cutoff..=cutoff).contains(&p.distance) {
                return None;
            }
            let faces = topology?.faces_of(p.node);
            let (omega, xi) = node_contact_parameters(faces, cell.face_types(), params);
            let curvature = if p.distance < 0.0 { xi } else { omega.min(p.adhesion_cap) };
            let area = faces.iter().map(|&f| areas[f as usize]).sum::<Real>() / 3.0;
            Some((p.node, p.direction, area * curvature))
        })
    }

    /// Adds contact forces to `forces` (one entry per cell, internal forces already computed, so
    /// face normals and areas are current) and their energy to each cell's `energy.contact`.
    /// Returns the total contact energy (J).
    pub fn add_contacts(
        &mut self,
        tissue: &Tissue,
        cell_params: &[CellTypeParams],
        cutoff: Real,
        forces: &mut [CellForces],
    ) -> Real {
        let cells = tissue.cells();
        let n = cells.len();
        self.pair_count = 0;
        self.cutoff = cutoff;
        let faces_mode = self.quadrature == ContactQuadrature::Faces;
        self.timings = ContactTimings::default();
        let started = std::time::Instant::now();
        if n < 2 || cutoff <= 0.0 {
            self.pairs.iter_mut().for_each(Vec::clear);
            return 0.0;
        }
        self.topology.resize_with(n, CellTopology::default);
        self.pairs.resize_with(n, Vec::new);
        if self.hints.len() != n {
            // Other cells (or another tissue): the hints name faces of cells that moved in the list.
            self.hints.clear();
            self.hints.resize_with(n, ClosestHints::default);
        }
        // Per-cell topology (cached until the triangles change).
        self.topology.par_iter_mut().zip(cells.par_iter()).for_each(|(topo, cell)| topo.update(cell.mesh()));

        // Search radius: the cutoff; with the face quadrature, also every corner of a face that has
        // a corner within the cutoff, which (the distance being 1-Lipschitz) lies within the cutoff
        // plus the face's longest edge.
        let search = if faces_mode {
            let longest = cells
                .par_iter()
                .map(|cell| {
                    let p = cell.mesh().positions();
                    cell.mesh().triangles().iter().fold(0.0 as Real, |m, t| {
                        let (a, b, c) = (p[t[0] as usize], p[t[1] as usize], p[t[2] as usize]);
                        m.max((a - b).norm_squared()).max((b - c).norm_squared()).max((c - a).norm_squared())
                    })
                })
                .reduce(|| 0.0, Real::max)
                .sqrt();
            cutoff + longest
        } else {
            cutoff
        };
        // Every face's box padded by the search radius.
        self.face_offsets.clear();
        self.face_offsets.push(0);
        self.boxes.clear();
        for cell in cells {
            padded_face_boxes(cell.mesh(), search, &mut self.boxes);
            self.face_offsets.push(self.boxes.len() as u32);
        }
        // The host cell of each nucleus: the first cell of another kind containing its centroid
        // (the cells' boxes only where there are nuclei).
        let nuclei = cells.iter().any(|c| c.kind() == CellKind::Nucleus);
        let cell_boxes = if nuclei { cell_boxes(&self.boxes, &self.face_offsets) } else { Vec::new() };
        let host: Vec<Option<usize>> = cells
            .par_iter()
            .map(|cell| {
                if cell.kind() != CellKind::Nucleus {
                    return None;
                }
                let centroid = cell.mesh().volume_centroid()?;
                let boxed = |b: &(Vec3, Vec3)| (0..3).all(|k| b.0[k] <= centroid[k] && centroid[k] <= b.1[k]);
                cells.iter().zip(&cell_boxes).position(|(other, bx)| {
                    other.kind().is_cell() && boxed(bx) && other.mesh().winding_number(&centroid) > 0.5
                })
            })
            .collect();
        // Candidate faces of every node, reused while no node has moved far enough to matter.
        let rebuilding = std::time::Instant::now();
        match self.candidates.refresh(cells, &self.boxes, &self.face_offsets, search, &mut self.grid) {
            Refresh::Reused => {}
            Refresh::Updated => {
                self.candidate_updates += 1;
                self.timings.lists = rebuilding.elapsed();
            }
            Refresh::Rebuilt => {
                self.candidate_rebuilds += 1;
                self.timings.lists = rebuilding.elapsed();
            }
        }
        self.timings.broad = started.elapsed();
        if self.candidates.is_empty() {
            self.pairs.iter_mut().for_each(Vec::clear);
            for f in forces.iter_mut() {
                f.energy.contact = 0.0;
            }
            return 0.0;
        }
        let started = std::time::Instant::now();

        // Narrow phase, per cell in parallel: for each node, the closest face of every other cell
        // whose padded faces cover it (among its candidates, a superset: see [`CandidateLists`]).
        let forces_ro: &[CellForces] = forces;
        self.folds.clear();
        self.folds.resize_with(n, OnceLock::new);
        let folds = &self.folds;
        let face_offsets = &self.face_offsets;
        let topology = &self.topology;
        // Adhesion towards a nucleus: the nucleus's own (mean ω of its type), capped (module doc).
        let nucleus_adhesion: Vec<Real> = cell_params
            .iter()
            .map(|p| FaceType::ALL.iter().map(|&t| p.faces.get(t).adhesion).sum::<Real>() / 3.0)
            .collect();
        let nucleus_adhesion = &nucleus_adhesion;
        let (boxes, host) = (&self.boxes, &host);
        let lists = &self.candidates.cells;
        let coupling = self.model == ContactModel::Coupling;
        let prune_margin = PRUNE_MARGIN * cutoff;
        self.pairs.par_iter_mut().zip(self.hints.par_iter_mut()).enumerate().for_each(|(a, (pairs, hints))| {
            pairs.clear();
            std::mem::swap(&mut hints.last, &mut hints.next);
            hints.next.clear();
            let cell_a = &cells[a];
            let mesh_a = cell_a.mesh();
            let list = &lists[a];
            if list.is_empty() {
                return;
            }
            let mut hint_at = 0;
            let inside = |p: &Vec3, b: &(Vec3, Vec3)| (0..3).all(|k| b.0[k] <= p[k] && p[k] <= b.1[k]);
            for (node, p) in mesh_a.positions().iter().enumerate() {
                let candidates = list.of(node);
                if candidates.is_empty() {
                    continue;
                }
                let first_pair = pairs.len();
                let mut node_terms: Option<(Real, Real, Real)> = None;
                let mut k = 0;
                while k < candidates.len() {
                    let b = face_offsets.partition_point(|&o| o <= candidates[k]) - 1;
                    let end = face_offsets[b + 1];
                    let group_start = k;
                    while k < candidates.len() && candidates[k] < end {
                        k += 1;
                    }
                    let mesh_b = cells[b].mesh();
                    let pb = mesh_b.positions();
                    let mut best: Option<(u32, crate::geometry::PointTriangle)> = None;
                    // Faces whose box lies farther than this cannot be the closest face within the
                    // cutoff (see `box_distance_squared`), nor farther than last evaluation's closest
                    // face (see `ClosestHints`).
                    let mut bound = search;
                    let last = &hints.last;
                    while hint_at < last.len() && (last[hint_at].0, last[hint_at].1) < (node as u32, b as u32) {
                        hint_at += 1;
                    }
                    // The hinted face's closest point, reused when the scan reaches that face.
                    let mut hinted = None;
                    if let Some(&(hn, hb, hf)) = last.get(hint_at)
                        && (hn, hb) == (node as u32, b as u32)
                        && let Some(t) = mesh_b.triangles().get(hf as usize)
                    {
                        let q =
                            closest_point_on_triangle(p, &pb[t[0] as usize], &pb[t[1] as usize], &pb[t[2] as usize]);
                        bound = bound.min(q.distance);
                        hinted = Some((hf, q));
                    }
                    bound += prune_margin;
                    for &g in &candidates[group_start..k] {
                        // A face farther than the cutoff cannot matter: skip it unless its padded
                        // box holds p (a few comparisons instead of an exact distance).
                        let bx = &boxes[g as usize];
                        if !inside(p, bx) || box_distance_squared(p, bx, search) > bound * bound {
                            continue;
                        }
                        let f = g - face_offsets[b];
                        let q = match hinted {
                            Some((hf, q)) if hf == f => q,
                            _ => {
                                let t = mesh_b.triangles()[f as usize];
                                closest_point_on_triangle(p, &pb[t[0] as usize], &pb[t[1] as usize], &pb[t[2] as usize])
                            }
                        };
                        if best.is_none_or(|(_, bq)| q.distance < bq.distance) {
                            bound = bound.min(q.distance + prune_margin);
                            best = Some((f, q));
                        }
                    }
                    let Some((f, q)) = best else { continue };
                    hints.next.push((node as u32, b as u32, f));
                    if q.distance > search {
                        continue;
                    }
                    let normals_b = &forces_ro[b].geometry.normals;
                    let separation = p - q.point;
                    let mut sign = outside_sign(
                        mesh_b,
                        &topology[b],
                        f,
                        &q,
                        p,
                        FaceFrames { normals: normals_b, folds: &folds[b] },
                        SIGN_TIE * cutoff,
                    );
                    if (cells[b].kind() == CellKind::Ecm && cell_a.kind() != CellKind::Ecm) || host[a] == Some(b) {
                        sign = -sign;
                    }
                    let d = sign * q.distance;
                    if d < -search {
                        continue;
                    }
                    let direction = match separation.try_normalize(0.0) {
                        Some(u) => sign * u,
                        None => sign * normals_b[f as usize],
                    };
                    let mut adhesion_cap = Real::INFINITY;
                    if coupling && cell_a.kind().is_cell() && cells[b].kind().is_cell() {
                        adhesion_cap = 0.0;
                    }
                    if cells[b].kind() == CellKind::Nucleus {
                        adhesion_cap = adhesion_cap.min(nucleus_adhesion[b]);
                    }
                    // The node's own area and mean ω, ξ (once per node): the vertex quadrature's
                    // energy; the face quadrature integrates per face in `face_quadrature::assemble`.
                    let (area, omega, xi) = if faces_mode {
                        (0.0, 0.0, 0.0)
                    } else {
                        *node_terms.get_or_insert_with(|| {
                            let faces_a = topology[a].faces_of(node as u32);
                            let (omega, xi) = node_contact_parameters(faces_a, cell_a.face_types(), &cell_params[a]);
                            let area =
                                faces_a.iter().map(|&g| forces_ro[a].geometry.areas[g as usize]).sum::<Real>() / 3.0;
                            (area, omega, xi)
                        })
                    };
                    let omega = omega.min(adhesion_cap);
                    pairs.push(Pair {
                        node: node as u32,
                        other: b as u32,
                        face: f,
                        weights: q.weights,
                        direction,
                        area,
                        distance: d,
                        phi: repulsion_energy_density(d, cutoff, xi),
                        sigma: repulsion_stress(d, cutoff, xi),
                        well: adhesion_energy_density(d, cutoff, omega),
                        well_slope: adhesion_stress(d, cutoff, omega),
                        adhesion_cap,
                        coefficient: 0.0,
                    });
                }
                if let Some((_, omega, _)) = node_terms {
                    combine_wells(&mut pairs[first_pair..], 0.25 * omega * cutoff * cutoff);
                }
            }
        });

        if faces_mode {
            self.face_density.resize_with(n, Vec::new);
            let topology = &self.topology;
            self.pairs.par_iter_mut().zip(self.face_density.par_iter_mut()).enumerate().for_each(
                |(a, (pairs, density))| {
                    face_quadrature::assemble(
                        &cells[a],
                        &cell_params[a],
                        &forces_ro[a].geometry.areas,
                        &topology[a],
                        cutoff,
                        pairs,
                        density,
                    )
                },
            );
        }

        self.timings.narrow = started.elapsed();
        let started = std::time::Instant::now();
        if faces_mode {
            let total = self.apply_faces(tissue, forces);
            self.timings.apply = started.elapsed();
            return total;
        }
        // Apply in a fixed order.
        let mut total = 0.0;
        for a in 0..n {
            let mut energy = 0.0;
            for pair in &self.pairs[a] {
                self.pair_count += 1;
                energy += pair.area * pair.phi;
                let push = pair.area * pair.sigma * pair.direction;
                forces[a].forces[pair.node as usize] -= push;
                let t = cells[pair.other as usize].mesh().triangles()[pair.face as usize];
                for (k, &v) in t.iter().enumerate() {
                    forces[pair.other as usize].forces[v as usize] += pair.weights[k] * push;
                }
                // −Φ·∇a_p: a third of each adjacent face's area gradient.
                if pair.phi != 0.0 {
                    let mesh_a = cells[a].mesh();
                    let pa = mesh_a.positions();
                    for &g in self.topology[a].faces_of(pair.node) {
                        let tri = mesh_a.triangles()[g as usize].map(|x| x as usize);
                        let scaled = (pair.phi / 3.0) * forces[a].geometry.normals[g as usize];
                        let grad = triangle_area_gradients(&pa[tri[0]], &pa[tri[1]], &pa[tri[2]], &scaled);
                        for (v, gv) in tri.iter().zip(grad) {
                            forces[a].forces[*v] -= gv;
                        }
                    }
                }
            }
            forces[a].energy.contact = energy;
            total += energy;
        }
        self.timings.apply = started.elapsed();
        total
    }

    /// Applies the face quadrature's pair coefficients and face densities in a fixed order: each
    /// pair's −(∂E/∂d)·∂d/∂x on the node and the other cell's closest face, and each face's
    /// −Φ_f·∇A_f. Returns the total contact energy Σ_f A_f·Φ_f.
    fn apply_faces(&mut self, tissue: &Tissue, forces: &mut [CellForces]) -> Real {
        let cells = tissue.cells();
        let mut total = 0.0;
        for a in 0..cells.len() {
            for pair in &self.pairs[a] {
                self.pair_count += 1;
                if pair.coefficient == 0.0 {
                    continue;
                }
                let push = pair.coefficient * pair.direction;
                forces[a].forces[pair.node as usize] -= push;
                let t = cells[pair.other as usize].mesh().triangles()[pair.face as usize];
                for (k, &v) in t.iter().enumerate() {
                    forces[pair.other as usize].forces[v as usize] += pair.weights[k] * push;
                }
            }
            let mesh_a = cells[a].mesh();
            let pa = mesh_a.positions();
            let mut energy = 0.0;
            for (g, &phi) in self.face_density[a].iter().enumerate() {
                if phi == 0.0 {
                    continue;
                }
                energy += forces[a].geometry.areas[g] * phi;
                let tri = mesh_a.triangles()[g].map(|x| x as usize);
                let scaled = phi * forces[a].geometry.normals[g];
                let grad = triangle_area_gradients(&pa[tri[0]], &pa[tri[1]], &pa[tri[2]], &scaled);
                for (v, gv) in tri.iter().zip(grad) {
                    forces[a].forces[*v] -= gv;
                }
            }
            forces[a].energy.contact = energy;
            total += energy;
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::closest_point_on_triangle;
    use crate::mesh::CellMesh;

    /// A box x ∈ [0, 1], y, z ∈ [−1, 1] whose front face (x = 0, outward −x) has an "ear" (c2, v,
    /// c3) between its top edge c2–c3 and a rim node v at (0, y_v, 0). Oriented outward with
    /// y_v > 1; moving v below 1 inverts the ear over the front face's triangle (k, c2, c3): the
    /// fold the doublets at w/(2γ) = 0.5 made at their contact rim (issue 20).
    fn box_with_ear(y_v: Real) -> (CellMesh, u32) {
        let positions = vec![
            Vec3::new(0.0, 0.0, 0.0),   // 0 k
            Vec3::new(0.0, -1.0, -1.0), // 1 c1
            Vec3::new(0.0, 1.0, -1.0),  // 2 c2
            Vec3::new(0.0, 1.02, 0.0),  // 3 v (outside the chord while orienting)
            Vec3::new(0.0, 1.0, 1.0),   // 4 c3
            Vec3::new(0.0, -1.0, 1.0),  // 5 c4
            Vec3::new(1.0, -1.0, -1.0), // 6 b1
            Vec3::new(1.0, 1.0, -1.0),  // 7 b2
            Vec3::new(1.0, 1.0, 1.0),   // 8 b3
            Vec3::new(1.0, -1.0, 1.0),  // 9 b4
        ];
        let mut triangles: Vec<[u32; 3]> = vec![
            [0, 1, 2],
            [0, 2, 4],
            [2, 3, 4], // the ear
            [0, 4, 5],
            [0, 5, 1],
            [3, 2, 7],
            [3, 7, 8],
            [3, 8, 4],
            [1, 6, 9],
            [1, 9, 5],
            [6, 7, 8],
            [6, 8, 9],
            [1, 2, 7],
            [1, 7, 6],
            [5, 4, 8],
            [5, 8, 9],
        ];
        let centre = Vec3::new(0.5, 0.0, 0.0);
        for t in &mut triangles {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            if (b - a).cross(&(c - a)).dot(&((a + b + c) / 3.0 - centre)) < 0.0 {
                t.swap(1, 2);
            }
        }
        let mut mesh = CellMesh::from_triangles(positions, triangles).expect("a closed box");
        mesh.positions_mut()[3].y = y_v;
        (mesh, 2)
    }

    fn unit_normals(mesh: &CellMesh) -> Vec<Vec3> {
        let p = mesh.positions();
        mesh.triangles()
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| p[i as usize]);
                (b - a).cross(&(c - a)).normalize()
            })
            .collect()
    }

    /// Issue 20 regression: a node 0.3 in front of an inverted sliver at a contact rim was read as
    /// 0.3 deep inside the other cell (the pseudo-normal of a folded feature points the wrong way),
    /// and the contact energy jumped by the full repulsion at fixed geometry. Where the surface
    /// folds, the winding number decides.
    #[test]
    fn a_folded_sliver_does_not_turn_an_outside_node_inside() {
        let (mesh, ear) = box_with_ear(0.98);
        let mut topo = CellTopology::default();
        topo.update(&mesh);
        let normals = unit_normals(&mesh);
        let folds = fold_flags(&topo, &normals);
        let p = mesh.positions();
        let [a, b, c] = mesh.triangles()[ear as usize].map(|i| p[i as usize]);
        // The ear is inverted: its normal points into the box (+x).
        assert!(normals[ear as usize].x > 0.99, "{:?}", normals[ear as usize]);
        // In front of the ear (outside) and behind it, below the top face (inside).
        for (x, y, expected) in [(-0.3, 0.993, 1.0), (0.3, 0.97, -1.0)] {
            let node = Vec3::new(x, y, 0.0);
            let q = closest_point_on_triangle(&node, &a, &b, &c);
            assert!(folded_feature(&topo, mesh.triangles()[ear as usize], ear, q.region, &folds));
            // The ear's own normal gives the wrong side: the trap is real.
            if q.region == TriangleRegion::Face {
                let naive = if (node - q.point).dot(&normals[ear as usize]) < 0.0 { -1.0 } else { 1.0 };
                assert_eq!(naive, -expected, "x = {x}");
            }
            assert_eq!(
                outside_sign(
                    &mesh,
                    &topo,
                    ear,
                    &q,
                    &node,
                    FaceFrames { normals: &normals, folds: &OnceLock::new() },
                    1e-6
                ),
                expected,
                "x = {x}"
            );
        }
        // Unfolded (v outside the chord), the same feature is not flagged and the pseudo-normal decides.
        let (mesh, ear) = box_with_ear(1.02);
        topo.update(&mesh);
        let normals = unit_normals(&mesh);
        let folds = fold_flags(&topo, &normals);
        assert!(!mesh.triangles().iter().enumerate().any(|(f, &t)| {
            [TriangleRegion::Face, TriangleRegion::Edge(0), TriangleRegion::Vertex(0)]
                .into_iter()
                .any(|r| folded_feature(&topo, t, f as u32, r, &folds))
        }));
        let p = mesh.positions();
        let [a, b, c] = mesh.triangles()[ear as usize].map(|i| p[i as usize]);
        let node = Vec3::new(-0.3, 1.005, 0.0);
        let q = closest_point_on_triangle(&node, &a, &b, &c);
        assert_eq!(
            outside_sign(&mesh, &topo, ear, &q, &node, FaceFrames { normals: &normals, folds: &OnceLock::new() }, 1e-6),
            1.0
        );
    }
}
