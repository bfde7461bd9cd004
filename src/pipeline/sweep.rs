//! Parameter sweeps (`tissuefit sweep SWEEP.toml`, issue 10): one base pipeline, many variants of it,
//! each an ordinary run directory `DIR/run-NNNN/`, then one results table and plots over all of them.
//!
//! The sweep file:
//! ```toml
//! base = "demo.toml"                  # the pipeline, relative to the sweep file
//! [grid]                              # dotted keys into the pipeline → lists of values
//! "mesh.target_nodes" = [100, 200]
//! "simulate.model_overrides.cell_types[0].faces.lateral.surface_tension" = [2e-4, 5e-4]
//! [table]                             # optional: the outputs in results.csv, FILE:JSON.PATH
//! columns = ["simulate/morphology.json:mean_sphericity", "simulate/morphology.json:layers"]
//! ```
//! or, instead of `[grid]`, an explicit list `[[runs]]` of tables of dotted keys. A grid runs the
//! Cartesian product: the keys sorted by name, the first varying slowest and the last fastest, each
//! key's values in the order written; run `i` is always the same variant. A dotted key may index a list
//! (`cell_types[0]`), and brace groups set several keys to the same value
//! (`cell_types[0].faces.{apical,lateral,basal}.surface_tension`: one axis, three keys);
//! `model_overrides.cell_types` that the overrides do not hold yet starts as the
//! model file's list (or the defaults'), so one entry's value can be swept. Values that are paths
//! (`input.labels`, `input.mesh`, `simulate.model`, `fit.model`) are relative to the sweep file; the
//! base's own paths to the base. In a grid, such a value may be a glob pattern, expanded to the
//! sorted paths it matches: `"input.labels" = ["embryos/*.tif"]` is one run per label volume (many
//! samples, each its own run directory, one results table). Every key is checked against the pipeline schema (unknown keys named,
//! with the nearest valid one suggested) and every run's resolved pipeline is checked before any run
//! starts.

use super::config::{PipelineConfig, schema_message};
use super::lock::DirLock;
use super::manifest::Manifest;
use super::run::{PipelineOptions, run_pipeline_locked};
use super::{PipelineError, nearest};
use crate::io::write_bytes_atomically;
use crate::stages::simulate::RunSummary;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;
use toml::{Table, Value};

/// The outputs a column may read: `FILE` of `FILE:PATH`, relative to a run directory.
pub const OUTPUT_FILES: [&str; 6] = [
    "mesh/report.json",
    "measure/summary.json",
    "simulate/summary.json",
    "simulate/morphology.json",
    "fit/result.json",
    "series/series.json",
];

/// The sweep file as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepFile {
    base: PathBuf,
    #[serde(default)]
    grid: Option<Table>,
    #[serde(default)]
    runs: Option<Vec<Table>>,
    #[serde(default)]
    table: Option<TableSection>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TableSection {
    columns: Vec<String>,
}

/// One run of a sweep: its index and the values of the swept keys (`None`: the base's value).
#[derive(Clone, Debug)]
pub struct SweepRun {
    pub index: usize,
    pub values: Vec<Option<Value>>,
    /// The run's pipeline (the base with the values applied, paths absolute), as TOML.
    pub pipeline: String,
}

/// One results column: `FILE:PATH` (e.g. `simulate/morphology.json:layers`).
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    pub file: String,
    pub path: String,
}

impl Column {
    /// The column's header: `FILE:PATH`.
    pub fn name(&self) -> String {
        format!("{}:{}", self.file, self.path)
    }
}

/// A checked sweep: every run's pipeline resolved and validated.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The sweep file.
    pub path: PathBuf,
    /// The base pipeline file.
    pub base: PathBuf,
    /// The swept dotted keys, sorted.
    pub keys: Vec<String>,
    pub runs: Vec<SweepRun>,
    pub columns: Vec<Column>,
    /// Whether the runs came from `[grid]` (else `[[runs]]`).
    pub grid: bool,
}

fn config_err(origin: &Path, message: impl std::fmt::Display) -> PipelineError {
    PipelineError::Config(format!("{}: {message}", origin.display()))
}

/// A dotted key's segments: `name` or `name[i]`.
#[derive(Clone, Debug, PartialEq)]
struct Segment {
    name: String,
    index: Option<usize>,
}

fn parse_key(key: &str) -> Result<Vec<Segment>, String> {
    key.split('.')
        .map(|part| {
            let (name, index) = match part.split_once('[') {
                Some((name, rest)) => {
                    let digits = rest.strip_suffix(']').ok_or_else(|| format!("`{part}`: expected name[index]"))?;
                    let i = digits.parse::<usize>().map_err(|_| format!("`{part}`: the index must be a number ≥ 0"))?;
                    (name, Some(i))
                }
                None => (part, None),
            };
            if name.is_empty() {
                return Err("an empty part (two dots in a row, or a dot at an end)".to_string());
            }
            Ok(Segment { name: name.to_string(), index })
        })
        .collect()
}

