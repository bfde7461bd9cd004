//! Cell division as a mesh operation: cut a closed cell surface by a plane and close both halves with a
//! shared planar cap (paper, Methods "Cell division"; Fig. 1d). *When* a cell divides (V > V_max) and
//! the bookkeeping of the new cells belong to `mechanics`; this module only builds the two surfaces.
//!
//! [`divide_mesh`] works in four steps:
//!
//! 1. **Classify.** Every node gets the side of the plane it lies on from its signed distance
//!    `d = (x − x₀)·n̂`: `+` when `d > ε`, `−` when `d < −ε`, and "on the plane" when `|d| ≤ ε`, with
//!    `ε = 10⁻³·l_min` ([`SNAP_FRACTION`]). Snapping is topological only — no node moves — so a cut
//!    that passes within ε of a node goes *through* the node instead of creating a sliver next to it,
//!    and a node exactly on the plane is handled the same way.
//! 2. **Cut.** A face whose corners are all `+`/on (all `−`/on) goes whole to that side. A face with
//!    corners on both sides is split at the intersection points of its crossing edges (one point per
//!    mother edge, shared by the two faces of that edge): into two triangles when one corner is on the
//!    plane, or into a triangle and a quad (split along its shorter diagonal) otherwise. The pieces lie in
//!    their parent's plane and keep its winding and face type. A face with all three corners on the
//!    plane is an error (the plane is tangent to the surface there).
//! 3. **Close.** The edges between the two sides must form exactly one simple loop (otherwise
//!    [`DivisionError::CutLoops`] / [`DivisionError::PinchedCut`]: the caller tries another plane).
//!    The loop is filled in the plane by `cap.rs`: Poisson-disk points at spacing
//!    [`CAP_SPACING`]`·l_min` (seeded ChaCha8, so deterministic), the loop nodes, and spade's
//!    constrained Delaunay triangulation with the loop edges as constraints, keeping the triangles
//!    inside the loop. The same cap closes both daughters, wound oppositely; cap faces are lateral
//!    (they will face the sister cell). The inherited surface is not re-triangulated.
//! 4. **Check.** Both daughters must pass [`CellMesh::validate`]; otherwise an error names the
//!    daughter and the defect. Nothing panics on bad input.
//!
//! Because the daughters' surfaces are the mother's faces (cut exactly in their own planes) plus one
//! cap counted once with each orientation, `V_a + V_b = V_mother` up to round-off, whatever the cap's
//! shape. Short edges left next to the cut (where the plane passes close to, but farther than ε from,
//! a node) are not removed here, to keep that exactness; [`Daughter::remesh`] tidies them (the
//! simulation remeshes every step anyway).
//!
//! [`division_plane_normal`] gives the plane's orientation: Hertwig's rule (normal along the longest
//! principal axis of the solid, i.e. the largest variance of [`CellMesh::principal_axes`]; the paper's
//! "smallest eigenvalue" refers to the inertia tensor) or a uniformly random direction.

use super::cap::{PlanarCap, triangulate_cap};
use super::remesh::{RemeshError, RemeshReport, RemeshSettings, remesh_cell};
use super::{CellMesh, FaceType, MeshDefect, MeshError};
use crate::geometry::{Real, Vec3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, UnitSphere};
use std::collections::{HashMap, HashSet};

/// Nodes within `SNAP_FRACTION·l_min` of the plane count as lying on it (dimensionless).
pub const SNAP_FRACTION: Real = 1e-3;
/// Spacing of the cap's Poisson-disk points in units of `l_min` (dimensionless). Delaunay edges of a
/// maximal Poisson-disk set with spacing r lie in [r, 2r], here [1.25, 2.5]·l_min: inside the remeshing
/// bounds [l_min, 3·l_min] with a margin against round-off at l_min. Edges touching the loop follow the
/// loop's spacing instead (chords between cut nodes that lie close together can be short); on
/// icospheres and ellipsoids cut along many planes 99.9 % of the cap's interior edges lie in bounds.
pub const CAP_SPACING: Real = 1.25;

