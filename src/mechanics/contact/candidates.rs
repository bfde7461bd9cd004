//! Candidate faces of every node for the narrow phase (Verlet lists, [`CandidateLists`]): built
//! through a spatial grid, reused while nodes move little, brought up to date for the cells whose
//! triangles changed (a remeshing pass usually touches a few cells of many) and rebuilt otherwise.
//! Which lists are kept changes no selected face, only the cost (see [`CandidateLists`]).

use crate::geometry::{Real, SpatialGrid, Vec3, closest_point_on_triangle};
use crate::mesh::Cell;
use rayon::prelude::*;

use super::{boxes_overlap, cell_boxes};

/// The candidate lists' skin, as a fraction of the search radius: lists are built for the search
/// radius times (1 + `SKIN`) and reused until some node has moved by half the skin. On a relaxing
/// 64-cell aggregate nearly every rebuild follows a remeshing (99 of 600 steps at skin 1.0, 102 at
/// 0.5), so a thin skin costs few extra rebuilds and shortens every list (`bench relax`, 600 FIRE
/// steps, contact stage per node-step: 0.5 → 2.20 µs, 0.3 → 1.77, 0.2 → 1.68 with 128 rebuilds,
/// 0.1 → 3.87 with 494); moving tissues (growth, dynamics) rebuild more often at a thin skin.
const SKIN: Real = 0.25;

/// The lists hold only the faces within their radius (the exact distance, not the padded box) when
/// the lists before them were reused at least this many times: the exact test costs the rebuild
/// what it saves each later evaluation, so where the lists are rebuilt at nearly every step
/// (dynamic steps from a raw file) it is left out. Either way the same face is selected.
const EXACT_AFTER_REUSES: usize = 2;

/// Where nodes outrun the skin (dynamics: up to 70 nm per step on embryo_1 against c = 0.2 µm) the
/// lists would be rebuilt at nearly every step; each rebuild forced by a move widens the skin by
/// [`SKIN_WIDEN`] up to [`SKIN_MAX`] (the fixed skin before), and each forced by new triangles
/// narrows it by [`SKIN_NARROW`] back towards [`SKIN`]. The skin changes only which faces are
/// listed, never which one is selected: results are the same whatever it is.
const SKIN_MAX: Real = 0.5;
const SKIN_WIDEN: Real = 1.5;
const SKIN_NARROW: Real = 0.8;

/// The lists are brought up to date instead of rebuilt when at most this fraction of the cells
/// changed triangles (each changed cell makes its neighbours search again near it, so beyond
/// about a quarter of the tissue the update costs as much as a rebuild).
const UPDATE_MAX_CHANGED_FRACTION: Real = 0.25;

/// Quantile of the padded face extents that sets the grid cell size (measured on embryo_1 when the
/// grid was queried at every evaluation: 0.75 gave the fastest contact stage; 1.0, the largest
/// face, was 13 % slower).
const CELL_QUANTILE: Real = 0.75;

/// The grid cell size as a fraction of that quantile. The grid now serves only the candidate-list
/// rebuilds, where each node reads the faces of its grid cell: half the extent holds about a
/// quarter as many faces per cell for ~3 registrations per axis instead of 2 (64-cell aggregate,
/// `bench relax`, 600 FIRE steps: candidate-list rebuilds 0.97 → 0.70 µs per node-step; 0.33:
/// 1.03; 0.25: 2.82, from the registrations).
const GRID_CELL_FRACTION: Real = 0.5;

/// Candidate faces of one cell's nodes (CSR): node n's are `faces[offsets[n]..offsets[n + 1]]`,
/// global face indices, ascending.
#[derive(Clone, Debug, Default)]
pub(super) struct NodeCandidates {
    offsets: Vec<u32>,
    faces: Vec<u32>,
}

impl NodeCandidates {
    pub(super) fn of(&self, node: usize) -> &[u32] {
        &self.faces[self.offsets[node] as usize..self.offsets[node + 1] as usize]
    }

    pub(super) fn is_empty(&self) -> bool {
        self.faces.is_empty()
    }

    fn clear(&mut self) {
        self.offsets.clear();
        self.faces.clear();
    }
}

/// What [`CandidateLists::refresh`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Refresh {
    /// The lists still held every face that can be selected.
    Reused,
    /// Only the lists of cells whose triangles changed, and their neighbours' entries towards
    /// them, were searched again.
    Updated,
    /// Every list was built again.
    Rebuilt,
}

