//! The integration tests: one test binary (one link, and its tests share the test threads), one module per
//! area. Run one area with `cargo test --release --test integration <module>::`, e.g. `fit::`.
//! The validations that take minutes (fit round trips, Surface Evolver clusters, spring Young–Dupré
//! doublets, the paper's applications, kill-and-resume at random moments) are the slow binary
//! (`tests/slow`), which `cargo test` leaves out and `.ci/run` runs: `cargo test --release --test slow`.

#[allow(dead_code)] // shared with the slow binary, which uses other parts
mod support;

mod application2;
mod bad_input;
mod cell_overrides;
mod checkpoint;
mod cli;
mod cli_reference;
mod config_reference;
mod contact_models;
mod contacts;
mod direct_tensions;
mod division;
mod fit;
mod fit_safety;
mod fit_series;
mod fuzz_inputs;
mod fuzz_replay;
mod generate_mesh;
mod growth;
mod growth_cli;
mod imaging;
mod io_formats;
mod label_readers;
mod mechanics_forces;
mod mechanics_physics;
mod mesh_bad_input;
mod mesh_invariants;
mod mesh_labels;
mod meshing;
mod morphology;
mod morphology_labels;
mod output_units;
mod per_cell_fit;
mod pipeline;
mod polarity;
mod presets;
mod real_data;
mod relaxation;
mod remesh_properties;
mod render;
mod resource_bounds;
mod retriangulate;
mod scenarios;
mod sheet_tensions;
mod simulate_defaults;
mod stage_parity;
mod sweep;
mod zarr_properties;