/// Which daughter a [`DivisionError::InvalidDaughter`] refers to.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DaughterSide {
    /// On the side the plane normal points to (the first daughter).
    Positive,
    /// On the other side (the second daughter).
    Negative,
}

impl std::fmt::Display for DaughterSide {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            DaughterSide::Positive => "positive-side",
            DaughterSide::Negative => "negative-side",
        })
    }
}

/// Errors of a division. Node numbers refer to the mother mesh; numbers at or above its node count
/// are intersection nodes created by the cut.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum DivisionError {
    #[error("invalid division argument: {reason}")]
    InvalidArgument { reason: String },
    #[error("{face_types} face types given for {faces} faces")]
    FaceTypeCount { face_types: usize, faces: usize },
    #[error("the mother cell is not a valid surface: {defect}")]
    InvalidMother { defect: MeshDefect },
    #[error("the cell has no volume, so it has no centroid or principal axes")]
    NoVolume,
    #[error("the plane misses the cell: {above} faces above it, {below} below")]
    PlaneMissesCell { above: usize, below: usize },
    #[error("face {face} lies in the cutting plane (the plane is tangent to the surface)")]
    FaceInPlane { face: u32 },
    #[error("the cut touches itself at node {node} (the plane grazes the surface there)")]
    PinchedCut { node: u32 },
    #[error("the cut is not closed at node {node}")]
    OpenCut { node: u32 },
    #[error("the plane cuts the surface along {loops} loops; a division needs exactly one")]
    CutLoops { loops: usize },
    #[error("cap points {a} and {b} coincide in the cutting plane")]
    CoincidentLoopNodes { a: usize, b: usize },
    #[error("edge {a}-{b} of the cut loop could not be kept in the cap triangulation (the loop crosses itself)")]
    LoopEdgeLost { a: usize, b: usize },
    #[error("the cap has {found} triangles, expected {expected} (the loop is not simple in the plane)")]
    CapTriangleCount { expected: usize, found: usize },
    #[error("cap triangulation failed: {reason}")]
    Triangulation { reason: String },
    #[error("the {side} daughter is not a valid cell surface: {defect}")]
    InvalidDaughter { side: DaughterSide, defect: MeshDefect },
    #[error("remeshing a daughter failed: {0}")]
    Remesh(#[from] RemeshError),
    #[error(transparent)]
    Mesh(#[from] MeshError),
}

/// Where a daughter's node comes from, so per-node data (momenta) can follow the division.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum NodeOrigin {
    /// A node of the mother, with its index there (same position).
    Mother(u32),
    /// A node where the plane crosses the mother's edge `a`–`b`, at `a + t·(b − a)`.
    Cut { a: u32, b: u32, t: Real },
    /// An interior node of the cap.
    Cap,
}

/// One daughter cell: a valid closed surface, the type of each of its faces, and the origin of each
/// of its nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct Daughter {
    pub mesh: CellMesh,
    pub face_types: Vec<FaceType>,
    /// One per node of `mesh`.
    pub origins: Vec<NodeOrigin>,
}

impl Daughter {
    /// One remeshing pass with the paper's bounds for `l_min` (m), face types kept in step: collapses
    /// the short edges the cut may leave next to mother nodes. Changes the volume slightly (collapses move
    /// nodes). On error the daughter is unchanged. Node origins no longer apply afterwards and are
    /// cleared.
    pub fn remesh(&mut self, l_min: Real) -> Result<RemeshReport, DivisionError> {
        let report = remesh_cell(&mut self.mesh, None, Some(&mut self.face_types), &RemeshSettings::new(l_min))?;
        if report.operations() > 0 {
            self.origins.clear();
        }
        Ok(report)
    }

    /// Per-node values of the daughter from those of the mother (`mother`, one per mother node):
    /// inherited nodes keep theirs, cut nodes interpolate linearly along their mother edge, cap nodes
    /// get `cap`.
    pub fn inherit<T>(&self, mother: &[T], cap: T) -> Vec<T>
    where
        T: Copy + std::ops::Mul<Real, Output = T> + std::ops::Add<Output = T>,
    {
        self.origins
            .iter()
            .map(|o| match *o {
                NodeOrigin::Mother(n) => mother[n as usize],
                NodeOrigin::Cut { a, b, t } => mother[a as usize] * (1.0 - t) + mother[b as usize] * t,
                NodeOrigin::Cap => cap,
            })
            .collect()
    }
}