/// The list a missing `model_overrides.cell_types` starts from: the section's model file's, or the
/// defaults'.
fn seed_cell_types(root: &Table, section: &str) -> Result<Value, String> {
    let model = root.get(section).and_then(|s| s.get("model")).and_then(Value::as_str);
    let table: Table = match model {
        Some(path) => {
            let text = std::fs::read_to_string(path).map_err(|e| format!("reading {section}.model {path}: {e}"))?;
            toml::from_str(&text).map_err(|e| format!("{section}.model {path}: {}", e.message()))?
        }
        None => Table::new(),
    };
    match table.get("cell_types") {
        Some(list) => Ok(list.clone()),
        None => {
            let defaults = crate::mechanics::Parameters::default().to_toml_string();
            let t: Table = toml::from_str(&defaults).map_err(|e| e.message().to_string())?;
            t.get("cell_types").cloned().ok_or_else(|| "the default parameters have no cell_types".to_string())
        }
    }
}

/// The keys a key with brace groups stands for: `a.{b,c}.d` → `a.b.d`, `a.c.d` (several groups
/// expand as their product, in the order written). A key without braces stands for itself.
fn expand_braces(key: &str) -> Result<Vec<String>, String> {
    let Some(open) = key.find('{') else {
        if key.contains('}') {
            return Err(format!("`{key}`: a `}}` without its `{{`"));
        }
        return Ok(vec![key.to_string()]);
    };
    let close = key[open..].find('}').map(|c| open + c).ok_or_else(|| format!("`{key}`: a `{{` without its `}}`"))?;
    let inner = &key[open + 1..close];
    if inner.contains('{') {
        return Err(format!("`{key}`: brace groups cannot nest"));
    }
    let choices: Vec<&str> = inner.split(',').map(str::trim).collect();
    if choices.len() < 2 || choices.iter().any(|c| c.is_empty() || c.contains('.')) {
        return Err(format!("`{key}`: a brace group lists two or more names without dots, e.g. {{apical,lateral}}"));
    }
    let rest = expand_braces(&key[close + 1..])?;
    Ok(choices.iter().flat_map(|c| rest.iter().map(move |r| format!("{}{c}{r}", &key[..open]))).collect())
}

/// Sets `key` to `value` in the pipeline table `root`, creating tables on the way; a key with brace
/// groups ([`expand_braces`]) sets every key it stands for to the same value.
fn set_key(root: &mut Table, key: &str, value: Value) -> Result<(), String> {
    let expanded = expand_braces(key)?;
    if expanded.len() > 1 {
        return expanded.iter().try_for_each(|k| set_key(root, k, value.clone()));
    }
    let segments = parse_key(key)?;
    // Seeded before the walk borrows `root` mutably.
    let seed = match segments.as_slice() {
        [s, o, c, ..]
            if (s.name == "simulate" || s.name == "fit") && o.name == "model_overrides" && c.name == "cell_types" =>
        {
            let present = root.get(&s.name).and_then(|t| t.get("model_overrides")).and_then(|t| t.get("cell_types"));
            if present.is_none() { Some(seed_cell_types(root, &s.name)?) } else { None }
        }
        _ => None,
    };
    let mut table = root;
    let mut walked = String::new();
    let last = segments.len() - 1;
    let mut value = Some(value);
    for (n, seg) in segments.iter().enumerate() {
        if !walked.is_empty() {
            walked.push('.');
        }
        walked.push_str(&seg.name);
        if seg.index.is_none() && n == last {
            table.insert(seg.name.clone(), value.take().expect("set once"));
            return Ok(());
        }
        if !table.contains_key(&seg.name) {
            let fresh = match (&seed, seg.index, n) {
                (Some(list), Some(_), 2) => list.clone(),
                (_, Some(_), _) => return Err(format!("`{walked}` is not there to index; it has no list")),
                (_, None, _) => Value::Table(Table::new()),
            };
            table.insert(seg.name.clone(), fresh);
        }
        let slot = table.get_mut(&seg.name).expect("inserted above");
        let slot = match seg.index {
            None => slot,
            Some(i) => {
                let Value::Array(items) = slot else {
                    return Err(format!("`{walked}` is {}, not a list to index", slot.type_str()));
                };
                let len = items.len();
                walked.push_str(&format!("[{i}]"));
                let item = items.get_mut(i).ok_or_else(|| format!("`{walked}`: the list has {len} entries"))?;
                if n == last {
                    *item = value.take().expect("set once");
                    return Ok(());
                }
                item
            }
        };
        table = match slot {
            Value::Table(t) => t,
            other => return Err(format!("`{walked}` is {}, not a table", other.type_str())),
        };
    }
    Ok(())
}

/// Flattens nested tables into dotted keys; `leaf` decides what counts as a value.
fn flatten(prefix: &str, table: &Table, out: &mut Vec<(String, Value)>) {
    for (k, v) in table {
        let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
        match v {
            Value::Table(t) => flatten(&key, t, out),
            _ => out.push((key, v.clone())),
        }
    }
}

/// The pipeline keys that hold paths.
const PATH_KEYS: [&str; 4] = ["input.labels", "input.mesh", "simulate.model", "fit.model"];

/// Makes the path at `key` absolute against `dir` (if present, a string and relative).
fn absolutize(root: &mut Table, key: &str, dir: &Path) {
    let (section, name) = key.split_once('.').expect("a dotted key");
    if let Some(Value::Table(t)) = root.get_mut(section)
        && let Some(Value::String(p)) = t.get_mut(name)
        && Path::new(p.as_str()).is_relative()
    {
        *p = dir.join(&*p).display().to_string();
    }
}

