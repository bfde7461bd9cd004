//! The SimuCell3D mechanical model (DESIGN.md §3): every cell a closed triangle surface with
//! energy U = K·V·(ln(V/V0) − 1) + (k_a/2)(A/A0 − 1)² + Σ_f γ_f·A_f + bending, contacts between
//! cells (adhesion ω, repulsion ξ within a cutoff c), and dynamic or overdamped motion. SI units
//! throughout; defaults are the paper's Table 2.
//!
//! [`Parameters`] is the simulation-parameter schema: the TOML config, its per-kind defaults and
//! its validation (including a time-step stability estimate). [`TissueForces`] evaluates the
//! internal forces; [`Fire`] relaxes to equilibrium.

mod area_elasticity;
mod bending;
mod cell_geometry;
mod contact;
mod fire;
mod forces;
mod growth;
mod motion;
mod params;
mod passage;
mod polarity;
mod pressure;
mod settings;
mod simulation;
mod tension;

pub use area_elasticity::{area_elasticity_energy, target_area};
pub use bending::{Hinge, add_bending_forces, build_hinges};
pub use cell_geometry::CellGeometry;
pub use contact::{
    ContactTimings, ContactWorkspace, CoupledPair, CouplingWorkspace, contact_energy_density, contact_stress,
};
pub use fire::*;
pub use forces::{
    CellForces, CellTerm, EnergyTerms, TermSet, TissueForces, UnknownCellType, apply_configured_kinds, cell_parameters,
};
pub use growth::{division_seed, draw_division_volume, draw_division_volumes, draw_growth_rate, draw_growth_rates};
pub use motion::integrate_step;
pub use params::{
    CellOverrideConfig, CellTypeParams, ContactModel, ContactQuadrature, DerivedValue, DivisionPlaneRule, Dynamics,
    ExplicitNumerics, FaceParams, FaceTypeParams, MEAN_EDGE_PER_MIN_EDGE, MIN_CUTOFF_FRACTION, MIN_EDGE_MISMATCH,
    MeshFit, MeshScale, Numerics, ParamError, Parameters, PerFaceType, Polarity, SPHERE_ISOPERIMETRIC_RATIO,
    TimeStepLimit, UnknownOverrideCell,
};
pub use passage::{CellInside, cells_inside_others, passage_warning};
pub use polarity::{
    RayCastError, RayCastReport, RayCastSettings, Region, polarize_by_ray_casting, polarize_from_contacts,
};
pub use pressure::pressure_energy;
pub use settings::{RelaxMethod, SimulationMode, SimulationSettings};
pub use simulation::{
    BEST_ENERGY_SLACK, BestState, CellData, CellForcesState, CellState, CheckpointRequest, LastGood, NoObserver,
    OVERLAP_WARNING, Observer, Phase, REPULSION_MARGIN, REPULSION_PER_ADHESION, REPULSION_PER_PRESSURE, RunProgress,
    Sample, Simulation, SimulationError, SimulationState, SimulationSummary, StageTimes, TopologyEvent,
    TopologyEventKind, TopologyStats, derived_repulsion,
};
pub use tension::tension_energy;