/// How the division plane is oriented.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum DivisionPlane {
    /// Hertwig's rule: perpendicular to the longest principal axis.
    LongestAxis,
    /// A uniformly distributed random direction drawn from ChaCha8 seeded with this value.
    Random(u64),
}

/// Unit normal of the division plane of `mesh` (see [`DivisionPlane`]). The plane passes through
/// [`CellMesh::volume_centroid`]; [`division_plane`] returns both.
pub fn division_plane_normal(mesh: &CellMesh, mode: DivisionPlane) -> Result<Vec3, DivisionError> {
    match mode {
        DivisionPlane::LongestAxis => Ok(mesh.principal_axes().ok_or(DivisionError::NoVolume)?.axes[0]),
        DivisionPlane::Random(seed) => {
            let [x, y, z]: [Real; 3] = UnitSphere.sample(&mut ChaCha8Rng::seed_from_u64(seed));
            Ok(Vec3::new(x, y, z))
        }
    }
}

/// Point (the volume centroid) and unit normal of the division plane of `mesh`.
pub fn division_plane(mesh: &CellMesh, mode: DivisionPlane) -> Result<(Vec3, Vec3), DivisionError> {
    let centroid = mesh.volume_centroid().ok_or(DivisionError::NoVolume)?;
    Ok((centroid, division_plane_normal(mesh, mode)?))
}

/// Divides a valid cell surface by the plane through `plane_point` with normal `plane_normal` (any
/// length > 0); `l_min` (m) sets the cap's point spacing and the snapping tolerance, `seed` the cap's
/// points. Returns the daughter on the side `plane_normal` points to first. See the module doc.
pub fn divide_mesh(
    mesh: &CellMesh,
    face_types: &[FaceType],
    plane_point: Vec3,
    plane_normal: Vec3,
    l_min: Real,
    seed: u64,
) -> Result<(Daughter, Daughter), DivisionError> {
    let normal = check_arguments(mesh, face_types, &plane_point, &plane_normal, l_min)?;
    let cut = cut_surface(mesh, face_types, &plane_point, &normal, SNAP_FRACTION * l_min)?;
    let mother_nodes = mesh.node_count();
    let cut_loop = boundary_loop(&cut.positive)?;
    let loop_positions: Vec<Vec3> = cut_loop.iter().map(|&i| cut.positions[i as usize]).collect();
    let cap = triangulate_cap(&loop_positions, &plane_point, &normal, CAP_SPACING * l_min, seed)?;
    let mut positions = cut.positions;
    let first_interior = positions.len() as u32;
    let mut origins: Vec<NodeOrigin> = (0..mother_nodes as u32).map(NodeOrigin::Mother).collect();
    origins.extend(cut.crossed.iter().map(|&(a, b, t)| NodeOrigin::Cut { a, b, t }));
    origins.resize(positions.len() + cap.interior.len(), NodeOrigin::Cap);
    positions.extend_from_slice(&cap.interior);
    let global = |i: u32| {
        if (i as usize) < cut_loop.len() { cut_loop[i as usize] } else { first_interior + i - cut_loop.len() as u32 }
    };
    let cap_faces = |cap: &PlanarCap, reverse: bool| -> Vec<[u32; 3]> {
        cap.triangles.iter().map(|&[a, b, c]| if reverse { [a, c, b] } else { [a, b, c] }.map(global)).collect()
    };
    // The cap's triangles point along +n: out of the negative daughter, into the positive one.
    let positive = assemble(&positions, &origins, cut.positive, cap_faces(&cap, true), DaughterSide::Positive)?;
    let negative = assemble(&positions, &origins, cut.negative, cap_faces(&cap, false), DaughterSide::Negative)?;
    Ok((positive, negative))
}

