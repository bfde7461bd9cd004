//! Pipelines (`tissuefit run PIPELINE.toml`, DESIGN.md §1 step 5, §2): one TOML file drives the
//! stages mesh → measure → (simulate) → (fit) into a run directory, reproducibly.
//!
//! Run directory: `DIR/<stage>/` per stage, `DIR/config.resolved.toml` (defaults filled in, paths
//! resolved) and `DIR/manifest.json` (version, git commit when known at build time, resolved config,
//! blake3 hashes of the inputs (an OME-Zarr store's without its per-label `properties`, which
//! `[measure] zarr_properties` writes back into it), seed, threads, and per stage its key, status, wall time and the
//! hashes of its outputs). A stage is written into a temporary sibling folder and renamed into
//! place when all its files are there; only then is it marked complete in the manifest. A stage's
//! key hashes its config section and the hashes of the files it reads (the label volume, an earlier
//! stage's outputs, model files): a complete stage whose key and outputs are unchanged is skipped
//! and its outputs reused, so an interrupted run resumes at its first unfinished stage. Results do
//! not depend on the thread count, so the key leaves it out.
//!
//! Nothing the program did not make is deleted: the manifest lists, per stage, the files the
//! program wrote into its folder, and a re-run replaces or removes only those. A stage folder that
//! holds other files (notes, an input kept there) is refused, naming them, unless `--force`, which
//! runs the stage beside them (still removing only the program's files, and refusing to replace a
//! file of the same name). A run holds the folder's lock ([`lock`]) from start to end: a second run
//! into it fails at once. Ctrl-C or SIGTERM marks the stage in progress `interrupted` in the
//! manifest; after a kill -9 the next run finds it `running` with the lock free and records it as
//! `interrupted` before going on.

mod config;
pub mod lock;
mod manifest;
pub mod preset;
mod reference;
mod run;
mod stages;
pub mod sweep;
mod sweep_plot;

pub use config::{
    DemoSection, InputSection, MeasureSection, OutputSection, PipelineConfig, SeriesSection, SimulateSection,
    fit_config, is_pipeline_file, nearest,
};
pub use manifest::{FileHash, Manifest, StageRecord, StageStatus, hash_file};
pub use reference::{REFERENCE_SECTIONS, config_reference};
pub use run::{DemoCheck, PipelineOptions, PipelineOutcome, interrupt_active_runs, run_pipeline};
pub use stages::{MESH_TISSUE, describe_morphology, measure_options, run_measure, run_mesh, run_simulate};
pub use sweep::{RunReport, Sweep, SweepOptions, collect_results, run_sweep};
pub use sweep_plot::plot_results;

/// Why a pipeline could not run.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// A bad pipeline file: the message names the file and the key.
    #[error("{0}")]
    Config(String),
    /// A stage failed; the message names the stage.
    #[error("stage {stage}: {message}")]
    Stage { stage: &'static str, message: String },
    /// Reading or writing the run directory.
    #[error("{path}: {message}")]
    Io { path: std::path::PathBuf, message: String },
    /// Another process holds the directory's lock ([`lock`]).
    #[error("{dir}: {message}")]
    Locked { dir: std::path::PathBuf, message: String },
}
