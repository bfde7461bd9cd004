//! Division and removal glue (see the module doc of `simulation` for the model): which cells divide
//! or are removed, the cut with retries, and keeping every per-cell array aligned.

use super::{Simulation, SimulationError, TopologyEvent, TopologyEventKind};
use crate::geometry::{Real, Vec3};
use crate::mechanics::growth::{division_seed, draw_division_volume, draw_growth_rate};
use crate::mechanics::{CellForces, DivisionPlaneRule};
use crate::mesh::{Cell, CellId, Daughter, DivisionError, DivisionPlane, divide_mesh};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, UnitSphere};
use rayon::prelude::*;

/// Division attempts per cell and step: the rule's plane, then tilted and shifted variants.
const DIVISION_ATTEMPTS: u32 = 6;
/// Largest tilt (rad) of the plane normal and shift (in units of l_min) of the plane point on retries.
const RETRY_TILT: Real = 0.15;
const RETRY_SHIFT: Real = 0.2;

/// Cuts `cell` through its volume centroid with its plane rule (see the module doc); on failure,
/// retries with seeded perturbations of the plane. Deterministic for (seed, cell id).
fn divide_cell(
    cell: &Cell,
    rule: DivisionPlaneRule,
    l_min: Real,
    seed: u64,
) -> Result<(Daughter, Daughter), DivisionError> {
    let mesh = cell.mesh();
    let centroid = mesh.volume_centroid().ok_or(DivisionError::NoVolume)?;
    let mut last = DivisionError::NoVolume;
    for attempt in 0..DIVISION_ATTEMPTS {
        let draw = division_seed(seed, cell.id(), attempt);
        let mode = match rule {
            DivisionPlaneRule::LongestAxis => DivisionPlane::LongestAxis,
            DivisionPlaneRule::Random => DivisionPlane::Random(draw),
        };
        let mut normal = crate::mesh::division_plane_normal(mesh, mode)?;
        let mut point = centroid;
        if attempt > 0 {
            let mut rng = ChaCha8Rng::seed_from_u64(draw ^ 0x5EED_CAFE);
            let [x, y, z]: [Real; 3] = UnitSphere.sample(&mut rng);
            let [u, _, _]: [Real; 3] = UnitSphere.sample(&mut rng);
            normal = (normal + RETRY_TILT * Vec3::new(x, y, z)).normalize();
            point += RETRY_SHIFT * l_min * u * normal;
        }
        match divide_mesh(mesh, cell.face_types(), point, normal, l_min, draw) {
            Ok(pair) => return Ok(pair),
            Err(e) => last = e,
        }
    }
    Err(last)
}

impl<'p> Simulation<'p> {
    /// Divides the cells above their division volume and removes those below their minimum volume
    /// (see the module doc). Returns whether the tissue changed.
    pub(super) fn divide_and_remove(&mut self) -> Result<bool, SimulationError> {
        let l_min = self.params.numerics.min_edge_length;
        let seed = self.params.numerics.seed;
        let cells = self.tissue.cells();
        // Volumes of the current (moved) surfaces.
        let volumes: Vec<Real> = cells.par_iter().map(|c| c.mesh().signed_volume()).collect();
        let volume = |c: usize| volumes[c];
        let dividing: Vec<usize> = (0..cells.len())
            .filter(|&c| !cells[c].kind().is_immobile() && volume(c) > self.cell_data.division_volumes[c])
            .collect();
        let removing: Vec<usize> = (0..cells.len())
            .filter(|&c| {
                let v_min = self.cell_params[c].min_volume;
                v_min > 0.0 && volume(c) < v_min && volume(c) <= self.cell_data.division_volumes[c]
            })
            .collect();
        if dividing.is_empty() && removing.is_empty() {
            return Ok(false);
        }
        let rules: Vec<DivisionPlaneRule> = dividing.iter().map(|&c| self.cell_params[c].division_plane).collect();
        let cuts: Vec<Result<(Daughter, Daughter), DivisionError>> = dividing
            .par_iter()
            .zip(rules.par_iter())
            .map(|(&c, &rule)| divide_cell(&cells[c], rule, l_min, seed))
            .collect();
        let mut changed = false;
        for (&c, cut) in dividing.iter().zip(cuts) {
            let (a, b) = match cut {
                Ok(pair) => pair,
                Err(e) => {
                    self.progress.topology.division_failures += 1;
                    tracing::debug!(
                        "step {}: cell {}: division postponed: {e}",
                        self.progress.step,
                        self.tissue.cells()[c].id()
                    );
                    continue;
                }
            };
            self.apply_division(c, a, b)?;
            changed = true;
        }
        for &c in removing.iter().rev() {
            let cell = self.tissue.remove(c);
            if self.cell_data.last_good.len() == self.tissue.len() + 1 {
                self.cell_data.last_good.remove(c);
            } else {
                self.cell_data.last_good.clear();
            }
            self.progress.events.push(TopologyEvent {
                step: self.progress.step,
                time: self.progress.time,
                kind: TopologyEventKind::Removal,
                cell: cell.id(),
                daughters: None,
                volume: volumes[c],
                daughter_volumes: None,
            });
            self.progress.topology.removals += 1;
            self.cell_params.remove(c);
            self.cell_data.momenta.remove(c);
            self.cell_data.growth_rates.remove(c);
            self.cell_data.division_volumes.remove(c);
            self.cell_data.remesh_idle.remove(c);
            self.work.forces.cells.remove(c);
            changed = true;
        }
        Ok(changed)
    }