/// Validates the arguments; returns the unit plane normal.
fn check_arguments(
    mesh: &CellMesh,
    face_types: &[FaceType],
    point: &Vec3,
    normal: &Vec3,
    l_min: Real,
) -> Result<Vec3, DivisionError> {
    let invalid = |reason: String| Err(DivisionError::InvalidArgument { reason });
    if !(l_min.is_finite() && l_min > 0.0) {
        return invalid(format!("l_min = {l_min} must be positive and finite"));
    }
    if !point.iter().all(|c| c.is_finite()) {
        return invalid(format!("plane point {point:?} is not finite"));
    }
    let length = normal.norm();
    if !(length.is_finite() && length > 0.0) {
        return invalid(format!("plane normal {normal:?} has no direction"));
    }
    if face_types.len() != mesh.face_count() {
        return Err(DivisionError::FaceTypeCount { face_types: face_types.len(), faces: mesh.face_count() });
    }
    mesh.validate().map_err(|defect| DivisionError::InvalidMother { defect })?;
    Ok(normal / length)
}

/// Faces of one side of the cut, in global node numbering, with their types.
struct Side {
    faces: Vec<[u32; 3]>,
    types: Vec<FaceType>,
}

/// The cut surface: the mother's nodes followed by the intersection nodes, and the two open halves.
struct Cut {
    positions: Vec<Vec3>,
    /// For each intersection node (in order): the mother edge `(a, b)` and the fraction `t` from a.
    crossed: Vec<(u32, u32, Real)>,
    positive: Side,
    negative: Side,
}

/// Steps 1 and 2 of the module doc.
fn cut_surface(
    mesh: &CellMesh,
    face_types: &[FaceType],
    point: &Vec3,
    n: &Vec3,
    snap: Real,
) -> Result<Cut, DivisionError> {
    let mut positions = mesh.positions().to_vec();
    let distance: Vec<Real> = positions.iter().map(|p| (p - point).dot(n)).collect();
    let sign: Vec<i8> = distance
        .iter()
        .map(|&d| {
            if d > snap {
                1
            } else if d < -snap {
                -1
            } else {
                0
            }
        })
        .collect();
    let mut crossings: HashMap<(u32, u32), u32> = HashMap::new();
    let mut crossed: Vec<(u32, u32, Real)> = Vec::new();
    // The node where the plane crosses edge a-b (a and b on opposite sides), created once per edge.
    let mut crossing = |a: u32, b: u32, positions: &mut Vec<Vec3>| -> u32 {
        let (lo, hi) = (a.min(b), a.max(b));
        *crossings.entry((lo, hi)).or_insert_with(|| {
            let (dl, dh) = (distance[lo as usize], distance[hi as usize]);
            let t = dl / (dl - dh);
            let (pl, ph) = (positions[lo as usize], positions[hi as usize]);
            positions.push(pl + t * (ph - pl));
            crossed.push((lo, hi, t));
            (positions.len() - 1) as u32
        })
    };
    let mut positive = Side { faces: Vec::new(), types: Vec::new() };
    let mut negative = Side { faces: Vec::new(), types: Vec::new() };
    for (f, (&tri, &ty)) in mesh.triangles().iter().zip(face_types).enumerate() {
        let s = tri.map(|i| sign[i as usize]);
        let (lo, hi) = (*s.iter().min().expect("3 corners"), *s.iter().max().expect("3 corners"));
        let mut put = |side: i8, t: [u32; 3]| {
            let dest = if side > 0 { &mut positive } else { &mut negative };
            dest.faces.push(t);
            dest.types.push(ty);
        };
        if lo >= 0 && hi > 0 {
            put(1, tri);
        } else if hi <= 0 && lo < 0 {
            put(-1, tri);
        } else if lo == 0 && hi == 0 {
            return Err(DivisionError::FaceInPlane { face: f as u32 });
        } else if let Some(z) = (0..3).find(|&k| s[k] == 0) {
            // One corner on the plane, the other two on opposite sides.
            let [a, b, c] = [tri[z], tri[(z + 1) % 3], tri[(z + 2) % 3]];
            let x = crossing(b, c, &mut positions);
            put(s[(z + 1) % 3], [a, b, x]);
            put(s[(z + 2) % 3], [a, x, c]);
        } else {
            // One corner alone on its side.
            let k = (0..3).find(|&k| s[k] != s[(k + 1) % 3] && s[k] != s[(k + 2) % 3]).expect("a lone corner");
            let [a, b, c] = [tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]];
            let (xab, xca) = (crossing(a, b, &mut positions), crossing(c, a, &mut positions));
            put(s[k], [a, xab, xca]);
            let p = |i: u32| positions[i as usize];
            if (p(b) - p(xca)).norm_squared() <= (p(c) - p(xab)).norm_squared() {
                put(-s[k], [xab, b, xca]);
                put(-s[k], [b, c, xca]);
            } else {
                put(-s[k], [xab, b, c]);
                put(-s[k], [xab, c, xca]);
            }
        }
    }
    if positive.faces.is_empty() || negative.faces.is_empty() {
        return Err(DivisionError::PlaneMissesCell { above: positive.faces.len(), below: negative.faces.len() });
    }
    Ok(Cut { positions, crossed, positive, negative })
}