/// Verlet lists of the narrow phase. For every node p of every cell, the faces g of the other cells
/// that lay within `radius` of p (closest point, exactly; or, when [`EXACT_AFTER_REUSES`] says so,
/// whose box padded by `radius` held p, a superset) when the lists were built. While every
/// node has moved by at most δ since then, a face within the current search radius s of the node
/// now is in its list if s + 2δ ≤ `radius` (the distance is 1-Lipschitz in the node and in each
/// corner of the face, each moved by at most δ). The narrow phase selects, per other cell, the
/// first face at the least distance among the faces whose box padded by s holds the node, and keeps
/// it only within s: a face farther than s can be neither that face nor beat it, so testing only
/// the listed faces, in the same (ascending) order, selects the same closest faces, bit for bit,
/// as an exhaustive grid query, without rebuilding the grid or scanning a grid cube's faces at
/// every evaluation.
///
/// When some cells' triangles change (remeshing) and the others' nodes moved by δ₀ since the
/// lists were built, with s + 2δ₀ within the radius, only the entries that involve a changed cell
/// are searched again ([`Self::update`]): the changed cells' nodes get new lists, and the other
/// nodes near a changed cell new entries towards it, both for the radius plus δ₀; the other
/// entries are kept (their face indices shifted where the cells before them changed face counts),
/// and a changed cell's reference positions become its current ones. An entry searched again then
/// spans both build times: a node or corner that is now δ from its reference was at most δ + δ₀
/// from where it was when the entry was found, so a face within s now lay within s + 2δ + δ₀ ≤
/// radius + δ₀ then, and the invariant above holds with the same δ test. A new tissue or cell
/// count, or changes in more than [`UPDATE_MAX_CHANGED_FRACTION`] of the cells, rebuild the lists.
#[derive(Clone, Debug, Default)]
pub(super) struct CandidateLists {
    /// Radius the lists were built for (m); 0 before the first build.
    radius: Real,
    /// The skin of the next rebuild, as a fraction of the search radius (0 before the first: then
    /// [`SKIN`]).
    skin: Real,
    /// Evaluations that reused the lists since their last build.
    reused: usize,
    /// Per cell: topology generation, and node positions when the lists were built.
    generations: Vec<u64>,
    reference: Vec<Vec<Vec3>>,
    /// Where each cell's faces started in the global face order when the lists were built or
    /// updated.
    offsets: Vec<u32>,
    pub(super) cells: Vec<NodeCandidates>,
    /// Scratch of the rebuild (kept to avoid reallocating): every face's box padded by the radius,
    /// with the faces that cannot be near another cell emptied; the grid holds these.
    registered: Vec<(Vec3, Vec3)>,
    /// Scratch of the update: new lists, swapped in.
    scratch: Vec<NodeCandidates>,
}

/// Whether each cell's triangles changed since the lists were built, and how far the others'
/// nodes moved (m; infinite for a non-finite position).
struct Changes {
    changed: Vec<bool>,
    moved: Real,
}

impl CandidateLists {
    pub(super) fn is_empty(&self) -> bool {
        self.cells.iter().all(|c| c.faces.is_empty())
    }

    /// Makes the lists hold every face that the search radius `search` can select for `cells`:
    /// reuses, updates or rebuilds them. `boxes` and `face_offsets` are every face's box padded by
    /// `search` and where each cell's faces start (as in [`super::ContactWorkspace`]).
    pub(super) fn refresh(
        &mut self,
        cells: &[Cell],
        boxes: &[(Vec3, Vec3)],
        face_offsets: &[u32],
        search: Real,
        grid: &mut Option<SpatialGrid>,
    ) -> Refresh {
        let n = cells.len();
        if self.radius <= 0.0 || self.generations.len() != n || self.offsets.len() != n + 1 {
            self.rebuild(cells, boxes, face_offsets, search, grid);
            return Refresh::Rebuilt;
        }
        let Changes { changed, moved } = self.changes(cells);
        // The relative margin absorbs rounding of the padded boxes.
        let fits = search + 2.0 * moved <= self.radius * (1.0 - 1e-9);
        let count = changed.iter().filter(|&&c| c).count();
        if count == 0 {
            if fits {
                self.reused += 1;
                return Refresh::Reused;
            }
            if search <= self.radius {
                // Nodes outran the skin: the next lists get a wider one.
                self.skin = (self.skin * SKIN_WIDEN).min(SKIN_MAX);
            }
            self.rebuild(cells, boxes, face_offsets, search, grid);
            return Refresh::Rebuilt;
        }
        let few = (count as Real) <= UPDATE_MAX_CHANGED_FRACTION * n as Real;
        if let Some(grid) = grid.as_mut().filter(|_| fits && few) {
            self.update(cells, boxes, face_offsets, search, grid, &changed, moved);
            return Refresh::Updated;
        }
        // Rebuilt for the triangles: the skin narrows back (nodes did not outrun it).
        self.skin = (self.skin * SKIN_NARROW).max(SKIN);
        self.rebuild(cells, boxes, face_offsets, search, grid);
        Refresh::Rebuilt
    }

