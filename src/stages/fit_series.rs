//! A time series of label volumes mapped in order (`tissuefit fit-series`, issue 25): each frame's
//! labels matched to the previous frame's by overlap ([`crate::imaging::match_labels`]) and renumbered
//! to their tracks, so that a cell keeps its id through the series; each frame's per-cell map
//! started, for the cells it tracks, from its own direct estimate times the correction the previous
//! frame's refinement found (its answer over its direct estimate): the measurement's bias changes
//! slowly with the shapes while the direct estimate follows the tensions. (Starting from the
//! previous answer itself was tried first and measured worse: on a series whose tensions drift by
//! up to 10 % per frame it started further off than the direct estimate alone.)
//!
//! Files in the output folder: `tNNN/` (each frame's per-cell fit, its cell ids the track ids),
//! `tracks.csv` (each frame's labels and their tracks), `series_cells.csv` and
//! `series_interfaces.csv` (every frame's cells.csv and interfaces.csv with `frame` and `file` in
//! front, for plotting a cell's tension through time) and `series.json` (each frame's outcome),
//! written last.

use super::StageError;
use crate::geometry::Real;
use crate::imaging::{FrameTracks, LabelVolume, match_labels, read_labels, relabel};
use crate::inference::{CellTensions, FitConfig, FitMode, FitOptions, InferenceError, observe_labels};
use crate::io::OutputGroup;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The series' own files in its folder (beside the frames' `tNNN/` folders).
pub const SERIES_FILES: [&str; 4] = ["tracks.csv", "series_cells.csv", "series_interfaces.csv", "series.json"];

/// The IoU at or above which a cell of one frame continues a cell of the previous frame.
pub const DEFAULT_MIN_IOU: Real = 0.3;

/// One frame of a series: a label file, or a volume in memory (the Python API) with the name its
/// messages and tables use.
#[derive(Clone, Debug)]
pub enum SeriesFrame {
    File(PathBuf),
    Labels { name: String, volume: LabelVolume },
}

impl SeriesFrame {
    fn name(&self) -> String {
        match self {
            SeriesFrame::File(p) => p.display().to_string(),
            SeriesFrame::Labels { name, .. } => name.clone(),
        }
    }

    fn read(&self, options: &crate::imaging::LabelReadOptions) -> Result<LabelVolume, String> {
        match self {
            SeriesFrame::File(p) => read_labels(p, options).map(|r| r.volume).map_err(|e| e.to_string()),
            SeriesFrame::Labels { volume, .. } => Ok(volume.clone()),
        }
    }
}

/// How a series is run.
#[derive(Clone, Debug, Default)]
pub struct SeriesOptions {
    /// See [`DEFAULT_MIN_IOU`].
    pub min_iou: Option<Real>,
    /// Start every frame from its direct estimate alone, without the previous frame's correction.
    pub cold: bool,
    /// Each frame's fit (`resume` skips the frames whose folder holds a finished fit).
    pub fit: FitOptions,
}

/// The folder of frame `k`.
pub fn frame_dir(out: &Path, k: usize) -> PathBuf {
    out.join(format!("t{k:03}"))
}

/// One frame in `series.json`.
#[derive(Clone, Debug, Serialize)]
pub struct FrameOutcome {
    pub frame: usize,
    pub file: String,
    pub folder: String,
    /// The fit converged and is no poor fit.
    pub succeeded: bool,
    /// Why the frame's fit failed (its map is missing); empty otherwise.
    pub error: String,
    pub converged: Option<bool>,
    pub poor_fit: Option<bool>,
    pub iterations: Option<usize>,
    /// The rms mismatch of the first relaxation (from the start) and of the answer.
    pub start_mismatch: Option<Real>,
    pub rms_mismatch: Option<Real>,
    pub cells: Option<usize>,
    /// Cells started with the previous frame's correction.
    pub previous_frame_cells: usize,
    /// Tracks that begin (labels no previous cell continues) and end at this frame.
    pub new_tracks: Vec<u32>,
    pub ended_tracks: Vec<u32>,
    /// Read back from a finished folder (`--resume`), not run again.
    pub resumed: bool,
    pub wall_seconds: Real,
}

