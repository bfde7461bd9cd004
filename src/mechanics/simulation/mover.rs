//! How a relaxation moves the nodes: FIRE on packed arrays of all nodes (with contact masses when
//! they pay), or one step of the equations of motion.

use super::{Simulation, SimulationError};
use crate::geometry::{Mat3, Real, Vec3};
use crate::mechanics::{Fire, FireSettings, NodeMass};
use crate::mesh::FaceType;

/// FIRE uses contact masses when the stiffest contact would need a node this many times heavier
/// than unit mass to stay stable at Δt_max (see [`Simulation::contact_masses_pay`]). Measured on
/// spring doublets (docs: design note "Spring contacts and Young–Dupré"): at R = 10 µm, l_min = 1 µm,
/// ξ = 1e12 Pa/m (ratio ≈ 435) the masses moved touching starts from 13.6–28.7° short of Young–Dupré
/// to within 1.1–3.5° in 40,000 steps; at R = 1.9 µm, l_min = 0.19 µm (ratio ≈ 16) a fit's truth
/// relaxation (`tests/slow/fit_round_trips.rs`, spring round trip) stalled with them and ended +3.2° off
/// Young–Dupré instead of +1.7°, so below the ratio they are off. With masses FIRE still
/// restarts about every 20 steps on the R = 10 µm doublet, its Δt 30–100× below Δt_max: what else
/// limits it is not known yet.
const CONTACT_MASS_RATIO: Real = 100.0;

/// Whether a relaxation step moved the nodes.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(super) enum Moved {
    Yes,
    /// The mover is stuck; the nodes are where they were.
    Stalled,
}

/// How a relaxation moves the nodes: FIRE on packed arrays of all nodes, or the equations of motion.
pub(super) enum Mover {
    Fire {
        fire: Box<Fire>,
        offsets: Vec<usize>,
        mobile: Vec<bool>,
        x: Vec<Vec3>,
        f: Vec<Vec3>,
        /// The nodes' masses from their contacts (see [`Simulation::contact_masses`]) and their
        /// measured stiffnesses ([`MeasuredStiffness::add_masses`]).
        masses: Vec<NodeMass>,
        /// The nodes' measured stiffnesses (`simulation.fire_measured_masses`).
        measured: MeasuredStiffness,
    },
    Integrate,
}

impl Mover {
    pub(super) fn fire(sim: &Simulation<'_>) -> Self {
        let total = sim.tissue.node_count();
        let mut settings = FireSettings::for_scales(sim.params.numerics.min_edge_length, sim.progress.force_scale);
        if let Some(n) = sim.fire_max_uphill {
            settings.max_uphill = n;
        }
        Self::with_fire(sim, Box::new(Fire::new(settings, total)))
    }

    /// FIRE with a given minimiser state (fresh, or restored from a checkpoint) for the current layout.
    pub(super) fn with_fire(sim: &Simulation<'_>, fire: Box<Fire>) -> Self {
        let (offsets, mobile) = sim.layout();
        let total = *offsets.last().unwrap_or(&0);
        let zeros = vec![Vec3::zeros(); total];
        Mover::Fire {
            fire,
            offsets,
            mobile,
            x: zeros.clone(),
            f: zeros,
            masses: Vec::new(),
            measured: MeasuredStiffness::default(),
        }
    }

    /// After remeshing: a fresh FIRE on the new layout.
    pub(super) fn relayout(&mut self, sim: &Simulation<'_>) {
        match self {
            Mover::Fire { .. } => *self = Mover::fire(sim),
            Mover::Integrate => {}
        }
    }

    /// What a checkpoint saves: FIRE's state (None: integrating).
    pub(super) fn state(&self) -> Option<Box<Fire>> {
        match self {
            Mover::Fire { fire, .. } => Some(fire.clone()),
            Mover::Integrate => None,
        }
    }

    /// One step from the current, evaluated state; evaluates the forces at the new positions.
    pub(super) fn step(&mut self, sim: &mut Simulation<'_>) -> Result<Moved, SimulationError> {
        match self {
            Mover::Fire { fire, offsets, mobile, x, f, masses, measured } => {
                sim.pack(offsets, x, f);
                sim.save_good();
                let dt_max = fire.settings().dt_max;
                let mut heavy = sim.contact_masses(offsets, dt_max, masses);
                if sim.params.simulation.fire_measured_masses {
                    heavy |= measured.add_masses(x, f, mobile, dt_max, masses);
                }
                fire.step_with_masses(x, f, mobile, heavy.then_some(&masses[..]));
                if fire.stalled() {
                    return Ok(Moved::Stalled);
                }
                sim.unpack(offsets, x);
                sim.progress.step += 1;
                sim.evaluate()?;
                // Tied pairs move as one: new pairs take their mean velocity.
                sim.work.coupling.average_packed(&sim.tissue, offsets, fire.velocities_mut());
            }
            Mover::Integrate => sim.advance(false)?,
        }
        Ok(Moved::Yes)
    }
}

