//! Running a pipeline: the lock, stage keys, skipping, stages made in temporary folders and moved
//! into place, the manifest (and what the program owns in each stage folder).

use super::PipelineError;
use super::config::PipelineConfig;
use super::lock::DirLock;
use super::manifest::{FileHash, Manifest, StageRecord, StageStatus, hash_file, hash_named, hash_outputs, list_files};
use super::stages::{MESH_TISSUE, run_measure, run_mesh, run_simulate};
use crate::geometry::Real;
use crate::io::write_bytes_atomically;
use crate::stages::fit_series::{SeriesFrame, SeriesOptions};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

/// The manifests of the runs in progress in this process (a sweep runs several at a time), so that
/// Ctrl-C or SIGTERM can mark their running stages interrupted; and whether that has happened (after
/// which no manifest is written again, so the mark stays).
static ACTIVE: Mutex<(Vec<(PathBuf, Manifest)>, bool)> = Mutex::new((Vec::new(), false));

fn active() -> std::sync::MutexGuard<'static, (Vec<(PathBuf, Manifest)>, bool)> {
    ACTIVE.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Writes `out/manifest.json` and keeps a copy for [`interrupt_active_runs`]. Once those have been
/// marked interrupted, nothing is written (the process is about to exit).
fn publish(out: &Path, manifest: &Manifest) -> Result<(), PipelineError> {
    let mut guard = active();
    let (runs, stopping) = &mut *guard;
    if *stopping {
        return Ok(());
    }
    match runs.iter_mut().find(|(dir, _)| dir == out) {
        Some((_, m)) => *m = manifest.clone(),
        None => runs.push((out.to_path_buf(), manifest.clone())),
    }
    manifest.write(out)
}

/// Forgets a run directory's manifest when its run ends, however it ends.
struct ActiveRun(PathBuf);

impl Drop for ActiveRun {
    fn drop(&mut self) {
        active().0.retain(|(dir, _)| *dir != self.0);
    }
}

/// For a Ctrl-C/SIGTERM handler: marks every stage running in this process `interrupted` in its
/// run directory's manifest, and stops all further manifest writes (call it, then exit). Returns
/// `(run directory, stage)` for each stage marked.
pub fn interrupt_active_runs() -> Vec<(PathBuf, String)> {
    let mut guard = active();
    let (runs, stopping) = &mut *guard;
    *stopping = true;
    let mut marked = Vec::new();
    for (dir, manifest) in runs.iter_mut() {
        for stage in manifest.stages.iter_mut().filter(|s| s.status == StageStatus::Running) {
            stage.status = StageStatus::Interrupted;
            stage.note = Some("interrupted by Ctrl-C or SIGTERM; run the same command again to redo it".into());
            marked.push((dir.clone(), stage.name.clone()));
        }
        if let Err(e) = manifest.write(dir) {
            eprintln!("{e}");
        }
    }
    marked
}

/// How to run.
pub struct PipelineOptions<'a> {
    /// The run directory (created if needed).
    pub out: PathBuf,
    /// Run every stage even when its outputs are up to date.
    pub force: bool,
    /// Progress bars on stderr (hidden anyway when stderr is not a terminal).
    pub progress: bool,
    /// Called with one line per stage event (ran, skipped, summary).
    pub on_event: &'a dyn Fn(&str),
}

/// One truth of `[demo]` against the fit.
#[derive(Clone, Debug, Serialize)]
pub struct DemoCheck {
    pub name: String,
    pub truth: Real,
    /// `None` when the fit's result has no such parameter or ratio.
    pub fitted: Option<Real>,
    pub relative_error: Option<Real>,
    pub tolerance: Real,
    pub within: bool,
}