/// A path key's grid values with every glob pattern (`*`, `?`, `[…]`, relative to the sweep file's
/// folder) replaced by the paths it matches, sorted, as written relative to that folder: one run per
/// sample of `"input.labels" = ["embryos/*.tif"]`. A pattern that matches nothing is an error.
fn expand_globs(key: &str, items: Vec<Value>, sweep_dir: &Path) -> Result<Vec<Value>, String> {
    let mut out = Vec::with_capacity(items.len());
    for item in items {
        let pattern = match &item {
            Value::String(p) if p.contains(['*', '?', '[']) => p.clone(),
            _ => {
                out.push(item);
                continue;
            }
        };
        let absolute = if Path::new(&pattern).is_relative() {
            sweep_dir.join(&pattern).display().to_string()
        } else {
            pattern.clone()
        };
        let matches = glob::glob(&absolute).map_err(|e| format!("grid key `{key}`: pattern {pattern:?}: {e}"))?;
        let mut paths = Vec::new();
        for m in matches {
            let m = m.map_err(|e| format!("grid key `{key}`: pattern {pattern:?}: {e}"))?;
            let shown = m.strip_prefix(sweep_dir).map_or(m.clone(), Path::to_path_buf);
            paths.push(shown.display().to_string());
        }
        if paths.is_empty() {
            return Err(format!(
                "grid key `{key}`: pattern {pattern:?} matches no file (relative to {})",
                sweep_dir.display()
            ));
        }
        paths.sort();
        out.extend(paths.into_iter().map(Value::String));
    }
    Ok(out)
}

fn absolute_dir(file: &Path) -> PathBuf {
    let dir = file.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf())
}

/// A value as written in results.csv and plots: strings bare, floats in Rust's shortest round-trip
/// form (`1e-11`, `0.0003`), others as TOML writes them.
pub fn show_value(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => show_toml(other),
    }
}

/// A value in TOML syntax, floats in Rust's shortest round-trip form (valid TOML too).
pub fn show_toml(v: &Value) -> String {
    match v {
        Value::Float(f) if f.is_finite() => format!("{f:?}"),
        other => other.to_string(),
    }
}

impl Sweep {
    /// Reads and checks a sweep file and every run's pipeline; nothing is written.
    pub fn load(path: &Path) -> Result<Sweep, PipelineError> {
        let text = crate::io::read_text_capped(path, crate::io::MAX_CONFIG_FILE)
            .map_err(|e| config_err(path, format!("reading: {e}")))?;
        let file: SweepFile = toml::from_str(&text).map_err(|e| {
            let line = e.span().map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
            let at = line.map_or(String::new(), |l| format!(":{l}"));
            PipelineError::Config(format!("{}{at}: {}", path.display(), schema_message(&e)))
        })?;
        let sweep_dir = absolute_dir(path);
        let base = sweep_dir.join(&file.base);
        if !base.is_file() {
            return Err(config_err(path, format!("base: {} does not exist", base.display())));
        }
        let base_text = crate::io::read_text_capped(&base, crate::io::MAX_CONFIG_FILE)
            .map_err(|e| config_err(path, format!("base {}: {e}", base.display())))?;
        // The base alone must be a valid pipeline: errors in it are reported against it.
        PipelineConfig::load_text(&base_text, &base)?;
        let mut base_table: Table = toml::from_str(&base_text).map_err(|e| config_err(&base, e.message()))?;
        let base_dir = absolute_dir(&base);
        for key in PATH_KEYS {
            absolutize(&mut base_table, key, &base_dir);
        }

        // The variants: (key, value) lists.
        let variants: Vec<Vec<(String, Value)>> = match (&file.grid, &file.runs) {
            (Some(_), Some(_)) => return Err(config_err(path, "give [grid] or [[runs]], not both")),
            (None, None) => {
                return Err(config_err(path, "give [grid] (lists of values) or [[runs]] (one table per run)"));
            }
            (Some(grid), None) => {
                let mut lists = Vec::new();
                flatten("", grid, &mut lists);
                lists.sort_by(|a, b| a.0.cmp(&b.0));
                if lists.is_empty() {
                    return Err(config_err(path, "[grid] is empty; give at least one key = [values]"));
                }
                let mut axes = Vec::new();
                for (key, v) in lists {
                    match v {
                        Value::Array(items) if !items.is_empty() => {
                            let items = if PATH_KEYS.contains(&key.as_str()) {
                                expand_globs(&key, items, &sweep_dir).map_err(|e| config_err(path, e))?
                            } else {
                                items
                            };
                            axes.push((key, items))
                        }
                        Value::Array(_) => {
                            return Err(config_err(path, format!("grid key `{key}`: the list is empty")));
                        }
                        other => {
                            return Err(config_err(
                                path,
                                format!("grid key `{key}` = {other}: give a list of values, e.g. [{other}]"),
                            ));
                        }
                    }
                }
                let total: usize = axes.iter().map(|(_, v)| v.len()).product();
                (0..total)
                    .map(|mut i| {
                        let mut picks = vec![None; axes.len()];
                        for (a, (key, values)) in axes.iter().enumerate().rev() {
                            picks[a] = Some((key.clone(), values[i % values.len()].clone()));
                            i /= values.len();
                        }
                        picks.into_iter().flatten().collect()
                    })
                    .collect()
            }
            (None, Some(runs)) => {
                if runs.is_empty() {
                    return Err(config_err(path, "[[runs]] is empty"));
                }
                runs.iter()
                    .map(|t| {
                        let mut kv = Vec::new();
                        flatten("", t, &mut kv);
                        kv.sort_by(|a, b| a.0.cmp(&b.0));
                        kv
                    })
                    .collect()
            }
        };
        let mut keys: Vec<String> = variants.iter().flatten().map(|(k, _)| k.clone()).collect();
        keys.sort();
        keys.dedup();
        let what = if file.grid.is_some() { "grid key" } else { "runs key" };

        // Each key alone against the base: schema errors name the key and suggest the nearest.
        for key in &keys {
            let value = variants.iter().flatten().find(|(k, _)| k == key).map(|(_, v)| v.clone()).expect("a key");
            let value_shown = show_toml(&value);
            let mut table = base_table.clone();
            set_key(&mut table, key, value).map_err(|e| config_err(path, format!("{what} `{key}`: {e}")))?;
            if let Err(e) = Value::Table(table.clone()).try_into::<PipelineConfig>() {
                return Err(config_err(path, format!("{what} `{key}`: {}", schema_message(&e))));
            }
            // The checks beyond the schema (model files and their overrides included), this key alone.
            let text = toml::to_string(&table).map_err(|e| config_err(path, format!("{what} `{key}`: {e}")))?;
            if let Err(e) = PipelineConfig::load_text(&text, &base) {
                return Err(config_err(path, format!("{what} `{key}` = {value_shown}: {e}")));
            }
        }

        // Every run resolved and checked in full.
        let mut runs = Vec::with_capacity(variants.len());
        for (index, kv) in variants.iter().enumerate() {
            let mut table = base_table.clone();
            for (key, value) in kv {
                set_key(&mut table, key, value.clone())
                    .map_err(|e| config_err(path, format!("{what} `{key}`: {e}")))?;
            }
            for key in PATH_KEYS {
                if kv.iter().any(|(k, _)| k == key) {
                    absolutize(&mut table, key, &sweep_dir);
                }
            }
            let pipeline = toml::to_string(&table).map_err(|e| config_err(path, format!("run {index}: {e}")))?;
            let origin = PathBuf::from(format!("{} [run {index}: {}]", path.display(), describe_values(kv)));
            PipelineConfig::load_text(&pipeline, &origin)?;
            let values = keys.iter().map(|k| kv.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone())).collect();
            runs.push(SweepRun { index, values, pipeline });
        }

