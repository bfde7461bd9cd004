//! `manifest.json`: what a run directory holds and how it was made.

use super::PipelineError;
use crate::io::write_bytes_atomically;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One input file and its blake3 hash (hex).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq, Eq)]
pub struct FileHash {
    pub path: PathBuf,
    pub blake3: String,
}

/// Where a stage stands.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum StageStatus {
    /// Started, not finished (an interrupted run leaves this).
    Running,
    /// Ran to the end in this run; outputs in place.
    Complete,
    /// Complete in an earlier run with the same key; outputs reused.
    Skipped,
    /// Ended with an error (the message is in `note`).
    Failed,
    /// Stopped before it finished: Ctrl-C or SIGTERM, or found `running` by the next run (whose lock
    /// proves the process that wrote it has ended: killed, or out of time).
    Interrupted,
}

impl std::fmt::Display for StageStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            StageStatus::Running => "running",
            StageStatus::Complete => "complete",
            StageStatus::Skipped => "skipped",
            StageStatus::Failed => "failed",
            StageStatus::Interrupted => "interrupted",
        })
    }
}

impl StageStatus {
    /// Whether the stage's outputs are in place.
    pub fn done(self) -> bool {
        matches!(self, StageStatus::Complete | StageStatus::Skipped)
    }
}

/// One stage's record.
#[derive(Clone, Debug, Deserialize, Serialize)]
pub struct StageRecord {
    pub name: String,
    pub status: StageStatus,
    /// blake3 of the stage's config section and the hashes of what it reads.
    pub key: String,
    /// Seconds the stage ran (0 when skipped: see `ran_seconds` for the run that made the outputs).
    pub wall_seconds: f64,
    /// Seconds of the run that made the outputs (a resumed fit's earlier sessions included, up to
    /// their last recorded evaluation).
    pub ran_seconds: f64,
    /// Output file (relative to the stage folder, `/`-separated) → blake3. These are the files the
    /// program owns in the stage folder, whatever the status: a re-run replaces or removes only them,
    /// never another file in the folder (while a stage's new files are moved in, they are listed
    /// here with the old ones, so an interruption leaves none unowned).
    pub outputs: BTreeMap<String, String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// The whole `manifest.json`.
#[derive(Clone, Debug, Deserialize, Serialize)]
pub struct Manifest {
    pub tissuefit_version: String,
    /// Git commit, when the build set `TISSUEFIT_GIT_COMMIT`; null otherwise.
    pub git_commit: Option<String>,
    pub pipeline: PathBuf,
    pub seed: u64,
    pub threads: usize,
    pub inputs: Vec<FileHash>,
    /// The resolved config (as `config.resolved.toml`).
    pub config: serde_json::Value,
    pub stages: Vec<StageRecord>,
}

impl Manifest {
    /// Reads DIR/manifest.json if present and readable; a damaged manifest counts as absent (every
    /// stage then runs again).
    pub fn read(dir: &Path) -> Option<Manifest> {
        let text = std::fs::read_to_string(dir.join("manifest.json")).ok()?;
        match serde_json::from_str(&text) {
            Ok(m) => Some(m),
            Err(e) => {
                tracing::warn!("{}: unreadable manifest ({e}); every stage runs again", dir.display());
                None
            }
        }
    }

    /// Reads DIR/manifest.json for a run into DIR: `None` when there is none; an error when the file
    /// is there but is not a tissuefit manifest (a run never replaces a file it did not make).
    pub fn read_own(dir: &Path) -> Result<Option<Manifest>, PipelineError> {
        let path = dir.join("manifest.json");
        let text = match std::fs::read_to_string(&path) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(PipelineError::Io { path, message: e.to_string() }),
        };
        serde_json::from_str(&text).map(Some).map_err(|e| PipelineError::Io {
            path,
            message: format!(
                "is not a manifest of tissuefit ({e}), and a run would replace it; move it away, or choose \
                 another --out"
            ),
        })
    }

    /// Writes DIR/manifest.json atomically.
    pub fn write(&self, dir: &Path) -> Result<(), PipelineError> {
        let path = dir.join("manifest.json");
        let mut json = serde_json::to_string_pretty(self)
            .map_err(|e| PipelineError::Io { path: path.clone(), message: e.to_string() })?;
        json.push('\n');
        write_bytes_atomically(&path, json.as_bytes())
            .map_err(|e| PipelineError::Io { path: path.clone(), message: e.to_string() })
    }

    pub fn stage(&self, name: &str) -> Option<&StageRecord> {
        self.stages.iter().find(|s| s.name == name)
    }

    /// Replaces (or appends) the record of `record.name`.
    pub fn set_stage(&mut self, record: StageRecord) {
        match self.stages.iter_mut().find(|s| s.name == record.name) {
            Some(s) => *s = record,
            None => self.stages.push(record),
        }
    }
}

