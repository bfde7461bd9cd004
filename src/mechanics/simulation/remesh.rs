//! Remeshing glue: scheduled passes over every moving cell, out-of-turn repair of short edges and
//! slivers on fixed meshes, and the back-off of cells whose passes can do nothing.

use super::{Simulation, SimulationError};
use crate::geometry::{Real, Vec3};
use crate::mesh::MeshDefect;
use crate::mesh::remesh::{RemeshError, RemeshReport, RemeshSettings, triangle_quality};
use rayon::prelude::*;

/// Remeshing passes a cell skips after a pass in which every operation it needed was refused.
pub(super) const REMESH_BACKOFF: u32 = 4;

/// Checks (steps) a cell skips after an out-of-turn remeshing that left its short edge in place.
const NEED_BACKOFF: u32 = 100;

impl<'p> Simulation<'p> {
    /// Local remeshing of every moving cell (split, collapse, flip; momenta follow their nodes).
    /// Returns whether any mesh changed; then forces are re-evaluated.
    pub(super) fn remesh(&mut self) -> Result<bool, SimulationError> {
        let changed = self.remesh_cells(None)?;
        self.evaluate_remeshed(changed)
    }

    /// Repairs [`Self::cells_needing_repair`] now (short edges collapsed, slivers flipped) and
    /// re-evaluates the forces. Returns whether any mesh changed.
    pub(super) fn repair_out_of_turn(&mut self) -> Result<bool, SimulationError> {
        let Some(cells) = self.cells_needing_repair() else { return Ok(false) };
        let changed = self.repair_meshes(cells)?;
        self.evaluate_remeshed(changed)
    }

    /// After a remeshing that `changed` a mesh: the new state is the last good one, forces evaluated.
    fn evaluate_remeshed(&mut self, changed: bool) -> Result<bool, SimulationError> {
        if changed {
            self.save_good();
            self.evaluate()?;
        }
        Ok(changed)
    }

    /// The moving cells with an edge below `simulation.remesh_below_edge_fraction`·l_min or a sliver
    /// (None: none, the check is off, or scheduled passes remesh the cells: see the setting).
    pub(super) fn cells_needing_repair(&self) -> Option<Vec<bool>> {
        let settings = &self.params.simulation;
        let fraction = settings.remesh_below_edge_fraction;
        if fraction <= 0.0 || settings.remesh_every_steps > 0 {
            return None;
        }
        let threshold = fraction * self.params.numerics.min_edge_length;
        let due: Vec<bool> = self
            .tissue
            .cells()
            .par_iter()
            .map(|c| !c.kind().is_immobile() && needs_repair(c.mesh().positions(), c.mesh().triangles(), threshold))
            .collect();
        due.contains(&true).then_some(due)
    }

    /// The repairs of [`Self::repair_out_of_turn`] without the evaluation. A cell whose short edge or
    /// sliver survives its pass (every operation that would remove it refused) is left alone for
    /// [`NEED_BACKOFF`] checks instead of being remeshed again at every step.
    pub(super) fn repair_meshes(&mut self, mut cells: Vec<bool>) -> Result<bool, SimulationError> {
        for (c, due) in cells.iter_mut().enumerate() {
            if *due && self.cell_data.remesh_idle[c] > 0 {
                self.cell_data.remesh_idle[c] -= 1;
                *due = false;
            }
        }
        if !cells.contains(&true) {
            return Ok(false);
        }
        if tracing::enabled!(tracing::Level::DEBUG) {
            let ids: Vec<String> =
                (0..cells.len()).filter(|&c| cells[c]).map(|c| self.tissue.cells()[c].id().to_string()).collect();
            tracing::debug!(
                "step {}: repairing cell(s) {} out of turn (edges below remesh_below_edge_fraction·l_min, slivers)",
                self.progress.step,
                ids.join(", ")
            );
        }
        self.progress.topology.need_passes += 1;
        let changed = self.remesh_cells(Some(&cells))?;
        if let Some(still) = self.cells_needing_repair() {
            for (c, _) in cells.iter().zip(&still).enumerate().filter(|(_, (due, still))| **due && **still) {
                self.cell_data.remesh_idle[c] = NEED_BACKOFF;
            }
        }
        Ok(changed)
    }

