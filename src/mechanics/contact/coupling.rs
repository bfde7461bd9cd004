//! The node-coupling contact model (paper Methods, "Intercellular contacts", second model).
//!
//! Node pairs {n_a, n_b} of two different cells closer than the cutoff c are tied: both move to
//! their midpoint, and their forces and momenta are replaced by the pair averages, so the two nodes
//! follow the same dynamics (one merged node with the summed force). A pair forms only if the local
//! mean curvature of both surfaces lies below the threshold H_max of each cell's type (so cells can
//! detach where the contact rim sharpens) and the two surfaces face each other (node normals
//! opposed). Each node has at most one partner; pairs are redetermined at every force evaluation.
//!
//! **Matching.** All candidate pairs are collected, sorted by (distance, first node, second node) and
//! accepted greedily while both nodes are free: the nearest pairs first, and the result depends only
//! on the geometry, never on the thread count or the cell order. (The reference program lets each
//! node claim a partner from its own thread, which races; and its pairs need not be mutual.)
//!
//! **Which cells.** Only epithelial and static cells couple (as in the reference). A node tied to a
//! static cell's node is pinned there: it snaps onto the static node and its force and momentum are
//! zeroed. ECM, lumen and nuclei interact through the spring model.
//!
//! **Energy.** For fixed pairs the tie is a holonomic constraint r_a = r_b, and the averaged force is
//! the projection of −∇U onto it, so equilibrium means f_a + f_b = 0 for every pair. The snap itself
//! is a position projection, not a force: the energy can rise when a new pair forms (documented in
//! the paper's model; overdamped energy monotonicity holds only between pair changes).

use crate::geometry::{Real, SpatialGrid, Vec3};
use crate::mechanics::{CellForces, CellTypeParams};
use crate::mesh::Tissue;
use rayon::prelude::*;

/// One tied node pair: (cell index, node index) of each side, `a` before `b` in tissue order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoupledPair {
    pub a: (u32, u32),
    pub b: (u32, u32),
}

/// Reusable buffers of the coupling stage.
#[derive(Default)]
pub struct CouplingWorkspace {
    grid: Option<SpatialGrid>,
    /// Eligible nodes: (cell, node).
    nodes: Vec<(u32, u32)>,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    boxes: Vec<(Vec3, Vec3)>,
    candidates: Vec<(Real, u32, u32)>,
    taken: Vec<bool>,
    pairs: Vec<CoupledPair>,
}

impl CouplingWorkspace {
    /// The pairs of the last [`Self::couple`].
    pub fn pairs(&self) -> &[CoupledPair] {
        &self.pairs
    }

    /// Puts back the pairs of a saved state (a resumed run averages momenta and FIRE velocities
    /// over the pairs of the evaluation it was saved after).
    pub fn restore_pairs(&mut self, pairs: Vec<CoupledPair>) {
        self.pairs = pairs;
    }

