//! The measure stage: morphology of a tissue mesh, or of a label volume measured on its voxels, into
//! `cells.csv`, `contacts.csv` and `summary.json` (SI units, or µm with the output unit: see
//! [`super::output_unit`]), all or nothing. With a comparison
//! input, every cell also gets its IoU and χ = 1 − IoU against the same label of the other input.
//! `tissuefit measure` and the pipeline's `[measure]` both run [`run`].
//!
//! `zarr_properties` (`--zarr-properties`) also writes every measured cell's row into the OME-Zarr
//! label image's NGFF `image-label.properties` (see `crate::imaging`'s `zarr_properties.rs` for the
//! merge rule and the provenance): the keys are the `cells.csv` columns in µm (`volume_um3`, as with
//! the µm output unit, whatever the files' unit), `cell` becoming `label-value`. The store is
//! checked to be writable before measuring and written last, after the three files: when that last
//! write fails the folder holds a complete measurement and the store is unchanged.

use super::{StageError, output_unit, write_csv, write_csv_renamed, write_json};
use crate::geometry::Real;
use crate::imaging::{
    ImagingError, LabelFormat, LabelOverlap, LabelProperties, LabelReadOptions, LabelVolume, PropertiesTarget,
    detect_label_format, is_label_volume, label_overlap, properties_target, read_labels, utc_now,
    write_label_properties,
};
use crate::io::{OutputGroup, OutputUnit, ReadOptions, read_tissue};
use crate::mesh::{CellKind, Tissue};
use crate::meshing::{BorderPolicy, DEFAULT_MIN_VOXELS};
use crate::morphology::{
    CellMorphology, ContactMorphology, ContactRule, DEFAULT_EXTERIOR_FREE_FRACTION, DroppedLabel, LabelMeasureSettings,
    MeasureSettings, Morphology, compare_shapes, compare_tissues, mean_edge_length, measure_labels, measure_tissue,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What the stage writes into its folder.
pub const OUTPUT_FILES: [&str; 3] = ["cells.csv", "contacts.csv", "summary.json"];

/// Bytes per voxel that measuring a label volume needs besides the volume itself (4 bytes per voxel):
/// the dense relabelled copy (4), label statistics and the per-label smoothed fields (~5); about 13
/// in all. The label reader checks the total against the memory limit before decoding.
const MEASURE_WORK_BYTES_PER_VOXEL: u64 = 9;

/// Options of a label-volume input (ignored for a tissue mesh).
#[derive(Clone, Debug)]
pub struct LabelInputOptions {
    /// Voxel size `[z, y, x]` (m) overriding the file's metadata.
    pub voxel_size: Option<[Real; 3]>,
    /// OME-Zarr: the multiscales level to read.
    pub zarr_level: Option<usize>,
    /// Labels touching the image border: kept, static or dropped.
    pub border: BorderPolicy,
    /// Lumen bodies (for the layer count).
    pub lumen_labels: Vec<u32>,
    /// Labels with fewer voxels are debris and dropped.
    pub min_voxels: u64,
    /// σ of the normal smoothing (m); default 2 × the largest voxel size.
    pub normal_smoothing: Option<Real>,
}

impl Default for LabelInputOptions {
    fn default() -> Self {
        Self {
            voxel_size: None,
            zarr_level: None,
            border: BorderPolicy::Keep,
            lumen_labels: Vec::new(),
            min_voxels: DEFAULT_MIN_VOXELS,
            normal_smoothing: None,
        }
    }
}

impl LabelInputOptions {
    /// Whether any option differs from its default (they apply to label volumes only).
    pub fn any_set(&self) -> bool {
        self.voxel_size.is_some()
            || self.zarr_level.is_some()
            || self.border != BorderPolicy::Keep
            || !self.lumen_labels.is_empty()
            || self.min_voxels != DEFAULT_MIN_VOXELS
            || self.normal_smoothing.is_some()
    }
}

/// How a tissue is measured: the pipeline's `[measure]` as written (its fields' docs are the
/// configuration reference's), the flags of `tissuefit measure`, and how the simulate stage
/// measures its final tissue.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize, JsonSchema, clap::Args)]
#[serde(deny_unknown_fields)]
pub struct MeasureConfig {
    /// Contact distance δ: a face whose centroid lies within δ of another cell's surface is in contact
    /// with it (m in a file; on the command line a length with unit, 0.1um). Default: 0.25 × the
    /// tissue's mean edge length. Not used for the contacts of a multi-material mesh, whose faces
    /// name the cells on both sides (see `distance_contacts`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[arg(long, value_name = "LENGTH", value_parser = crate::io::parse_length)]
    pub contact_distance: Option<Real>,
    /// Find contacts by the contact distance δ even when the tissue's faces carry interface labels (a
    /// multi-material mesh: label1/label2, or a .vtp with `interface_label`), whose contacts are
    /// otherwise read from the labels: exact areas and rims.
    #[serde(default)]
    #[arg(long)]
    pub distance_contacts: bool,
    /// Count static cells in the tissue statistics (they are left out by default).
    #[serde(default)]
    #[arg(long)]
    pub include_static: bool,
    /// Without an ECM body, a cell faces the exterior (for the layer count) when at least this
    /// fraction of its surface is free.
    #[serde(default = "default_exterior_free_fraction")]
    #[arg(long, value_name = "FRACTION", default_value_t = DEFAULT_EXTERIOR_FREE_FRACTION)]
    pub exterior_free_fraction: Real,
    /// OME-Zarr label input only: after the other outputs, also write every measured cell's row into
    /// the label image's NGFF `image-label.properties` (`{"label-value": 3, "volume_um3": …}`: the
    /// cells.csv columns, always in µm and named so), which napari-ome-zarr shows as the Labels
    /// layer's features, with a `tissuefit` provenance object beside. Entries of other labels, and
    /// other keys, are kept; a re-run replaces our keys. In a pipeline the label image is
    /// `input.labels` (an error for any other input). Default false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    #[arg(long)]
    pub zarr_properties: bool,
}

fn default_exterior_free_fraction() -> Real {
    DEFAULT_EXTERIOR_FREE_FRACTION
}

impl Default for MeasureConfig {
    fn default() -> Self {
        Self {
            contact_distance: None,
            distance_contacts: false,
            include_static: false,
            exterior_free_fraction: DEFAULT_EXTERIOR_FREE_FRACTION,
            zarr_properties: false,
        }
    }
}

impl MeasureConfig {
    /// The measurement of a tissue mesh with these settings.
    pub fn settings(&self) -> MeasureSettings {
        MeasureSettings {
            contact_distance: self.contact_distance,
            include_static: self.include_static,
            exterior_free_fraction: self.exterior_free_fraction,
            interface_labels: !self.distance_contacts,
        }
    }
}

/// The stage's options: its settings plus how the input is read, compared and named.
#[derive(Clone, Debug, Default)]
pub struct MeasureOptions {
    pub config: MeasureConfig,
    /// How a tissue file is read (length unit, re-orientation).
    pub read: ReadOptions,
    /// Label-volume inputs only.
    pub labels: LabelInputOptions,
    /// Compare shapes with this tissue or label volume (cells matched by id = label).
    pub compare: Option<PathBuf>,
    /// Voxel size of the common grid when both inputs are tissues; default half the mean edge length.
    pub compare_voxel_size: Option<[Real; 3]>,
    /// How `summary.json` names the input (`file`); default the path as given. The pipeline names
    /// its mesh stage's tissue relative to the measure folder (`../mesh/tissue.vtp`), so that a run
    /// directory's files do not depend on where it lies.
    pub input_name: Option<String>,
    /// Length unit of the written tables and summary (default SI; see [`super::output_unit`]).
    pub output_unit: OutputUnit,
    /// The OME-Zarr label image `zarr_properties` writes into; default the input itself. The
    /// pipeline gives its `input.labels`, whose meshed tissue the stage measures.
    pub label_store: Option<PathBuf>,
    /// How the `zarr_properties` provenance names the output folder; default `out` as given. The
    /// pipeline gives its measure folder, not the temporary one the stage is written into.
    pub output_name: Option<String>,
}

/// What [`run`] measured.
pub struct MeasureReport {
    pub morphology: Morphology,
    /// Seconds spent measuring (and comparing), reading excluded.
    pub wall_seconds: f64,
}

/// `summary.json`: the tissue statistics and how they were made.
#[derive(Serialize)]
struct SummaryFile<'a> {
    file: String,
    /// `tissue` (a mesh) or `labels` (a label volume measured on its voxels).
    input: &'static str,
    /// Seconds spent measuring (and comparing), reading excluded.
    wall_seconds: f64,
    threads: usize,
    /// Label volumes: σ of the normal smoothing (m), and the labels left out as debris or border.
    #[serde(skip_serializing_if = "Option::is_none")]
    normal_smoothing: Option<Real>,
    #[serde(skip_serializing_if = "Option::is_none")]
    dropped_labels: Option<&'a [DroppedLabel]>,
    /// The file compared with and how many labels were compared.
    #[serde(skip_serializing_if = "Option::is_none")]
    compare: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    compared_cells: Option<usize>,
    #[serde(flatten)]
    summary: &'a crate::morphology::MorphologySummary,
}