    /// One remeshing pass over every moving cell, in parallel (each cell on its own, so the result
    /// does not depend on the thread count). Refused operations are skipped and counted; a pass that
    /// would break a surface is discarded and counted. Returns whether any mesh changed.
    /// `only`: the cells to remesh (their back-off ignored), collapsing only the edges below
    /// `simulation.remesh_below_edge_fraction`·l_min and flipping only slivers; None: every moving
    /// cell, a full pass.
    pub(super) fn remesh_cells(&mut self, only: Option<&[bool]>) -> Result<bool, SimulationError> {
        let numerics = &self.params.numerics;
        let settings = match only {
            None => {
                RemeshSettings { l_max: numerics.max_edge_length(), ..RemeshSettings::new(numerics.min_edge_length) }
            }
            // Out of turn: only the short edges go and only slivers flip (no splits), so that a mesh
            // the run keeps fixed changes by those few nodes and edges and no more.
            Some(_) => RemeshSettings {
                l_min: self.params.simulation.remesh_below_edge_fraction * numerics.min_edge_length,
                l_max: Real::MAX,
                min_quality: SLIVER_QUALITY,
                ..RemeshSettings::new(numerics.min_edge_length)
            },
        };
        let results: Vec<Option<(u64, Result<RemeshReport, RemeshError>)>> = self
            .tissue
            .cells_mut()
            .par_iter_mut()
            .zip(self.cell_data.momenta.par_iter_mut())
            .zip(self.cell_data.remesh_idle.par_iter_mut())
            .enumerate()
            .map(|(c, ((cell, momenta), idle))| {
                if cell.kind().is_immobile() {
                    return None;
                }
                if let Some(only) = only {
                    if !only[c] {
                        return None;
                    }
                } else if *idle > 0 {
                    *idle -= 1;
                    return None;
                }
                let before = cell.mesh().topology_generation();
                let result = cell.remesh(Some(momenta), &settings);
                Some((before, result))
            })
            .collect();
        let mut changed = false;
        for (c, result) in results.into_iter().enumerate() {
            let Some((before, result)) = result else { continue };
            match result {
                Ok(report) => {
                    if report.rounds > 0 {
                        self.progress.topology.add_remesh(&report);
                        if report.operations() == 0 {
                            self.cell_data.remesh_idle[c] = REMESH_BACKOFF;
                        }
                    }
                    changed |= self.tissue.cells()[c].mesh().topology_generation() != before;
                }
                Err(e) => {
                    let cell = self.tissue.cells()[c].id();
                    let inner = match e {
                        RemeshError::Cell { source, .. } => *source,
                        other => other,
                    };
                    match inner {
                        // The pass would have broken a valid surface, or the surface has a face that
                        // motion flattened (geometric, not topological): keep the mesh this step.
                        RemeshError::Broke { .. }
                        | RemeshError::InvalidInput {
                            defect: MeshDefect::DegenerateFace { .. } | MeshDefect::NonPositiveVolume { .. },
                        } => {
                            self.progress.topology.rejected_passes += 1;
                            tracing::debug!(
                                "step {}: cell {cell}: remeshing pass discarded: {inner}",
                                self.progress.step
                            );
                        }
                        other => {
                            return Err(SimulationError::Remesh {
                                step: self.progress.step,
                                source: Box::new(RemeshError::Cell { cell, source: Box::new(other) }),
                            });
                        }
                    }
                }
            }
        }
        Ok(changed)
    }
}

/// Triangles below this quality (12√3·A/P², 1 for an equilateral triangle) are slivers that the
/// out-of-turn repair flips away: near-degenerate faces whose normal swings with tiny moves.
const SLIVER_QUALITY: Real = 0.02;

/// Whether a mesh has an edge shorter than `threshold` or a sliver (see [`SLIVER_QUALITY`]).
fn needs_repair(x: &[Vec3], triangles: &[[u32; 3]], threshold: Real) -> bool {
    let t2 = threshold * threshold;
    triangles.iter().any(|t| {
        let [a, b, c] = t.map(|i| x[i as usize]);
        [(a, b), (b, c), (c, a)].iter().any(|(p, q)| (p - q).norm_squared() < t2)
            || triangle_quality(&a, &b, &c) < SLIVER_QUALITY
    })
}
