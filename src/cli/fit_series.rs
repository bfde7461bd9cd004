//! `tissuefit fit-series --config FIT.toml --out DIR FRAME...`: a time series of label volumes
//! mapped in order by the per-cell fit, cells tracked by overlap.

use super::Outcome;
use crate::inference::FitOptions;
use crate::io::OutputPolicy;
use crate::stages::fit_series::{SERIES_FILES, SeriesFrame, SeriesOptions, frame_dir};
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct FitSeriesArgs {
    /// Per-cell fit configuration (`mode = "per_cell"`), or a pipeline file with such a `[fit]`:
    /// its `[observed]` (or `[input]` and `[mesh]`) says how every frame is read and meshed
    /// (`voxel_size`, `[observed.meshing]`); a labels file named there is not read, the frames
    /// replace it. `[observed]` may be left out.
    #[arg(long, value_name = "TOML")]
    pub config: PathBuf,
    /// Output folder: tNNN/ (each frame's per-cell fit, cell ids = track ids), tracks.csv,
    /// series_cells.csv, series_interfaces.csv (every frame's table with `frame` and `file` in
    /// front) and series.json (each frame's outcome; written last).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// The label volumes of the series in time order, on one grid (registered: cells move by less
    /// than a fraction of their size between frames).
    #[arg(required = true, value_name = "FRAME")]
    pub frames: Vec<PathBuf>,
    /// The IoU at or above which a cell continues a cell of the previous frame (one to one,
    /// largest overlaps first); below it a cell starts a new track. Default 0.3.
    #[arg(long, value_name = "IOU")]
    pub min_iou: Option<f64>,
    /// Start every frame from its own direct estimate alone, without the correction the previous
    /// frame's refinement found.
    #[arg(long)]
    pub cold: bool,
    /// Skip the frames whose folder holds a finished fit (result.json and cell_overrides.toml),
    /// taking their correction for the next frame's start.
    #[arg(long)]
    pub resume: bool,
}

pub fn run(args: &FitSeriesArgs) -> anyhow::Result<Outcome> {
    let config = if crate::pipeline::is_pipeline_file(&args.config) {
        super::fit::load_config(&args.config)?.0
    } else {
        crate::inference::FitConfig::load_without_observed(&args.config)?
    };
    let mut policy = OutputPolicy::new().input("--config", &args.config);
    for f in &args.frames {
        policy = policy.input("FRAME", f);
    }
    policy.folder("--out", &args.out, &SERIES_FILES)?;
    for k in 0..args.frames.len() {
        let dir = frame_dir(&args.out, k);
        policy.folder("--out", &dir, &crate::stages::fit::output_files())?;
    }
    let options = SeriesOptions {
        min_iou: args.min_iou,
        cold: args.cold,
        fit: FitOptions { resume: args.resume, progress: true, plots: true, ..Default::default() },
    };
    let frames: Vec<SeriesFrame> = args.frames.iter().cloned().map(SeriesFrame::File).collect();
    let result = crate::stages::fit_series::run(&config, &frames, &args.out, &options)
        .with_context(|| format!("mapping the series of {}", args.config.display()))?;
    eprintln!("{}; {:.1} s; outputs in {}", result.summary_line(), result.wall_seconds, args.out.display());
    Ok(if result.succeeded { Outcome::Success } else { Outcome::CheckFailed })
}