/// `series.json`.
#[derive(Clone, Debug, Serialize)]
pub struct SeriesResult {
    pub mode: &'static str,
    pub frames: Vec<FrameOutcome>,
    /// Every frame's fit succeeded.
    pub succeeded: bool,
    pub min_iou: Real,
    pub warm_start: bool,
    pub wall_seconds: Real,
    pub threads: usize,
}

impl SeriesResult {
    /// One line for a terminal or log.
    pub fn summary_line(&self) -> String {
        let ok = self.frames.iter().filter(|f| f.succeeded).count();
        let iterations: usize = self.frames.iter().filter_map(|f| f.iterations).sum();
        format!(
            "time series of {} frames: {ok} mapped and converged, {} not; {iterations} iterations in all",
            self.frames.len(),
            self.frames.len() - ok
        )
    }
}

/// A row of `tracks.csv`.
#[derive(Serialize, Default)]
struct TrackRow {
    frame: usize,
    file: String,
    /// The label in the frame's file.
    label: u32,
    /// The cell's id in the series (the frame's fit and its files use it).
    track: u32,
    /// The IoU with the previous frame's cell it continues; empty for a track that begins here.
    iou: Option<Real>,
    /// A new track's previous-frame cell of largest overlap (a division's mother).
    parent: Option<u32>,
    voxels: u64,
}

fn err(message: impl Into<String>) -> StageError {
    StageError::new("fit-series", message)
}

/// The correction a finished frame folder holds (its answer in `cell_overrides.toml` over the
/// direct estimate in `cells.csv`), and its `result.json`.
fn read_finished(dir: &Path) -> Option<(CellTensions, serde_json::Value)> {
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("result.json")).ok()?).ok()?;
    #[derive(serde::Deserialize)]
    struct Overrides {
        cell_overrides: Vec<crate::mechanics::CellOverrideConfig>,
    }
    let text = std::fs::read_to_string(dir.join("cell_overrides.toml")).ok()?;
    let overrides: Overrides = toml::from_str(&text).ok()?;
    let mut answer = CellTensions::default();
    for o in overrides.cell_overrides {
        if let Some(f) = o.surface_tension.apical {
            answer.free.insert(o.id, f);
        }
        if let Some(a) = o.surface_tension.lateral {
            answer.lateral.insert(o.id, a);
        }
    }
    #[derive(serde::Deserialize)]
    struct Direct {
        cell: u32,
        direct_free_tension_n_per_m: Option<Real>,
        direct_lateral_tension_n_per_m: Option<Real>,
    }
    let mut start = CellTensions::default();
    for row in csv::Reader::from_path(dir.join("cells.csv")).ok()?.deserialize::<Direct>() {
        let row = row.ok()?;
        if let Some(f) = row.direct_free_tension_n_per_m {
            start.free.insert(row.cell, f);
        }
        if let Some(a) = row.direct_lateral_tension_n_per_m {
            start.lateral.insert(row.cell, a);
        }
    }
    let correction = CellTensions {
        free: crate::inference::ratios(&answer.free, &start.free),
        lateral: crate::inference::ratios(&answer.lateral, &start.lateral),
    };
    Some((correction, result))
}