        let columns = match &file.table {
            Some(t) => {
                if t.columns.is_empty() {
                    return Err(config_err(path, "table.columns is empty; leave [table] out for the default columns"));
                }
                t.columns.iter().map(|c| parse_column(c).map_err(|e| config_err(path, e))).collect::<Result<_, _>>()?
            }
            None => default_columns(&runs),
        };
        // A column must read a stage that some run has.
        for c in &columns {
            let stage = c.file.split('/').next().unwrap_or("");
            let has = |r: &SweepRun| toml::from_str::<Table>(&r.pipeline).is_ok_and(|t| t.contains_key(stage));
            if matches!(stage, "simulate" | "fit") && !runs.iter().any(has) {
                return Err(config_err(
                    path,
                    format!("table.columns `{}`: no run has a [{stage}] stage to read it from", c.name()),
                ));
            }
        }
        Ok(Sweep { path: path.to_path_buf(), base, keys, runs, columns, grid: file.grid.is_some() })
    }

    /// `key=value` pairs of a run, tab-separated (values as TOML writes them).
    pub fn describe(&self, run: &SweepRun) -> String {
        self.keys
            .iter()
            .zip(&run.values)
            .filter_map(|(k, v)| v.as_ref().map(|v| format!("{k}={}", show_toml(v))))
            .collect::<Vec<_>>()
            .join("\t")
    }
}

fn describe_values(kv: &[(String, Value)]) -> String {
    kv.iter().map(|(k, v)| format!("{k} = {}", show_toml(v))).collect::<Vec<_>>().join(", ")
}

fn parse_column(spec: &str) -> Result<Column, String> {
    let Some((file, path)) = spec.split_once(':') else {
        return Err(format!(
            "table.columns `{spec}`: expected FILE:JSON.PATH, e.g. `simulate/morphology.json:layers` (FILE one of {})",
            OUTPUT_FILES.join(", ")
        ));
    };
    if !OUTPUT_FILES.contains(&file) {
        let valid: Vec<String> = OUTPUT_FILES.iter().map(|s| s.to_string()).collect();
        let hint = nearest(file, &valid).map_or(String::new(), |n| format!("; did you mean `{n}`?"));
        return Err(format!(
            "table.columns `{spec}`: `{file}` is not an output a column can read (one of {}){hint}",
            OUTPUT_FILES.join(", ")
        ));
    }
    if path.is_empty() || path.split('.').any(str::is_empty) {
        return Err(format!("table.columns `{spec}`: give a dotted JSON path after the colon, e.g. `layers`"));
    }
    // The simulate stage's summary.json is the run's; its final tissue's morphology is morphology.json
    // (a run summary key read from the morphology is left to the run: those files vary by tissue).
    let first = path.split('.').next().unwrap_or_default();
    if file == "simulate/summary.json" && !RunSummary::keys().iter().any(|k| k == first) {
        return Err(format!(
            "table.columns `{spec}`: simulate/summary.json is the run summary (steps, converged, residual, …) \
             and has no `{first}`; the final tissue's morphology is in simulate/morphology.json: \
             `simulate/morphology.json:{path}`"
        ));
    }
    Ok(Column { file: file.to_string(), path: path.to_string() })
}