/// What a run did.
#[derive(Debug)]
pub struct PipelineOutcome {
    pub manifest: Manifest,
    /// `Some(converged)` when a fit stage is configured.
    pub fit_converged: Option<bool>,
    /// `Some(poor_fit)` when a fit stage is configured (result.json's `poor_fit`).
    pub fit_poor: Option<bool>,
    /// The reason when the fit's relaxation at its best point failed (result.json's
    /// `best_relaxation`): no `fit/best.vtp` then.
    pub fit_best_failed: Option<String>,
    /// `Some(succeeded)` when a `[series]` is configured: every frame was mapped, converged and no
    /// poor fit (series.json's `succeeded`). The fit fields are `None` then.
    pub series_succeeded: Option<bool>,
    /// `Some(reached)` when a simulate stage is configured: the run reached its goal (a relaxation
    /// and its reference converged, no cell passed through another; see
    /// [`crate::stages::simulate::RunSummary::reached_goal`]).
    pub simulate_converged: Option<bool>,
    /// The `[demo]` truths against the fit (empty without `[demo]`).
    pub demo: Vec<DemoCheck>,
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> PipelineError + '_ {
    move |e| PipelineError::Io { path: path.to_path_buf(), message: e.to_string() }
}

/// blake3 over the stage's name, the program version, its config text and the hashes it depends on.
fn stage_key(name: &str, section: &str, deps: &[&str]) -> String {
    let mut h = blake3::Hasher::new();
    for part in ["tissuefit-stage-v1", name, env!("CARGO_PKG_VERSION"), section].into_iter().chain(deps.iter().copied())
    {
        h.update(&(part.len() as u64).to_le_bytes());
        h.update(part.as_bytes());
    }
    h.finalize().to_hex().to_string()
}

fn toml_of<T: Serialize>(value: &T) -> Result<String, PipelineError> {
    toml::to_string(value).map_err(|e| PipelineError::Config(format!("serialising a section: {e}")))
}

/// Runs `tissuefit run`: every stage of `pipeline` into `options.out`, holding its lock throughout.
pub fn run_pipeline(pipeline: &Path, options: &PipelineOptions<'_>) -> Result<PipelineOutcome, PipelineError> {
    let config = PipelineConfig::load(pipeline)?;
    let lock = DirLock::exclusive(&options.out)?;
    run_locked(pipeline, config, options, &lock)
}

/// [`run_pipeline`] for a caller that holds `options.out`'s lock already (a sweep's run).
pub(super) fn run_pipeline_locked(
    pipeline: &Path,
    options: &PipelineOptions<'_>,
    lock: &DirLock,
) -> Result<PipelineOutcome, PipelineError> {
    run_locked(pipeline, PipelineConfig::load(pipeline)?, options, lock)
}

