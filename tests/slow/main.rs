//! The slow integration tests: validations that take minutes each on 2 cores (the fit round trips,
//! the Surface Evolver clusters, the spring Young–Dupré doublets, the Neumann triplets, the paper's
//! first application, kill-and-resume at random moments). `cargo test --release` leaves this binary
//! out (it is declared with `test = false` in Cargo.toml) so that the everyday test command stays
//! fast; `.ci/run` runs it on every change: `cargo test --release --test slow` (one area:
//! `-- evolver_clusters::`).

#[allow(dead_code)] // shared with the fast binary, which uses other parts
#[path = "../integration/support/mod.rs"]
mod support;

mod application1;
mod evolver_clusters;
mod fit_round_trips;
mod kill_resume;
mod neumann_triplets;
mod spring_young_dupre;