/// Maps `frames` (label volumes on one grid, in time order) with the per-cell fit of `config`
/// (`mode = "per_cell"`; its `[observed]` says how each frame is read and meshed, its `labels` is
/// replaced by each frame) into `out`. A frame whose fit fails is recorded and the series goes on
/// (the next frame starts with the last correction found); only a stop request ends it early.
pub fn run(
    config: &FitConfig,
    frames: &[SeriesFrame],
    out: &Path,
    options: &SeriesOptions,
) -> Result<SeriesResult, StageError> {
    let started = Instant::now();
    if config.mode != FitMode::PerCell {
        return Err(err(
            "a time series is mapped by the per-cell fit: set `mode = \"per_cell\"` in the fit config (a global fit \
             of each frame is `tissuefit fit` per frame)",
        ));
    }
    if frames.is_empty() {
        return Err(err("no frames: give the label volumes of the series in time order"));
    }
    let min_iou = options.min_iou.unwrap_or(DEFAULT_MIN_IOU);
    if !(min_iou > 0.0 && min_iou <= 1.0) {
        return Err(err(format!("--min-iou {min_iou}: give a value in (0, 1]")));
    }
    let observed = config.observed.as_ref();
    if observed.is_some_and(|o| o.tissue.is_some()) {
        return Err(err(
            "the fit config's [observed] reads a tissue file; a time series is label volumes: use `labels` \
             (its meshing and voxel size apply to every frame)",
        ));
    }
    let read_options = observed.map(|o| o.read_options()).unwrap_or_default();
    let meshing = observed.map(|o| o.meshing.clone()).unwrap_or_default();
    // Every frame readable and on the first one's grid before any is mapped (a series refused at
    // its last frame would have cost the others' fits).
    let mut first: Option<LabelVolume> = None;
    for (k, frame) in frames.iter().enumerate() {
        let volume = frame.read(&read_options).map_err(|e| err(format!("frame {k}: {}: {e}", frame.name())))?;
        match &first {
            None => first = Some(volume),
            Some(f) => crate::imaging::check_same_grid(
                f,
                &volume,
                "map",
                "the frames of a series must share one grid (crop or resample them alike)",
            )
            .map_err(|e| err(format!("frame {k}: {} against frame 0: {e}", frame.name())))?,
        }
    }
    drop(first);
    std::fs::create_dir_all(out).map_err(|e| err(format!("{}: {e}", out.display())))?;
    let mut previous: Option<LabelVolume> = None;
    let mut correction: Option<CellTensions> = None;
    let mut next_track = 1;
    let mut outcomes = Vec::new();
    let mut track_rows = Vec::new();
    for (k, frame) in frames.iter().enumerate() {
        let t0 = Instant::now();
        let name = frame.name();
        let volume = frame.read(&read_options).map_err(|e| err(format!("frame {k}: {name}: {e}")))?;
        let tracks = match &previous {
            None => FrameTracks::first(&volume),
            Some(p) => match_labels(p, &volume, min_iou, &mut next_track)
                .map_err(|e| err(format!("frame {k}: {name} against frame {}: {e}", k - 1)))?,
        };
        next_track = next_track.max(tracks.labels.iter().map(|l| l.track + 1).max().unwrap_or(1));
        let tracked = relabel(&volume, &tracks.relabelling());
        let new_tracks: Vec<u32> = if previous.is_some() {
            tracks.labels.iter().filter(|l| l.iou.is_none()).map(|l| l.track).collect()
        } else {
            Vec::new()
        };
        track_rows.extend(tracks.labels.iter().map(|l| TrackRow {
            frame: k,
            file: name.clone(),
            label: l.label,
            track: l.track,
            iou: l.iou,
            parent: l.parent,
            voxels: l.voxels,
        }));
        let dir = frame_dir(out, k);
        let mut outcome = FrameOutcome {
            frame: k,
            file: name.clone(),
            folder: dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
            succeeded: false,
            error: String::new(),
            converged: None,
            poor_fit: None,
            iterations: None,
            start_mismatch: None,
            rms_mismatch: None,
            cells: None,
            previous_frame_cells: 0,
            new_tracks,
            ended_tracks: tracks.ended.clone(),
            resumed: false,
            wall_seconds: 0.0,
        };
        let finished = if options.fit.resume { read_finished(&dir) } else { None };
        if let Some((done, result)) = finished {
            let num = |key: &str| result[key].as_f64();
            outcome.resumed = true;
            outcome.converged = result["converged"].as_bool();
            outcome.poor_fit = result["poor_fit"].as_bool();
            outcome.succeeded = outcome.converged == Some(true) && outcome.poor_fit == Some(false);
            outcome.iterations = result["iterations"].as_u64().map(|n| n as usize);
            outcome.start_mismatch = num("start_mismatch");
            outcome.rms_mismatch = num("rms_mismatch");
            outcome.cells = result["cells"].as_u64().map(|n| n as usize);
            outcome.previous_frame_cells = result["previous_frame_cells"].as_u64().unwrap_or(0) as usize;
            tracing::info!("frame {k} ({name}): finished in {}, not run again", dir.display());
            correction = Some(done);
        } else {
            let start = if options.cold { None } else { correction.as_ref() };
            let fitted = observe_labels(tracked.clone(), &meshing, &name).and_then(|observation| {
                crate::inference::run_per_cell_from(config, observation, &dir, &options.fit, start)
            });
            match fitted {
                Ok(r) => {
                    outcome.converged = Some(r.converged);
                    outcome.poor_fit = Some(r.poor_fit);
                    outcome.succeeded = r.converged && !r.poor_fit;
                    outcome.iterations = Some(r.iterations);
                    outcome.start_mismatch = Some(r.start_mismatch);
                    outcome.rms_mismatch = Some(r.rms_mismatch);
                    outcome.cells = Some(r.cells);
                    outcome.previous_frame_cells = r.previous_frame_cells;
                    correction = Some(r.correction);
                }
                Err(InferenceError::Stopped) => return Err(err("stopped")),
                Err(e) => outcome.error = e.to_string(),
            }
        }
        outcome.wall_seconds = t0.elapsed().as_secs_f64();
        let state = if !outcome.error.is_empty() {
            format!("FAILED: {}", outcome.error)
        } else {
            format!(
                "{}, mismatch {:.4} after {} iterations",
                if outcome.succeeded { "converged" } else { "NOT converged or a poor fit" },
                outcome.rms_mismatch.unwrap_or(Real::NAN),
                outcome.iterations.unwrap_or(0)
            )
        };
        let tracking = if k == 0 {
            format!("{} labels", tracks.labels.len())
        } else {
            format!(
                "{} cells tracked from frame {}, {} new, {} ended",
                tracks.labels.len() - outcome.new_tracks.len(),
                k - 1,
                outcome.new_tracks.len(),
                outcome.ended_tracks.len()
            )
        };
        let resumed = if outcome.resumed { " (finished earlier: read back, not run again)" } else { "" };
        eprintln!("frame {k} ({name}){resumed}: {state}; {tracking}; {:.1} s", outcome.wall_seconds);
        outcomes.push(outcome);
        previous = Some(tracked);
    }
    let result = SeriesResult {
        mode: "per_cell_series",
        succeeded: outcomes.iter().all(|f| f.succeeded),
        frames: outcomes,
        min_iou,
        warm_start: !options.cold,
        wall_seconds: started.elapsed().as_secs_f64(),
        threads: rayon::current_num_threads(),
    };
    write_series(out, &result, &track_rows)?;
    Ok(result)
}

