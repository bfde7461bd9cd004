//! Helpers shared by several test modules.

pub mod analytic_doublet;
pub mod cli;
pub mod fit_doublet;
pub mod generated;
pub mod power_sheet;
pub mod round_trip;
pub mod run_dirs;
pub mod young_dupre;