    /// Replaces cell `c` by daughter `a` and appends daughter `b`, keeping every per-cell array aligned.
    fn apply_division(&mut self, c: usize, a: Daughter, b: Daughter) -> Result<(), SimulationError> {
        let seed = self.params.numerics.seed;
        let p = self.cell_params[c].clone();
        let mother = &self.tissue.cells()[c];
        let (mother_id, kind, cell_type, overrides) =
            (mother.id(), mother.kind(), mother.cell_type(), *mother.overrides());
        let v0 = 0.5 * mother.target_volume();
        let volume = mother.mesh().signed_volume();
        let daughter_volumes = [a.mesh.signed_volume(), b.mesh.signed_volume()];
        let momenta = [
            a.inherit(&self.cell_data.momenta[c], Vec3::zeros()),
            b.inherit(&self.cell_data.momenta[c], Vec3::zeros()),
        ];
        // Keep the saved positions aligned with the cells (the daughters' are their current ones).
        if self.cell_data.last_good.len() == self.tissue.len() {
            self.cell_data.last_good[c] = a.mesh.positions().to_vec();
            self.cell_data.last_good.push(b.mesh.positions().to_vec());
        } else {
            self.cell_data.last_good.clear();
        }
        let ids = [self.tissue.allocate_id(), self.tissue.allocate_id()];
        let to_cell = |id: CellId, d: Daughter| {
            Cell::new(id, kind, cell_type, d.mesh)
                .with_face_types(d.face_types)
                .map(|cell| cell.with_target_volume(v0).with_parent(mother_id).with_overrides(overrides))
                .map_err(|e| SimulationError::Topology {
                    step: self.progress.step,
                    cell: mother_id,
                    what: e.to_string(),
                })
        };
        let (cell_a, cell_b) = (to_cell(ids[0], a)?, to_cell(ids[1], b)?);
        let topology = |e: crate::mesh::TissueError| SimulationError::Topology {
            step: self.progress.step,
            cell: mother_id,
            what: e.to_string(),
        };
        self.tissue.replace(c, cell_a).map_err(topology)?;
        self.tissue.push(cell_b).map_err(topology)?;
        let [ma, mb] = momenta;
        self.cell_data.momenta[c] = ma;
        self.cell_data.momenta.push(mb);
        self.cell_data.growth_rates[c] = draw_growth_rate(&p, seed, ids[0]);
        self.cell_data.growth_rates.push(draw_growth_rate(&p, seed, ids[1]));
        self.cell_data.division_volumes[c] = draw_division_volume(&p, seed, ids[0]);
        self.cell_data.division_volumes.push(draw_division_volume(&p, seed, ids[1]));
        self.cell_data.remesh_idle[c] = 0;
        self.cell_data.remesh_idle.push(0);
        self.cell_params.push(p);
        self.work.forces.cells.push(CellForces::default());
        self.progress.events.push(TopologyEvent {
            step: self.progress.step,
            time: self.progress.time,
            kind: TopologyEventKind::Division,
            cell: mother_id,
            daughters: Some(ids),
            volume,
            daughter_volumes: Some(daughter_volumes),
        });
        self.progress.topology.divisions += 1;
        self.polarity_due = true;
        Ok(())
    }
}
