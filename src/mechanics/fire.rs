//! FIRE minimiser: relaxes a tissue to mechanical equilibrium (zero net force on every mobile node).
//!
//! FIRE, the Fast Inertial Relaxation Engine (Bitzek et al., PRL 97, 170201, 2006), in its FIRE 2.0
//! form (Guénolé et al., Comput. Mater. Sci. 175, 109584, 2020, Algorithm 2 with semi-implicit Euler
//! and the initial delay). Nodes of unit mass move under the forces F = −∇U with fictitious
//! velocities v; motion is kept only while it goes downhill. One step, with the forces at the current
//! positions:
//!
//! 1. Power P = Σ F·v over the mobile nodes.
//! 2. P > 0: after more than N_delay consecutive such steps, Δt ← min(f_inc·Δt, Δt_max) and
//!    α ← f_α·α. P ≤ 0 (a *restart*): unless within the first N_delay steps, Δt ← f_dec·Δt (only if
//!    that stays ≥ Δt_min) and α ← α_start; then x ← x − ½Δt·v (half-step back) and v ← 0.
//! 3. v ← v + Δt·F.
//! 4. If P > 0, mixing: v ← (1 − α)·v + α·|v|·F/|F|, with |v| and |F| the norms of the whole
//!    configuration vector (all mobile nodes together).
//! 5. Displacement cap, then x ← x + Δt·v.
//!
//! FIRE needs no energy, only forces, so it fits a force pipeline; the caller owns positions and
//! forces (ask/tell: `step`, recompute forces, `step` again) and decides convergence, usually
//! max |F| below a tolerance. Units: with unit mass, Δt has unit √(length/force) of the caller's
//! units; [`FireSettings::for_scales`] derives every setting from a length and a force scale.
//!
//! # Choices beyond the paper
//! - **Displacement cap.** A triangle mesh folds when a node moves far compared with its edges, so
//!   no mobile node moves more than `max_displacement` in one step, counting the half-step back of
//!   a restart: when some node would, the whole step (all nodes, back-correction and move) is scaled
//!   by one factor, which keeps its direction. Velocities are not scaled.
//! - **Half-step back.** The paper moves back by ½Δt·v with the already reduced Δt. When the cap
//!   shortened the previous move this could overshoot past the previous positions, so the step
//!   back is ½·min(Δt, Δt_last)·v, with Δt_last the time the previous move actually used.
//! - **At rest.** With all velocities zero (the first step, or after [`Fire::reset`]) P = 0 says
//!   nothing about overshooting: such a step is neither a restart nor a downhill step. This is what
//!   the paper's initial delay achieves for the first step.
//!
//! - **Per-node masses (preconditioning).** [`Fire::step_with_masses`] gives node i a symmetric
//!   positive-definite 3×3 mass M_i: the kick uses M⁻¹F, the power stays F·v (the true rate of
//!   work), and |v|, |F| in the mixing become the norms √(v·Mv) and √(F·M⁻¹F). This is FIRE with unit
//!   masses in the coordinates y = M^{1/2}x, so the equilibria (F = 0) and the descent test are
//!   unchanged; a stiff direction made heavy no longer limits Δt for every node. Velocities are kept
//!   in x, so masses may change between steps.
//!
//! # Determinism
//! Every reduction (P, |v|², |F|², the largest displacement) is summed sequentially within fixed
//! chunks of 1024 nodes, and the chunk results are combined sequentially in chunk order. Chunks
//! run in parallel (rayon) for large problems, but their boundaries do not depend on the thread
//! count, so 1 and N threads give bitwise-identical trajectories. A step allocates nothing.

use crate::geometry::{Mat3, Real, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Nodes per reduction chunk: the fixed summation blocks behind the determinism guarantee.
const CHUNK: usize = 1024;

/// Problems smaller than this run their chunks on the calling thread: below it, handing work to the
/// rayon pool costs more than the few flops per node it saves. Either path gives the same bits.
const PARALLEL_MIN_NODES: usize = 4 * CHUNK;

/// Settings of the FIRE 2.0 minimiser. Times are in the caller's √(length/force) (unit mass),
/// lengths in the caller's length unit. Defaults from [`FireSettings::for_scales`] (paper Table 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FireSettings {
    /// Initial (and after [`Fire::reset`]) time step Δt_start. Default: one step from rest moves a
    /// node by 1e-2·length under force_scale, Δt_start = √(1e-2·length/force_scale).
    pub dt_start: Real,
    /// Largest time step Δt_max. Default 10·Δt_start.
    pub dt_max: Real,
    /// Smallest time step Δt_min: a restart does not shrink Δt below it. Default 0.02·Δt_start.
    pub dt_min: Real,
    /// N_delay: Δt grows only after more than this many consecutive steps with P > 0, and
    /// restarts within the first N_delay steps leave Δt and α alone. Default 20.
    pub n_delay: usize,
    /// Growth factor f_inc of Δt on downhill steps, > 1. Default 1.1.
    pub f_inc: Real,
    /// Shrink factor f_dec of Δt on restarts, in (0, 1). Default 0.5.
    pub f_dec: Real,
    /// Mixing weight α_start after a restart, in (0, 1). Default 0.25.
    pub alpha_start: Real,
    /// Decay factor f_α of α on downhill steps, in (0, 1]. Default 0.99.
    pub f_alpha: Real,
    /// Largest distance any node moves in one step, > 0 (may be infinite: no cap). Default
    /// 0.1·length.
    pub max_displacement: Real,
    /// N_P≤0^max: after more than this many consecutive restarts (steps with P ≤ 0, i.e. moving
    /// uphill), [`Fire::stalled`] turns true. Then even the smallest steps overshoot (Δt is at
    /// Δt_min), usually because the forces are not the gradient of an energy or are too noisy; the
    /// caller should stop or change method (the simulation driver falls back to integrating the equations of motion). Default 200 (the FIRE 2.0 paper uses 2000; a stalled relaxation of a mesh without remeshing does not recover, so giving up early wastes fewer evaluations).
    pub max_uphill: usize,
}