/// Whether `path` is a label volume rather than a tissue mesh: a .vtk/.vtp is a tissue; anything else
/// is a label volume when its content or extension says so ([`is_label_volume`]).
pub fn is_labels(path: &Path) -> bool {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    !matches!(ext.as_deref(), Some("vtk" | "vtp")) && is_label_volume(path)
}

/// A measured or compared input.
enum Input {
    Tissue(Tissue),
    Labels(LabelVolume),
}

fn err(message: String) -> StageError {
    StageError::new("measure", message)
}

fn read_input(path: &Path, options: &MeasureOptions) -> Result<Input, StageError> {
    if is_labels(path) {
        let read_options = LabelReadOptions {
            voxel_size: options.labels.voxel_size,
            work_bytes_per_voxel: MEASURE_WORK_BYTES_PER_VOXEL,
            zarr_level: options.labels.zarr_level,
            ..Default::default()
        };
        let read = read_labels(path, &read_options)
            .map_err(|e| err(format!("reading label volume {}: {e}", path.display())))?;
        for w in &read.warnings {
            tracing::warn!("{}: {w}", path.display());
        }
        Ok(Input::Labels(read.volume))
    } else {
        let read = read_tissue(path, &options.read).map_err(|e| err(format!("{}: {e}", reading_tissue(path))))?;
        for w in &read.warnings {
            tracing::warn!("{}: {w}", path.display());
        }
        Ok(Input::Tissue(read.tissue))
    }
}