/// Without `[table]`: the morphology of the last tissue (simulate's if any run simulates, else
/// measure's), the simulation's steps, and the fit's objective and fitted parameters.
fn default_columns(runs: &[SweepRun]) -> Vec<Column> {
    let tables: Vec<Table> = runs.iter().filter_map(|r| toml::from_str(&r.pipeline).ok()).collect();
    let simulate = tables.iter().any(|t| t.contains_key("simulate"));
    let morph = if simulate { "simulate/morphology.json" } else { "measure/summary.json" };
    let col = |file: &str, path: &str| Column { file: file.to_string(), path: path.to_string() };
    let mut cols: Vec<Column> = ["cells", "mean_sphericity", "mean_contact_fraction", "mean_coordination", "layers"]
        .iter()
        .map(|p| col(morph, p))
        .collect();
    if simulate {
        cols.push(col("simulate/summary.json", "steps"));
        cols.push(col("simulate/summary.json", "converged"));
    }
    let mut fitted: Vec<String> = tables
        .iter()
        .filter_map(|t| t.get("fit")?.get("parameters")?.as_table().cloned())
        .flat_map(|p| p.into_iter().filter(|(_, v)| v.get("bounds").is_some()).map(|(k, _)| k))
        .collect();
    if tables.iter().any(|t| t.contains_key("series")) {
        cols.push(col("series/series.json", "succeeded"));
        cols.push(col("series/series.json", "wall_seconds"));
    } else if !fitted.is_empty() || tables.iter().any(|t| t.contains_key("fit")) {
        cols.push(col("fit/result.json", "objective"));
        cols.push(col("fit/result.json", "converged"));
        fitted.sort();
        fitted.dedup();
        for name in fitted {
            cols.push(col("fit/result.json", &format!("parameters.{name}.si")));
        }
    }
    cols
}

/// The run directory of run `index`: `DIR/run-0003`.
pub fn run_dir(out: &Path, index: usize) -> PathBuf {
    out.join(format!("run-{index:04}"))
}

/// Where a failed run's reason is kept (removed when the run succeeds).
const FAILED_FILE: &str = "failed.txt";

/// How to run a sweep.
pub struct SweepOptions<'a> {
    pub out: PathBuf,
    /// Runs at a time.
    pub jobs: usize,
    /// Threads in all, split between the jobs (each run gets `threads / jobs`, at least 1).
    pub threads: usize,
    pub force: bool,
    /// Only this run (for job arrays).
    pub only: Option<usize>,
    /// One line per run started and finished.
    pub on_event: &'a (dyn Fn(&str) + Sync),
}

/// What one run of this invocation did.
#[derive(Clone, Debug)]
pub struct RunReport {
    pub index: usize,
    /// `complete` (something ran), `skipped` (every stage up to date) or `failed`.
    pub status: &'static str,
    pub reason: Option<String>,
    pub wall_seconds: f64,
}

/// Runs the sweep's runs (all, or `options.only`), `options.jobs` at a time. A failed run is
/// recorded (in its report and `DIR/run-NNNN/failed.txt`), never fatal to the others. The sweep
/// folder's lock is held throughout: exclusive for a whole sweep, shared for one run of a job array
/// (`options.only`; the tasks run side by side, each holding its run folder's lock).
pub fn run_sweep(sweep: &Sweep, options: &SweepOptions<'_>) -> Result<Vec<RunReport>, PipelineError> {
    let selected: Vec<&SweepRun> = match options.only {
        Some(i) => match sweep.runs.get(i) {
            Some(r) => vec![r],
            None => {
                return Err(config_err(
                    &sweep.path,
                    format!("--index {i}: the sweep has runs 0 to {}", sweep.runs.len() - 1),
                ));
            }
        },
        None => sweep.runs.iter().collect(),
    };
    let _lock = if options.only.is_some() { DirLock::shared(&options.out)? } else { DirLock::exclusive(&options.out)? };
    let jobs = options.jobs.clamp(1, selected.len().max(1));
    let threads = (options.threads / jobs).max(1);
    let next = AtomicUsize::new(0);
    let reports = std::sync::Mutex::new(Vec::new());
    let worker = || -> Result<(), PipelineError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| PipelineError::Config(format!("starting {threads} threads: {e}")))?;
        loop {
            let n = next.fetch_add(1, Ordering::SeqCst);
            let Some(run) = selected.get(n) else { return Ok(()) };
            let report = pool.install(|| run_one(sweep, run, options));
            reports.lock().expect("lock").push(report);
        }
    };
    let results: Vec<Result<(), PipelineError>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..jobs).map(|_| s.spawn(worker)).collect();
        handles.into_iter().map(|h| h.join().unwrap_or(Ok(()))).collect()
    });
    for r in results {
        r?;
    }
    let mut reports = reports.into_inner().expect("lock");
    reports.sort_by_key(|r| r.index);
    Ok(reports)
}

