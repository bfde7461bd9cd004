//! Running the `tissuefit` binary from the tests.

use std::path::PathBuf;
use std::process::{Command, Output};

/// The repository root (where `pipelines/` and `tests/data/` are).
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs the `tissuefit` binary with `args` and returns its output (whatever its exit status).
pub fn tissuefit(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tissuefit")).args(args).output().expect("the tissuefit binary runs")
}

/// Runs the `tissuefit` binary with `args` and asserts it exits 0, printing its output if not.
pub fn ok(args: &[&str]) {
    let o = tissuefit(args);
    assert_eq!(
        o.status.code(),
        Some(0),
        "tissuefit {args:?}\n{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// A pipeline fitting the demo doublet (`data/demo/doublet.tif`, its truth model) with a short
/// budget: `max_evaluations` evaluations of 150-step relaxations on a 60-node mesh, one profile point
/// and one noise replicate. It need not converge: for checks of the fit's files, not its answer.
pub fn short_demo_fit_pipeline(seed: u64, initial: f64, max_evaluations: usize) -> String {
    format!(
        "[input]\nlabels = {labels:?}\nseed = {seed}\n\n[mesh]\ntarget_nodes = 60\n\n[fit]\nmodel = {model:?}\n\
         [fit.model_overrides.simulation]\nmax_steps = 150\n\
         [fit.parameters.surface_tension]\nvalue = 1e-3\n\
         [fit.parameters.surface_tension_lateral]\nbounds = [2e-4, 1e-3]\ninitial = {initial:e}\n\
         [fit.objective]\nsphericity = 1.0\ncontact_fraction = 0.0\ncoordination = 0.0\ncontact_angle = 0.0\n\
         [fit.optimizer]\nmethod = \"nelder_mead\"\nmax_evaluations = {max_evaluations}\n\
         [fit.forward]\naccept_residual = 1e9\n[fit.profile]\npoints = 1\nnoise_replicates = 1\n",
        labels = repo().join("data/demo/doublet.tif").display().to_string(),
        model = repo().join("data/demo/doublet_truth.toml").display().to_string()
    )
}