fn run_locked(
    pipeline: &Path,
    config: PipelineConfig,
    options: &PipelineOptions<'_>,
    _lock: &DirLock,
) -> Result<PipelineOutcome, PipelineError> {
    let out = &options.out;
    let _active = ActiveRun(out.clone());
    // What a process killed while writing left (the lock proves it has ended).
    crate::io::remove_stale_temporaries_of(out, &["manifest.json", "config.resolved.toml"])
        .map_err(|e| PipelineError::Io { path: out.clone(), message: e.to_string() })?;
    // Read with --force too: it records what the program owns in the stage folders.
    let previous = Manifest::read_own(out)?;
    let resolved_path = out.join("config.resolved.toml");
    if previous.is_none() && resolved_path.exists() {
        return Err(PipelineError::Io {
            path: resolved_path,
            message: "was not made by a tissuefit run (there is no manifest.json beside it), and a run would \
                      replace it; move it away, or choose another --out"
                .into(),
        });
    }

    // A generated input has no file: its key is the generator's specification (in the mesh key).
    let (input_hash, mut inputs) = match config.input.source() {
        Some((_, input_path)) => {
            let h = hash_file(input_path)?;
            (h.clone(), vec![FileHash { path: input_path.to_path_buf(), blake3: h }])
        }
        None => (String::new(), Vec::new()),
    };
    // The nuclei volume is a second input of the mesh stage.
    let nuclei_hash = match &config.input.nuclei {
        Some(path) => {
            let h = hash_file(path)?;
            inputs.push(FileHash { path: path.clone(), blake3: h.clone() });
            Some(h)
        }
        None => None,
    };
    let generate = config.input.generate_spec().map_err(PipelineError::Config)?;
    let simulate_model = config.simulate.as_ref().and_then(|s| s.model.clone());
    let fit_model = config.fit.as_ref().and_then(|f| f.model.clone());
    let mut model_hash = |p: &Option<PathBuf>| -> Result<String, PipelineError> {
        match p {
            Some(p) => {
                let h = hash_file(p)?;
                if !inputs.iter().any(|i| i.path == *p) {
                    inputs.push(FileHash { path: p.clone(), blake3: h.clone() });
                }
                Ok(h)
            }
            None => Ok(String::new()),
        }
    };
    let simulate_model_hash = model_hash(&simulate_model)?;
    let fit_model_hash = model_hash(&fit_model)?;
    // A series' later frames are inputs of its stage.
    let mut frame_hashes = Vec::new();
    for path in config.series.iter().flat_map(|s| &s.frames) {
        let h = hash_file(path)?;
        inputs.push(FileHash { path: path.clone(), blake3: h.clone() });
        frame_hashes.push(h);
    }

    // We hold the lock, so a stage still `running` belongs to a run that has ended: killed (kill -9,
    // a time limit) before it could say so.
    let mut stages = previous.as_ref().map_or_else(Vec::new, |m| m.stages.clone());
    for s in stages.iter_mut().filter(|s| s.status == StageStatus::Running) {
        tracing::warn!(
            "stage {}: the run that started it in {} ended before it finished; it runs again",
            s.name,
            out.display()
        );
        s.status = StageStatus::Interrupted;
        s.note = Some("interrupted: the run that started it ended before it finished (killed, or out of time)".into());
    }
    let config_json = serde_json::to_value(&config).map_err(|e| PipelineError::Config(e.to_string()))?;
    let mut manifest = Manifest {
        tissuefit_version: env!("CARGO_PKG_VERSION").to_string(),
        git_commit: option_env!("TISSUEFIT_GIT_COMMIT").map(str::to_string),
        pipeline: pipeline.to_path_buf(),
        seed: config.input.seed,
        threads: rayon::current_num_threads(),
        inputs,
        config: config_json,
        stages,
    };
    publish(out, &manifest)?;
    // Written after the manifest: a config.resolved.toml without one is not the program's.
    let resolved = config.to_toml_string()?;
    write_bytes_atomically(&resolved_path, resolved.as_bytes())
        .map_err(|e| PipelineError::Io { path: resolved_path.clone(), message: e.to_string() })?;

    let mut runner = Runner { out, previous: previous.as_ref(), manifest: &mut manifest, options };

    // mesh
    let mesh_section = toml_of(&MeshKey {
        voxel_size: config.input.voxel_size,
        zarr_level: config.input.zarr_level,
        mesh_input: config.input.mesh.is_some(),
        retriangulate: config.input.retriangulate,
        length_unit: config.input.length_unit.as_deref(),
        generate: generate.as_ref(),
        mesh: &config.mesh,
    })? + &config.output.stage_key_text();
    let mesh_deps: Vec<&str> = std::iter::once(input_hash.as_str()).chain(nuclei_hash.as_deref()).collect();
    let mesh_key = stage_key("mesh", &mesh_section, &mesh_deps);
    let mesh = runner.stage("mesh", mesh_key, None, |dir, _| {
        run_mesh(&config.input, &config.mesh, &config.output, dir, options.progress).map(|s| (s, true))
    })?;
    let tissue_hash = mesh.outputs.get(MESH_TISSUE).cloned().unwrap_or_default();
    let tissue = out.join("mesh").join(MESH_TISSUE);

    // measure
    let output_key = config.output.stage_key_text();
    let measure_key = stage_key("measure", &(toml_of(&config.measure)? + &output_key), &[&tissue_hash]);
    runner.stage("measure", measure_key, None, |dir, _| {
        run_measure(&tissue, &config, dir, &out.join("measure")).map(|s| (s, true))
    })?;

    // simulate
    let mut simulate_converged = None;
    if let Some(section) = &config.simulate {
        // The simulate stage measures its final tissue with [measure]'s settings; writing cells into
        // the label store is the measure stage's alone, so `zarr_properties` does not re-run it.
        let measure = super::MeasureSection { zarr_properties: false, ..config.measure.clone() };
        let text = toml_of(section)? + &toml_of(&measure)? + &output_key;
        let key = stage_key("simulate", &text, &[&tissue_hash, &simulate_model_hash]);
        let record = runner.stage("simulate", key, Some(Resumable::Checkpoint), |dir, resume| {
            run_simulate(&tissue, section, &config.measure, &config.output, dir, false, resume, options.progress)
        })?;
        let summary = out.join("simulate").join(crate::stages::simulate::SUMMARY_FILE);
        simulate_converged = Some(crate::stages::simulate::RunSummary::read(&summary)?.reached_goal());
        debug_assert!(record.status.done());
    }

    // fit
    let mut fit_converged = None;
    let mut fit_poor = None;
    let mut fit_best_failed = None;
    let mut series_succeeded = None;
    let mut demo = Vec::new();
    if let (Some(section), Some(series)) = (&config.fit, &config.series) {
        // The series maps every frame itself (frame 0 meshed as the mesh stage meshes it).
        let text = toml_of(section)? + &toml_of(series)? + &mesh_section;
        let deps: Vec<&str> = std::iter::once(input_hash.as_str())
            .chain(frame_hashes.iter().map(String::as_str))
            .chain(std::iter::once(fit_model_hash.as_str()))
            .collect();
        let key = stage_key("series", &text, &deps);
        let output_unit = config.output.length_unit;
        runner.stage("series", key, Some(Resumable::Frames), |dir, resume| {
            let fit = super::fit_config(section, &config.input, &config.mesh);
            let frames: Vec<SeriesFrame> =
                series.all_frames(&config.input).map(|p| SeriesFrame::File(p.to_path_buf())).collect();
            let options = SeriesOptions {
                min_iou: series.min_iou,
                cold: series.cold,
                fit: crate::inference::FitOptions {
                    resume,
                    progress: options.progress,
                    plots: true,
                    output_unit,
                    ..Default::default()
                },
            };
            let r = crate::stages::fit_series::run(&fit, &frames, dir, &options)?;
            Ok((r.summary_line(), r.succeeded))
        })?;
        let json = out.join("series").join("series.json");
        let text = std::fs::read_to_string(&json).map_err(io_err(&json))?;
        let value: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| PipelineError::Io { path: json.clone(), message: e.to_string() })?;
        series_succeeded = Some(value["succeeded"] == true);
    } else if let Some(section) = &config.fit {
        let text = toml_of(section)? + &mesh_section;
        // The fit starts from the mesh stage's tissue and measures simulations on the labels' grid.
        let key = stage_key("fit", &text, &[&input_hash, &tissue_hash, &fit_model_hash]);
        let mesh_dir = out.join("mesh");
        let output_unit = config.output.length_unit;
        runner.stage("fit", key, Some(Resumable::Trace), |dir, resume| {
            let config = super::fit_config(section, &config.input, &config.mesh);
            let options = crate::inference::FitOptions {
                resume,
                progress: options.progress,
                plots: true,
                output_unit,
                ..Default::default()
            };
            let r =
                crate::stages::fit::run(&config, crate::stages::fit::Observed::MeshStage(&mesh_dir), dir, &options)?;
            let line = r.summary_line();
            Ok((line, r.converged()))
        })?;
        let result = crate::stages::fit::read_result(&out.join("fit"))?;
        fit_converged = Some(result.converged);
        fit_poor = Some(result.poor_fit);
        fit_best_failed = result.best_relaxation.failed.then(|| result.best_relaxation.reason.clone());
        if let Some(d) = &config.demo {
            for (name, &truth) in &d.truth {
                let fitted = result.value(name);
                let relative_error = fitted.map(|f| (f - truth) / truth);
                demo.push(DemoCheck {
                    name: name.clone(),
                    truth,
                    fitted,
                    relative_error,
                    tolerance: d.tolerance,
                    within: relative_error.is_some_and(|e| e.abs() <= d.tolerance),
                });
            }
        }
    }
    Ok(PipelineOutcome {
        manifest,
        fit_converged,
        fit_poor,
        fit_best_failed,
        series_succeeded,
        simulate_converged,
        demo,
    })
}