/// Context for a failed tissue read where a label volume was also possible: names the label formats
/// too when the extension did not say "tissue".
pub fn reading_tissue(path: &Path) -> String {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("vtk" | "vtp") => format!("reading {}", path.display()),
        _ => format!(
            "reading {} (not a label volume either: those are {})",
            path.display(),
            crate::imaging::SUPPORTED_FORMATS
        ),
    }
}

/// Measures `input` (a tissue file or a label volume) into the folder `out` (made when missing, only
/// once the measurement succeeded):
/// `cells.csv`, `contacts.csv` (a header when nothing touches) and `summary.json`, all or nothing.
///
/// With `zarr_properties`, the label image's metadata is checked to be writable first, and the
/// measured cells are written into it ([`write_zarr_properties`]) once the three files are.
pub fn run(input: &Path, options: &MeasureOptions, out: &Path) -> Result<MeasureReport, StageError> {
    let zarr_target = options.config.zarr_properties.then(|| zarr_properties_target(input, options)).transpose()?;
    let measured = read_input(input, options)?;
    match &measured {
        Input::Tissue(tissue) if crate::morphology::sheet::is_sheet(tissue) => {
            return Err(err(format!(
                "{} is a 2.5-D cell sheet ({} open cell patches of one surface): volumes, sphericity and contact angles \
                 need closed 3-D cells; `tissuefit tensions` maps a sheet's wall tensions",
                input.display(),
                tissue.len()
            )));
        }
        Input::Tissue(_) if options.labels.any_set() => {
            return Err(err(format!(
                "{} is a tissue mesh: --voxel-size, --zarr-level, --border, --lumen-labels, --min-voxels and \
                 --normal-smoothing apply to label volumes",
                input.display()
            )));
        }
        Input::Labels(_) if options.config.contact_distance.is_some() => {
            return Err(err(format!(
                "{} is a label volume: contacts are voxel-face adjacency, --contact-distance applies to meshes",
                input.display()
            )));
        }
        _ => {}
    }
    let other = options.compare.as_deref().map(|p| read_input(p, options)).transpose()?;
    let start = Instant::now();
    let (mut morphology, label_route) = match &measured {
        Input::Tissue(tissue) => {
            let m = measure_tissue(tissue, &options.config.settings())
                .map_err(|e| err(format!("measuring {}: {e}", input.display())))?;
            if m.summary.contact_rule == ContactRule::InterfaceLabels && options.config.contact_distance.is_some() {
                tracing::warn!(
                    "{}: contacts were read from the file's interface labels, so the contact distance only bounds \
                     the rim search; find contacts by distance (--distance-contacts) to use it",
                    input.display()
                );
            }
            (m, None)
        }
        Input::Labels(volume) => {
            let l = &options.labels;
            let settings = LabelMeasureSettings {
                include_static: options.config.include_static,
                exterior_free_fraction: options.config.exterior_free_fraction,
                border: l.border,
                lumen_labels: l.lumen_labels.clone(),
                min_voxels: l.min_voxels,
                normal_smoothing: l.normal_smoothing,
            };
            let m = measure_labels(volume, &settings)
                .map_err(|e| err(format!("measuring {} ({}): {e}", input.display(), volume.describe_grid())))?;
            for label in &l.lumen_labels {
                if !m.morphology.cells.iter().any(|c| c.cell == *label) {
                    tracing::warn!("lumen label {label} is not measured in {}", input.display());
                }
            }
            (m.morphology, Some((m.dropped, m.normal_smoothing)))
        }
    };
    let compared = match (&measured, &other, options.compare.as_deref()) {
        (input_read, Some(other), Some(path)) => {
            let overlaps = compare_inputs(input_read, other, options)
                .map_err(|e| err(format!("comparing {} with {}: {e}", input.display(), path.display())))?;
            morphology.set_overlap(&overlaps);
            Some((path.display().to_string(), overlaps.iter().filter(|o| o.voxels_a > 0 && o.voxels_b > 0).count()))
        }
        _ => None,
    };
    let wall_seconds = start.elapsed().as_secs_f64();
    let inside_out: Vec<String> =
        morphology.cells.iter().filter(|c| c.volume <= 0.0).map(|c| c.cell.to_string()).collect();
    if !inside_out.is_empty() {
        tracing::warn!(
            "{}: cells {} have no positive volume (inside-out or open surfaces; sphericity reads 0); --orient repairs mixed windings",
            input.display(),
            inside_out.join(", ")
        );
    }
    if let Some((dropped, _)) = &label_route {
        for d in dropped {
            tracing::info!("{}: label {} left out: {}", input.display(), d.label, d.reason);
        }
    }
    let summary = SummaryFile {
        file: options.input_name.clone().unwrap_or_else(|| input.display().to_string()),
        input: if label_route.is_some() { "labels" } else { "tissue" },
        wall_seconds,
        threads: rayon::current_num_threads(),
        normal_smoothing: label_route.as_ref().map(|r| r.1),
        dropped_labels: label_route.as_ref().map(|r| r.0.as_slice()),
        compare: compared.as_ref().map(|c| c.0.clone()),
        compared_cells: compared.as_ref().map(|c| c.1),
        summary: &morphology.summary,
    };
    write_outputs(out, &morphology, &summary, options.output_unit)?;
    if let Some(target) = &zarr_target {
        write_zarr_properties(target, &morphology, input, options, out, label_route.is_some()).map_err(|e| {
            err(format!(
                "the measurement is complete in {} ({}), but the cells could not be written into the label image \
                 (--zarr-properties), which is left as it was: {e}",
                out.display(),
                OUTPUT_FILES.join(", ")
            ))
        })?;
    }
    Ok(MeasureReport { morphology, wall_seconds })
}