impl FireSettings {
    /// Defaults of FIRE 2.0 for a problem whose nodes have unit mass, whose typical force is
    /// `force_scale` and whose natural length is `length` (both > 0): Δt chosen so that one step
    /// from rest (Δx = Δt²·F) moves a node by 1e-2·length under force_scale, Δt_max = 10·Δt_start,
    /// Δt_min = 0.02·Δt_start, max_displacement = 0.1·length, and the paper's N_delay = 20,
    /// f_inc = 1.1, f_dec = 0.5, α_start = 0.25, f_α = 0.99, N_P≤0^max = 200 (see `max_uphill`).
    pub fn for_scales(length: Real, force_scale: Real) -> Self {
        let dt_start = (1e-2 * length / force_scale).sqrt();
        Self {
            dt_start,
            dt_max: 10.0 * dt_start,
            dt_min: 0.02 * dt_start,
            n_delay: 20,
            f_inc: 1.1,
            f_dec: 0.5,
            alpha_start: 0.25,
            f_alpha: 0.99,
            max_displacement: 0.1 * length,
            max_uphill: 200,
        }
    }

    /// Every problem with these settings, each naming the field; empty when they are usable.
    pub fn problems(&self) -> Vec<String> {
        let mut problems = Vec::new();
        let mut check = |ok: bool, field: &str, value: Real, want: &str| {
            if !ok {
                problems.push(format!("fire.{field} = {value}: must be {want}"));
            }
        };
        let positive = |x: Real| x.is_finite() && x > 0.0;
        check(positive(self.dt_min), "dt_min", self.dt_min, "finite and > 0");
        check(positive(self.dt_start), "dt_start", self.dt_start, "finite and > 0");
        check(positive(self.dt_max), "dt_max", self.dt_max, "finite and > 0");
        check(self.dt_min <= self.dt_start, "dt_start", self.dt_start, "≥ dt_min");
        check(self.dt_start <= self.dt_max, "dt_start", self.dt_start, "≤ dt_max");
        check(self.f_inc.is_finite() && self.f_inc > 1.0, "f_inc", self.f_inc, "finite and > 1");
        check(self.f_dec > 0.0 && self.f_dec < 1.0, "f_dec", self.f_dec, "in (0, 1)");
        check(self.alpha_start > 0.0 && self.alpha_start < 1.0, "alpha_start", self.alpha_start, "in (0, 1)");
        check(self.f_alpha > 0.0 && self.f_alpha <= 1.0, "f_alpha", self.f_alpha, "in (0, 1]");
        check(self.max_displacement > 0.0, "max_displacement", self.max_displacement, "> 0 (may be infinite)");
        problems
    }
}

/// What one [`Fire::step`] did.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum FireStep {
    /// Velocities integrated and nodes moved. `power_positive`: P > 0 (downhill, velocities mixed);
    /// false only when starting from rest.
    Moved { power_positive: bool },
    /// P ≤ 0 (uphill): positions corrected half a step back, velocities zeroed, Δt and α reset, then
    /// integrated and moved from rest.
    Restarted,
    /// A force (or the power or a norm) is not finite: nothing changed. The caller should stop with
    /// an error naming the step.
    NonFinite,
}

/// The FIRE 2.0 minimiser's state for one configuration of `nodes` nodes (see the module doc).
/// Serialisable: a checkpoint holds it whole, so a resumed relaxation continues bitwise.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Fire {
    settings: FireSettings,
    dt: Real,
    alpha: Real,
    /// Consecutive steps with P > 0.
    downhill_run: usize,
    /// Consecutive steps with P ≤ 0.
    uphill_run: usize,
    /// Steps since [`Fire::new`] or [`Fire::reset`] (the initial delay counts these).
    steps: usize,
    /// Restarts since [`Fire::new`] or [`Fire::reset`].
    restarts: usize,
    /// Time the last move used, Δt times the cap's scale: how far back the velocities reach.
    last_move_dt: Real,
    velocities: Vec<Vec3>,
    /// Workspace: per-node displacement of a restart step (back-correction plus move).
    displacements: Vec<Vec3>,
    /// Workspace: one partial result per chunk.
    partials: Vec<[Real; 3]>,
}

/// Coefficients of the velocity update of one step: v ← velocity·v + force·M⁻¹F, then the node moves
/// by dt·v − back·v_old.
struct Kick {
    velocity: Real,
    force: Real,
    dt: Real,
    /// Half-step back of a restart, `None` otherwise.
    back: Option<Real>,
}

impl Fire {
    /// A minimiser at rest (zero velocities, Δt = Δt_start, α = α_start) for `nodes` nodes.
    ///
    /// # Panics
    /// If `settings` has [`FireSettings::problems`]: validate settings from configs first.
    pub fn new(settings: FireSettings, nodes: usize) -> Self {
        let problems = settings.problems();
        assert!(problems.is_empty(), "invalid FIRE settings: {}", problems.join("; "));
        Self {
            dt: settings.dt_start,
            alpha: settings.alpha_start,
            settings,
            downhill_run: 0,
            uphill_run: 0,
            steps: 0,
            restarts: 0,
            last_move_dt: 0.0,
            velocities: vec![Vec3::zeros(); nodes],
            displacements: vec![Vec3::zeros(); nodes],
            partials: vec![[0.0; 3]; nodes.div_ceil(CHUNK)],
        }
    }