    /// Which cells changed triangles (or node count) since the lists were built, and the largest
    /// move of the other cells' nodes since then.
    fn changes(&self, cells: &[Cell]) -> Changes {
        let per_cell: Vec<(bool, Real)> = cells
            .par_iter()
            .zip(self.reference.par_iter())
            .zip(self.generations.par_iter())
            .map(|((cell, reference), &generation)| {
                let p = cell.mesh().positions();
                if cell.mesh().topology_generation() != generation || p.len() != reference.len() {
                    return (true, 0.0);
                }
                let moved = p.iter().zip(reference).fold(0.0 as Real, |m, (x, y)| {
                    let d = (x - y).norm_squared();
                    // A NaN position invalidates the lists.
                    if d.is_nan() { Real::INFINITY } else { m.max(d) }
                });
                (false, moved)
            })
            .collect();
        Changes {
            changed: per_cell.iter().map(|c| c.0).collect(),
            moved: per_cell.iter().map(|c| c.1).fold(0.0, Real::max).sqrt(),
        }
    }

    /// Builds the lists from the current positions for the search radius `search` plus the skin,
    /// through one grid of every face's box padded by that radius.
    fn rebuild(
        &mut self,
        cells: &[Cell],
        boxes: &[(Vec3, Vec3)],
        face_offsets: &[u32],
        search: Real,
        grid: &mut Option<SpatialGrid>,
    ) {
        let n = cells.len();
        self.skin = self.skin.clamp(SKIN, SKIN_MAX);
        // Only faces within the radius when the lists before lived long enough to pay for it.
        let exact = self.reused >= EXACT_AFTER_REUSES;
        self.reused = 0;
        let skin = self.skin * search;
        self.radius = search + skin;
        self.generations = cells.iter().map(|c| c.mesh().topology_generation()).collect();
        self.offsets.clear();
        self.offsets.extend_from_slice(face_offsets);
        self.reference.resize_with(n, Vec::new);
        for (r, cell) in self.reference.iter_mut().zip(cells) {
            r.clear();
            r.extend_from_slice(cell.mesh().positions());
        }
        self.cells.resize_with(n, NodeCandidates::default);
        self.cells.iter_mut().for_each(NodeCandidates::clear);
        let registered = &mut self.registered;
        let (cell_boxes, neighbours) = register(registered, boxes, skin, face_offsets, |_, _| true);
        let largest = registered.iter().fold(0.0 as Real, |m, (lo, hi)| m.max((hi - lo).max()));
        if !(largest.is_finite() && largest > 0.0) {
            // Non-finite coordinates: no candidates, and a rebuild at the next evaluation.
            self.radius = 0.0;
            return;
        }
        if neighbours.iter().all(Vec::is_empty) {
            // No candidates (every node's list empty, as an update expects).
            for (list, cell) in self.cells.iter_mut().zip(cells) {
                list.offsets.resize(cell.mesh().node_count() + 1, 0);
            }
            return;
        }
        // Only faces inside another cell's box can be near its nodes; the others stay out of the
        // grid (an inverted box is skipped by it, and never tested below).
        cull(registered, face_offsets, &cell_boxes, &neighbours);
        // Grid cell = a quantile of the padded face extents: small enough that a lookup returns
        // few faces, large enough that most faces span at most 2×2×2 cells (bigger ones span more).
        let mut extents: Vec<Real> =
            registered.iter().map(|(lo, hi)| (hi - lo).max()).filter(|e| e.is_finite()).collect();
        let q = ((extents.len() as Real * CELL_QUANTILE) as usize).min(extents.len().saturating_sub(1));
        let cell_size =
            if extents.is_empty() { largest } else { *extents.select_nth_unstable_by(q, Real::total_cmp).1 };
        let cell_size = GRID_CELL_FRACTION * cell_size;
        let grid = grid.get_or_insert_with(|| SpatialGrid::new(cell_size));
        if grid.cell_size() != cell_size {
            grid.set_cell_size(cell_size);
        }
        grid.rebuild(registered);
        let search = Search::new(grid, cells, registered, face_offsets, exact.then_some(self.radius));
        let (neighbours, cell_boxes) = (&neighbours, &cell_boxes);
        self.cells.par_iter_mut().enumerate().for_each(|(a, list)| {
            let positions = cells[a].mesh().positions();
            list.offsets.push(0);
            let mut found = Vec::new();
            for p in positions {
                if neighbours[a].iter().any(|&b| inside(p, &cell_boxes[b])) {
                    search.faces_near(p, a, |_| true, &mut found, &mut list.faces);
                }
                list.offsets.push(list.faces.len() as u32);
            }
        });
    }

