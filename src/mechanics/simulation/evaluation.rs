//! Force evaluation: node coupling, internal forces, contacts, polarity (ray casting or from
//! contacts), the optional projection onto node normals, and the health check of the result.

use super::Simulation;
use super::SimulationError;
use crate::geometry::{Real, Vec3};
use crate::mechanics::forces::TermSet;
use crate::mechanics::polarity::{RayCastSettings, polarize_by_ray_casting, polarize_from_contacts};
use crate::mechanics::{ContactModel, Dynamics, Polarity};
use crate::mesh::Cell;
use rayon::prelude::*;
use std::time::Instant;

impl<'p> Simulation<'p> {
    /// Largest nodal force of a moving cell, over γ̄·l_min.
    pub(super) fn residual(&self) -> Real {
        let mut max: Real = 0.0;
        for (cell, work) in self.tissue.cells().iter().zip(&self.work.forces.cells) {
            if !cell.kind().is_immobile() {
                for f in &work.forces {
                    max = max.max(f.norm_squared());
                }
            }
        }
        max.sqrt() / self.progress.force_scale
    }

    /// Forces at the current positions: node coupling (which snaps tied pairs together), internal
    /// forces, contacts, and the averaging of tied pairs' forces.
    fn compute_forces(&mut self) {
        let numerics = &self.params.numerics;
        let coupling = numerics.contact_model == ContactModel::Coupling;
        let started = Instant::now();
        if coupling {
            self.work.coupling.couple(
                &mut self.tissue,
                &self.cell_params,
                numerics.contact_cutoff,
                numerics.coupling_junctions,
                numerics.coupling_persistent_junctions,
            );
        }
        let coupled = Instant::now();
        self.work.forces.compute(&self.tissue, &self.cell_params, TermSet::ALL);
        let internal = coupled.elapsed().as_secs_f64();
        self.work.contacts.add_contacts(
            &self.tissue,
            &self.cell_params,
            numerics.contact_cutoff,
            &mut self.work.forces.cells,
        );
        let averaging = Instant::now();
        if coupling {
            self.work.coupling.average_forces(&self.tissue, &mut self.work.forces.cells);
        }
        let c = self.work.contacts.timings;
        let times = &mut self.work.times;
        times.coupling += (coupled - started).as_secs_f64() + averaging.elapsed().as_secs_f64();
        times.internal += internal;
        times.contact_broad += c.broad.as_secs_f64();
        times.contact_lists += c.lists.as_secs_f64();
        times.contact_narrow += c.narrow.as_secs_f64();
        times.contact_apply += c.apply.as_secs_f64();
    }

    /// Re-types the faces by ray casting when due: at the first evaluation, every
    /// `polarity_interval` steps and after a division (once per step).
    fn polarize_if_due(&mut self) {
        let numerics = &self.params.numerics;
        // Step 0 is a multiple of every interval: a fresh run polarises at its first evaluation.
        let due = self.polarity_due
            || (self.progress.step.is_multiple_of(numerics.polarity_interval.max(1))
                && self.polarized_at != Some(self.progress.step));
        if !due {
            return;
        }
        match polarize_by_ray_casting(&mut self.tissue, &RayCastSettings::from_numerics(numerics)) {
            Ok(report) => {
                if !report.cells_without_cytoplasm.is_empty() && self.polarizations == 0 {
                    tracing::warn!(
                        "polarity: cells {:?} have no interior voxel at a voxel size of {:.3e} m, so rays cross \
                         them; lower numerics.polarity_voxel_size",
                        report.cells_without_cytoplasm.iter().map(|c| c.0).collect::<Vec<_>>(),
                        report.voxel_size
                    );
                }
                tracing::debug!(
                    "step {}: ray-casting polarity: {} faces changed (apical, lateral, basal: {:?})",
                    self.progress.step,
                    report.changed,
                    report.faces
                );
                self.polarizations += 1;
            }
            // Only non-finite positions stop it; the health check below names the cell.
            Err(e) => tracing::debug!("step {}: polarity skipped: {e}", self.progress.step),
        }
        self.polarized_at = Some(self.progress.step);
        self.polarity_due = false;
    }

