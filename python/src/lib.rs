//! `tissuefit._tissuefit`: the Python extension over tissuefit's stages. The Python layer
//! (`python/tissuefit/__init__.py`) wraps these functions in documented classes; this module converts
//! between numpy arrays and the library's types and runs the library's own stage code:
//!
//! - lengths cross the boundary in micrometres (numpy arrays of `f64`), and are metres inside;
//! - tables and reports cross as JSON text (the same keys as the CLI's files), which the Python
//!   layer turns into dicts and numpy columns;
//! - long calls release the GIL; a [`Watch`] hears their progress, calls the Python callback with it
//!   (at most every 0.2 s, holding the GIL only then), checks for Ctrl-C, and stops the work when the
//!   callback returns `False`, raises, or Ctrl-C was pressed: the call then raises `Cancelled` (or
//!   the callback's exception).

use ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray3};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use tissuefit::geometry::{Real, Vec3};
use tissuefit::imaging::{BorderPolicy, LabelReadOptions, LabelVolume, read_labels as read_label_file};
use tissuefit::inference::{FitConfig, FitOptions, InferenceError};
use tissuefit::io::{LengthScale, OutputUnit, ReadOptions, Watch, read_tissue as read_tissue_file, write_tissue_in};
use tissuefit::meshing::{LabelMeshingError, LabelMeshingOptions, mesh_labels_with_progress};
use tissuefit::morphology::{LabelMeasureSettings, measure_labels, measure_tissue};
use tissuefit::pipeline::PipelineConfig;
use tissuefit::stages;
use tissuefit::stages::measure::MeasureConfig;
use tissuefit::stages::output_unit::{
    CELL_LENGTH_COLUMNS, CONTACT_LENGTH_COLUMNS, cells_in, column_name, contacts_in, summary_in,
};
use tissuefit::stages::simulate::{Model, SimulateOptions, SimulateOutcome};

pyo3::create_exception!(_tissuefit, TissuefitError, PyRuntimeError, "An error of tissuefit, with its message.");
pyo3::create_exception!(
    _tissuefit,
    Cancelled,
    TissuefitError,
    "The call was stopped: the progress callback returned False, or Ctrl-C was pressed."
);

const UM: Real = 1e-6;

fn error(message: impl std::fmt::Display) -> PyErr {
    TissuefitError::new_err(message.to_string())
}

/// A voxel size given in metres by the Python layer (which converts µm, or passes the file's own
/// metres unchanged so that a volume read here meshes bit for bit as the CLI meshes the file).
fn checked_voxel_size(v: [Real; 3]) -> PyResult<[Real; 3]> {
    if v.iter().all(|x| x.is_finite() && *x > 0.0) {
        Ok(v)
    } else {
        Err(error(format!(
            "voxel_size must be three positive finite lengths (z, y, x), got {:?} µm",
            v.map(|x| x / UM)
        )))
    }
}

/// The watch of one call: its Python callback (if any), Ctrl-C, and why it stopped.
struct CallWatch {
    watch: Watch,
    /// The callback's exception, or the KeyboardInterrupt of Ctrl-C, to raise instead of `Cancelled`.
    raised: Arc<Mutex<Option<PyErr>>>,
}

impl CallWatch {
    fn new(callback: Option<Py<PyAny>>) -> Self {
        let raised: Arc<Mutex<Option<PyErr>>> = Arc::new(Mutex::new(None));
        let keep = raised.clone();
        let watch = Watch::new(move |r| {
            Python::attach(|py| {
                let outcome = py.check_signals().and_then(|()| match &callback {
                    Some(cb) => cb
                        .call1(py, (r.label, r.done, r.total, r.message))
                        .map(|v| !v.bind(py).is(pyo3::types::PyBool::new(py, false))),
                    None => Ok(true),
                });
                match outcome {
                    Ok(go_on) => go_on,
                    Err(e) => {
                        if let Ok(mut slot) = keep.lock() {
                            slot.get_or_insert(e);
                        }
                        false
                    }
                }
            })
        });
        Self { watch, raised }
    }

