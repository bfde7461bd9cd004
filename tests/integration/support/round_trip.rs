//! The model and the aggregate of the fit round trips (`tissuefit::inference::round_trip`), with the
//! fallible steps unwrapped for the tests and `examples/fit_aggregate.rs`.

// Each includer uses its own part.
#![allow(dead_code, unused_imports)]

use std::path::Path;
use tissuefit::geometry::Real;
use tissuefit::mechanics::Parameters;
use tissuefit::mesh::Tissue;

pub use tissuefit::inference::round_trip::{
    AGGREGATE_COUPLING_STEPS, AGGREGATE_GAMMA, AGGREGATE_SETTLE_STEPS, AGGREGATE_SPRING_STEPS, AGGREGATE_TRUTH_STEPS,
    Observed, aggregate_fit_config, aggregate_model, aggregate_truth, fitted_truth, round_trip_model, spring_adhesion,
};

/// [`tissuefit::inference::round_trip::initial_aggregate`], which must succeed.
pub fn initial_aggregate(cells: usize, nodes: usize) -> (Tissue, Real) {
    tissuefit::inference::round_trip::initial_aggregate(cells, nodes).expect("the initial aggregate")
}

/// [`tissuefit::inference::round_trip::observe_aggregate`], which must succeed.
pub fn observe_aggregate(dir: &Path, truth: &Parameters, initial: &Tissue, vpd: Real) -> Observed {
    tissuefit::inference::round_trip::observe_aggregate(dir, truth, initial, vpd).expect("the observed aggregate")
}