/// What the mesh stage's key covers besides the input file's bytes: the input's kind and options
/// (not its path, nor the seed when [mesh] sets its own) and the meshing options.
#[derive(Serialize)]
struct MeshKey<'a> {
    voxel_size: Option<[Real; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    zarr_level: Option<usize>,
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    mesh_input: bool,
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    retriangulate: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    length_unit: Option<&'a str>,
    /// The generator's specification of a generated input (defaults and seed filled in).
    #[serde(skip_serializing_if = "Option::is_none")]
    generate: Option<&'a crate::meshing::TissueSpec>,
    mesh: &'a crate::meshing::LabelMeshingOptions,
}

struct Runner<'a, 'o> {
    out: &'a Path,
    previous: Option<&'a Manifest>,
    manifest: &'a mut Manifest,
    options: &'a PipelineOptions<'o>,
}

impl Runner<'_, '_> {
    fn publish(&self) -> Result<(), PipelineError> {
        publish(self.out, self.manifest)
    }

    /// Skips the stage when an earlier run completed it with the same key and its files are
    /// unchanged (unless `--force`); otherwise runs `body` into a temporary folder and moves its
    /// files into the stage folder, replacing only the files the program owns there (see the
    /// module doc of [`crate::pipeline`]), and records it.
    ///
    /// A `resumable` stage (the fit, the simulation) whose run with the same key was interrupted
    /// (killed, Ctrl-C, a time limit) goes on in the temporary folder that run left, from its
    /// `trace.csv` or `checkpoint.bin`: `body` is called with `true` then, and the finished stage
    /// is the one an uninterrupted run makes.
    fn stage<F>(
        &mut self,
        name: &'static str,
        key: String,
        resumable: Option<Resumable>,
        body: F,
    ) -> Result<StageRecord, PipelineError>
    where
        F: FnOnce(&Path, bool) -> Result<(String, bool), PipelineError>,
    {
        let dir = self.out.join(name);
        if dir.exists() && !dir.is_dir() {
            return Err(PipelineError::Io {
                path: dir.clone(),
                message: format!("is not a folder, but stage {name} writes its files there; move it away"),
            });
        }
        let prev = self.previous.and_then(|m| m.stage(name));
        // What the program made in the folder: every file an earlier run recorded, whatever its status.
        let owned: BTreeMap<String, String> = prev.map(|p| p.outputs.clone()).unwrap_or_default();
        if let Some(prev) = prev
            && !self.options.force
            && prev.status.done()
            && prev.key == key
            && dir.is_dir()
        {
            let now = hash_named(&dir, owned.keys())?;
            if now == prev.outputs {
                let record = StageRecord {
                    status: StageStatus::Skipped,
                    wall_seconds: 0.0,
                    note: Some("inputs and config unchanged; outputs reused".into()),
                    ..prev.clone()
                };
                tracing::info!("stage {name}: inputs and config unchanged, outputs in {} reused", dir.display());
                (self.options.on_event)(&format!(
                    "{name}: skipped (inputs and config unchanged; outputs in {} reused, made in {:.2} s)",
                    dir.display(),
                    prev.ran_seconds
                ));
                self.manifest.set_stage(record.clone());
                self.publish()?;
                return Ok(record);
            }
            tracing::info!("stage {name}: outputs in {} changed since the last run; running again", dir.display());
        }
        // Files in the folder that no run of the program made: never removed nor replaced.
        let foreign: Vec<String> = list_files(&dir)?.into_iter().filter(|f| !owned.contains_key(f)).collect();
        if !foreign.is_empty() && !self.options.force {
            return Err(PipelineError::Io {
                path: dir.clone(),
                message: format!(
                    "holds {} that tissuefit did not make ({}); the program never deletes what it did not \
                     create. Move {} out of the stage folder, or pass --force to run the stage beside {} \
                     (only the files tissuefit made are replaced)",
                    if foreign.len() == 1 { "a file" } else { "files" },
                    show_list(&foreign),
                    if foreign.len() == 1 { "it" } else { "them" },
                    if foreign.len() == 1 { "it" } else { "them" },
                ),
            });
        }
        let interrupted =
            prev.is_some_and(|p| matches!(p.status, StageStatus::Running | StageStatus::Interrupted) && p.key == key);
        let mut record = StageRecord {
            name: name.to_string(),
            status: StageStatus::Running,
            key,
            wall_seconds: 0.0,
            ran_seconds: 0.0,
            outputs: owned.clone(),
            note: None,
        };
        self.manifest.set_stage(record.clone());
        self.publish()?;
        (self.options.on_event)(&format!("{name}: running"));
        // Temporary folders of this stage left by an interrupted run (`.NAME.tmp-<process id>`) go first.
        // (The lock proves the processes that made them have ended.) One holding the trace of an
        // interrupted resumable stage with this key is kept to go on from.
        let prefix = format!(".{name}.tmp-");
        let mut stale = Vec::new();
        for entry in std::fs::read_dir(self.out).map_err(io_err(self.out))?.flatten() {
            let file_name = entry.file_name().to_string_lossy().into_owned();
            let ours = file_name
                .strip_prefix(&prefix)
                .is_some_and(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()));
            if ours && entry.file_type().is_ok_and(|t| t.is_dir()) {
                stale.push(entry.path());
            }
        }
        let keep = resumable
            .filter(|_| interrupted && !self.options.force)
            .and_then(|r| stale.iter().position(|d| d.join(r.marker()).is_file()))
            .map(|i| stale.swap_remove(i));
        for d in stale {
            std::fs::remove_dir_all(&d).map_err(io_err(&d))?;
        }
        let tmp = self.out.join(format!("{prefix}{}", std::process::id()));
        let resume = match keep {
            Some(kept) => {
                std::fs::rename(&kept, &tmp).map_err(io_err(&tmp))?;
                // The files the killed process was writing (`trace.csv.tmp-PID`, ...).
                crate::io::remove_stale_temporaries(&tmp)
                    .map_err(|e| PipelineError::Io { path: tmp.clone(), message: e.to_string() })?;
                let from = resumable.map_or(String::new(), |r| r.describe(&tmp));
                tracing::info!("stage {name}: going on from {} ({from})", kept.display());
                (self.options.on_event)(&format!("{name}: resuming the interrupted run from {from}"));
                true
            }
            None => {
                std::fs::create_dir_all(&tmp).map_err(io_err(&tmp))?;
                false
            }
        };
        // A resumed stage's earlier sessions count in the time that made the outputs.
        let earlier = match resumable {
            Some(r) if resume => r.earlier_seconds(&tmp),
            _ => 0.0,
        };
        let started = Instant::now();
        let result = body(&tmp, resume).and_then(|r| {
            let made = hash_outputs(&tmp)?;
            if let Some(clash) = made.keys().find(|f| foreign.contains(f)) {
                return Err(PipelineError::Io {
                    path: dir.join(clash),
                    message: format!(
                        "stage {name} writes a file of this name, but tissuefit did not make the one there; \
                         move it away and run again"
                    ),
                });
            }
            Ok((r, made))
        });
        let wall = started.elapsed().as_secs_f64();
        let ((line, ok), made) = match result {
            Ok(r) => r,
            Err(e) => {
                let _ = std::fs::remove_dir_all(&tmp);
                record.status = StageStatus::Failed;
                record.wall_seconds = wall;
                record.note = Some(e.to_string());
                self.manifest.set_stage(record);
                self.publish()?;
                return Err(e);
            }
        };
        // Owned while they move in: the record lists the old files and the new ones.
        record.outputs.extend(made.iter().map(|(k, v)| (k.clone(), v.clone())));
        self.manifest.set_stage(record.clone());
        self.publish()?;
        install(&tmp, &dir, &owned, &made)?;
        record.outputs = made;
        record.status = StageStatus::Complete;
        record.wall_seconds = wall;
        record.ran_seconds = earlier + wall;
        record.note = (!ok).then(|| "completed, but did not converge".to_string());
        self.manifest.set_stage(record.clone());
        self.publish()?;
        (self.options.on_event)(&format!("{name}: done in {wall:.2} s: {line}"));
        Ok(record)
    }
}