    /// The error of a call that failed with `message`: the callback's exception or `Cancelled` when
    /// the watch stopped it, else `TissuefitError`.
    fn fail(&self, message: impl std::fmt::Display) -> PyErr {
        if let Some(e) = self.raised.lock().ok().and_then(|mut slot| slot.take()) {
            return e;
        }
        if self.watch.stopped() { Cancelled::new_err(message.to_string()) } else { error(message) }
    }
}

/// A tissue: closed triangle surfaces, one per cell (metres inside).
#[pyclass(module = "tissuefit._tissuefit", name = "Tissue", frozen)]
struct PyTissue {
    tissue: tissuefit::mesh::Tissue,
    /// m; the meshing's l_min when meshed from labels.
    l_min: Option<Real>,
    /// The mesh stage's per-label report (JSON list), when meshed from labels.
    report: String,
}

#[pymethods]
impl PyTissue {
    fn __len__(&self) -> usize {
        self.tissue.len()
    }

    /// The meshing's minimum edge length (µm), or None.
    #[getter]
    fn l_min_um(&self) -> Option<Real> {
        self.l_min.map(|l| l / UM)
    }

    /// The per-label report of the meshing (JSON text: label, status, reason, ...).
    #[getter]
    fn report_json(&self) -> String {
        self.report.clone()
    }

    /// One tuple per cell: (id, kind, cell_type, vertices (n, 3) x y z µm, faces (m, 3), volume µm³,
    /// area µm²).
    #[allow(clippy::type_complexity)]
    fn cell_arrays<'py>(
        &self,
        py: Python<'py>,
    ) -> Vec<(u32, &'static str, u32, Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>, f64, f64)> {
        self.tissue
            .cells()
            .iter()
            .map(|c| {
                let mesh = c.mesh();
                let p = mesh.positions();
                let vertices = Array2::from_shape_fn((p.len(), 3), |(i, k)| p[i][k] / UM);
                let t = mesh.triangles();
                let faces = Array2::from_shape_fn((t.len(), 3), |(i, k)| i64::from(t[i][k]));
                (
                    c.id().0,
                    c.kind().name(),
                    c.cell_type(),
                    vertices.into_pyarray(py),
                    faces.into_pyarray(py),
                    mesh.signed_volume() / (UM * UM * UM),
                    mesh.area() / (UM * UM),
                )
            })
            .collect()
    }

    /// Writes the tissue: a .vtp in µm (it records its unit) or metres, or a SimuCell3D .vtk (metres).
    #[pyo3(signature = (path, unit = "um"))]
    fn save(&self, path: PathBuf, unit: &str) -> PyResult<()> {
        let unit: OutputUnit = unit.parse().map_err(error)?;
        write_tissue_in(&path, &self.tissue, &[], unit).map_err(|e| error(format!("writing {}: {e}", path.display())))
    }
}

/// What [`read_labels`] returns.
type ReadLabels<'py> = (Bound<'py, PyArray3<u32>>, [Real; 3], [Real; 3], Vec<String>);

/// Reads a label volume: (labels uint32 [z, y, x], voxel size (z, y, x) m, centre of voxel [0, 0, 0]
/// (x, y, z) m, warnings).
#[pyfunction]
#[pyo3(signature = (path, voxel_size_m = None, zarr_level = None))]
fn read_labels<'py>(
    py: Python<'py>,
    path: PathBuf,
    voxel_size_m: Option<[Real; 3]>,
    zarr_level: Option<usize>,
) -> PyResult<ReadLabels<'py>> {
    let voxel_size = voxel_size_m.map(checked_voxel_size).transpose()?;
    let options = LabelReadOptions { voxel_size, zarr_level, ..Default::default() };
    let read = py
        .detach(|| read_label_file(&path, &options))
        .map_err(|e| error(format!("reading {}: {e}", path.display())))?;
    let voxel = read.volume.voxel_size();
    let o = read.volume.origin();
    Ok((read.volume.into_labels().into_pyarray(py), voxel, [o.x, o.y, o.z], read.warnings))
}