    /// One FIRE step. On entry `forces` are the forces at `positions`, one entry per node of the
    /// flat array the caller packs; `mobile` (same length) is false for nodes that must not move:
    /// their forces are ignored, their velocities stay zero and their positions are not touched.
    /// Updates velocities and positions in place; the caller then recomputes the forces at the new
    /// positions. Allocates nothing.
    ///
    /// # Panics
    /// If the three slices do not all have the length given to [`Fire::new`].
    pub fn step(&mut self, positions: &mut [Vec3], forces: &[Vec3], mobile: &[bool]) -> FireStep {
        self.step_with_masses(positions, forces, mobile, None)
    }

    /// [`Fire::step`] with a mass per node (`None`: unit masses): see "Per-node masses" in the
    /// module doc. `masses`, when given, has one entry per node.
    ///
    /// # Panics
    /// If the slices do not all have the length given to [`Fire::new`].
    pub fn step_with_masses(
        &mut self,
        positions: &mut [Vec3],
        forces: &[Vec3],
        mobile: &[bool],
        masses: Option<&[NodeMass]>,
    ) -> FireStep {
        let nodes = self.velocities.len();
        assert!(masses.is_none_or(|m| m.len() == nodes), "FIRE step: masses for {nodes} nodes expected");
        assert!(
            positions.len() == nodes && forces.len() == nodes && mobile.len() == nodes,
            "FIRE step: {} positions, {} forces, {} mobile flags for {nodes} nodes",
            positions.len(),
            forces.len(),
            mobile.len()
        );
        let parallel = nodes >= PARALLEL_MIN_NODES;

        // 1. P, |v|², |F|² with the forces at the current positions.
        if parallel {
            self.partials
                .par_iter_mut()
                .zip(self.velocities.par_chunks(CHUNK))
                .zip(forces.par_chunks(CHUNK))
                .zip(mobile.par_chunks(CHUNK))
                .enumerate()
                .for_each(|(c, (((partial, v), f), m))| *partial = power_chunk(v, f, m, chunk_of(masses, c)));
        } else {
            for (c, (((partial, v), f), m)) in self
                .partials
                .iter_mut()
                .zip(self.velocities.chunks(CHUNK))
                .zip(forces.chunks(CHUNK))
                .zip(mobile.chunks(CHUNK))
                .enumerate()
            {
                *partial = power_chunk(v, f, m, chunk_of(masses, c));
            }
        }
        let [power, vv, ff] =
            self.partials.iter().fold([0.0; 3], |acc, p| [acc[0] + p[0], acc[1] + p[1], acc[2] + p[2]]);
        if !(power.is_finite() && vv.is_finite() && ff.is_finite()) {
            return FireStep::NonFinite;
        }
        self.steps += 1;

        // 2. Adapt Δt and α, or restart.
        let settings = &self.settings;
        let at_rest = vv == 0.0;
        let downhill = power > 0.0;
        let mut back = None;
        if at_rest {
            self.downhill_run = 0;
        } else if downhill {
            self.downhill_run += 1;
            self.uphill_run = 0;
            if self.downhill_run > settings.n_delay {
                self.dt = (self.dt * settings.f_inc).min(settings.dt_max);
                self.alpha *= settings.f_alpha;
            }
        } else {
            self.downhill_run = 0;
            self.uphill_run += 1;
            self.restarts += 1;
            if self.steps >= settings.n_delay {
                if self.dt * settings.f_dec >= settings.dt_min {
                    self.dt *= settings.f_dec;
                }
                self.alpha = settings.alpha_start;
            }
            back = Some(0.5 * self.dt.min(self.last_move_dt));
        }

        // 3.–4. Semi-implicit Euler kick, mixed when downhill. |v + Δt·F|² is expanded so that
        // the mixing needs no second pass.
        let dt = self.dt;
        let kick = if back.is_some() {
            Kick { velocity: 0.0, force: dt, dt, back }
        } else if downhill && ff > 0.0 {
            let kicked_speed = (vv + 2.0 * dt * power + dt * dt * ff).max(0.0).sqrt();
            let alpha = self.alpha;
            Kick { velocity: 1.0 - alpha, force: (1.0 - alpha) * dt + alpha * kicked_speed / ff.sqrt(), dt, back }
        } else {
            Kick { velocity: 1.0, force: dt, dt, back }
        };
        if parallel {
            self.partials
                .par_iter_mut()
                .zip(self.velocities.par_chunks_mut(CHUNK))
                .zip(self.displacements.par_chunks_mut(CHUNK))
                .zip(forces.par_chunks(CHUNK))
                .zip(mobile.par_chunks(CHUNK))
                .enumerate()
                .for_each(|(c, ((((partial, v), d), f), m))| {
                    partial[0] = kick_chunk(&kick, v, d, f, m, chunk_of(masses, c))
                });
        } else {
            for (c, ((((partial, v), d), f), m)) in self
                .partials
                .iter_mut()
                .zip(self.velocities.chunks_mut(CHUNK))
                .zip(self.displacements.chunks_mut(CHUNK))
                .zip(forces.chunks(CHUNK))
                .zip(mobile.chunks(CHUNK))
                .enumerate()
            {
                partial[0] = kick_chunk(&kick, v, d, f, m, chunk_of(masses, c));
            }
        }

        // 5. Cap the largest displacement, then move.
        let largest = self.partials.iter().fold(0.0, |acc: Real, p| acc.max(p[0])).sqrt();
        let scale =
            if largest > self.settings.max_displacement { self.settings.max_displacement / largest } else { 1.0 };
        let restart = back.is_some();
        let move_dt = scale * dt;
        let (velocities, displacements) = (&self.velocities, &self.displacements);
        let move_chunk = |x: &mut [Vec3], v: &[Vec3], d: &[Vec3], m: &[bool]| {
            for (((x, v), d), &m) in x.iter_mut().zip(v).zip(d).zip(m) {
                if m {
                    *x += if restart { scale * d } else { move_dt * v };
                }
            }
        };
        if parallel {
            positions
                .par_chunks_mut(CHUNK)
                .zip(velocities.par_chunks(CHUNK))
                .zip(displacements.par_chunks(CHUNK))
                .zip(mobile.par_chunks(CHUNK))
                .for_each(|(((x, v), d), m)| move_chunk(x, v, d, m));
        } else {
            for (((x, v), d), m) in positions
                .chunks_mut(CHUNK)
                .zip(velocities.chunks(CHUNK))
                .zip(displacements.chunks(CHUNK))
                .zip(mobile.chunks(CHUNK))
            {
                move_chunk(x, v, d, m);
            }
        }
        self.last_move_dt = move_dt;

        if restart { FireStep::Restarted } else { FireStep::Moved { power_positive: downhill } }
    }