/// The boundary of the positive half as one loop of nodes, each consecutive pair an edge of a positive
/// face in that direction (counter-clockwise about the plane normal for a convex cell).
fn boundary_loop(side: &Side) -> Result<Vec<u32>, DivisionError> {
    let directed: HashSet<(u32, u32)> =
        side.faces.iter().flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]).collect();
    let mut next: HashMap<u32, u32> = HashMap::new();
    let mut order = Vec::new();
    for t in &side.faces {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if !directed.contains(&(b, a)) {
                if next.insert(a, b).is_some() {
                    return Err(DivisionError::PinchedCut { node: a });
                }
                order.push(a);
            }
        }
    }
    let mut seen: HashSet<u32> = HashSet::new();
    let mut loops: Vec<Vec<u32>> = Vec::new();
    for &start in &order {
        if seen.contains(&start) {
            continue;
        }
        let mut cycle = vec![start];
        seen.insert(start);
        let mut node = start;
        loop {
            node = *next.get(&node).ok_or(DivisionError::OpenCut { node })?;
            if node == start {
                break;
            }
            if !seen.insert(node) {
                return Err(DivisionError::PinchedCut { node });
            }
            cycle.push(node);
        }
        loops.push(cycle);
    }
    match loops.len() {
        1 if loops[0].len() >= 3 => Ok(loops.pop().expect("one loop")),
        1 => Err(DivisionError::CutLoops { loops: 0 }),
        n => Err(DivisionError::CutLoops { loops: n }),
    }
}

/// Builds one daughter from its half and its cap: renumbers the used nodes compactly (in global order)
/// and validates the result.
fn assemble(
    positions: &[Vec3],
    origins: &[NodeOrigin],
    side: Side,
    cap: Vec<[u32; 3]>,
    which: DaughterSide,
) -> Result<Daughter, DivisionError> {
    let mut faces = side.faces;
    let mut face_types = side.types;
    face_types.extend(std::iter::repeat_n(FaceType::Lateral, cap.len()));
    faces.extend(cap);
    let mut local = vec![u32::MAX; positions.len()];
    faces.iter().flatten().for_each(|&i| local[i as usize] = 0);
    let mut kept = Vec::new();
    let mut kept_origins = Vec::new();
    for (i, l) in local.iter_mut().enumerate() {
        if *l == 0 {
            *l = kept.len() as u32;
            kept.push(positions[i]);
            kept_origins.push(origins[i]);
        }
    }
    let faces = faces.into_iter().map(|t| t.map(|i| local[i as usize])).collect();
    let mesh = CellMesh::from_triangles(kept, faces)?;
    mesh.validate().map_err(|defect| DivisionError::InvalidDaughter { side: which, defect })?;
    Ok(Daughter { mesh, face_types, origins: kept_origins })
}