    /// Brings the lists up to date for the cells marked `changed` (see the type's doc), the others'
    /// nodes having moved by at most `moved` since the lists were built.
    #[allow(clippy::too_many_arguments)]
    fn update(
        &mut self,
        cells: &[Cell],
        boxes: &[(Vec3, Vec3)],
        face_offsets: &[u32],
        search: Real,
        grid: &mut SpatialGrid,
        changed: &[bool],
        moved: Real,
    ) {
        let n = cells.len();
        // New entries are found out to the radius plus the others' move (see the type's doc).
        let build = self.radius + moved;
        let registered = &mut self.registered;
        // A changed cell searches all its neighbours; an unchanged one only its changed neighbours.
        let (cell_boxes, neighbours) =
            register(registered, boxes, build - search, face_offsets, |a, b| changed[a] || changed[b]);
        cull(registered, face_offsets, &cell_boxes, &neighbours);
        grid.rebuild(registered);
        let search = Search::new(grid, cells, registered, face_offsets, Some(build));
        let old_offsets = &self.offsets;
        self.scratch.resize_with(n, NodeCandidates::default);
        let (neighbours, cell_boxes) = (&neighbours, &cell_boxes);
        self.scratch.par_iter_mut().zip(self.cells.par_iter()).enumerate().for_each(|(a, (new, old))| {
            new.clear();
            new.offsets.push(0);
            let positions = cells[a].mesh().positions();
            let mut found = Vec::new();
            let mut fresh = Vec::new();
            let near = &neighbours[a];
            for (node, p) in positions.iter().enumerate() {
                let searched = !near.is_empty() && near.iter().any(|&b| inside(p, &cell_boxes[b]));
                if changed[a] {
                    if searched {
                        search.faces_near(p, a, |_| true, &mut found, &mut new.faces);
                    }
                } else {
                    fresh.clear();
                    if searched {
                        search.faces_near(p, a, |b| changed[b], &mut found, &mut fresh);
                    }
                    // The kept entries (towards unchanged cells, at their new indices) and the new
                    // ones (towards changed cells), merged in ascending order.
                    let mut kept = old.of(node).iter().copied().filter_map(|g| {
                        let b = old_offsets.partition_point(|&o| o <= g) - 1;
                        (!changed[b]).then(|| g - old_offsets[b] + face_offsets[b])
                    });
                    let mut fresh = fresh.iter().copied().peekable();
                    let mut next_kept = kept.next();
                    loop {
                        match (next_kept, fresh.peek()) {
                            (Some(k), Some(&f)) if f < k => {
                                new.faces.push(f);
                                fresh.next();
                            }
                            (Some(k), _) => {
                                new.faces.push(k);
                                next_kept = kept.next();
                            }
                            (None, Some(&f)) => {
                                new.faces.push(f);
                                fresh.next();
                            }
                            (None, None) => break,
                        }
                    }
                }
                new.offsets.push(new.faces.len() as u32);
            }
        });
        std::mem::swap(&mut self.cells, &mut self.scratch);
        for (c, cell) in cells.iter().enumerate().filter(|(c, _)| changed[*c]) {
            self.generations[c] = cell.mesh().topology_generation();
            self.reference[c].clear();
            self.reference[c].extend_from_slice(cell.mesh().positions());
        }
        self.offsets.clear();
        self.offsets.extend_from_slice(face_offsets);
    }
}