/// A label volume of the Python layer's array, voxel size (m) and origin (x, y, z m; default 0).
fn volume_from(
    labels: PyReadonlyArray3<'_, u32>,
    voxel_size_m: [Real; 3],
    origin_m: Option<[Real; 3]>,
) -> PyResult<LabelVolume> {
    let voxel_size = checked_voxel_size(voxel_size_m)?;
    let labels: Array3<u32> = labels.as_array().to_owned();
    let origin = origin_m.map_or_else(Vec3::zeros, |[x, y, z]| Vec3::new(x, y, z));
    LabelVolume::new(labels, voxel_size, origin).map_err(error)
}

fn border_policy(border: &str) -> PyResult<BorderPolicy> {
    serde_json::from_value(serde_json::Value::String(border.to_string()))
        .map_err(|_| error(format!("border = {border:?}: one of \"keep\", \"static\", \"drop\"")))
}

/// Meshes every label of a volume (`tissuefit mesh`'s meshing).
#[pyfunction]
#[pyo3(signature = (labels, voxel_size_m, origin_m = None, *, seed = 0, target_nodes = None, l_min_um = None, border = "keep", min_voxels = None, denoise_voxels = None, progress = None))]
#[allow(clippy::too_many_arguments)]
fn mesh(
    py: Python<'_>,
    labels: PyReadonlyArray3<'_, u32>,
    voxel_size_m: [Real; 3],
    origin_m: Option<[Real; 3]>,
    seed: u64,
    target_nodes: Option<usize>,
    l_min_um: Option<Real>,
    border: &str,
    min_voxels: Option<u64>,
    denoise_voxels: Option<Real>,
    progress: Option<Py<PyAny>>,
) -> PyResult<PyTissue> {
    let volume = volume_from(labels, voxel_size_m, origin_m)?;
    let mut options =
        LabelMeshingOptions { seed, border: border_policy(border)?, denoise_voxels, ..Default::default() };
    if let Some(n) = target_nodes {
        options.target_nodes = n;
    }
    if let Some(l) = l_min_um {
        if !(l.is_finite() && l > 0.0) {
            return Err(error(format!("l_min must be a positive length in µm, got {l}")));
        }
        options.l_min = Some(l * UM);
    }
    if let Some(n) = min_voxels {
        options.min_voxels = n;
    }
    let call = CallWatch::new(progress);
    let total = volume.label_stats().len() as u64;
    let done = std::sync::atomic::AtomicU64::new(0);
    let watch = call.watch.clone();
    let meshed = py.detach(|| {
        tissuefit::on_pool(|| {
            mesh_labels_with_progress(&volume, &options, &|label| {
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                watch.tick("mesh", n, total, "label", || format!("label {label} meshed"));
                !watch.stopped()
            })
        })
    });
    let meshing = match meshed {
        Ok(m) => m,
        Err(e @ LabelMeshingError::Stopped) => return Err(call.fail(e)),
        Err(e) => return Err(error(format!("meshing the labels ({}): {e}", volume.describe_grid()))),
    };
    if meshing.tissue.is_empty() {
        return Err(error(format!(
            "no cell meshed from the labels ({}): every label was dropped; see the reasons with measure() or \
             `tissuefit mesh`",
            volume.describe_grid()
        )));
    }
    let report = serde_json::to_string(&meshing.report).map_err(error)?;
    Ok(PyTissue { tissue: meshing.tissue, l_min: meshing.l_min, report })
}

