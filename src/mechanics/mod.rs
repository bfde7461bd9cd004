//! The SimuCell3D mechanical model (DESIGN.md §3): every cell a closed triangle surface with
//! energy U = K·V·(ln(V/V0) − 1) + (k_a/2)(A/A0 − 1)² + Σ_f γ_f·A_f + bending, contacts between
//! cells (adhesion ω, repulsion ξ within a cutoff c), and dynamic or overdamped motion. SI units
//! throughout; defaults are the paper's Table 2.
//!
//! [`Parameters`] is the simulation-parameter schema: the TOML config, its per-kind defaults and
//! its validation (including a time-step stability estimate).

mod params;

pub use params::{
    CellTypeParams, ContactModel, Dynamics, FaceParams, FaceTypeParams, Numerics, ParamError, Parameters,
    SPHERE_ISOPERIMETRIC_RATIO, TimeStepLimit,
};