/// The metadata file `zarr_properties` writes into: the label image of `options.label_store`, or of
/// the input; anything but an OME-Zarr label image, or a read-only one, is refused naming the flag.
fn zarr_properties_target(input: &Path, options: &MeasureOptions) -> Result<PropertiesTarget, StageError> {
    let store = options.label_store.as_deref().unwrap_or(input);
    let what = match detect_label_format(store) {
        Some(LabelFormat::OmeZarr) => None,
        Some(format) => Some(format!("a {format} file")),
        None if !is_labels(store) && store.is_file() => Some("a tissue mesh".to_string()),
        None => Some("not an OME-Zarr store".to_string()),
    };
    if let Some(what) = what {
        return Err(err(format!(
            "--zarr-properties (`zarr_properties`) writes the measured cells into an OME-Zarr label image, but {} is \
             {what}; leave the flag out (cells.csv holds the same rows)",
            store.display()
        )));
    }
    properties_target(store).map_err(|e| err(format!("--zarr-properties (`zarr_properties`): {e}")))
}

/// The `cells.csv` column names as written in µm (`volume_um3`, …), without `cell` (an entry's
/// `label-value`): the keys an entry of `image-label.properties` gets from us.
fn zarr_property_keys() -> Vec<String> {
    let um = OutputUnit::Micrometre;
    match serde_json::to_value(CellMorphology::example()) {
        Ok(Value::Object(map)) => map
            .keys()
            .filter(|k| *k != "cell")
            .map(|k| output_unit::column_name(&output_unit::CELL_LENGTH_COLUMNS, um, k))
            .collect(),
        _ => Vec::new(),
    }
}