/// Reads a tissue file (.vtp, SimuCell3D .vtk, multi-material meshes) whose lengths are in `length_unit`
/// (a .vtp that records its unit is read in it).
#[pyfunction]
#[pyo3(signature = (path, length_unit = None))]
fn read_tissue(py: Python<'_>, path: PathBuf, length_unit: Option<&str>) -> PyResult<PyTissue> {
    let length_scale: LengthScale = match length_unit {
        Some(u) => u.parse().map_err(|e: String| error(format!("length_unit: {e}")))?,
        None => LengthScale::default(),
    };
    let read = py
        .detach(|| read_tissue_file(&path, &ReadOptions { length_scale, orient: false }))
        .map_err(|e| error(format!("reading {}: {e}", path.display())))?;
    Ok(PyTissue { tissue: read.tissue, l_min: None, report: "[]".into() })
}

/// The measured rows and summary in µm, as JSON: {"cells": [...], "contacts": [...], "summary": {...}}.
fn morphology_json(m: &tissuefit::morphology::Morphology) -> PyResult<String> {
    let unit = OutputUnit::Micrometre;
    let rename = |rows: serde_json::Value, table: &[(&str, i32)]| -> serde_json::Value {
        match rows {
            serde_json::Value::Array(rows) => rows
                .into_iter()
                .map(|row| match row {
                    serde_json::Value::Object(map) => {
                        map.into_iter().map(|(k, v)| (column_name(table, unit, &k), v)).collect()
                    }
                    other => other,
                })
                .collect(),
            other => other,
        }
    };
    let cells = rename(serde_json::to_value(cells_in(&m.cells, unit)).map_err(error)?, &CELL_LENGTH_COLUMNS);
    let contacts =
        rename(serde_json::to_value(contacts_in(&m.contacts, unit)).map_err(error)?, &CONTACT_LENGTH_COLUMNS);
    let summary = summary_in(serde_json::to_value(&m.summary).map_err(error)?, unit);
    serde_json::to_string(&serde_json::json!({ "cells": cells, "contacts": contacts, "summary": summary }))
        .map_err(error)
}

/// Measures a tissue as `tissuefit measure` does (default settings), lengths in µm.
#[pyfunction]
fn measure_tissue_json(py: Python<'_>, tissue: &PyTissue) -> PyResult<String> {
    let settings = MeasureConfig::default().settings();
    let m = py
        .detach(|| tissuefit::on_pool(|| measure_tissue(&tissue.tissue, &settings)))
        .map_err(|e| error(format!("measuring: {e}")))?;
    morphology_json(&m)
}

/// Measures a label volume on its voxels as `tissuefit measure LABELS` does, lengths in µm.
#[pyfunction]
#[pyo3(signature = (labels, voxel_size_m, origin_m = None, *, border = "keep", min_voxels = None))]
fn measure_labels_json(
    py: Python<'_>,
    labels: PyReadonlyArray3<'_, u32>,
    voxel_size_m: [Real; 3],
    origin_m: Option<[Real; 3]>,
    border: &str,
    min_voxels: Option<u64>,
) -> PyResult<String> {
    let volume = volume_from(labels, voxel_size_m, origin_m)?;
    let config = MeasureConfig::default();
    let mut settings = LabelMeasureSettings {
        include_static: config.include_static,
        exterior_free_fraction: config.exterior_free_fraction,
        border: border_policy(border)?,
        ..Default::default()
    };
    if let Some(n) = min_voxels {
        settings.min_voxels = n;
    }
    let m = py
        .detach(|| tissuefit::on_pool(|| measure_labels(&volume, &settings)))
        .map_err(|e| error(format!("measuring the labels ({}): {e}", volume.describe_grid())))?;
    morphology_json(&m.morphology)
}

/// TOML text → table, naming `what` in errors.
fn toml_table(text: &str, what: &str) -> PyResult<toml::Table> {
    toml::from_str(text).map_err(|e| error(format!("{what}: {e}")))
}

