//! Run settings of `tissuefit simulate`: what to run (relax to equilibrium, or a time span), with
//! which method, when to stop, and how often to sample. The `[simulation]` section of a config.

use crate::geometry::Real;
use serde::{Deserialize, Serialize};

/// What a simulation does.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SimulationMode {
    /// Relax to mechanical equilibrium; stop when relaxed or at `max_steps` (then reported as not
    /// converged).
    #[default]
    Equilibrium,
    /// Integrate the equations of motion for `duration` seconds (growth included).
    Time,
}

impl SimulationMode {
    pub const ALL: [SimulationMode; 2] = [SimulationMode::Equilibrium, SimulationMode::Time];
}

/// How equilibrium is reached.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum RelaxMethod {
    /// FIRE 2.0 minimiser with adaptive step: the same equilibrium in far fewer force evaluations.
    #[default]
    Fire,
    /// Integrate the configured equations of motion (`numerics.dynamics`) with `numerics.time_step`.
    Integrate,
}

impl RelaxMethod {
    pub const ALL: [RelaxMethod; 2] = [RelaxMethod::Fire, RelaxMethod::Integrate];
}

/// The `[simulation]` section.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SimulationSettings {
    /// "equilibrium" (relax until the stopping criteria hold, or max_steps: not converged) or
    /// "time" (integrate for duration, with growth).
    ///
    /// Default [`SimulationMode::Equilibrium`].
    pub mode: SimulationMode,
    /// Equilibrium method: "fire" (FIRE 2.0 minimiser, adaptive step: far fewer force evaluations)
    /// or "integrate" (the equations of motion of numerics.dynamics).
    ///
    /// Default [`RelaxMethod::Fire`].
    pub method: RelaxMethod,
    /// Simulated time span of a "time" run. Unit: s.
    ///
    /// Default 1e-3 s (10,000 steps of 1e-7 s).
    pub duration: Real,
    /// Step budget of an "equilibrium" run; reaching it is reported as not converged.
    ///
    /// Default 200,000.
    pub max_steps: u64,
    /// Simulated time between saved frames (and stats rows) of a "time" run. Unit: s.
    ///
    /// Default 1e-5 s.
    pub sampling_period: Real,
    /// Steps between saved frames (and stats rows) of an "equilibrium" run.
    ///
    /// Default 1,000.
    pub sample_every_steps: u64,
    /// Steps between checkpoints (OUT/checkpoint.bin, continued by `tissuefit simulate --resume
    /// OUT`); 0 = not by step count.
    ///
    /// Default 0.
    pub checkpoint_every_steps: u64,
    /// Wall time between checkpoints; 0 = not by time. Ctrl-C/SIGTERM also saves one. Unit: s.
    ///
    /// Default 600 s (at most ten minutes of work lost to a crash).
    pub checkpoint_every_seconds: Real,
    /// Steps between local remeshing passes of the moving cells (split edges longer than l_max =
    /// numerics.max_edge_ratio·l_min, collapse edges shorter than l_min, flip poor triangles); 0 =
    /// never.
    ///
    /// Default 0.
    pub remesh_every_steps: u64,
    /// On a fixed mesh (remesh_every_steps = 0), edges of moving cells shorter than this fraction
    /// of l_min are still collapsed at the step they appear, and slivers (triangle quality below
    /// 0.02) get an edge flipped (no splits, no other flips): an edge that nodes drifting along the
    /// surface shrink to ~1 nm otherwise stalls FIRE and folds the surface, and a sliver's swinging
    /// normal stalls FIRE; 0 = neither.
    ///
    /// Default 0.02. A sliver's normal swings with nanometre moves and its nodes' bending and
    /// contact forces with it, so FIRE stalls. Without the check, nodes that drift along the
    /// surface can shrink an edge to ~1 nm: the two nodes then carry the largest forces of the
    /// tissue, flipping sign from step to step, FIRE stalls and the surface folds (a 64-cell
    /// spheroid at l_min = 1.4 µm: an edge of 1 nm at step ~1,100, "volume turned non-positive" at
    /// 1,174; with 0.02, 363 collapses and 551 sliver flips in 3,000 steps and no fold). With
    /// scheduled remeshing the passes collapse every edge below l_min and this check is off:
    /// between passes it fired in healthy runs (meshes with tiny junction edges, as Surface
    /// Evolver's) and moved their results.
    pub remesh_below_edge_fraction: Real,
    /// Equilibrium mode: no remeshing pass at step max_steps − settle_steps or later, so at least
    /// the last settle_steps steps run on a fixed mesh and the minimiser ends on it (with remeshing
    /// to the end an adhesive relaxation keeps creeping); 0 = remesh to the end.
    ///
    /// Default 0. With remeshing every few steps a relaxation never settles: each pass moves nodes
    /// (an adhesive spring aggregate: ~1 split or collapse per cell per pass) and restarts FIRE,
    /// and the shape creeps on (contact fraction +0.05 over 9,000 steps). On a fixed mesh it stops
    /// (φ, sphericity constant to 4 digits within 1,000 steps).
    pub settle_steps: u64,
    /// Equilibrium mode: move nodes along their normals only (forces, and momenta when integrating,
    /// projected onto the node normals). Adhesive spring contacts otherwise stream nodes out of
    /// every contact and the relaxation churns without settling.
    ///
    /// Default false. Momenta are projected too, or momenta gathered along earlier normals would
    /// move nodes tangentially where the projected forces do no work and the energy could rise (a
    /// 64-cell spheroid folded). Tangential forces only slide nodes within the surface; with
    /// adhesive spring contacts they never stop: the contact energy weights each node by its area,
    /// so nodes stream out of a contact along it, remeshing refills it, and the relaxation churns
    /// (a 20-cell aggregate: 2,600 splits and as many collapses in 16,000 steps, the contact
    /// fraction still creeping). Moved along normals, the same aggregate needed 52 splits and 59
    /// collapses and its shape settled within 2,500 steps.
    pub normal_relaxation: bool,
    /// With `normal_relaxation` and spring contacts: nodes within the contact cutoff of another
    /// cell keep their whole force, so that contact lines slide; free surfaces still move along
    /// their normals.
    ///
    /// Default false. At a contact rim the adhesion pulls a node along the surface, and the
    /// projection removes that pull: the contact line then stays near where it started (a
    /// doublet of R = 4 µm, c = l_min = 0.6 µm, w/(2γ) = 0.4: −3.1° from touching spheres, −0.4°
    /// from an over-adhered start, 20,000 steps). With the contact nodes' full forces the line
    /// moves (−0.4° and +2.1°), and a spring fit of Surface Evolver's doublet (γ_l/γ_a = 0.6, so
    /// w/(2γ) = 0.4) recovers 0.397 where the projection everywhere gave 0.493 (docs book: Design
    /// notes, "Spring contacts and Young–Dupré").
    pub full_forces_at_contacts: bool,
    /// Equilibrium mode with FIRE: give each node a mass from its stiffness measured along its last
    /// move (−ΔF·Δx/|Δx|², the largest of recent steps), where that stiffness would make FIRE's
    /// largest step unstable, so that a few stiff nodes do not hold the step of all the others down.
    ///
    /// Default false. Near-degenerate faces at a contact make a few nodes ~1,000 times stiffer than
    /// the tension (bending turns with a thin face's normal); FIRE restarts every time such a mode
    /// turns, every ~18 steps on SimuCell3D's doublet, fewer than the 20 steps it waits before it
    /// lengthens its step, so its step stays at 1–4 % of the largest and the relaxation crawls.
    /// Measured on SimuCell3D's doublet and triplet (face quadrature, normal_relaxation): converged
    /// in 3,727 and 5,811 steps, where without it the doublet had not converged after 20,000 (docs
    /// book: Design notes, "Spring contacts and Young–Dupré"). With the full forces it speeds the
    /// descent, but nodes then drift along the contacts and the repairs restart FIRE (256 times in
    /// 20,000 steps). The stiffnesses are not in checkpoints: a resumed run measures them afresh,
    /// so its outputs are close to an uninterrupted run's but not byte-identical.
    pub fire_measured_masses: bool,
    /// Equilibrium mode: a relaxation that does not converge ends at its lowest-residual state
    /// since the last remeshing instead of its last step (summary: ended_at_step). A relaxation
    /// whose FIRE stalled does so from the stall on whatever this says (the integration it
    /// continues with may still ring at the end).
    ///
    /// The lowest-residual state is passed over when its energy lies more than 1e-3·γ̄A above the
    /// last one's. Default false: the state it picks shifts what the spring aggregate fit reads
    /// (w/(2γ) 0.2 recovered at −11.9 % instead of within ±10 %; measured 2026-11-26), so the fit
    /// and its round trips keep reading the last state of runs that did not stall.
    pub end_at_lowest_residual: bool,
    /// Equilibrium when the largest nodal force is below this fraction of the typical tension force
    /// γ·l_min (γ: mean surface tension of the moving cells' faces) ...
    ///
    /// Default 1e-3.
    pub force_tolerance: Real,
    /// ... and the total energy changes by less than this fraction per step ...
    ///
    /// Default 1e-9.
    pub energy_tolerance: Real,
    /// ... and no cell volume changes by more than this fraction per step.
    ///
    /// Default 1e-9.
    pub volume_tolerance: Real,
}

impl Default for SimulationSettings {
    fn default() -> Self {
        Self {
            mode: SimulationMode::Equilibrium,
            method: RelaxMethod::Fire,
            duration: 1e-3,
            max_steps: 200_000,
            sampling_period: 1e-5,
            sample_every_steps: 1_000,
            remesh_every_steps: 0,
            remesh_below_edge_fraction: 0.02,
            settle_steps: 0,
            normal_relaxation: false,
            full_forces_at_contacts: false,
            fire_measured_masses: false,
            end_at_lowest_residual: false,
            force_tolerance: 1e-3,
            energy_tolerance: 1e-9,
            volume_tolerance: 1e-9,
            checkpoint_every_steps: 0,
            checkpoint_every_seconds: 600.0,
        }
    }
}