/// Fills `registered` with every face's box (`boxes`) padded by `pad`; returns each cell's box
/// (the cell-level prefilter: a node has candidates only inside a neighbour's box) and, for each
/// cell a, the other cells b with `related(a, b)` whose boxes overlap a's.
fn register(
    registered: &mut Vec<(Vec3, Vec3)>,
    boxes: &[(Vec3, Vec3)],
    pad: Real,
    face_offsets: &[u32],
    related: impl Fn(usize, usize) -> bool,
) -> (Vec<(Vec3, Vec3)>, Vec<Vec<usize>>) {
    registered.clear();
    registered.extend(boxes.iter().map(|(lo, hi)| (lo.add_scalar(-pad), hi.add_scalar(pad))));
    let cell_boxes = cell_boxes(registered, face_offsets);
    let n = cell_boxes.len();
    let neighbours = (0..n)
        .map(|a| (0..n).filter(|&b| b != a && related(a, b) && boxes_overlap(&cell_boxes[a], &cell_boxes[b])).collect())
        .collect();
    (cell_boxes, neighbours)
}

/// Whether `p` lies in the box `b`.
fn inside(p: &Vec3, b: &(Vec3, Vec3)) -> bool {
    (0..3).all(|k| b.0[k] <= p[k] && p[k] <= b.1[k])
}

/// Empties (inverts) the registered box of every face of cell a that lies outside the boxes of all
/// of `neighbours[a]`: no node of those cells can find it, so it stays out of the grid.
fn cull(registered: &mut [(Vec3, Vec3)], face_offsets: &[u32], cell_boxes: &[(Vec3, Vec3)], neighbours: &[Vec<usize>]) {
    for (a, near) in neighbours.iter().enumerate() {
        let range = face_offsets[a] as usize..face_offsets[a + 1] as usize;
        for bx in &mut registered[range] {
            if !near.iter().any(|&b| boxes_overlap(bx, &cell_boxes[b])) {
                *bx = (Vec3::repeat(Real::INFINITY), Vec3::repeat(Real::NEG_INFINITY));
            }
        }
    }
}

/// One grid query of a list build: the faces registered in `grid` (boxes `boxes`) whose box holds
/// a node, and, with `radius`, whose closest point lies within it.
struct Search<'a> {
    grid: &'a SpatialGrid,
    oversized: bool,
    cells: &'a [Cell],
    boxes: &'a [(Vec3, Vec3)],
    face_offsets: &'a [u32],
    radius: Option<Real>,
}

impl<'a> Search<'a> {
    fn new(
        grid: &'a SpatialGrid,
        cells: &'a [Cell],
        boxes: &'a [(Vec3, Vec3)],
        face_offsets: &'a [u32],
        radius: Option<Real>,
    ) -> Self {
        Search { grid, oversized: !grid.oversized_items().is_empty(), cells, boxes, face_offsets, radius }
    }

    /// Appends to `out`, ascending, the faces of the other cells b with `accept(b)` (not of cell
    /// `own`) whose registered box holds `p` and, with a radius, that lie within it of `p`.
    /// `found` is scratch.
    fn faces_near(
        &self,
        p: &Vec3,
        own: usize,
        accept: impl Fn(usize) -> bool,
        found: &mut Vec<u32>,
        out: &mut Vec<u32>,
    ) {
        let offsets = self.face_offsets;
        found.clear();
        if self.oversized {
            self.grid.for_each_at(p, |item| found.push(item));
            found.sort_unstable();
            found.dedup();
        } else {
            // Already sorted and unique within a grid cell.
            found.extend_from_slice(self.grid.items_at(p));
        }
        let own = offsets[own]..offsets[own + 1];
        // Of the faces whose padded box holds p, only those within the radius (the closest point,
        // exactly): the narrow phase can select no other (see `CandidateLists`), and a box's corners
        // hold about twice as many faces as the ball.
        let mut b = 0;
        for &g in found.iter() {
            if own.contains(&g) || !inside(p, &self.boxes[g as usize]) {
                continue;
            }
            while offsets[b + 1] <= g {
                b += 1;
            }
            if !accept(b) {
                continue;
            }
            let Some(radius) = self.radius else {
                out.push(g);
                continue;
            };
            let mesh_b = self.cells[b].mesh();
            let (pb, t) = (mesh_b.positions(), mesh_b.triangles()[(g - offsets[b]) as usize]);
            let q = closest_point_on_triangle(p, &pb[t[0] as usize], &pb[t[1] as usize], &pb[t[2] as usize]);
            if q.distance <= radius {
                out.push(g);
            }
        }
    }
}