    /// Finds the node pairs of the current configuration and snaps each pair together (to the
    /// midpoint; onto the static node when one side is static). Returns the number of pairs.
    pub fn couple(&mut self, tissue: &mut Tissue, cell_params: &[&CellTypeParams], cutoff: Real) -> usize {
        self.pairs.clear();
        let cells = tissue.cells();
        let eligible_cells = cells.iter().filter(|c| c.kind().is_cell()).count();
        if eligible_cells < 2 || cutoff.is_nan() || cutoff <= 0.0 {
            return 0;
        }
        // Eligible nodes of every coupling cell: flatter than its H_max.
        let per_cell: Vec<Vec<(u32, Vec3, Vec3)>> = cells
            .par_iter()
            .zip(cell_params.par_iter())
            .map(|(cell, p)| {
                if !cell.kind().is_cell() {
                    return Vec::new();
                }
                let (curvature, normals) = cell.mesh().mean_curvature_and_normals();
                let positions = cell.mesh().positions();
                (0..positions.len())
                    .filter(|&n| curvature[n] < p.max_coupling_curvature)
                    .map(|n| (n as u32, positions[n], normals[n]))
                    .collect()
            })
            .collect();
        self.nodes.clear();
        self.positions.clear();
        self.normals.clear();
        for (c, list) in per_cell.iter().enumerate() {
            for &(n, p, nrm) in list {
                self.nodes.push((c as u32, n));
                self.positions.push(p);
                self.normals.push(nrm);
            }
        }
        if self.nodes.is_empty() {
            return 0;
        }
        self.boxes.clear();
        self.boxes.extend(self.positions.iter().map(|p| (*p, *p)));
        // Cubes of edge 2c: a query box [p − c, p + c] then spans 2 cubes per axis (4 rows of
        // cubes to look up) instead of 3 (9 rows) with cubes of edge c; the extra nodes it returns
        // are rejected by the distance test. Every pair closer than c is found either way.
        let cell_size = 2.0 * cutoff;
        let grid = self.grid.get_or_insert_with(|| SpatialGrid::new(cell_size));
        if grid.cell_size() != cell_size {
            grid.set_cell_size(cell_size);
        }
        grid.rebuild(&self.boxes);
        let grid = &*grid;

        // Candidate pairs (i < j in the eligible-node order), in parallel by chunks of nodes.
        let (nodes, positions, normals) = (&self.nodes, &self.positions, &self.normals);
        let immobile: Vec<bool> = cells.iter().map(|c| c.kind().is_immobile()).collect();
        let c2 = cutoff * cutoff;
        let found: Vec<Vec<(Real, u32, u32)>> = (0..nodes.len())
            .into_par_iter()
            .chunks(1024)
            .map(|chunk| {
                let mut out = Vec::new();
                let mut near = Vec::new();
                for i in chunk {
                    let (ci, p) = (nodes[i].0, positions[i]);
                    let r = Vec3::repeat(cutoff);
                    // Each node is a point, registered in exactly one grid cube, so the query
                    // yields every node once: no sort or dedup needed (the candidates are sorted
                    // in full below, so their order here does not matter).
                    near.clear();
                    grid.for_each_candidate(&(p - r), &(p + r), |j| near.push(j));
                    for &j in &near {
                        let j = j as usize;
                        let cj = nodes[j].0;
                        if j <= i || cj == ci || (immobile[ci as usize] && immobile[cj as usize]) {
                            continue;
                        }
                        let d2 = (positions[j] - p).norm_squared();
                        if d2 < c2 && normals[i].dot(&normals[j]) < 0.0 {
                            out.push((d2, i as u32, j as u32));
                        }
                    }
                }
                out
            })
            .collect();
        self.candidates.clear();
        for list in found {
            self.candidates.extend(list);
        }
        self.candidates.par_sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
        self.taken.clear();
        self.taken.resize(nodes.len(), false);
        for &(_, i, j) in &self.candidates {
            let (i, j) = (i as usize, j as usize);
            if self.taken[i] || self.taken[j] {
                continue;
            }
            self.taken[i] = true;
            self.taken[j] = true;
            self.pairs.push(CoupledPair { a: nodes[i], b: nodes[j] });
        }
        // Snap.
        let cells = tissue.cells_mut();
        for pair in &self.pairs {
            let (ca, na) = (pair.a.0 as usize, pair.a.1 as usize);
            let (cb, nb) = (pair.b.0 as usize, pair.b.1 as usize);
            let pa = cells[ca].mesh().positions()[na];
            let pb = cells[cb].mesh().positions()[nb];
            let target = match (immobile[ca], immobile[cb]) {
                (true, _) => pa,
                (_, true) => pb,
                _ => 0.5 * (pa + pb),
            };
            cells[ca].positions_mut()[na] = target;
            cells[cb].positions_mut()[nb] = target;
        }
        self.pairs.len()
    }

    /// Replaces the forces of each pair by their average (zero for a node tied to a static cell).
    pub fn average_forces(&self, tissue: &Tissue, forces: &mut [CellForces]) {
        for pair in &self.pairs {
            let (ca, na) = (pair.a.0 as usize, pair.a.1 as usize);
            let (cb, nb) = (pair.b.0 as usize, pair.b.1 as usize);
            let mean = if pinned(tissue, pair) {
                Vec3::zeros()
            } else {
                0.5 * (forces[ca].forces[na] + forces[cb].forces[nb])
            };
            forces[ca].forces[na] = mean;
            forces[cb].forces[nb] = mean;
        }
    }

    /// Replaces the momenta of each pair by their average (zero for a node tied to a static cell);
    /// `momenta[c][n]` as in the integrator.
    pub fn average_momenta(&self, tissue: &Tissue, momenta: &mut [Vec<Vec3>]) {
        for pair in &self.pairs {
            let (ca, na) = (pair.a.0 as usize, pair.a.1 as usize);
            let (cb, nb) = (pair.b.0 as usize, pair.b.1 as usize);
            let mean = if pinned(tissue, pair) { Vec3::zeros() } else { 0.5 * (momenta[ca][na] + momenta[cb][nb]) };
            momenta[ca][na] = mean;
            momenta[cb][nb] = mean;
        }
    }

    /// The same for vectors packed over all nodes of the tissue, cell c's nodes starting at
    /// `offsets[c]` (FIRE's velocities).
    pub fn average_packed(&self, tissue: &Tissue, offsets: &[usize], values: &mut [Vec3]) {
        for pair in &self.pairs {
            let ia = offsets[pair.a.0 as usize] + pair.a.1 as usize;
            let ib = offsets[pair.b.0 as usize] + pair.b.1 as usize;
            let mean = if pinned(tissue, pair) { Vec3::zeros() } else { 0.5 * (values[ia] + values[ib]) };
            values[ia] = mean;
            values[ib] = mean;
        }
    }
}

/// Whether one side of the pair is immobile, which pins the other.
fn pinned(tissue: &Tissue, pair: &CoupledPair) -> bool {
    tissue.cells()[pair.a.0 as usize].kind().is_immobile() || tissue.cells()[pair.b.0 as usize].kind().is_immobile()
}