/// blake3 of a file's bytes, hex. A folder (an OME-Zarr store) is hashed as every file under it:
/// each one's relative name and bytes, in name order, its Zarr metadata files (`.zattrs`,
/// `zarr.json`) without the label image's `image-label.properties` and `tissuefit` provenance
/// ([`crate::imaging::metadata_for_hash`]: results that `zarr_properties` writes back, so that writing
/// them does not re-run the stages); a dataset in an HDF5 file (`FILE.h5/DATASET`)
/// as the dataset's path and the file's bytes.
pub fn hash_file(path: &Path) -> Result<String, PipelineError> {
    let mut hasher = blake3::Hasher::new();
    let inner = if path.exists() { None } else { crate::imaging::split_hdf5_path(path) };
    if let Some((file, dataset)) = inner {
        hasher.update(&(dataset.len() as u64).to_le_bytes());
        hasher.update(dataset.as_bytes());
        let mut f = std::fs::File::open(&file)
            .map_err(|e| PipelineError::Io { path: file.clone(), message: format!("hashing: {e}") })?;
        std::io::copy(&mut f, &mut hasher)
            .map_err(|e| PipelineError::Io { path: file.clone(), message: format!("hashing: {e}") })?;
        return Ok(hasher.finalize().to_hex().to_string());
    }
    if path.is_dir() {
        for name in list_files(path)? {
            let file = path.join(&name);
            hasher.update(&(name.len() as u64).to_le_bytes());
            hasher.update(name.as_bytes());
            let failed = |e: std::io::Error| PipelineError::Io { path: file.clone(), message: format!("hashing: {e}") };
            if is_zarr_metadata(&name) {
                // Small JSON: the label image's properties and tissuefit's note, results written
                // back by `zarr_properties`, are left out.
                let bytes = std::fs::read(&file).map_err(failed)?;
                let view = crate::imaging::metadata_for_hash(&name, &bytes);
                hasher.update(&(view.len() as u64).to_le_bytes());
                hasher.update(&view);
                continue;
            }
            let len = std::fs::metadata(&file).map_err(failed)?.len();
            hasher.update(&len.to_le_bytes());
            let mut f = std::fs::File::open(&file).map_err(failed)?;
            std::io::copy(&mut f, &mut hasher).map_err(failed)?;
        }
        return Ok(hasher.finalize().to_hex().to_string());
    }
    let mut file = std::fs::File::open(path)
        .map_err(|e| PipelineError::Io { path: path.to_path_buf(), message: format!("hashing: {e}") })?;
    std::io::copy(&mut file, &mut hasher)
        .map_err(|e| PipelineError::Io { path: path.to_path_buf(), message: format!("hashing: {e}") })?;
    Ok(hasher.finalize().to_hex().to_string())
}

/// Whether the store file `name` (relative, with `/`) is Zarr group or array metadata.
fn is_zarr_metadata(name: &str) -> bool {
    matches!(name.rsplit('/').next(), Some(".zattrs" | "zarr.json"))
}

/// blake3 of every file under `dir` (relative names with `/`, sorted).
pub fn hash_outputs(dir: &Path) -> Result<BTreeMap<String, String>, PipelineError> {
    hash_named(dir, list_files(dir)?)
}

/// blake3 of the files `names` under `dir` that exist (a missing one is left out).
pub fn hash_named<S: AsRef<str>>(
    dir: &Path,
    names: impl IntoIterator<Item = S>,
) -> Result<BTreeMap<String, String>, PipelineError> {
    let mut out = BTreeMap::new();
    for name in names {
        let path = dir.join(name.as_ref());
        if path.is_file() {
            out.insert(name.as_ref().to_string(), hash_file(&path)?);
        }
    }
    Ok(out)
}

/// Every file under `dir`, relative names with `/`, sorted (none when `dir` is missing).
pub fn list_files(dir: &Path) -> Result<Vec<String>, PipelineError> {
    let mut out = Vec::new();
    if !dir.exists() {
        return Ok(out);
    }
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let entries =
            std::fs::read_dir(&d).map_err(|e| PipelineError::Io { path: d.clone(), message: e.to_string() })?;
        for entry in entries {
            let entry = entry.map_err(|e| PipelineError::Io { path: d.clone(), message: e.to_string() })?;
            let path = entry.path();
            // Not followed: a link to a folder is listed as one entry, never walked into.
            if entry.file_type().is_ok_and(|t| t.is_dir()) {
                stack.push(path);
            } else {
                let rel = path.strip_prefix(dir).unwrap_or(&path);
                out.push(rel.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/"));
            }
        }
    }
    out.sort();
    Ok(out)
}
