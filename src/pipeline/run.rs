//! Running a pipeline: stage keys, skipping, temporary stage folders renamed into place, manifest.

use super::PipelineError;
use super::config::PipelineConfig;
use super::manifest::{FileHash, Manifest, StageRecord, StageStatus, hash_file, hash_outputs};
use super::stages::{MESH_TISSUE, run_fit_stage, run_measure, run_mesh, run_simulate};
use crate::geometry::Real;
use crate::io::write_bytes_atomically;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

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
    /// `Some(converged)` when a simulate stage is configured.
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

/// Runs `tissuefit run`: every stage of `pipeline` into `options.out`.
pub fn run_pipeline(pipeline: &Path, options: &PipelineOptions<'_>) -> Result<PipelineOutcome, PipelineError> {
    let config = PipelineConfig::load(pipeline)?;
    let out = &options.out;
    std::fs::create_dir_all(out).map_err(io_err(out))?;
    let resolved = config.to_toml_string()?;
    let resolved_path = out.join("config.resolved.toml");
    write_bytes_atomically(&resolved_path, resolved.as_bytes())
        .map_err(|e| PipelineError::Io { path: resolved_path.clone(), message: e.to_string() })?;

    // A generated input has no file: its key is the generator's specification (in the mesh key).
    let (input_hash, mut inputs) = match config.input.source() {
        Some((_, input_path)) => {
            let h = hash_file(input_path)?;
            (h.clone(), vec![FileHash { path: input_path.to_path_buf(), blake3: h }])
        }
        None => (String::new(), Vec::new()),
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

    let previous = if options.force { None } else { Manifest::read(out) };
    let config_json = serde_json::to_value(&config).map_err(|e| PipelineError::Config(e.to_string()))?;
    let mut manifest = Manifest {
        tissuefit_version: env!("CARGO_PKG_VERSION").to_string(),
        git_commit: option_env!("TISSUEFIT_GIT_COMMIT").map(str::to_string),
        pipeline: pipeline.to_path_buf(),
        seed: config.input.seed,
        threads: rayon::current_num_threads(),
        inputs,
        config: config_json,
        stages: Vec::new(),
    };
    manifest.write(out)?;

    let mut runner = Runner { out, previous: previous.as_ref(), manifest: &mut manifest, options };

    // mesh
    let mesh_section = toml_of(&MeshKey {
        voxel_size: config.input.voxel_size,
        mesh_input: config.input.mesh.is_some(),
        length_unit: config.input.length_unit.as_deref(),
        generate: generate.as_ref(),
        mesh: &config.mesh,
    })?;
    let mesh_key = stage_key("mesh", &mesh_section, &[&input_hash]);
    let mesh = runner.stage("mesh", mesh_key, |dir| run_mesh(&config.input, &config.mesh, dir).map(|s| (s, true)))?;
    let tissue_hash = mesh.outputs.get(MESH_TISSUE).cloned().unwrap_or_default();
    let tissue = out.join("mesh").join(MESH_TISSUE);

    // measure
    let measure_key = stage_key("measure", &toml_of(&config.measure)?, &[&tissue_hash]);
    runner.stage("measure", measure_key, |dir| run_measure(&tissue, &config.measure, dir).map(|s| (s, true)))?;

    // simulate
    let mut simulate_converged = None;
    if let Some(section) = &config.simulate {
        let text = toml_of(section)? + &toml_of(&config.measure)?;
        let key = stage_key("simulate", &text, &[&tissue_hash, &simulate_model_hash]);
        let record = runner.stage("simulate", key, |dir| run_simulate(&tissue, section, &config.measure, dir))?;
        let run = read_json(&out.join("simulate").join("simulation.json"))?;
        let time_run = run["mode"] == "time";
        let reference_ok =
            run["reference"].is_null() || time_run || run["reference"]["converged"].as_bool().unwrap_or(false);
        simulate_converged = Some((time_run || run["converged"].as_bool().unwrap_or(false)) && reference_ok);
        debug_assert!(record.status.done());
    }

    // fit
    let mut fit_converged = None;
    let mut demo = Vec::new();
    if let Some(section) = &config.fit {
        let text = toml_of(section)? + &mesh_section;
        // The fit starts from the mesh stage's tissue and measures simulations on the labels' grid.
        let key = stage_key("fit", &text, &[&input_hash, &tissue_hash, &fit_model_hash]);
        let mesh_dir = out.join("mesh");
        runner.stage("fit", key, |dir| {
            let r = run_fit_stage(&config.input, &config.mesh, section, &mesh_dir, dir, options.progress)?;
            let fitted: Vec<String> = r
                .parameters
                .iter()
                .filter(|(_, p)| p.fitted)
                .map(|(n, p)| format!("{n} = {:.4e} [{:.3e}, {:.3e}]", p.si, p.range[0], p.range[1]))
                .collect();
            let line = format!(
                "objective {:.4e} after {} evaluations ({}); {}",
                r.objective,
                r.evaluations,
                if r.converged { "converged".to_string() } else { format!("NOT converged: {}", r.stop_reason) },
                fitted.join("; ")
            );
            Ok((line, r.converged))
        })?;
        let result = read_json(&out.join("fit").join("result.json"))?;
        fit_converged = Some(result["converged"].as_bool().unwrap_or(false));
        if let Some(d) = &config.demo {
            for (name, &truth) in &d.truth {
                let fitted =
                    result["parameters"][name]["si"].as_f64().or_else(|| result["ratios"][name]["value"].as_f64());
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
    Ok(PipelineOutcome { manifest, fit_converged, simulate_converged, demo })
}

/// What the mesh stage's key covers besides the input file's bytes: the input's kind and options
/// (not its path, nor the seed when [mesh] sets its own) and the meshing options.
#[derive(Serialize)]
struct MeshKey<'a> {
    voxel_size: Option<[Real; 3]>,
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    mesh_input: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    length_unit: Option<&'a str>,
    /// The generator's specification of a generated input (defaults and seed filled in).
    #[serde(skip_serializing_if = "Option::is_none")]
    generate: Option<&'a crate::meshing::TissueSpec>,
    mesh: &'a crate::inference::MeshingConfig,
}

fn read_json(path: &Path) -> Result<serde_json::Value, PipelineError> {
    let text = std::fs::read_to_string(path).map_err(io_err(path))?;
    serde_json::from_str(&text).map_err(|e| PipelineError::Io { path: path.to_path_buf(), message: e.to_string() })
}

struct Runner<'a, 'o> {
    out: &'a Path,
    previous: Option<&'a Manifest>,
    manifest: &'a mut Manifest,
    options: &'a PipelineOptions<'o>,
}

impl Runner<'_, '_> {
    /// Skips the stage when an earlier run completed it with the same key and its outputs are
    /// unchanged; otherwise runs `body` into a temporary folder, renames it into place, and records it.
    fn stage<F>(&mut self, name: &'static str, key: String, body: F) -> Result<StageRecord, PipelineError>
    where
        F: FnOnce(&Path) -> Result<(String, bool), PipelineError>,
    {
        let dir = self.out.join(name);
        if let Some(prev) = self.previous.and_then(|m| m.stage(name))
            && prev.status.done()
            && prev.key == key
            && dir.is_dir()
        {
            let now = hash_outputs(&dir)?;
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
                self.manifest.write(self.out)?;
                return Ok(record);
            }
            tracing::info!("stage {name}: outputs in {} changed since the last run; running again", dir.display());
        }
        let mut record = StageRecord {
            name: name.to_string(),
            status: StageStatus::Running,
            key,
            wall_seconds: 0.0,
            ran_seconds: 0.0,
            outputs: Default::default(),
            note: None,
        };
        self.manifest.set_stage(record.clone());
        self.manifest.write(self.out)?;
        (self.options.on_event)(&format!("{name}: running"));
        // Temporary folders of this stage left by an interrupted run (any process id) go first.
        let prefix = format!(".{name}.tmp-");
        for entry in std::fs::read_dir(self.out).map_err(io_err(self.out))?.flatten() {
            if entry.file_name().to_string_lossy().starts_with(&prefix) && entry.path().is_dir() {
                std::fs::remove_dir_all(entry.path()).map_err(io_err(&entry.path()))?;
            }
        }
        let tmp = self.out.join(format!("{prefix}{}", std::process::id()));
        std::fs::create_dir_all(&tmp).map_err(io_err(&tmp))?;
        let started = Instant::now();
        let result = body(&tmp);
        let wall = started.elapsed().as_secs_f64();
        let (line, ok) = match result {
            Ok(r) => r,
            Err(e) => {
                let _ = std::fs::remove_dir_all(&tmp);
                record.status = StageStatus::Failed;
                record.wall_seconds = wall;
                record.note = Some(e.to_string());
                self.manifest.set_stage(record);
                self.manifest.write(self.out)?;
                return Err(e);
            }
        };
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(io_err(&dir))?;
        }
        std::fs::rename(&tmp, &dir).map_err(io_err(&dir))?;
        record.outputs = hash_outputs(&dir)?;
        record.status = StageStatus::Complete;
        record.wall_seconds = wall;
        record.ran_seconds = wall;
        record.note = (!ok).then(|| "completed, but did not converge".to_string());
        self.manifest.set_stage(record.clone());
        self.manifest.write(self.out)?;
        (self.options.on_event)(&format!("{name}: done in {wall:.2} s: {line}"));
        Ok(record)
    }
}