/// Every measured cell (not the nuclei a pipeline's mesh adds, whose ids are not labels) as an
/// `image-label.properties` entry: its `cells.csv` row in µm, empty values left out; with a
/// `tissuefit` provenance object (version, time, input, outputs, settings).
fn write_zarr_properties(
    target: &PropertiesTarget,
    m: &Morphology,
    input: &Path,
    options: &MeasureOptions,
    out: &Path,
    labels_input: bool,
) -> Result<(), ImagingError> {
    let um = OutputUnit::Micrometre;
    let cells: Vec<CellMorphology> =
        output_unit::cells_in(&m.cells, um).into_iter().filter(|c| c.kind != CellKind::Nucleus).collect();
    let mut rows = Vec::with_capacity(cells.len());
    for c in &cells {
        let Ok(Value::Object(map)) = serde_json::to_value(c) else {
            return Err(ImagingError::Write {
                path: target.file.clone(),
                message: format!("cell {} does not serialise as an object", c.cell),
            });
        };
        let values = map
            .into_iter()
            .filter(|(k, v)| k != "cell" && !v.is_null())
            .map(|(k, v)| (output_unit::column_name(&output_unit::CELL_LENGTH_COLUMNS, um, &k), v))
            .collect();
        rows.push(LabelProperties { label: c.cell, values });
    }
    let l = &options.labels;
    let mut settings = serde_json::json!({ "measure": options.config });
    if labels_input {
        settings["labels"] = serde_json::json!({
            "voxel_size_m": l.voxel_size,
            "zarr_level": l.zarr_level.unwrap_or(0),
            "border": l.border.to_string(),
            "lumen_labels": l.lumen_labels,
            "min_voxels": l.min_voxels,
            "normal_smoothing_m": l.normal_smoothing,
        });
    }
    let provenance = serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "written": utc_now(),
        "input": options.input_name.clone().unwrap_or_else(|| input.display().to_string()),
        "outputs": options.output_name.clone().unwrap_or_else(|| out.display().to_string()),
        "cells": rows.len(),
        "length_unit": um.name(),
        "settings": settings,
    });
    write_label_properties(target, &rows, &zarr_property_keys(), provenance)
}

/// Per-label overlap of the measured input (`voxels_a`) with the compared one (`voxels_b`).
fn compare_inputs(input: &Input, other: &Input, options: &MeasureOptions) -> Result<Vec<LabelOverlap>, String> {
    let swap = |o: Vec<LabelOverlap>| -> Vec<LabelOverlap> {
        o.into_iter().map(|o| LabelOverlap { voxels_a: o.voxels_b, voxels_b: o.voxels_a, ..o }).collect()
    };
    let e = |e: &dyn std::fmt::Display| e.to_string();
    Ok(match (input, other) {
        (Input::Labels(a), Input::Labels(b)) => label_overlap(a, b).map_err(|x| e(&x))?,
        (Input::Tissue(a), Input::Labels(b)) => swap(compare_shapes(a, b).map_err(|x| e(&x))?),
        (Input::Labels(a), Input::Tissue(b)) => compare_shapes(b, a).map_err(|x| e(&x))?,
        (Input::Tissue(a), Input::Tissue(b)) => {
            let voxel_size = match options.compare_voxel_size {
                Some(v) => v,
                None => match mean_edge_length(a) {
                    Some(h) if h.is_finite() && h > 0.0 => [h / 2.0; 3],
                    _ => {
                        return Err(
                            "cannot derive a comparison grid from the tissue's edges; give --compare-voxel-size".into(),
                        );
                    }
                },
            };
            compare_tissues(a, b, voxel_size).map_err(|x| e(&x))?
        }
    })
}