impl<'p> Simulation<'p> {
    /// Whether contact masses pay at FIRE's largest step `dt_max`: the stiffest contact law of any
    /// cell type (max ξ, ω over its faces) on a node of area √3/2·l_min² (a regular mesh of edge
    /// l_min) gives k·Δt_max²/2 above [`CONTACT_MASS_RATIO`].
    fn contact_masses_pay(&self, dt_max: Real) -> bool {
        if let Some(on) = self.fire_contact_masses {
            return on;
        }
        let stiffest = self
            .cell_params
            .iter()
            .flat_map(|p| FaceType::ALL.map(|t| p.faces.get(t)))
            .map(|f| f.repulsion.max(f.adhesion))
            .fold(0.0, Real::max);
        let l = self.params.numerics.min_edge_length;
        let area = 0.5 * (3.0 as Real).sqrt() * l * l;
        0.5 * stiffest * area * dt_max * dt_max > CONTACT_MASS_RATIO
    }

    /// Node offsets of each cell in the packed arrays, and which packed nodes may move.
    fn layout(&self) -> (Vec<usize>, Vec<bool>) {
        let mut offsets = vec![0];
        let mut mobile = Vec::new();
        for cell in self.tissue.cells() {
            let n = cell.mesh().node_count();
            offsets.push(offsets.last().unwrap() + n);
            mobile.extend(std::iter::repeat_n(!cell.kind().is_immobile(), n));
        }
        (offsets, mobile)
    }

    fn pack(&self, offsets: &[usize], x: &mut [Vec3], f: &mut [Vec3]) {
        for (c, (cell, work)) in self.tissue.cells().iter().zip(&self.work.forces.cells).enumerate() {
            x[offsets[c]..offsets[c + 1]].copy_from_slice(cell.mesh().positions());
            f[offsets[c]..offsets[c + 1]].copy_from_slice(&work.forces);
        }
    }

    /// FIRE's node masses (packed like `pack`): a node within the cutoff of another cell is heavier
    /// along each contact direction, by μ = k·Δt_max²/2 − 1 where the contact stiffness k
    /// ([`ContactWorkspace::pair_stiffnesses`]) exceeds 2/Δt_max², so that k/m·Δt_max² ≤ 2 keeps
    /// the stiff contact modes stable at FIRE's largest step instead of forcing Δt down for every
    /// node (ξ = 1e12 Pa/m on 1 µm elements is ~1,000× the tension stiffness). A normal relaxation
    /// uses the scalar mass 1 + max μ so that motion stays along the normals. The equilibria are
    /// the same (F = 0). Returns false, leaving unit masses, when no node is heavier or when the
    /// masses do not pay ([`Simulation::contact_masses_pay`]).
    fn contact_masses(&self, offsets: &[usize], dt_max: Real, masses: &mut Vec<NodeMass>) -> bool {
        masses.clear();
        if self.tissue.cells().len() < 2 || !self.contact_masses_pay(dt_max) {
            return false;
        }
        masses.resize(*offsets.last().unwrap_or(&0), NodeMass::UNIT);
        let threshold = 2.0 / (dt_max * dt_max);
        let mut heavy = false;
        let mut extra: Vec<(Vec3, Real)> = Vec::new();
        for (c, cell) in self.tissue.cells().iter().enumerate() {
            let areas = &self.work.forces.cells[c].geometry.areas;
            let mut flush = |node: Option<u32>, extra: &mut Vec<(Vec3, Real)>| {
                if let (Some(node), false) = (node, extra.is_empty()) {
                    let mass = if self.normal_only {
                        Some(NodeMass::scalar(1.0 + extra.iter().map(|e| e.1).fold(0.0, Real::max)))
                    } else {
                        NodeMass::along(extra)
                    };
                    if let Some(mass) = mass {
                        masses[offsets[c] + node as usize] = mass;
                        heavy = true;
                    }
                }
                extra.clear();
            };
            let mut current = None;
            for (node, direction, k) in self.work.contacts.pair_stiffnesses(c, cell, &self.cell_params[c], areas) {
                if current != Some(node) {
                    flush(current, &mut extra);
                    current = Some(node);
                }
                if k > threshold {
                    extra.push((direction, 0.5 * k * dt_max * dt_max - 1.0));
                }
            }
            flush(current, &mut extra);
        }
        heavy
    }

    fn unpack(&mut self, offsets: &[usize], x: &[Vec3]) {
        for (c, cell) in self.tissue.cells_mut().iter_mut().enumerate() {
            cell.positions_mut().copy_from_slice(&x[offsets[c]..offsets[c + 1]]);
        }
    }
}

/// The stiffness a node's measured stiffness keeps from one step to the next (it decays by 1 % a
/// step unless a new move measures it again): a stiff mode measured on the step it moved is still
/// there on the steps it rests.
const MEASURED_STIFFNESS_DECAY: Real = 0.99;

/// A node's move is measured when it is at least this fraction of the step's largest move (the
/// force change of a node that hardly moved is its neighbours' doing, and dividing it by that
/// node's own tiny move would make it heavy for nothing).
const MEASURED_MOVE_FRACTION: Real = 0.1;