/// Relaxes a tissue with the simulate stage into `out` (input.vtp, final.vtp, summary.json, ...),
/// returning the final tissue and summary.json's text.
#[pyfunction]
#[pyo3(signature = (tissue, out, *, model = None, overrides = Vec::new(), force = false, progress = None))]
fn simulate(
    py: Python<'_>,
    tissue: &PyTissue,
    out: PathBuf,
    model: Option<PathBuf>,
    overrides: Vec<String>,
    force: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<(PyTissue, String)> {
    // Layers of keys over the model (or the defaults), later ones winning key by key.
    let mut merged: Option<toml::Table> = None;
    for (i, text) in overrides.iter().enumerate() {
        let layer = toml_table(text, &format!("model keys (layer {})", i + 1))?;
        match &mut merged {
            Some(m) => tissuefit::pipeline::preset::merge(m, layer),
            None => merged = Some(layer),
        }
    }
    let overrides = merged;
    let (params, explicit) =
        tissuefit::mechanics::Parameters::load_with_overrides_explicit(model.as_deref(), overrides.as_ref())
            .map_err(error)?;
    let origin = model.as_ref().map_or_else(|| "the model given in Python".to_string(), |p| p.display().to_string());
    let model = Model { params, explicit, origin, reported: Vec::new() };
    std::fs::create_dir_all(&out).map_err(|e| error(format!("creating {}: {e}", out.display())))?;
    // The input is written beside the outputs, so the folder holds the whole run (and
    // `tissuefit simulate out/input.vtp --config out/config.toml` repeats it).
    let input = out.join("input.vtp");
    if input.exists() && !force {
        return Err(error(format!(
            "{} already holds a simulation's input; choose another out or pass force=True",
            out.display()
        )));
    }
    write_tissue_in(&input, &tissue.tissue, &[], OutputUnit::Metre)
        .map_err(|e| error(format!("writing {}: {e}", input.display())))?;
    let call = CallWatch::new(progress);
    let options = SimulateOptions {
        force,
        label: Some("simulate".into()),
        watch: call.watch.clone(),
        input_name: Some("input.vtp".into()),
        ..Default::default()
    };
    let outcome = py
        .detach(|| tissuefit::on_pool(|| stages::simulate::run(&input, model, &options, &out)))
        .map_err(|e| call.fail(e))?;
    match outcome {
        SimulateOutcome::Completed(_) => {}
        SimulateOutcome::Interrupted { step } => {
            return Err(call.fail(format!(
                "the simulation was stopped at step {step}; its checkpoint is in {} (tissuefit simulate --resume {} \
                 goes on)",
                out.display(),
                out.display()
            )));
        }
    }
    let final_path = out.join("final.vtp");
    let read = read_tissue_file(&final_path, &ReadOptions::default())
        .map_err(|e| error(format!("reading {}: {e}", final_path.display())))?;
    let summary = std::fs::read_to_string(out.join("summary.json"))
        .map_err(|e| error(format!("reading {}: {e}", out.join("summary.json").display())))?;
    Ok((PyTissue { tissue: read.tissue, l_min: None, report: "[]".into() }, summary))
}

/// The fit config of TOML text whose relative paths are relative to `base`; `[observed]` may be
/// left out (the observed tissue is given in Python). A pipeline file (it has `[input]`) gives its
/// `[fit]` with `[input]` and `[mesh]` as `tissuefit fit --config PIPELINE` takes it; the second
/// value is then the pipeline's `[output] length_unit` (for `best.vtp`), and `None` for a fit config
/// (a pipeline's `[input]` gives way to an observed tissue given in Python).
fn fit_config(text: &str, base: &Path, origin: &str) -> PyResult<(FitConfig, Option<OutputUnit>)> {
    let table: toml::Table = toml::from_str(text).map_err(|e| error(format!("{origin}: {e}")))?;
    if table.contains_key("input") {
        let name = Path::new(origin).file_name().map_or_else(|| "pipeline.toml".into(), |n| n.to_os_string());
        let pipeline = PipelineConfig::load_text(text, &base.join(name)).map_err(error)?;
        let fit = pipeline
            .fit
            .as_ref()
            .ok_or_else(|| error(format!("{origin}: the pipeline has no [fit] section; add one to fit")))?;
        let config = tissuefit::pipeline::fit_config(fit, &pipeline.input, &pipeline.mesh);
        return Ok((config, Some(pipeline.output.length_unit)));
    }
    let mut config: FitConfig = toml::from_str(text).map_err(|e| error(format!("{origin}: {e}")))?;
    config.check_settings().map_err(|e| error(format!("{origin}: {e}")))?;
    config.resolve_paths(base);
    Ok((config, None))
}

/// Runs the fit stage into `out` on the observed tissue: a label volume (meshed with the config's
/// `[observed.meshing]`), a tissue, or the config's own `[observed]` (both None). Returns
/// result.json's text.
#[pyfunction]
#[pyo3(signature = (config, base, origin, out, *, labels = None, voxel_size_m = None, origin_m = None, tissue = None, resume = false, progress = None))]
#[allow(clippy::too_many_arguments)]
fn fit(
    py: Python<'_>,
    config: &str,
    base: PathBuf,
    origin: &str,
    out: PathBuf,
    labels: Option<PyReadonlyArray3<'_, u32>>,
    voxel_size_m: Option<[Real; 3]>,
    origin_m: Option<[Real; 3]>,
    tissue: Option<&PyTissue>,
    resume: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let (mut config, pipeline_unit) = fit_config(config, &base, origin)?;
    let pipeline = pipeline_unit.is_some();
    let volume = match (labels, voxel_size_m) {
        (Some(l), Some(v)) => Some(volume_from(l, v, origin_m)?),
        (Some(_), None) => return Err(error("labels need their voxel_size (z, y, x) in µm")),
        (None, _) => None,
    };
    let given = volume.is_some() || tissue.is_some();
    if given && let Some(observed) = config.observed.as_mut() {
        if observed.labels.is_some() || observed.tissue.is_some() {
            if !pipeline {
                return Err(error(format!(
                    "{origin}: [observed] names an input file and an observed tissue was given too; give one of them"
                )));
            }
            // A pipeline's [input] gives way to the tissue given here; its [mesh] settings stay.
            observed.labels = None;
            observed.tissue = None;
        }
        // Recorded in the fit's fit.toml, like a labels file's voxel size.
        observed.voxel_size = volume.as_ref().map(|v| v.voxel_size());
    }
    let observed = match (&volume, tissue) {
        (Some(v), None) => stages::fit::Observed::Labels(v),
        (None, Some(t)) => stages::fit::Observed::Tissue(&t.tissue),
        (None, None) => {
            if config.observed.as_ref().is_none_or(|o| o.labels.is_none() && o.tissue.is_none()) {
                return Err(error(format!(
                    "{origin}: no observed tissue: give labels (with voxel_size) or a tissue, or an [observed] \
                     section naming a file"
                )));
            }
            stages::fit::Observed::Config
        }
        (Some(_), Some(_)) => return Err(error("give labels or a tissue to fit, not both")),
    };
    let call = CallWatch::new(progress);
    let options = FitOptions {
        resume,
        progress: false,
        plots: true,
        watch: call.watch.clone(),
        output_unit: pipeline_unit.unwrap_or_default(),
    };
    py.detach(|| tissuefit::on_pool(|| stages::fit::run(&config, observed, &out, &options))).map_err(|e| {
        if call.watch.stopped() {
            call.fail(format!("{}; the fit folder is {}", InferenceError::Stopped, out.display()))
        } else {
            call.fail(e)
        }
    })?;
    let path = out.join(stages::fit::RESULT_FILE);
    std::fs::read_to_string(&path).map_err(|e| error(format!("reading {}: {e}", path.display())))
}

/// Maps a time series in order with the per-cell fit (`tissuefit fit-series`) into `out`: frames
/// as label files (`files`) or arrays (`arrays`, with their voxel size and origin), not both.
/// Returns series.json's text.
#[pyfunction]
#[pyo3(signature = (config, base, origin, out, *, files = Vec::new(), arrays = Vec::new(), voxel_size_m = None, origin_m = None, cold = false, min_iou = None, resume = false, progress = None))]
#[allow(clippy::too_many_arguments)]
fn fit_series(
    py: Python<'_>,
    config: &str,
    base: PathBuf,
    origin: &str,
    out: PathBuf,
    files: Vec<PathBuf>,
    arrays: Vec<PyReadonlyArray3<'_, u32>>,
    voxel_size_m: Option<[Real; 3]>,
    origin_m: Option<[Real; 3]>,
    cold: bool,
    min_iou: Option<Real>,
    resume: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    use stages::fit_series::SeriesFrame;
    let (config, _) = fit_config(config, &base, origin)?;
    let frames: Vec<SeriesFrame> = match (files.is_empty(), arrays.is_empty()) {
        (false, true) => files.into_iter().map(SeriesFrame::File).collect(),
        (true, false) => {
            let Some(v) = voxel_size_m else {
                return Err(error("label arrays need their voxel_size (z, y, x) in µm"));
            };
            arrays
                .into_iter()
                .enumerate()
                .map(|(k, a)| {
                    Ok(SeriesFrame::Labels { name: format!("frames[{k}]"), volume: volume_from(a, v, origin_m)? })
                })
                .collect::<PyResult<_>>()?
        }
        (true, true) => return Err(error("fit_series: no frames; give the label volumes of the series in time order")),
        (false, false) => return Err(error("fit_series: give label files or arrays, not both")),
    };
    let call = CallWatch::new(progress);
    let options = stages::fit_series::SeriesOptions {
        min_iou,
        cold,
        fit: FitOptions { resume, progress: false, plots: true, watch: call.watch.clone(), ..Default::default() },
    };
    py.detach(|| tissuefit::on_pool(|| stages::fit_series::run(&config, &frames, &out, &options))).map_err(|e| {
        if call.watch.stopped() {
            call.fail(format!("{}; the series folder is {}", InferenceError::Stopped, out.display()))
        } else {
            call.fail(e)
        }
    })?;
    let path = out.join("series.json");
    std::fs::read_to_string(&path).map_err(|e| error(format!("reading {}: {e}", path.display())))
}

/// What [`tensions`] returns.
type Tensions<'py> = (Vec<Bound<'py, PyArray1<f64>>>, Bound<'py, PyArray1<f64>>, String);

/// The direct estimate of interface tensions and cell pressures (the tensions stage) into `out`:
/// (per cell in tissue order: its faces' tensions; per cell: its pressure; summary.json's text).
#[pyfunction]
/// `labels` (with its voxel size and origin): the volume `tissue` was meshed from, from which each
/// face's neighbour and the imaged box (which cuts the cells that reach its sides) are read, as
/// `tissuefit tensions` does for a label volume.
#[pyo3(signature = (tissue, out, *, file, kind, gauge = None, gauge_tension = None, one_medium_tension = false, rounding_scale_m = None, labels = None, voxel_size_m = None, origin_m = None, far_field = "auto"))]
#[allow(clippy::too_many_arguments)]
fn tensions<'py>(
    py: Python<'py>,
    tissue: &PyTissue,
    out: PathBuf,
    file: &str,
    kind: &str,
    gauge: Option<(u32, u32)>,
    gauge_tension: Option<Real>,
    one_medium_tension: bool,
    rounding_scale_m: Option<Real>,
    labels: Option<PyReadonlyArray3<'_, u32>>,
    voxel_size_m: Option<[Real; 3]>,
    origin_m: Option<[Real; 3]>,
    far_field: &str,
) -> PyResult<Tensions<'py>> {
    use tissuefit::morphology::tensions::{FarField, FieldOfView, Gauge, TensionSettings};
    let far_field: FarField = far_field.parse().map_err(|e: String| error(format!("tensions: far_field {e}")))?;
    let (labelled, field_of_view) = match (labels, voxel_size_m) {
        (Some(labels), Some(size)) => {
            let volume = volume_from(labels, size, origin_m)?;
            let mut labelled = tissue.tissue.clone();
            tissuefit::meshing::label_interfaces(&mut labelled, &volume).map_err(error)?;
            (Some(labelled), Some(FieldOfView::of_volume(&volume)))
        }
        (None, None) => (None, None),
        _ => return Err(error("tensions: labels and voxel_size_m go together")),
    };
    if let Some(t) = gauge_tension
        && !(t.is_finite() && t > 0.0)
    {
        return Err(error(format!("gauge_tension must be a positive tension in mN/m, got {t}")));
    }
    let settings = TensionSettings {
        one_medium_tension,
        gauge: gauge.map_or(Gauge::MediumMean, |(a, b)| Gauge::Interface(a, b)),
        gauge_value: gauge_tension.unwrap_or(1.0),
        rounding_scale: rounding_scale_m,
        field_of_view,
        far_field,
        ..Default::default()
    };
    let kind = if kind == "labels" { "labels" } else { "tissue" };
    if labelled.is_none() && tissuefit::morphology::sheet::is_sheet(&tissue.tissue) {
        // A 2.5-D sheet: relative line tensions of its walls, in-plane pressures.
        if gauge_tension.is_some() || one_medium_tension {
            return Err(error(format!(
                "tensions: {file} is a 2.5-D cell sheet (open cell patches of one surface): its walls' line tensions \
                 are relative to the gauge; gauge_tension and one_medium_tension apply to 3-D cells"
            )));
        }
        let gauge = settings.gauge;
        let outcome = py
            .detach(|| tissuefit::on_pool(|| stages::tensions::run_sheet(&tissue.tissue, gauge, file, &out)))
            .map_err(error)?;
        let summary = serde_json::to_string(&outcome.summary).map_err(error)?;
        return Ok((
            faces_per_cell(py, &tissue.tissue, &outcome.face_tension),
            outcome.pressure.into_pyarray(py),
            summary,
        ));
    }
    let input = stages::tensions::TensionsInput { file, kind, gauge_in_mn_per_m: gauge_tension.is_some() };
    let estimated = labelled.as_ref().unwrap_or(&tissue.tissue);
    let outcome = py
        .detach(|| tissuefit::on_pool(|| stages::tensions::run(estimated, &settings, &input, &out)))
        .map_err(error)?;
    let summary = serde_json::to_string(&outcome.summary).map_err(error)?;
    Ok((faces_per_cell(py, &tissue.tissue, &outcome.face_tension), outcome.pressure.into_pyarray(py), summary))
}