/// How a stage goes on from the temporary folder of an interrupted run.
#[derive(Clone, Copy, Debug)]
enum Resumable {
    /// The fit, from the evaluations in its `trace.csv`.
    Trace,
    /// The simulation, from its last periodic `checkpoint.bin`.
    Checkpoint,
    /// A time series, from its finished frames (`tNNN/` with their `result.json`).
    Frames,
}

impl Resumable {
    /// The file whose presence makes a temporary folder worth going on from.
    fn marker(self) -> &'static str {
        match self {
            Resumable::Trace => "trace.csv",
            Resumable::Checkpoint => crate::io::CHECKPOINT_FILE,
            Resumable::Frames => "t000/result.json",
        }
    }

    /// `the 12 evaluations in its trace`, `its checkpoint at step 4000`.
    fn describe(self, tmp: &Path) -> String {
        match self {
            Resumable::Trace => {
                let rows = std::fs::read_to_string(tmp.join("trace.csv")).map_or(0, |t| t.lines().count().max(1) - 1);
                format!("the {rows} evaluations in its trace")
            }
            Resumable::Checkpoint => match crate::stages::simulate::checkpoint_progress(tmp) {
                Some((step, _)) => format!("its checkpoint at step {step}"),
                None => "its checkpoint".to_string(),
            },
            Resumable::Frames => {
                let n = finished_frames(tmp).count();
                format!("its {n} finished frame{}", if n == 1 { "" } else { "s" })
            }
        }
    }

    /// Wall time (s) the earlier sessions spent on what the folder holds.
    fn earlier_seconds(self, tmp: &Path) -> f64 {
        match self {
            Resumable::Trace => crate::inference::recorded_elapsed_seconds(&tmp.join("trace.csv")),
            Resumable::Checkpoint => crate::stages::simulate::checkpoint_progress(tmp).map_or(0.0, |(_, s)| s),
            Resumable::Frames => finished_frames(tmp)
                .filter_map(|json| {
                    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(json).ok()?).ok()?;
                    v["wall_seconds"].as_f64()
                })
                .sum(),
        }
    }
}