fn run_one(sweep: &Sweep, run: &SweepRun, options: &SweepOptions<'_>) -> RunReport {
    let dir = run_dir(&options.out, run.index);
    let label = format!("run {:04} [{}]", run.index, sweep.describe(run).replace('\t', ", "));
    (options.on_event)(&format!("{label}: started"));
    let started = Instant::now();
    let quiet = |line: &str| tracing::info!("run {:04}: {line}", run.index);
    // Locked before anything in the folder is touched: a run folder another process is writing into
    // is left alone (no failed.txt either).
    let lock = match DirLock::exclusive(&dir) {
        Ok(lock) => lock,
        Err(e) => {
            let reason = e.to_string();
            (options.on_event)(&format!("{label}: failed: {reason}"));
            return RunReport { index: run.index, status: "failed", reason: Some(reason), wall_seconds: 0.0 };
        }
    };
    let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| -> Result<_, PipelineError> {
        // What a process killed while writing left (the lock proves it has ended).
        crate::io::remove_stale_temporaries_of(&dir, &["pipeline.toml", FAILED_FILE])
            .map_err(|e| PipelineError::Io { path: dir.clone(), message: e.to_string() })?;
        let failed = dir.join(FAILED_FILE);
        if failed.exists() {
            std::fs::remove_file(&failed)
                .map_err(|e| PipelineError::Io { path: failed.clone(), message: e.to_string() })?;
        }
        let pipeline = dir.join("pipeline.toml");
        let text = format!(
            "# Run {} of the sweep {} (base {}): {}\n{}",
            run.index,
            sweep.path.display(),
            sweep.base.display(),
            sweep.describe(run).replace('\t', ", "),
            run.pipeline
        );
        write_bytes_atomically(&pipeline, text.as_bytes())
            .map_err(|e| PipelineError::Io { path: pipeline.clone(), message: e.to_string() })?;
        let po = PipelineOptions { out: dir.clone(), force: options.force, progress: false, on_event: &quiet };
        run_pipeline_locked(&pipeline, &po, &lock)
    }));
    let wall_seconds = started.elapsed().as_secs_f64();
    let (status, reason) = match outcome {
        Ok(Ok(o)) => {
            let all_skipped = o.manifest.stages.iter().all(|s| s.status == super::StageStatus::Skipped);
            let notes: Vec<String> =
                o.manifest.stages.iter().filter_map(|s| s.note.as_ref().map(|n| format!("{}: {n}", s.name))).collect();
            let notes: Vec<String> = notes.into_iter().filter(|n| !n.contains("outputs reused")).collect();
            (if all_skipped { "skipped" } else { "complete" }, (!notes.is_empty()).then(|| notes.join("; ")))
        }
        Ok(Err(e)) => ("failed", Some(e.to_string())),
        Err(panic) => {
            let what = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown".into());
            ("failed", Some(format!("internal error (panic): {what}")))
        }
    };
    if status == "failed" {
        let message = reason.clone().unwrap_or_default();
        if let Err(e) = write_bytes_atomically(&dir.join(FAILED_FILE), format!("{message}\n").as_bytes()) {
            tracing::warn!("{}: {e}", dir.display());
        }
    }
    let tail = reason.as_ref().map_or(String::new(), |r| format!(": {r}"));
    (options.on_event)(&format!("{label}: {status} in {wall_seconds:.2} s{tail}"));
    RunReport { index: run.index, status, reason, wall_seconds }
}

/// One row of results.csv, read back from a run directory.
#[derive(Clone, Debug)]
pub struct ResultRow {
    pub index: usize,
    /// `complete`, `failed`, `incomplete` (a stage not finished), `running` (another process holds the
    /// run folder's lock) or `missing` (never run).
    pub status: String,
    pub reason: String,
    /// Seconds the stages took to make the outputs (the manifest's `ran_seconds`, summed).
    pub wall_seconds: Option<f64>,
    /// One per column: the JSON value, `None` when absent.
    pub outputs: Vec<Option<serde_json::Value>>,
}

/// The JSON value at a dotted path (`a.b.0.c`).
pub fn json_at<'v>(v: &'v serde_json::Value, path: &str) -> Option<&'v serde_json::Value> {
    path.split('.').try_fold(v, |v, seg| match v {
        serde_json::Value::Array(items) => items.get(seg.parse::<usize>().ok()?),
        serde_json::Value::Object(map) => map.get(seg),
        _ => None,
    })
}

/// Why a complete simulate or fit stage fell short, read from its outputs (not from the stage's note,
/// which a skipped stage replaces by "outputs reused").
fn unconverged(stage: &str, read_json: &dyn Fn(&str) -> Option<serde_json::Value>) -> Option<String> {
    match stage {
        "simulate" => {
            let run = read_json("simulate/summary.json")?;
            (run["mode"] == "equilibrium" && run["converged"] == false)
                .then(|| "simulate: the relaxation did not converge".to_string())
        }
        "fit" => (read_json("fit/result.json")?["converged"] == false)
            .then(|| "fit: the optimiser stopped on its budget, not converged".to_string()),
        "series" => {
            let series = read_json("series/series.json")?;
            let frames = series["frames"].as_array()?;
            let bad: Vec<String> = frames
                .iter()
                .filter(|f| f["succeeded"] != true)
                .map(|f| f["frame"].as_u64().map_or("?".to_string(), |k| k.to_string()))
                .collect();
            (!bad.is_empty())
                .then(|| format!("series: frame(s) {} failed, did not converge or are a poor fit", bad.join(", ")))
        }
        _ => None,
    }
}