/// Per-face values of a whole tissue (cell after cell) split into one array per cell.
fn faces_per_cell<'py>(
    py: Python<'py>,
    tissue: &tissuefit::mesh::Tissue,
    values: &[Real],
) -> Vec<Bound<'py, PyArray1<f64>>> {
    let mut faces = Vec::with_capacity(tissue.len());
    let mut at = 0;
    for cell in tissue.cells() {
        let n = cell.mesh().face_count();
        faces.push(values[at..at + n].to_vec().into_pyarray(py));
        at += n;
    }
    faces
}

/// The library's version.
#[pyfunction]
fn version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

#[pymodule]
fn _tissuefit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("TissuefitError", m.py().get_type::<TissuefitError>())?;
    m.add("Cancelled", m.py().get_type::<Cancelled>())?;
    m.add_class::<PyTissue>()?;
    m.add_function(wrap_pyfunction!(read_labels, m)?)?;
    m.add_function(wrap_pyfunction!(mesh, m)?)?;
    m.add_function(wrap_pyfunction!(read_tissue, m)?)?;
    m.add_function(wrap_pyfunction!(measure_tissue_json, m)?)?;
    m.add_function(wrap_pyfunction!(measure_labels_json, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(fit_series, m)?)?;
    m.add_function(wrap_pyfunction!(tensions, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