    /// Current time step Δt.
    pub fn dt(&self) -> Real {
        self.dt
    }

    /// Current mixing weight α.
    pub fn alpha(&self) -> Real {
        self.alpha
    }

    /// Current velocities (zero for immobile nodes).
    pub fn velocities(&self) -> &[Vec3] {
        &self.velocities
    }

    /// Mutable velocities, for constraints that tie nodes together (node coupling averages the
    /// velocities of each tied pair).
    pub fn velocities_mut(&mut self) -> &mut [Vec3] {
        &mut self.velocities
    }

    /// The settings.
    pub fn settings(&self) -> &FireSettings {
        &self.settings
    }

    /// Steps taken since [`Fire::new`] or [`Fire::reset`] (not counting [`FireStep::NonFinite`]).
    pub fn steps(&self) -> usize {
        self.steps
    }

    /// Restarts (steps with P ≤ 0) since [`Fire::new`] or [`Fire::reset`].
    pub fn restarts(&self) -> usize {
        self.restarts
    }

    /// Consecutive restarts up to now.
    pub fn uphill_run(&self) -> usize {
        self.uphill_run
    }

    /// More than `max_uphill` consecutive restarts: the minimiser is stuck (see
    /// [`FireSettings::max_uphill`]); the caller should stop and report non-convergence.
    pub fn stalled(&self) -> bool {
        self.uphill_run > self.settings.max_uphill
    }

    /// Back to rest, as after [`Fire::new`]: zero velocities, Δt = Δt_start, α = α_start, counters
    /// zero. Call it when the configuration changed under the minimiser (remeshing, new parameters).
    pub fn reset(&mut self) {
        self.velocities.fill(Vec3::zeros());
        self.dt = self.settings.dt_start;
        self.alpha = self.settings.alpha_start;
        self.downhill_run = 0;
        self.uphill_run = 0;
        self.steps = 0;
        self.restarts = 0;
        self.last_move_dt = 0.0;
    }
}

/// The mass of one node for [`Fire::step_with_masses`]: a symmetric positive-definite M and its
/// inverse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeMass {
    pub mass: Mat3,
    pub inverse: Mat3,
}

impl NodeMass {
    /// Unit mass.
    pub const UNIT: NodeMass = NodeMass {
        mass: Mat3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        inverse: Mat3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
    };

    /// M = I + Σ_k μ_k·n_k n_kᵀ for unit directions n_k and extra masses μ_k ≥ 0 (heavier along each
    /// n_k only); `None` when M cannot be inverted (never for finite inputs).
    pub fn along(extra: &[(Vec3, Real)]) -> Option<NodeMass> {
        let mut mass = Mat3::identity();
        for (n, mu) in extra {
            mass += *mu * n * n.transpose();
        }
        let inverse = match extra {
            // Sherman–Morrison: (I + μnnᵀ)⁻¹ = I − μ/(1 + μ)·nnᵀ for a unit n.
            [(n, mu)] => Mat3::identity() - (*mu / (1.0 + *mu)) * n * n.transpose(),
            _ => mass.try_inverse()?,
        };
        Some(NodeMass { mass, inverse })
    }

    /// A scalar mass m·I.
    pub fn scalar(m: Real) -> NodeMass {
        NodeMass { mass: m * Mat3::identity(), inverse: Mat3::identity() / m }
    }
}

/// Chunk `c` of the masses, if any.
fn chunk_of(masses: Option<&[NodeMass]>, c: usize) -> Option<&[NodeMass]> {
    masses.map(|m| &m[c * CHUNK..((c + 1) * CHUNK).min(m.len())])
}

/// [F·v, |v|², |F|²] over the mobile nodes of one chunk, summed in node order; with masses the
/// norms are v·Mv and F·M⁻¹F.
fn power_chunk(velocities: &[Vec3], forces: &[Vec3], mobile: &[bool], masses: Option<&[NodeMass]>) -> [Real; 3] {
    let mut sums = [0.0; 3];
    for (i, ((v, f), &m)) in velocities.iter().zip(forces).zip(mobile).enumerate() {
        if m {
            sums[0] += f.dot(v);
            match masses {
                None => {
                    sums[1] += v.norm_squared();
                    sums[2] += f.norm_squared();
                }
                Some(masses) => {
                    sums[1] += v.dot(&(masses[i].mass * v));
                    sums[2] += f.dot(&(masses[i].inverse * f));
                }
            }
        }
    }
    sums
}