fn read_row(sweep: &Sweep, run: &SweepRun, out: &Path) -> ResultRow {
    let dir = run_dir(out, run.index);
    // A run folder another process is writing into is reported as running, not read half-made. The
    // shared lock is held while the folder is read.
    let _lock = if dir.is_dir() {
        match DirLock::shared(&dir) {
            Ok(lock) => Some(lock),
            Err(PipelineError::Locked { .. }) => {
                return ResultRow {
                    index: run.index,
                    status: "running".into(),
                    reason: format!("another tissuefit process is writing into {} (its lock is held)", dir.display()),
                    wall_seconds: None,
                    outputs: vec![None; sweep.columns.len()],
                };
            }
            Err(e) => {
                return ResultRow {
                    index: run.index,
                    status: "failed".into(),
                    reason: e.to_string(),
                    wall_seconds: None,
                    outputs: vec![None; sweep.columns.len()],
                };
            }
        }
    } else {
        None
    };
    let read_json = |file: &str| -> Option<serde_json::Value> {
        serde_json::from_str(&std::fs::read_to_string(dir.join(file)).ok()?).ok()
    };
    let mut row = ResultRow {
        index: run.index,
        status: "complete".into(),
        reason: String::new(),
        wall_seconds: None,
        outputs: Vec::new(),
    };
    let manifest = Manifest::read(&dir);
    if let Ok(text) = std::fs::read_to_string(dir.join(FAILED_FILE)) {
        row.status = "failed".into();
        row.reason = text.trim().to_string();
    } else if let Some(m) = &manifest {
        let has = |s: &str| m.config.get(s).is_some_and(|v| !v.is_null());
        // With a [series] its stage maps the frames in place of the fit stage.
        let series = has("series");
        let expected = ["mesh", "measure"]
            .into_iter()
            .chain(["simulate", "fit", "series"].into_iter().filter(|s| has(s) && !(*s == "fit" && series)));
        let mut notes = Vec::new();
        for name in expected {
            match m.stage(name) {
                // Read from the outputs, not the stage's note (a skipped stage's note says "reused").
                Some(s) if s.status.done() => {
                    if let Some(note) = unconverged(name, &read_json) {
                        notes.push(note);
                    }
                }
                Some(s) if s.status == super::StageStatus::Failed => {
                    row.status = "failed".into();
                    notes.push(format!("stage {name}: {}", s.note.as_deref().unwrap_or("failed")));
                }
                _ => {
                    if row.status == "complete" {
                        row.status = "incomplete".into();
                    }
                    notes.push(format!("stage {name} not finished"));
                }
            }
        }
        row.reason = notes.join("; ");
    } else {
        row.status = "missing".into();
        row.reason = format!("no {}/manifest.json: not run yet", dir.display());
    }
    if let Some(m) = &manifest {
        row.wall_seconds = Some(m.stages.iter().map(|s| s.ran_seconds).sum());
    }
    let mut cache: std::collections::BTreeMap<&str, Option<serde_json::Value>> = Default::default();
    for c in &sweep.columns {
        let doc = cache.entry(c.file.as_str()).or_insert_with(|| read_json(&c.file));
        row.outputs.push(doc.as_ref().and_then(|d| json_at(d, &c.path)).filter(|v| !v.is_null()).cloned());
    }
    row
}

/// A JSON value as a CSV cell: numbers as Rust prints them (shortest round trip), strings bare,
/// `true`/`false`, others as JSON.
pub fn show_json(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::String(s) => s.clone(),
        serde_json::Value::Number(n) => {
            n.as_f64().map_or(n.to_string(), |f| if n.is_f64() { format!("{f:?}") } else { n.to_string() })
        }
        other => other.to_string(),
    }
}