    /// Evaluates forces at the current positions (re-typing faces by ray casting first, or from
    /// contacts after, when polarity is on) and checks the state's health.
    pub(super) fn evaluate(&mut self) -> Result<(), SimulationError> {
        if self.params.numerics.polarity == Polarity::RayCasting {
            let started = Instant::now();
            self.polarize_if_due();
            self.work.times.polarity += started.elapsed().as_secs_f64();
        }
        self.compute_forces();
        if self.params.numerics.polarity == Polarity::Contacts {
            let started = Instant::now();
            let changed = polarize_from_contacts(&mut self.tissue, &self.work.contacts);
            self.work.times.polarity += started.elapsed().as_secs_f64();
            if changed > 0 {
                // Tensions changed with the face types: the forces must match the new types.
                self.compute_forces();
            }
        }
        self.progress.force_evaluations += 1;
        self.progress.node_evaluations += self.tissue.node_count() as u64;
        if self.normal_only {
            self.project_to_normals();
            if self.params.numerics.contact_model == ContactModel::Coupling {
                // Tied nodes share one force again: the mean of the two projections.
                self.work.coupling.average_forces(&self.tissue, &mut self.work.forces.cells);
            }
        }
        self.check_health()
    }

    /// Keeps only the component of every nodal force along the node's normal (the sum of its faces'
    /// area vectors; see `SimulationSettings::normal_relaxation`), except at the nodes within the
    /// contact cutoff of another cell with `SimulationSettings::full_forces_at_contacts`. A descent along these forces
    /// still lowers the energy (dE = −|F_n|²·dt), and its fixed points are the shapes on which no
    /// node is pushed off the surface.
    /// Projects every node's force onto its normal and, integrating the dynamic model, its momentum
    /// too (the momentum is used at these positions by the next [`Self::move_nodes`]). Forces alone
    /// are not enough: a momentum gathered along earlier normals keeps a tangential part as the
    /// normals turn, and that part moves nodes where the projected forces do no work, so the
    /// potential energy can rise with nothing to pay for it (a 64-cell spheroid grew spikes and
    /// folded within 150–230 steps at a time step 5× below the stability limit).
    fn project_to_normals(&mut self) {
        let cells = self.tissue.cells();
        let dynamic = self.params.numerics.dynamics == Dynamics::Dynamic;
        let spare_contacts = self.params.simulation.full_forces_at_contacts
            && self.params.numerics.contact_model == ContactModel::Spring;
        let contacts = &self.work.contacts;
        self.work
            .forces
            .cells
            .par_iter_mut()
            .zip(cells.par_iter())
            .zip(self.cell_data.momenta.par_iter_mut())
            .enumerate()
            .for_each(|(c, ((work, cell), momenta))| {
                let mut normals = node_normals(cell, &work.geometry.area_vectors);
                if spare_contacts {
                    // A zero normal leaves the node's force (and momentum) whole.
                    for (node, _, _) in contacts.node_contacts(c) {
                        normals[node as usize] = Vec3::zeros();
                    }
                }
                project_onto(&normals, &mut work.forces);
                if dynamic {
                    project_onto(&normals, momenta);
                }
            });
    }

    pub(super) fn volumes(&self) -> Vec<Real> {
        self.work.forces.cells.iter().map(|w| w.geometry.volume).collect()
    }
}

/// Each node's normal (not normalised): the sum of its triangles' area vectors `area_vectors`, as
/// [`CellGeometry`](crate::mechanics::CellGeometry) keeps them.
fn node_normals(cell: &Cell, area_vectors: &[Vec3]) -> Vec<Vec3> {
    let mut normals = vec![Vec3::zeros(); cell.mesh().node_count()];
    for (t, a) in cell.mesh().triangles().iter().zip(area_vectors) {
        for &n in t {
            normals[n as usize] += a;
        }
    }
    normals
}

/// Replaces each node's vector by its component along the node's normal.
fn project_onto(normals: &[Vec3], values: &mut [Vec3]) {
    for (v, n) in values.iter_mut().zip(normals) {
        let norm2 = n.norm_squared();
        if norm2 > 0.0 {
            *v = n * (v.dot(n) / norm2);
        }
    }
}