/// Kicks the velocities of one chunk (immobile ones set to zero), stores restart displacements,
/// and returns the largest squared displacement of the chunk.
fn kick_chunk(
    kick: &Kick,
    velocities: &mut [Vec3],
    displacements: &mut [Vec3],
    forces: &[Vec3],
    mobile: &[bool],
    masses: Option<&[NodeMass]>,
) -> Real {
    let mut largest: Real = 0.0;
    for (i, (((v, d), f), &m)) in velocities.iter_mut().zip(displacements).zip(forces).zip(mobile).enumerate() {
        if !m {
            *v = Vec3::zeros();
            continue;
        }
        let old = *v;
        let accel = match masses {
            None => *f,
            Some(masses) => masses[i].inverse * f,
        };
        *v = kick.velocity * old + kick.force * accel;
        let displacement = match kick.back {
            Some(back) => {
                *d = kick.dt * *v - back * old;
                *d
            }
            None => kick.dt * *v,
        };
        largest = largest.max(displacement.norm_squared());
    }
    largest
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Largest force norm over the mobile nodes.
    fn max_force(forces: &[Vec3], mobile: &[bool]) -> Real {
        forces.iter().zip(mobile).filter(|(_, m)| **m).fold(0.0, |acc: Real, (f, _)| acc.max(f.norm()))
    }

    /// Runs FIRE until max |F| < `tolerance` over the mobile nodes; calls `inspect(before, after,
    /// outcome)` after each step. Returns the number of steps, or `None` after `max_steps`.
    fn relax(
        fire: &mut Fire,
        positions: &mut [Vec3],
        mobile: &[bool],
        forces_at: impl Fn(&[Vec3], &mut [Vec3]),
        tolerance: Real,
        max_steps: usize,
        inspect: impl FnMut(&[Vec3], &[Vec3], FireStep),
    ) -> Option<usize> {
        relax_with_masses(fire, positions, mobile, None, forces_at, tolerance, max_steps, inspect)
    }

    /// [`relax`] with node masses ([`Fire::step_with_masses`]).
    #[allow(clippy::too_many_arguments)]
    fn relax_with_masses(
        fire: &mut Fire,
        positions: &mut [Vec3],
        mobile: &[bool],
        masses: Option<&[NodeMass]>,
        forces_at: impl Fn(&[Vec3], &mut [Vec3]),
        tolerance: Real,
        max_steps: usize,
        mut inspect: impl FnMut(&[Vec3], &[Vec3], FireStep),
    ) -> Option<usize> {
        let mut forces = vec![Vec3::zeros(); positions.len()];
        let mut before = positions.to_vec();
        for step in 0..max_steps {
            forces_at(positions, &mut forces);
            if max_force(&forces, mobile) < tolerance {
                return Some(step);
            }
            before.copy_from_slice(positions);
            let outcome = fire.step_with_masses(positions, &forces, mobile, masses);
            assert_ne!(outcome, FireStep::NonFinite);
            inspect(&before, positions, outcome);
        }
        None
    }

    /// Anisotropic quadratic bowl U = ½ Σ_k λ_k (x_k − x*_k)², k over the 3·n flat coordinates,
    /// λ log-spaced over [1, condition], spread over nodes and axes by a coprime stride.
    struct Bowl {
        stiffness: Vec<Vec3>,
        minimum: Vec<Vec3>,
    }

    impl Bowl {
        fn new(nodes: usize, condition: Real) -> Self {
            let dims = 3 * nodes;
            let lambda = |k: usize| condition.powf(((7 * k) % dims) as Real / (dims - 1) as Real);
            let stiffness =
                (0..nodes).map(|i| Vec3::new(lambda(3 * i), lambda(3 * i + 1), lambda(3 * i + 2))).collect();
            let minimum = (0..nodes).map(|i| Vec3::new(i as Real, (0.3 * i as Real).sin(), -0.5)).collect();
            Self { stiffness, minimum }
        }

        /// A start about one length unit from the minimum in every coordinate.
        fn start(&self) -> Vec<Vec3> {
            let offset = |k: usize| (1.3 * k as Real + 0.5).sin() + 0.2;
            self.minimum
                .iter()
                .enumerate()
                .map(|(i, m)| m + Vec3::new(offset(3 * i), offset(3 * i + 1), offset(3 * i + 2)))
                .collect()
        }

        fn forces(&self, x: &[Vec3], f: &mut [Vec3]) {
            for (((f, x), m), k) in f.iter_mut().zip(x).zip(&self.minimum).zip(&self.stiffness) {
                *f = -k.component_mul(&(x - m));
            }
        }
    }

    /// FIRE on an ill-conditioned bowl (κ = 1e4, 150 dimensions) needs far fewer force evaluations
    /// than steepest descent with the best fixed step 2/(λ_min + λ_max), which is also (to 1e-4)
    /// the largest stable one. Steepest descent needs ~κ·ln(1/ε)/2 steps; FIRE's damped dynamics
    /// ~√κ·ln(1/ε), so ≥ 10× fewer is a loose bound.
    #[test]
    fn quadratic_bowl_converges_far_faster_than_steepest_descent() {
        let condition = 1e4;
        let bowl = Bowl::new(50, condition);
        let mobile = vec![true; 50];
        let start = bowl.start();
        let mut forces = vec![Vec3::zeros(); 50];
        bowl.forces(&start, &mut forces);
        let tolerance = 1e-8 * max_force(&forces, &mobile);

        let mut x = start.clone();
        let fixed_step = 2.0 / (1.0 + condition);
        let mut steepest = None;
        for step in 0..2_000_000 {
            bowl.forces(&x, &mut forces);
            if max_force(&forces, &mobile) < tolerance {
                steepest = Some(step);
                break;
            }
            for (x, f) in x.iter_mut().zip(&forces) {
                *x += fixed_step * f;
            }
        }
        let steepest = steepest.expect("steepest descent converges");

        let mut x = start.clone();
        let mut fire = Fire::new(FireSettings::for_scales(1.0, condition), 50);
        let fire_steps = relax(&mut fire, &mut x, &mobile, |x, f| bowl.forces(x, f), tolerance, 100_000, |_, _, _| {})
            .expect("FIRE converges");
        eprintln!("bowl κ = {condition:e}: FIRE {fire_steps} steps, steepest descent {steepest} steps");
        assert!(10 * fire_steps <= steepest, "FIRE {fire_steps} steps vs steepest descent {steepest}");
        for (x, m) in x.iter().zip(&bowl.minimum) {
            // |x − x*| ≤ |F|/λ_min = tolerance / 1.
            assert!((x - m).norm() < 2.0 * tolerance, "{x} vs {m}");
        }
    }

    /// Stiff along one direction per node (a contact's normal), soft across it: U = ½ Σ_i
    /// [λ_i((x_i − x*_i)·n_i)² + |x_i − x*_i|² − ((x_i − x*_i)·n_i)²] with λ_i up to `stiff`.
    struct Needles {
        directions: Vec<Vec3>,
        stiffness: Vec<Real>,
        minimum: Vec<Vec3>,
    }

    impl Needles {
        fn new(nodes: usize, stiff: Real) -> Self {
            let directions = (0..nodes)
                .map(|i| {
                    let a = 0.7 * i as Real;
                    Vec3::new(a.cos(), a.sin(), 0.3 * (1.1 * a).sin()).normalize()
                })
                .collect();
            let stiffness = (0..nodes).map(|i| if i % 3 == 0 { 1.0 } else { stiff / (1 + i % 2) as Real }).collect();
            let minimum = (0..nodes).map(|i| Vec3::new(i as Real, 0.5, (0.2 * i as Real).cos())).collect();
            Self { directions, stiffness, minimum }
        }

        fn forces(&self, x: &[Vec3], f: &mut [Vec3]) {
            for (i, (f, x)) in f.iter_mut().zip(x).enumerate() {
                let (n, u) = (self.directions[i], x - self.minimum[i]);
                *f = -(u + (self.stiffness[i] - 1.0) * u.dot(&n) * n);
            }
        }

        fn masses(&self) -> Vec<NodeMass> {
            self.directions
                .iter()
                .zip(&self.stiffness)
                .map(|(n, k)| NodeMass::along(&[(*n, k - 1.0)]).expect("invertible"))
                .collect()
        }
    }

    /// Masses that make each node's stiff direction heavy turn a κ = 1e6 problem into a κ = 1
    /// one: FIRE with them needs far fewer steps than with unit masses and reaches the same
    /// minimum. Measured: 5,257 steps with unit masses, 248 with the masses (21×; at κ = 1e4, 1,054
    /// against 173): at κ = 1 the steps are mostly FIRE's Δt ramp, so the bound asks for 10×.
    #[test]
    fn masses_along_stiff_directions_precondition_fire() {
        let (nodes, stiff) = (40, 1e6);
        let problem = Needles::new(nodes, stiff);
        let mobile = vec![true; nodes];
        let start: Vec<Vec3> = problem.minimum.iter().map(|m| m + Vec3::new(0.8, -0.6, 0.5)).collect();
        let tolerance = 1e-8;
        let forces_at = |x: &[Vec3], f: &mut [Vec3]| problem.forces(x, f);

        let mut x = start.clone();
        let mut fire = Fire::new(FireSettings::for_scales(1.0, stiff), nodes);
        let unit = relax(&mut fire, &mut x, &mobile, forces_at, tolerance, 1_000_000, |_, _, _| {}).expect("converges");

        let masses = problem.masses();
        let mut y = start.clone();
        let mut fire = Fire::new(FireSettings::for_scales(1.0, 1.0), nodes);
        let heavy =
            relax_with_masses(&mut fire, &mut y, &mobile, Some(&masses), forces_at, tolerance, 200_000, |_, _, _| {})
                .expect("converges with masses");
        eprintln!("needles κ = {stiff:e}: unit masses {unit} steps, masses along the stiff directions {heavy}");
        assert!(10 * heavy <= unit, "{heavy} steps with masses vs {unit} without");
        for ((a, b), m) in x.iter().zip(&y).zip(&problem.minimum) {
            // |x − x*| ≤ |F|/λ_min = tolerance.
            assert!((a - m).norm() < 2.0 * tolerance && (b - m).norm() < 2.0 * tolerance, "{a} / {b} vs {m}");
        }
    }

    /// Unit masses given explicitly follow the unit-mass trajectory bit for bit.
    #[test]
    fn unit_masses_change_nothing() {
        let problem = Needles::new(12, 50.0);
        let mobile: Vec<bool> = (0..12).map(|i| i != 4).collect();
        let masses = vec![NodeMass::UNIT; 12];
        let mut a: Vec<Vec3> = problem.minimum.iter().map(|m| m + Vec3::new(0.3, 0.2, -0.1)).collect();
        let mut b = a.clone();
        let settings = FireSettings::for_scales(1.0, 50.0);
        let (mut fa, mut fb) = (Fire::new(settings.clone(), 12), Fire::new(settings, 12));
        let mut forces = vec![Vec3::zeros(); 12];
        for _ in 0..300 {
            problem.forces(&a, &mut forces);
            fa.step(&mut a, &forces, &mobile);
            problem.forces(&b, &mut forces);
            fb.step_with_masses(&mut b, &forces, &mobile, Some(&masses));
            assert_eq!(a, b);
        }
    }

    #[test]
    fn node_mass_inverse_is_the_inverse() {
        let n1 = Vec3::new(1.0, 2.0, -0.5).normalize();
        let n2 = Vec3::new(-0.3, 0.1, 1.0).normalize();
        for extra in [vec![(n1, 40.0)], vec![(n1, 40.0), (n2, 3.0)], vec![]] {
            let m = NodeMass::along(&extra).unwrap();
            assert!((m.mass * m.inverse - Mat3::identity()).norm() < 1e-12, "{extra:?}");
        }
        let s = NodeMass::scalar(4.0);
        assert!((s.mass * s.inverse - Mat3::identity()).norm() < 1e-15);
    }

    /// Chain of nonlinear springs, tension T(s) = k(s − L0) + k3(s − L0)³, anchored at an immobile
    /// first node and pulled along x by G = 2 at its last node: every spring carries tension G, so
    /// s − L0 = 1 (k = k3 = 1) and node i sits at (2i, 0, 0).
    #[test]
    fn nonlinear_spring_chain_reaches_its_known_equilibrium() {
        let nodes = 12;
        let pull = Vec3::new(2.0, 0.0, 0.0);
        let forces_at = |x: &[Vec3], f: &mut [Vec3]| {
            f.fill(Vec3::zeros());
            for i in 0..x.len() - 1 {
                let edge = x[i + 1] - x[i];
                let length = edge.norm();
                let stretch = length - 1.0;
                let tension = stretch + stretch.powi(3);
                let on_first = tension * edge / length;
                f[i] += on_first;
                f[i + 1] -= on_first;
            }
            f[x.len() - 1] += pull;
        };
        // Zigzag in 3-D, every spring stretched (s ≈ 1.6).
        let mut x: Vec<Vec3> = (0..nodes)
            .map(|i| {
                let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                if i == 0 { Vec3::zeros() } else { Vec3::new(1.5 * i as Real, 0.3 * sign, 0.2 * (i as Real).cos()) }
            })
            .collect();
        let mut mobile = vec![true; nodes];
        mobile[0] = false;
        let mut fire = Fire::new(FireSettings::for_scales(1.0, 2.0), nodes);
        let steps = relax(&mut fire, &mut x, &mobile, forces_at, 1e-10, 100_000, |_, _, _| {}).expect("chain relaxes");
        eprintln!("spring chain: {steps} steps, {} restarts", fire.restarts());
        for (i, x) in x.iter().enumerate() {
            let expected = Vec3::new(2.0 * i as Real, 0.0, 0.0);
            // Stiffness along the chain ≥ 1 per spring, across it T/s = 1: error ≲ tolerance·nodes.
            assert!((x - expected).norm() < 1e-8, "node {i} at {x}, expected {expected}");
        }
    }

    /// Rosenbrock's banana valley U = (1 − a)² + 100(b − a²)² + ½z² for one node (a, b, z) from the
    /// classic start (−1.2, 1): minimum (1, 1, 0).
    #[test]
    fn rosenbrock_valley_reaches_its_minimum() {
        let forces_at = |x: &[Vec3], f: &mut [Vec3]| {
            let (a, b, z) = (x[0].x, x[0].y, x[0].z);
            f[0] = -Vec3::new(-2.0 * (1.0 - a) - 400.0 * a * (b - a * a), 200.0 * (b - a * a), z);
        };
        let mut x = vec![Vec3::new(-1.2, 1.0, 0.5)];
        let mut fire = Fire::new(FireSettings::for_scales(1.0, 200.0), 1);
        let steps = relax(&mut fire, &mut x, &[true], forces_at, 1e-9, 100_000, |_, _, _| {}).expect("converges");
        eprintln!("Rosenbrock: {steps} steps, {} restarts", fire.restarts());
        // The Hessian's smallest eigenvalue at the minimum is ≈ 0.4: |x − x*| ≲ 2.5·1e-9.
        assert!((x[0] - Vec3::new(1.0, 1.0, 0.0)).norm() < 1e-8, "ended at {}", x[0]);
    }

    /// Immobile nodes keep their exact positions and zero velocities although forces act on them,
    /// while the mobile ones relax.
    #[test]
    fn immobile_nodes_never_move() {
        let bowl = Bowl::new(30, 100.0);
        let mobile: Vec<bool> = (0..30).map(|i| i % 3 != 1).collect();
        let start = bowl.start();
        let mut x = start.clone();
        let mut fire = Fire::new(FireSettings::for_scales(1.0, 100.0), 30);
        let mut trajectory = Vec::new();
        let steps = relax(
            &mut fire,
            &mut x,
            &mobile,
            |x, f| bowl.forces(x, f),
            1e-9,
            100_000,
            |_, after, _| {
                trajectory.push(after.to_vec());
            },
        )
        .expect("converges");
        assert!(steps > 10);
        for positions in &trajectory {
            for ((p, s), m) in positions.iter().zip(&start).zip(&mobile) {
                if !m {
                    assert_eq!(p.map(Real::to_bits), s.map(Real::to_bits));
                }
            }
        }
        for ((v, m), (x, target)) in fire.velocities().iter().zip(&mobile).zip(x.iter().zip(&bowl.minimum)) {
            if *m {
                assert!((x - target).norm() < 1e-8);
            } else {
                assert_eq!(*v, Vec3::zeros());
            }
        }
    }

    /// No node moves farther than max_displacement in any step, restarts (half-step back plus
    /// move) included, on a stiff bowl far from its minimum where the cap and restarts are active.
    #[test]
    fn displacement_cap_holds_in_every_step() {
        let bowl = Bowl::new(20, 1e3);
        let mobile = vec![true; 20];
        let mut x: Vec<Vec3> = bowl.start().iter().zip(&bowl.minimum).map(|(p, m)| m + 5.0 * (p - m)).collect();
        // Scales that make Δt large: uncapped, the first steps would move nodes by tens of units.
        let settings = FireSettings { max_displacement: 0.05, ..FireSettings::for_scales(1.0, 1.0) };
        let limit = settings.max_displacement * (1.0 + 1e-12);
        let mut fire = Fire::new(settings, 20);
        let (mut capped, mut capped_restarts, mut largest_ever) = (0, 0, 0.0 as Real);
        relax(
            &mut fire,
            &mut x,
            &mobile,
            |x, f| bowl.forces(x, f),
            1e-8,
            100_000,
            |before, after, outcome| {
                let largest = before.iter().zip(after).fold(0.0, |acc: Real, (b, a)| acc.max((a - b).norm()));
                assert!(largest <= limit, "a node moved {largest} in one step");
                largest_ever = largest_ever.max(largest);
                if largest > 0.999 * 0.05 {
                    capped += 1;
                    if outcome == FireStep::Restarted {
                        capped_restarts += 1;
                    }
                }
            },
        )
        .expect("converges");
        eprintln!("cap: {capped} capped steps ({capped_restarts} restarts), {} restarts", fire.restarts());
        assert!(capped > 10, "the cap was hardly active: {capped} steps");
        assert!(fire.restarts() > 0, "no restart happened");
    }

    /// A problem large enough for the parallel path (with immobile nodes and a nonlinear force)
    /// gives bitwise-identical trajectories on 1 and 2 threads.
    #[test]
    fn one_and_two_threads_give_identical_trajectories() {
        let nodes = 3 * PARALLEL_MIN_NODES / 2 + 17;
        let bowl = Bowl::new(nodes, 1e3);
        let mobile: Vec<bool> = (0..nodes).map(|i| i % 97 != 0).collect();
        let forces_at = |x: &[Vec3], f: &mut [Vec3]| {
            bowl.forces(x, f);
            for ((f, x), m) in f.iter_mut().zip(x).zip(&bowl.minimum) {
                *f -= 0.3 * (x - m).norm() * (x - m);
            }
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let mut x = bowl.start();
                let mut fire = Fire::new(FireSettings::for_scales(1.0, 10.0), nodes);
                let mut trace = Vec::new();
                relax(&mut fire, &mut x, &mobile, forces_at, 0.0, 400, |_, after, outcome| {
                    let digest = after.iter().fold(0u64, |acc, p| {
                        acc.rotate_left(5)
                            ^ p.x.to_bits()
                            ^ p.y.to_bits().rotate_left(21)
                            ^ p.z.to_bits().rotate_left(42)
                    });
                    trace.push((outcome, digest));
                });
                (x, fire.velocities().to_vec(), fire.dt().to_bits(), fire.restarts(), trace)
            })
        };
        let one = run(1);
        let two = run(2);
        assert!(one.3 > 0, "no restart exercised");
        assert_eq!(one.4.len(), 400);
        assert_eq!(one.4, two.4);
        assert_eq!(one.2, two.2);
        let bits =
            |v: &[Vec3]| v.iter().flat_map(|p| p.iter().map(|c| c.to_bits()).collect::<Vec<_>>()).collect::<Vec<_>>();
        assert_eq!(bits(&one.0), bits(&two.0));
        assert_eq!(bits(&one.1), bits(&two.1));
    }

    #[test]
    fn for_scales_settings_are_valid_and_round_trip() {
        let settings = FireSettings::for_scales(2e-7, 1e-9);
        assert!(settings.problems().is_empty(), "{:?}", settings.problems());
        let dt = settings.dt_start;
        // One step from rest moves Δt²·F = 1e-2·length.
        assert!((dt * dt * 1e-9 - 2e-9).abs() < 1e-22);
        let text = toml::to_string(&settings).unwrap();
        assert_eq!(toml::from_str::<FireSettings>(&text).unwrap(), settings);
        let bad = FireSettings { f_dec: 1.5, dt_min: 0.0, ..settings };
        let problems = bad.problems();
        assert_eq!(problems.len(), 2, "{problems:?}");
        assert!(problems.iter().any(|p| p.contains("f_dec")) && problems.iter().any(|p| p.contains("dt_min")));
    }

    #[test]
    fn non_finite_forces_change_nothing() {
        let mut fire = Fire::new(FireSettings::for_scales(1.0, 1.0), 2);
        let mut x = vec![Vec3::new(1.0, 2.0, 3.0), Vec3::zeros()];
        fire.step(&mut x, &[Vec3::new(1.0, 0.0, 0.0), Vec3::zeros()], &[true, true]);
        let (before, velocities) = (x.clone(), fire.velocities().to_vec());
        let outcome = fire.step(&mut x, &[Vec3::new(Real::NAN, 0.0, 0.0), Vec3::zeros()], &[true, true]);
        assert_eq!(outcome, FireStep::NonFinite);
        assert_eq!(x, before);
        assert_eq!(fire.velocities(), &velocities[..]);
        assert_eq!(fire.steps(), 1);
    }

    #[test]
    fn reset_returns_to_rest() {
        let bowl = Bowl::new(5, 10.0);
        let mut x = bowl.start();
        let settings = FireSettings::for_scales(1.0, 10.0);
        let mut fire = Fire::new(settings.clone(), 5);
        relax(&mut fire, &mut x, &[true; 5], |x, f| bowl.forces(x, f), 0.0, 200, |_, _, _| {});
        assert!(fire.dt() != settings.dt_start && fire.velocities().iter().any(|v| *v != Vec3::zeros()));
        fire.reset();
        assert_eq!(fire.dt(), settings.dt_start);
        assert_eq!(fire.alpha(), settings.alpha_start);
        assert!(fire.velocities().iter().all(|v| *v == Vec3::zeros()));
        assert_eq!((fire.steps(), fire.restarts(), fire.uphill_run()), (0, 0, 0));
    }
}