/// Reads every run directory back into rows (in run order) and writes `DIR/results.csv`:
/// `index, run, <swept keys>, <columns>, status, reason, wall_seconds`. Warns about a column that no
/// complete run has, suggesting the nearest key of that file.
///
/// Holds the sweep folder's lock exclusively while it reads and writes: it refuses to run beside a
/// whole sweep, beside job-array tasks (`--index`, which hold it shared: a table made while they run
/// would be out of date at once) and beside another collection. A run folder whose own lock another
/// process holds (a `tissuefit run` into it) is reported as `running`, not read half-made.
pub fn collect_results(sweep: &Sweep, out: &Path) -> Result<Vec<ResultRow>, PipelineError> {
    let _lock = DirLock::exclusive(out)?;
    // What a collection killed while writing left (the lock proves it has ended).
    crate::io::remove_stale_temporaries_of(out, &["results.csv"])
        .map_err(|e| PipelineError::Io { path: out.to_path_buf(), message: e.to_string() })?;
    let rows: Vec<ResultRow> = sweep.runs.iter().map(|r| read_row(sweep, r, out)).collect();
    for column in &sweep.columns {
        let complete: Vec<&ResultRow> = rows.iter().filter(|r| r.status == "complete").collect();
        let docs = || {
            complete.iter().filter_map(|r| {
                let text = std::fs::read_to_string(run_dir(out, r.index).join(&column.file)).ok()?;
                serde_json::from_str::<serde_json::Value>(&text).ok()
            })
        };
        // Absent (not merely null) in every complete run: most likely a typo.
        let absent = docs().count() > 0 && docs().all(|d| json_at(&d, &column.path).is_none());
        if absent {
            let hint = complete
                .first()
                .and_then(|r| {
                    let doc: serde_json::Value =
                        serde_json::from_str(&std::fs::read_to_string(run_dir(out, r.index).join(&column.file)).ok()?)
                            .ok()?;
                    let (parent, last) = column.path.rsplit_once('.').unwrap_or(("", &column.path));
                    let node = if parent.is_empty() { &doc } else { json_at(&doc, parent)? };
                    let keys: Vec<String> = node.as_object()?.keys().cloned().collect();
                    nearest(last, &keys).map(|n| {
                        format!("; did you mean `{}`?", if parent.is_empty() { n } else { format!("{parent}.{n}") })
                    })
                })
                .unwrap_or_default();
            tracing::warn!("column `{}`: no complete run has this key (empty in results.csv){hint}", column.name());
        }
    }
    let mut w = csv::Writer::from_writer(Vec::new());
    let csv_err = |e: csv::Error| PipelineError::Io { path: out.join("results.csv"), message: e.to_string() };
    let mut header = vec!["index".to_string(), "run".to_string()];
    header.extend(sweep.keys.iter().cloned());
    header.extend(sweep.columns.iter().map(Column::name));
    header.extend(["status", "reason", "wall_seconds"].map(String::from));
    w.write_record(&header).map_err(csv_err)?;
    for (row, run) in rows.iter().zip(&sweep.runs) {
        let mut rec = vec![row.index.to_string(), format!("run-{:04}", row.index)];
        rec.extend(run.values.iter().map(|v| v.as_ref().map_or(String::new(), show_value)));
        rec.extend(row.outputs.iter().map(|v| v.as_ref().map_or(String::new(), show_json)));
        rec.push(row.status.clone());
        rec.push(row.reason.clone());
        rec.push(row.wall_seconds.map_or(String::new(), |s| format!("{s:.3}")));
        w.write_record(&rec).map_err(csv_err)?;
    }
    let bytes =
        w.into_inner().map_err(|e| PipelineError::Io { path: out.join("results.csv"), message: e.to_string() })?;
    let path = out.join("results.csv");
    write_bytes_atomically(&path, &bytes)
        .map_err(|e| PipelineError::Io { path: path.clone(), message: e.to_string() })?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dotted_keys_set_nested_tables_and_list_entries() {
        let mut t: Table = toml::from_str(
            "[mesh]\ntarget_nodes = 200\n[simulate.model_overrides]\ncell_types = [{kind = \"epithelial\"}]\n",
        )
        .unwrap();
        set_key(&mut t, "mesh.target_nodes", Value::Integer(100)).unwrap();
        set_key(&mut t, "measure.include_static", Value::Boolean(true)).unwrap();
        set_key(&mut t, "simulate.model_overrides.cell_types[0].faces.apical.surface_tension", Value::Float(2e-3))
            .unwrap();
        assert_eq!(t["mesh"]["target_nodes"].as_integer(), Some(100));
        assert_eq!(t["measure"]["include_static"].as_bool(), Some(true));
        let ct = &t["simulate"]["model_overrides"]["cell_types"][0];
        assert_eq!(ct["kind"].as_str(), Some("epithelial"));
        assert_eq!(ct["faces"]["apical"]["surface_tension"].as_float(), Some(2e-3));
        let e = set_key(&mut t, "simulate.model_overrides.cell_types[3].kind", Value::Integer(1)).unwrap_err();
        assert!(e.contains("cell_types[3]") && e.contains("1 entries"), "{e}");
        let e = set_key(&mut t, "mesh.target_nodes.x", Value::Integer(1)).unwrap_err();
        assert!(e.contains("`mesh.target_nodes` is integer, not a table"), "{e}");
        assert!(parse_key("mesh..x").is_err() && parse_key("a[x]").is_err());
        // A brace group sets every face type to one value.
        set_key(&mut t, "simulate.model_overrides.cell_types[0].faces.{apical, basal}.adhesion", Value::Float(1e8))
            .unwrap();
        let faces = &t["simulate"]["model_overrides"]["cell_types"][0]["faces"];
        assert_eq!(
            (faces["apical"]["adhesion"].as_float(), faces["basal"]["adhesion"].as_float()),
            (Some(1e8), Some(1e8))
        );
        assert!(faces.get("lateral").is_none());
        assert_eq!(expand_braces("a.{b,c}.{d,e}").unwrap(), ["a.b.d", "a.b.e", "a.c.d", "a.c.e"]);
        for bad in ["a.{b}.c", "a.{b,c.d}", "a.{b,c", "a.b}", "a.{{b,c}}", "a.{b,}"] {
            assert!(expand_braces(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn json_paths_and_cells() {
        let v: serde_json::Value = serde_json::json!({"a": {"b": [1, {"c": 2.5}]}, "n": null, "s": "x"});
        assert_eq!(json_at(&v, "a.b.1.c").map(show_json).as_deref(), Some("2.5"));
        assert_eq!(json_at(&v, "a.b.0").map(show_json).as_deref(), Some("1"));
        assert_eq!(json_at(&v, "s").map(show_json).as_deref(), Some("x"));
        assert!(json_at(&v, "a.c").is_none());
        assert!(
            parse_column("simulate/sumary.json:layers").unwrap_err().contains("did you mean `simulate/summary.json`")
        );
        assert!(parse_column("layers").is_err());
        // The final tissue's morphology is not in the run summary: the column says where it is.
        assert_eq!(parse_column("simulate/summary.json:residual").unwrap().path, "residual");
        assert_eq!(parse_column("simulate/summary.json:reference.converged").unwrap().path, "reference.converged");
        let e = parse_column("simulate/summary.json:mean_sphericity").unwrap_err();
        assert!(e.contains("`simulate/morphology.json:mean_sphericity`"), "{e}");
    }
}