/// The three files all or nothing ([`OutputGroup`]): a full disk leaves none of them, never two.
fn write_outputs(dir: &Path, m: &Morphology, summary: &SummaryFile<'_>, unit: OutputUnit) -> Result<(), StageError> {
    let io = |e: crate::io::FileError| err(format!("writing the outputs into {}: {e}", dir.display()));
    if m.cells.is_empty() {
        return Err(err(format!("{}: no cell was measured", summary.file)));
    }
    std::fs::create_dir_all(dir).map_err(|e| err(format!("creating {}: {e}", dir.display())))?;
    let mut group = OutputGroup::new();
    write_tables(&mut group, dir, m, unit).map_err(io)?;
    write_summary(&mut group, &dir.join("summary.json"), summary, unit).map_err(io)?;
    group.commit().map_err(io)
}

/// A morphology summary as JSON into `group`, in `unit` ([`output_unit::summary_in`]).
pub fn write_summary<T: Serialize>(
    group: &mut OutputGroup,
    path: &Path,
    summary: &T,
    unit: OutputUnit,
) -> Result<(), crate::io::FileError> {
    if unit.is_si() {
        return write_json(group, path, summary);
    }
    let value = serde_json::to_value(summary)
        .map_err(|e| crate::io::FileError::Write { path: path.to_path_buf(), source: std::io::Error::other(e) })?;
    write_json(group, path, &output_unit::summary_in(value, unit))
}

/// `DIR/cells.csv` and `DIR/contacts.csv` into `group`, each with its header even without rows.
/// Lengths, areas and volumes in `unit`, their columns renamed with it ([`output_unit`]).
pub fn write_tables(
    group: &mut OutputGroup,
    dir: &Path,
    m: &Morphology,
    unit: OutputUnit,
) -> Result<(), crate::io::FileError> {
    if !unit.is_si() {
        let cells = output_unit::cells_in(&m.cells, unit);
        let contacts = output_unit::contacts_in(&m.contacts, unit);
        let cell_example = cells.first().cloned().unwrap_or_else(CellMorphology::example);
        write_csv_renamed(group, &dir.join("cells.csv"), &cells, &cell_example, &|name| {
            output_unit::column_name(&output_unit::CELL_LENGTH_COLUMNS, unit, name)
        })?;
        return write_csv_renamed(group, &dir.join("contacts.csv"), &contacts, &contact_example(), &|name| {
            output_unit::column_name(&output_unit::CONTACT_LENGTH_COLUMNS, unit, name)
        });
    }
    let cell_example = m.cells.first().cloned().unwrap_or_else(CellMorphology::example);
    write_csv(group, &dir.join("cells.csv"), &m.cells, &cell_example)?;
    write_csv(group, &dir.join("contacts.csv"), &m.contacts, &contact_example())
}

/// A row of zeros: its serialisation names the columns of `contacts.csv` when there is no row.
fn contact_example() -> ContactMorphology {
    ContactMorphology {
        cell_a: 0,
        cell_b: 0,
        area: 0.0,
        contact_angle_deg: None,
        kind_a: CellKind::Epithelial,
        kind_b: CellKind::Epithelial,
        area_a: 0.0,
        area_b: 0.0,
        rim_edges: 0,
        far_field_angle_deg: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::imaging::{LabelWriteOptions, write_label_tiff};

    #[test]
    fn label_volumes_are_told_by_content_or_extension() {
        let dir = tempfile::tempdir().unwrap();
        let volume = LabelVolume::new(ndarray::Array3::from_elem((2, 3, 4), 1u32), [1e-6; 3], Vec3::zeros()).unwrap();
        let unnamed = dir.path().join("labels.data");
        write_label_tiff(&unnamed, &volume, &LabelWriteOptions::default()).unwrap();
        assert!(is_labels(&unnamed));
        assert!(is_labels(Path::new("missing.TIF")));
        assert!(is_labels(Path::new("missing.npy")));
        assert!(is_labels(Path::new("missing.zarr")));
        assert!(is_labels(dir.path()), "a folder is an OME-Zarr store");
        let npy = dir.path().join("labels.raw");
        std::fs::write(&npy, b"\x93NUMPY\x01\x00").unwrap();
        assert!(is_labels(&npy));
        let text = dir.path().join("tissue.mesh");
        std::fs::write(&text, "# vtk DataFile Version 4.2\n").unwrap();
        assert!(!is_labels(&text));
        assert!(!is_labels(&dir.path().join("missing")));
        assert!(!is_labels(Path::new("missing.vtp")));
    }
}