/// `tracks.csv`, the frames' tables gathered, and `series.json` last (all or nothing).
fn write_series(out: &Path, result: &SeriesResult, tracks: &[TrackRow]) -> Result<(), StageError> {
    let io = |e: &dyn std::fmt::Display| err(format!("writing the series files in {}: {e}", out.display()));
    let mut group = OutputGroup::new();
    super::write_csv(&mut group, &out.join("tracks.csv"), tracks, &TrackRow::default()).map_err(|e| io(&e))?;
    for (table, gathered) in [("cells.csv", "series_cells.csv"), ("interfaces.csv", "series_interfaces.csv")] {
        let mut header: Option<csv::StringRecord> = None;
        let mut rows: Vec<csv::StringRecord> = Vec::new();
        for f in result.frames.iter().filter(|f| f.error.is_empty()) {
            let path = out.join(&f.folder).join(table);
            let mut reader = csv::Reader::from_path(&path).map_err(|e| io(&format!("{}: {e}", path.display())))?;
            let mut h = csv::StringRecord::from(vec!["frame", "file"]);
            h.extend(reader.headers().map_err(|e| io(&format!("{}: {e}", path.display())))?.iter());
            if header.as_ref().is_some_and(|x| *x != h) {
                return Err(io(&format!("{}: its columns differ from the other frames'", path.display())));
            }
            header = Some(h);
            for record in reader.records() {
                let record = record.map_err(|e| io(&format!("{}: {e}", path.display())))?;
                let mut row = csv::StringRecord::from(vec![f.frame.to_string(), f.file.clone()]);
                row.extend(record.iter());
                rows.push(row);
            }
        }
        group
            .write(&out.join(gathered), |w| {
                let mut writer = csv::Writer::from_writer(w);
                if let Some(h) = &header {
                    writer.write_record(h)?;
                }
                for r in &rows {
                    writer.write_record(r)?;
                }
                writer.flush()
            })
            .map_err(|e| io(&e))?;
    }
    let json = serde_json::to_vec_pretty(result).map_err(|e| io(&e))?;
    group.write(&out.join("series.json"), |w| std::io::Write::write_all(w, &json)).map_err(|e| io(&e))?;
    group.commit().map_err(|e| io(&e))
}