/// The `result.json` of every frame a series finished in `dir` (frames in order, up to the first
/// unfinished one).
fn finished_frames(dir: &Path) -> impl Iterator<Item = PathBuf> + '_ {
    (0..).map(move |k| crate::stages::fit_series::frame_dir(dir, k).join("result.json")).take_while(|p| p.is_file())
}

/// At most five names, then how many more.
fn show_list(names: &[String]) -> String {
    let mut shown: Vec<String> = names.iter().take(5).cloned().collect();
    if names.len() > 5 {
        shown.push(format!("and {} more", names.len() - 5));
    }
    shown.join(", ")
}

/// Moves the files `made` from the temporary folder `tmp` into the stage folder `dir`: first the
/// `owned` files of the earlier run go (and the folders they leave empty), then each new file is
/// renamed into place; `tmp` is removed at the end. Nothing else in `dir` is touched.
fn install(
    tmp: &Path,
    dir: &Path,
    owned: &BTreeMap<String, String>,
    made: &BTreeMap<String, String>,
) -> Result<(), PipelineError> {
    for name in owned.keys() {
        let path = dir.join(name);
        if std::fs::symlink_metadata(&path).is_ok() {
            std::fs::remove_file(&path).map_err(io_err(&path))?;
        }
    }
    // Folders the old files were in, deepest first: removed only when that left them empty.
    let mut parents: Vec<PathBuf> = owned
        .keys()
        .filter_map(|n| Path::new(n).parent().filter(|p| !p.as_os_str().is_empty()).map(|p| dir.join(p)))
        .collect();
    parents.sort_by_key(|p| std::cmp::Reverse(p.components().count()));
    parents.dedup();
    for p in parents {
        let _ = std::fs::remove_dir(&p);
    }
    std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    for name in made.keys() {
        let (from, to) = (tmp.join(name), dir.join(name));
        if let Some(parent) = to.parent() {
            std::fs::create_dir_all(parent).map_err(io_err(parent))?;
        }
        std::fs::rename(&from, &to).map_err(io_err(&to))?;
    }
    std::fs::remove_dir_all(tmp).map_err(io_err(tmp))
}