/// Each node's stiffness along its last move, for `simulation.fire_measured_masses`: k = −ΔF·Δx/|Δx|²
/// between two evaluated states (the secant of the energy's curvature along the move), kept as a
/// maximum that decays by [`MEASURED_STIFFNESS_DECAY`] a step. Starts afresh with FIRE (after
/// remeshing or a resume).
#[derive(Default)]
pub(super) struct MeasuredStiffness {
    x: Vec<Vec3>,
    f: Vec<Vec3>,
    k: Vec<Real>,
}

impl MeasuredStiffness {
    /// Measures the stiffnesses from the previous state to positions `x` with forces `f` (packed)
    /// and makes every node whose stiffness k exceeds 2/Δt_max² heavier by the scalar
    /// k·Δt_max²/2 − 1 (on top of any contact mass in `masses`, which it fills with unit masses
    /// when empty). Returns whether any node is heavier.
    pub(super) fn add_masses(
        &mut self,
        x: &[Vec3],
        f: &[Vec3],
        mobile: &[bool],
        dt_max: Real,
        masses: &mut Vec<NodeMass>,
    ) -> bool {
        if self.x.len() != x.len() {
            self.x = x.to_vec();
            self.f = f.to_vec();
            self.k = vec![0.0; x.len()];
            return false;
        }
        let largest =
            (0..x.len()).filter(|&i| mobile[i]).map(|i| (x[i] - self.x[i]).norm_squared()).fold(0.0, Real::max);
        let measured = MEASURED_MOVE_FRACTION * MEASURED_MOVE_FRACTION * largest;
        let threshold = 2.0 / (dt_max * dt_max);
        let mut heavy = false;
        for i in (0..x.len()).filter(|&i| mobile[i]) {
            let dx = x[i] - self.x[i];
            let moved = dx.norm_squared();
            let k = if moved > measured && moved > 0.0 { (-(f[i] - self.f[i]).dot(&dx) / moved).max(0.0) } else { 0.0 };
            self.k[i] = k.max(MEASURED_STIFFNESS_DECAY * self.k[i]);
            if self.k[i] > threshold {
                if masses.is_empty() {
                    masses.resize(x.len(), NodeMass::UNIT);
                }
                let mass = masses[i].mass + (0.5 * self.k[i] * dt_max * dt_max - 1.0) * Mat3::identity();
                if let Some(inverse) = mass.try_inverse() {
                    masses[i] = NodeMass { mass, inverse };
                    heavy = true;
                }
            }
        }
        self.x.copy_from_slice(x);
        self.f.copy_from_slice(f);
        heavy
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Nodes on springs of stiffness k_i (F = −k_i·x): after one move the measured stiffness is k_i
    /// for every node that moved at least a tenth of the largest move, the stiff node is heavier by
    /// k·Δt_max²/2 − 1 and the soft ones keep unit mass; the stiffness decays when not measured again.
    #[test]
    fn measured_masses_are_the_springs_stiffness_where_it_would_be_unstable() {
        let k = [50.0, 0.5, 80.0];
        let forces = |x: &[Vec3]| -> Vec<Vec3> { x.iter().zip(k).map(|(x, k)| -k * x).collect() };
        let dt_max = 1.0;
        let mobile = [true; 3];
        let mut measured = MeasuredStiffness::default();
        let mut masses = Vec::new();
        let x0 = vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 0.0, 1.0)];
        assert!(!measured.add_masses(&x0, &forces(&x0), &mobile, dt_max, &mut masses), "nothing measured yet");
        assert!(masses.is_empty());
        // Node 2 moves by 1e-3 of the largest move: not measured (its force change is too small to tell).
        let x1 = vec![Vec3::new(1.5, 0.0, 0.0), Vec3::new(0.0, 1.3, 0.0), Vec3::new(0.0, 0.0, 1.0005)];
        assert!(measured.add_masses(&x1, &forces(&x1), &mobile, dt_max, &mut masses));
        assert!((measured.k[0] - 50.0).abs() < 1e-9 && (measured.k[1] - 0.5).abs() < 1e-9 && measured.k[2] == 0.0);
        // 2/Δt_max² = 2: node 0 is heavier by 50/2 − 1 = 24, node 1 (0.5) and node 2 are not.
        assert!((masses[0].mass - 25.0 * Mat3::identity()).norm() < 1e-9);
        assert!((masses[0].inverse * masses[0].mass - Mat3::identity()).norm() < 1e-12);
        assert_eq!(masses[1], NodeMass::UNIT);
        assert_eq!(masses[2], NodeMass::UNIT);
        // At rest the stiffness decays by MEASURED_STIFFNESS_DECAY a step.
        masses.clear();
        measured.add_masses(&x1, &forces(&x1), &mobile, dt_max, &mut masses);
        assert!((measured.k[0] - 50.0 * MEASURED_STIFFNESS_DECAY).abs() < 1e-9);
    }
}
