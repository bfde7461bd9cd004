//! The pipeline file (`tissuefit run PIPELINE.toml`): one section per stage, each reusing the schema of
//! that stage's own config (the fit's [`FitConfig`] sections, the meshing's [`LabelMeshingOptions`], the
//! model's [`Parameters`]). Every table rejects unknown keys; the error names the file, the line and the
//! dotted key, and suggests the nearest valid key (Levenshtein distance). Relative paths resolve
//! against the pipeline file's folder.

use super::PipelineError;
use crate::geometry::Real;
use crate::inference::{FitConfig, ObservedConfig};
use crate::io::{LengthScale, OutputUnit};
use crate::mechanics::{ExplicitNumerics, Parameters};
use crate::meshing::LabelMeshingOptions;
use crate::meshing::{TissueKind, TissueSpec};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The whole pipeline. `[input]` is required; `[mesh]` and `[measure]` always run (defaults when
/// absent); `[simulate]` and `[fit]` run when present.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PipelineConfig {
    /// A named starting point for real data (`compact-embryo`, `epithelium`; `tissuefit
    /// config presets` lists them, `tissuefit config preset NAME` prints one): its `[mesh]`,
    /// `[measure]` and `[fit]` are the base, and this file's keys are laid over them (tables merge,
    /// other values replace; a section's `model = FILE` replaces the preset's model). Default: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// The segmented tissue.
    pub input: InputSection,
    /// Meshing of the label volume (the options of `tissuefit mesh`).
    #[serde(default)]
    pub mesh: LabelMeshingOptions,
    /// Morphology of the meshed tissue (the options of `tissuefit measure`). Default: [`MeasureSection::default`].
    #[serde(default)]
    pub measure: MeasureSection,
    /// A forward relaxation of the meshed tissue at given parameters. Default: absent (not run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simulate: Option<SimulateSection>,
    /// The fit of the model to the observed tissue. Default: absent (not run).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    /// The fit config of `tissuefit fit` without `[observed]`: the observed tissue is `[input]`
    /// meshed with `[mesh]`.
    pub fit: Option<FitConfig>,
    /// A time series: `[input] labels` is its first frame and `frames` the later ones. With it the
    /// fit (`mode = "per_cell"`) maps every frame in order, as `tissuefit fit-series` does, into the
    /// `series/` stage folder instead of fitting one tissue into `fit/`. Default: absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub series: Option<SeriesSection>,
    /// How the run's files for people are written (the length unit). Default: SI.
    #[serde(default, skip_serializing_if = "OutputSection::is_default")]
    pub output: OutputSection,
    /// Known parameters of a synthetic input, printed next to the fitted ones and checked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub demo: Option<DemoSection>,
}

/// `[output]`: one table for what applies to the files of several stages, rather than a key repeated
/// in each stage's section (the stages' own settings stay what `tissuefit mesh`, `measure` and
/// `simulate` take).
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// Length unit of the files written for people: "m" (SI) or "um", as `--output-unit` of `mesh`,
    /// `measure` and `simulate`. With "um" the mesh stage adds `mesh/tissue_um.vtp`, and the measure
    /// and simulate stages write their tables (columns renamed `volume_um3`, `area_um2`,
    /// `centroid_x_um`, …), morphology summaries (`length_unit = "um"`, keys renamed likewise) and
    /// ParaView files (`final.vtp`, frames; the unit recorded in each) in micrometres. The files the
    /// stages read from each other stay in metres: `mesh/tissue.vtp` (read by measure, simulate and
    /// fit), `mesh/report.json`, `simulate/summary.json`, `simulate/final.vtk`. The fit writes
    /// `fit/best.vtp` in this unit; its `residuals.csv` has both units, and its trace, result and
    /// models stay SI. Default "m".
    #[serde(default)]
    pub length_unit: OutputUnit,
}

impl OutputSection {
    fn is_default(&self) -> bool {
        *self == Self::default()
    }

    /// What the output unit adds to the key of a stage whose files it changes: nothing in SI, so
    /// that the keys (and a completed run's skipping) stay as they were without `[output]`.
    pub fn stage_key_text(&self) -> String {
        if self.length_unit.is_si() {
            String::new()
        } else {
            format!("output.length_unit = {:?}\n", self.length_unit.name())
        }
    }
}

/// `[series]`: the later frames of a time series whose first frame is `[input] labels`, mapped in
/// order by the per-cell fit (the options of `tissuefit fit-series`).
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SeriesSection {
    /// The label volumes of the later time points, in time order, on the grid of `input.labels`
    /// (any label format). Relative to the pipeline file. At least one.
    pub frames: Vec<PathBuf>,
    /// The overlap (intersection over union, in (0, 1]) at or above which a cell continues a cell of
    /// the previous frame and keeps its id. Default 0.3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_iou: Option<Real>,
    /// Start every frame from its own direct estimate, without the previous frame's correction.
    /// Default false (each frame's direct estimate times the previous frame's correction).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub cold: bool,
}

/// `[input]`: a label volume (`labels`), an already meshed tissue (`mesh`) or a synthetic tissue
/// (`generate`), exactly one of them.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct InputSection {
    /// Label volume (0 = background), meshed by the mesh stage: a TIFF stack, an OME-Zarr label or
    /// image group (a .zarr folder), an HDF5 dataset (`cells.h5`, or `cells.h5/segmentation` to name
    /// one) or a NumPy .npy array. Relative to the pipeline file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub labels: Option<PathBuf>,
    /// A tissue mesh (.vtp or .vtk) instead of labels: the mesh stage checks it and copies it into
    /// `mesh/tissue.vtp` (SI units), or re-triangulates it (`retriangulate`). Relative to the
    /// pipeline file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<PathBuf>,
    /// With `mesh`: re-triangulate every cell through a voxelisation, as `tissuefit mesh X.vtp` does,
    /// instead of checking and copying the mesh: for meshes from image tools, whose triangles are
    /// too fine, too coarse or uneven for the simulation. `[mesh]` sets the meshing (l_min,
    /// target_nodes, seed…) and `voxel_size` the intermediate grid (default l_min/2). Default false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub retriangulate: bool,
    /// A synthetic tissue made by the mesh stage (the options of `tissuefit generate mesh`), e.g.
    /// `generate = { kind = "vesicle", cells = 24, min_edge_length = 1.6e-6, aspect = 0.9, ecm_room = 2.0 }`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generate: Option<GenerateInput>,
    /// Length unit of the `mesh` file's coordinates (as `--length-unit`: m, mm, um, nm, metres per
    /// unit). Default "m". Only with `mesh`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length_unit: Option<String>,
    /// Voxel size `[z, y, x]` (m) instead of the label file's metadata. Default: the metadata (a .npy
    /// has none: give it here). With `labels`, or with `mesh` and `retriangulate` (the voxelisation's
    /// grid).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub voxel_size: Option<[Real; 3]>,
    /// Nuclei label volume on the grid of `labels` (any label format): each nucleus becomes a nucleus
    /// cell inside the cell holding most of its voxels, as `tissuefit mesh --nuclei`; nuclei outside
    /// every meshed cell are reported as dropped in `mesh/report.json`. Relative to the pipeline
    /// file. Only with `labels`, and not with `[fit]` (the fit's observed tissue has no nuclei).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nuclei: Option<PathBuf>,
    /// OME-Zarr `labels` only: the multiscales scale level to read (0 = full resolution, level N
    /// usually 2^N times coarser in x and y). Default 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub zarr_level: Option<usize>,
    /// The run's seed: the meshing's sampling seed (`mesh.seed`) and the optimiser's
    /// (`fit.optimizer.seed`) unless those sections set their own. Default 0.
    #[serde(default)]
    pub seed: u64,
}

/// `input.generate`: the options of `tissuefit generate mesh`, with its defaults; lengths in metres.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GenerateInput {
    /// sphere, cube, vesicle, sheet, tube or spheroid.
    pub kind: String,
    /// Number of cells. Default: 1 for sphere and cube, 100 for a vesicle, 37 for a sheet, 60 for a tube,
    /// 30 for a spheroid (the paper's Fig. 3a vesicle has 432).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cells: Option<usize>,
    /// Cube root of the mean cell volume, l (m). Default 8e-6.
    #[serde(default = "default_cell_size")]
    pub cell_size: Real,
    /// Minimum edge length l_min of every surface (m). Default: cell_size / 8.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_edge_length: Option<Real>,
    /// Height / width of the columnar cells of a vesicle, sheet or tube. Default 1.5.
    #[serde(default = "default_aspect")]
    pub aspect: Real,
    /// Seed of the cell centres and of the surface sampling. Default: `input.seed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// A nucleus (kind nucleus) inside every epithelial cell. Default false.
    #[serde(default)]
    pub nuclei: bool,
    /// Nucleus radius as a fraction of its cell's equivalent-sphere radius. Default 0.5; only with
    /// `nuclei = true`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nucleus_radius: Option<Real>,
    /// Elongation of each nucleus along its cell's longest principal axis (an ellipsoid of that
    /// semi-axis = this × its radius), ≥ 1. Default 1 (a sphere); only with `nuclei = true`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nucleus_aspect: Option<Real>,
    /// Sheet only: the outer ring of cells is static. Default false.
    #[serde(default)]
    pub static_border: bool,
    /// Tube only: fill the tube with a lumen. Default false.
    #[serde(default)]
    pub lumen: bool,
    /// Vesicle only: room inside the ECM as a multiple of the cells' volume (2: room to double, as in
    /// the paper's Application 1). Default 1.
    #[serde(default = "default_ecm_room")]
    pub ecm_room: Real,
}

fn default_cell_size() -> Real {
    8e-6
}

fn default_aspect() -> Real {
    1.5
}

fn default_ecm_room() -> Real {
    1.0
}

impl GenerateInput {
    /// The generator's specification (`seed` when the table gives none), checked like `generate mesh`
    /// checks its options; the message names the key.
    pub fn spec(&self, seed: u64) -> Result<TissueSpec, String> {
        let kind: TissueKind = self.kind.parse().map_err(|e| format!("input.generate.kind: {e}"))?;
        if self.nucleus_radius.is_some() && !self.nuclei {
            return Err("input.generate.nucleus_radius: applies with `nuclei = true`".into());
        }
        if self.nucleus_aspect.is_some() && !self.nuclei {
            return Err("input.generate.nucleus_aspect: applies with `nuclei = true`".into());
        }
        let spec = TissueSpec {
            kind,
            cells: self.cells.unwrap_or(kind.default_cells()),
            cell_size: self.cell_size,
            l_min: self.min_edge_length.unwrap_or(self.cell_size / 8.0),
            aspect: self.aspect,
            seed: self.seed.unwrap_or(seed),
            nucleus_radius: self.nuclei.then_some(self.nucleus_radius.unwrap_or(0.5)),
            nucleus_aspect: self.nucleus_aspect.unwrap_or(1.0),
            static_border: self.static_border,
            lumen: self.lumen,
            ecm_room: self.ecm_room,
        };
        spec.validate().map_err(|e| format!("input.generate: {e}"))?;
        Ok(spec)
    }
}

/// `[measure]`: the measure stage's own settings ([`crate::stages::measure::MeasureConfig`]).
pub type MeasureSection = crate::stages::measure::MeasureConfig;

/// `[simulate]`: relax the meshed tissue with `model` (+ `model_overrides`), same schema as `simulate --config`.
#[derive(Clone, Debug, Default, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SimulateSection {
    /// Parameter file (TOML). Default: the built-in defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model: Option<PathBuf>,
    /// Keys of the parameter schema given inline, applied on top of `model`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(with = "Option<BTreeMap<String, serde_json::Value>>")]
    pub model_overrides: Option<toml::Table>,
    /// Cell deformation by the nuclei (paper Fig. 4f): when true, the stage also relaxes the same
    /// input tissue with its nuclei removed (same model, same run settings) into `reference.vtp`, and
    /// writes χ = 1 − IoU(cell with nucleus, the same cell without) per cell into `cells.csv`
    /// (`iou`, `chi`) and their mean into `morphology.json` (`mean_chi`), both tissues voxelised on
    /// one grid of voxel `chi_voxel_size`. The reference's steps and convergence go into
    /// `summary.json` (`reference`). An input without nuclei is an error. Default false.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub chi_without_nuclei: bool,
    /// Voxel edge [m] of the χ comparison. Default: numerics.min_edge_length / 4.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chi_voxel_size: Option<Real>,
}

/// `[demo]`: the parameters a synthetic input was made with.
#[derive(Clone, Debug, Deserialize, Serialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DemoSection {
    /// Truth by name: a fitted parameter of `result.json` (`surface_tension_lateral`, …, SI) or a
    /// ratio (`lateral_over_apical`, `adhesion_over_tension`, …).
    pub truth: BTreeMap<String, Real>,
    /// Largest relative error |fit − truth|/truth counted as recovered. Default 0.1.
    #[serde(default = "default_tolerance")]
    pub tolerance: Real,
}

fn default_tolerance() -> Real {
    0.1
}

impl PipelineConfig {
    /// Reads, checks and resolves a pipeline file: relative paths become relative to its folder,
    /// `input.seed` fills the seeds the sections leave out, and the inputs must exist.
    pub fn load(path: &Path) -> Result<Self, PipelineError> {
        let text = crate::io::read_text_capped(path, crate::io::MAX_CONFIG_FILE)
            .map_err(|e| PipelineError::Config(format!("reading {}: {e}", path.display())))?;
        Self::load_text(&text, path)
    }

    /// [`PipelineConfig::load`] of `text` as if it were the file `path` (which need not exist):
    /// relative paths resolve against its folder.
    pub fn load_text(text: &str, path: &Path) -> Result<Self, PipelineError> {
        let mut config = Self::from_toml_str(text, path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        let fix = |p: &mut PathBuf| {
            if p.is_relative() {
                *p = base.join(&*p);
            }
        };
        config.input.labels.as_mut().map(fix);
        config.input.mesh.as_mut().map(fix);
        config.input.nuclei.as_mut().map(fix);
        if let Some(s) = &mut config.simulate {
            s.model.as_mut().map(fix);
        }
        if let Some(f) = &mut config.fit {
            f.model.as_mut().map(fix);
        }
        if let Some(s) = &mut config.series {
            s.frames.iter_mut().for_each(fix);
        }
        let origin = path.display();
        let mut files: Vec<(&str, &Path)> = config.input.source().into_iter().collect();
        if let Some(p) = &config.input.nuclei {
            files.push(("input.nuclei", p.as_path()));
        }
        if let Some(p) = config.simulate.as_ref().and_then(|s| s.model.as_ref()) {
            files.push(("simulate.model", p.as_path()));
        }
        if let Some(p) = config.fit.as_ref().and_then(|f| f.model.as_ref()) {
            files.push(("fit.model", p.as_path()));
        }
        let frame_keys: Vec<String> =
            config.series.iter().flat_map(|s| (0..s.frames.len()).map(|k| format!("series.frames[{k}]"))).collect();
        for (key, file) in frame_keys.iter().zip(config.series.iter().flat_map(|s| &s.frames)) {
            files.push((key.as_str(), file.as_path()));
        }
        for (key, file) in files {
            // An OME-Zarr label input is a folder; an HDF5 one may name a dataset (FILE.h5/DATASET).
            let label_input = matches!(key, "input.labels" | "input.nuclei") || key.starts_with("series.frames");
            let exists =
                file.is_file() || (label_input && (file.is_dir() || crate::imaging::split_hdf5_path(file).is_some()));
            if !exists {
                return Err(PipelineError::Config(format!("{origin}: {key}: {} does not exist", file.display())));
            }
        }
        if config.measure.zarr_properties
            && let Some(labels) = &config.input.labels
        {
            let format = crate::imaging::detect_label_format(labels);
            if format != Some(crate::imaging::LabelFormat::OmeZarr) {
                let what = format.map_or_else(|| "not an OME-Zarr store".to_string(), |f| format!("a {f} file"));
                return Err(PipelineError::Config(format!(
                    "{origin}: measure.zarr_properties: writes the measured cells into an OME-Zarr label image, but \
                     input.labels ({}) is {what}; remove the key (measure/cells.csv holds the same rows)",
                    labels.display()
                )));
            }
        }
        // The model files are only read now that they are known to exist.
        if let Some(s) = &config.simulate {
            s.parameters().map_err(|e| PipelineError::Config(format!("{origin}: simulate: {e}")))?;
        }
        if let Some(f) = &config.fit {
            f.base_parameters().map_err(|e| PipelineError::Config(format!("{origin}: fit: {e}")))?;
        }
        Ok(config)
    }

    /// Parses and checks TOML text (paths as written); `origin` names the file in errors.
    pub fn from_toml_str(text: &str, origin: &Path) -> Result<Self, PipelineError> {
        let mut table: toml::Table = toml::from_str(text).map_err(|e| describe_toml_error(&e, text, origin))?;
        let preset =
            super::preset::apply(&table).map_err(|e| PipelineError::Config(format!("{}: {e}", origin.display())))?;
        let with_preset = preset.as_ref().map(|(p, _)| p.name);
        let config: Self = match preset {
            None => {
                // Parsed from the text first, so that schema errors carry their place in the file…
                toml::from_str::<Self>(text).map_err(|e| describe_toml_error(&e, text, origin))?;
                // …then again with `input.seed` filled in where the sections leave their seeds out.
                inject_seed(&mut table);
                table.try_into().map_err(|e: toml::de::Error| describe_toml_error(&e, text, origin))?
            }
            Some((preset, mut merged)) => {
                // The file laid over its preset: a schema error is found in the merged text and
                // placed back in the file by its dotted key (the preset's own keys are valid).
                inject_seed(&mut merged);
                let merged_text = toml::to_string(&merged).map_err(|e| {
                    PipelineError::Config(format!("{}: preset `{}`: {e}", origin.display(), preset.name))
                })?;
                toml::from_str(&merged_text).map_err(|e: toml::de::Error| {
                    let key = e.span().and_then(|span| key_at(&merged_text, span.start));
                    let line = key.as_deref().and_then(|k| line_of_key(text, k));
                    let place = line.map_or(String::new(), |l| format!(":{l}"));
                    let key = key.map_or(String::new(), |k| format!(" key `{k}`:"));
                    PipelineError::Config(format!(
                        "{}{place} (with preset `{}`):{key} {}",
                        origin.display(),
                        preset.name,
                        schema_message(&e)
                    ))
                })?
            }
        };
        config.check().map_err(|e| match with_preset {
            Some(name) => PipelineError::Config(format!("{} with preset `{name}`: {e}", origin.display())),
            None => PipelineError::Config(format!("{}: {e}", origin.display())),
        })?;
        Ok(config)
    }

    /// Consistency checks beyond the schema; the message names the key.
    fn check(&self) -> Result<(), String> {
        self.input.check()?;
        if self.mesh.target_nodes < 4 {
            return Err(format!("mesh.target_nodes: need at least 4; got {}", self.mesh.target_nodes));
        }
        if let Some(l) = self.mesh.l_min
            && !(l.is_finite() && l > 0.0)
        {
            return Err(format!("mesh.l_min: must be a length > 0 (m); got {l}"));
        }
        if let Some(v) = self.mesh.denoise_voxels
            && !(v.is_finite() && (0.0..=crate::meshing::MAX_DENOISE_VOXELS).contains(&v))
        {
            return Err(format!(
                "mesh.denoise_voxels: must lie in [0, {}] (σ in voxels; about 2 for masks whose boundaries are off \
                 by a voxel); got {v}",
                crate::meshing::MAX_DENOISE_VOXELS
            ));
        }
        if let Some(v) = self.simulate.as_ref().and_then(|s| s.chi_voxel_size)
            && !(v.is_finite() && v > 0.0)
        {
            return Err(format!("simulate.chi_voxel_size: must be a length > 0 (m); got {v}"));
        }
        if let Some(v) = self.input.voxel_size
            && !v.iter().all(|s| s.is_finite() && *s > 0.0)
        {
            return Err(format!("input.voxel_size: three sizes > 0 (m, z,y,x); got {v:?}"));
        }
        // A bare number is metres: 0.235 meant as µm is refused with a hint.
        for (key, l) in self
            .input
            .voxel_size
            .iter()
            .flatten()
            .map(|&l| ("input.voxel_size", l))
            .chain(self.mesh.l_min.map(|l| ("mesh.l_min", l)))
        {
            if let Some(bad) = crate::io::implausible_length(key, l) {
                return Err(bad);
            }
        }
        if self.measure.zarr_properties && self.input.labels.is_none() {
            return Err("measure.zarr_properties: writes the measured cells into the OME-Zarr label image \
                        `input.labels`, and this pipeline has none; remove the key"
                .into());
        }
        let f = self.measure.exterior_free_fraction;
        if !(0.0..=1.0).contains(&f) {
            return Err(format!("measure.exterior_free_fraction: must lie in [0, 1]; got {f}"));
        }
        if let Some(d) = self.measure.contact_distance
            && !(d.is_finite() && d > 0.0)
        {
            return Err(format!("measure.contact_distance: must be a length > 0 (m); got {d}"));
        }
        if let Some(fit) = &self.fit {
            if self.input.nuclei.is_some() {
                return Err(
                    "input.nuclei: the fit's observed tissue and simulations have no nuclei yet; fit in a pipeline \
                            without `input.nuclei`"
                        .into(),
                );
            }
            if fit.observed.is_some() {
                return Err(
                    "fit.observed: the pipeline's observed tissue is [input] meshed with [mesh]; remove [fit.observed]"
                        .into(),
                );
            }
            fit.check_settings().map_err(|e| format!("fit.{e}"))?;
            if self.input.generate.is_some() {
                return Err("fit: a generated input has no observed data to fit; run the pipeline once and fit its \
                            mesh/tissue.vtp as `input.mesh`"
                    .into());
            }
            if fit.objective.shape > 0.0 && self.input.mesh.is_some() {
                return Err("fit.objective.shape: the shape term compares voxels and needs `input.labels`".into());
            }
        }
        if let Some(series) = &self.series {
            series.check(self)?;
        }
        if let Some(demo) = &self.demo {
            if self.series.is_some() {
                return Err("demo: the truth is compared with a fit of one tissue; a [series] maps every frame \
                            (compare series/series_interfaces.csv with your truths instead)"
                    .into());
            }
            if self.fit.is_none() {
                return Err("demo: the truth is compared with a fit; add a [fit] section".into());
            }
            if !(demo.tolerance.is_finite() && demo.tolerance > 0.0) {
                return Err(format!("demo.tolerance: must be > 0; got {}", demo.tolerance));
            }
            for (name, v) in &demo.truth {
                if !(v.is_finite() && *v > 0.0) {
                    return Err(format!("demo.truth.{name}: must be > 0; got {v}"));
                }
                // A truth the fit's ranges cannot reach contradicts them: the fit could never recover it.
                if let Some(([lo, hi], keys)) = self.fit.as_ref().and_then(|f| f.reachable(name))
                    && !(*v >= lo * (1.0 - 1e-12) && *v <= hi * (1.0 + 1e-12))
                {
                    let keys: Vec<String> = keys.iter().map(|k| format!("fit.{k}")).collect();
                    return Err(format!(
                        "demo.truth.{name} = {v} contradicts {}: they allow {name} only in [{lo:e}, {hi:e}]; widen \
                         the bounds or correct the truth",
                        keys.join(" and ")
                    ));
                }
            }
        }
        Ok(())
    }

    /// The resolved config as TOML (defaults filled in, paths resolved).
    pub fn to_toml_string(&self) -> Result<String, PipelineError> {
        toml::to_string(self).map_err(|e| PipelineError::Config(format!("writing the resolved config: {e}")))
    }
}

impl SeriesSection {
    /// The series' frames in order: `input.labels`, then `frames`.
    pub fn all_frames<'a>(&'a self, input: &'a InputSection) -> impl Iterator<Item = &'a Path> {
        input.labels.as_deref().into_iter().chain(self.frames.iter().map(PathBuf::as_path))
    }

    fn check(&self, pipeline: &PipelineConfig) -> Result<(), String> {
        if pipeline.input.labels.is_none() {
            return Err("series: a time series is label volumes; its first frame is `input.labels` (this pipeline's \
                        input is a mesh or a generated tissue)"
                .into());
        }
        if self.frames.is_empty() {
            return Err("series.frames: give the later frames' label volumes in time order (at least one; \
                        `input.labels` is the first)"
                .into());
        }
        match &pipeline.fit {
            None => {
                return Err("series: the frames are mapped by the per-cell fit: add a [fit] section with \
                            `mode = \"per_cell\"`"
                    .into());
            }
            Some(f) if f.mode != crate::inference::FitMode::PerCell => {
                return Err("series: a time series is mapped by the per-cell fit: set `mode = \"per_cell\"` in [fit] \
                            (a global fit of each frame is a pipeline per frame, or a sweep over input.labels)"
                    .into());
            }
            Some(_) => {}
        }
        if let Some(v) = self.min_iou
            && !(v > 0.0 && v <= 1.0)
        {
            return Err(format!("series.min_iou: give a value in (0, 1]; got {v}"));
        }
        Ok(())
    }
}

impl SimulateSection {
    /// The model: `model` (or the defaults) with `model_overrides` applied, validated; and which
    /// mesh-dependent numerics they set (the stage derives the others from the tissue).
    pub fn parameters(&self) -> Result<(Parameters, ExplicitNumerics), PipelineError> {
        let origin = self.origin();
        let (params, explicit) =
            Parameters::load_with_overrides_explicit(self.model.as_deref(), self.model_overrides.as_ref())
                .map_err(|e| PipelineError::Config(e.to_string()))?;
        for w in params.validate().map_err(|e| PipelineError::Config(format!("{origin}: {e}")))? {
            tracing::warn!("{origin}: {w}");
        }
        Ok((params, explicit))
    }

    /// Where the model comes from, for messages.
    pub fn origin(&self) -> String {
        match &self.model {
            Some(p) => format!("model {} + model_overrides", p.display()),
            None => "model_overrides".to_string(),
        }
    }
}

impl InputSection {
    /// The input file and its key: `("input.labels", labels)` or `("input.mesh", mesh)`; `None` for a
    /// generated input.
    pub fn source(&self) -> Option<(&'static str, &Path)> {
        match (&self.labels, &self.mesh) {
            (Some(l), _) => Some(("input.labels", l)),
            (None, Some(m)) => Some(("input.mesh", m)),
            (None, None) => None,
        }
    }

    /// The generator's specification of a `generate` input (checked), `None` for a file input.
    pub fn generate_spec(&self) -> Result<Option<TissueSpec>, String> {
        self.generate.as_ref().map(|g| g.spec(self.seed)).transpose()
    }

    /// How the mesh and fit stages read the `labels` input.
    pub fn read_options(&self) -> crate::imaging::LabelReadOptions {
        crate::imaging::LabelReadOptions {
            voxel_size: self.voxel_size,
            zarr_level: self.zarr_level,
            ..Default::default()
        }
    }

    /// The length scale of a `mesh` input (metres when `length_unit` is absent).
    pub fn length_scale(&self) -> Result<LengthScale, String> {
        self.length_unit.as_deref().unwrap_or("m").parse().map_err(|e: String| format!("input.length_unit: {e}"))
    }

    /// Exactly one input, with only the options that apply to it; the message names the key.
    fn check(&self) -> Result<(), String> {
        const ONE_OF: &str = "`labels` (a label TIFF), `mesh` (a .vtp/.vtk tissue) or `generate` (a synthetic tissue, \
                              the options of `tissuefit generate mesh`)";
        let given = [self.labels.is_some(), self.mesh.is_some(), self.generate.is_some()];
        match given.iter().filter(|g| **g).count() {
            0 => return Err(format!("input: give {ONE_OF}")),
            1 => {}
            _ => return Err(format!("input: give one of {ONE_OF}, not several")),
        }
        if self.retriangulate && self.mesh.is_none() {
            return Err("input.retriangulate: applies to a `mesh` input (labels are meshed anyway)".into());
        }
        if self.nuclei.is_some() && self.labels.is_none() {
            return Err("input.nuclei: applies to a `labels` input (the nuclei are meshed on its grid)".into());
        }
        if self.generate.is_some() {
            if self.length_unit.is_some() || self.voxel_size.is_some() || self.zarr_level.is_some() {
                return Err("input: `length_unit`, `voxel_size` and `zarr_level` apply to file inputs; `generate` is \
                            in metres"
                    .into());
            }
            self.generate_spec()?;
            return Ok(());
        }
        match (&self.labels, &self.mesh) {
            // Exactly one input, checked above.
            (Some(_), Some(_)) | (None, None) => {}
            (Some(_), None) => {
                if self.length_unit.is_some() {
                    return Err("input.length_unit: applies to a `mesh` input; a label TIFF has a voxel size".into());
                }
            }
            (None, Some(m)) => {
                if self.voxel_size.is_some() && !self.retriangulate {
                    return Err("input.voxel_size: applies to a `labels` input, or to a `mesh` with \
                                `retriangulate = true` (the grid it is voxelised on)"
                        .into());
                }
                if self.zarr_level.is_some() {
                    return Err("input.zarr_level: applies to an OME-Zarr `labels` input, not to a mesh".into());
                }
                let ext = m.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
                if !matches!(ext.as_deref(), Some("vtp" | "vtk")) {
                    return Err(format!("input.mesh: {}: expected a .vtp or .vtk tissue file", m.display()));
                }
                self.length_scale()?;
            }
        }
        Ok(())
    }
}

/// The `tissuefit fit` config of a pipeline's `[fit]`: observed = the input labels meshed like
/// `[mesh]`, or the input mesh.
pub fn fit_config(fit: &FitConfig, input: &InputSection, mesh: &LabelMeshingOptions) -> FitConfig {
    FitConfig {
        observed: Some(ObservedConfig {
            tissue: input.mesh.clone(),
            labels: input.labels.clone(),
            length_unit: input.length_unit.clone().unwrap_or_else(|| "m".to_string()),
            retriangulate: input.retriangulate,
            voxel_size: input.voxel_size,
            zarr_level: input.zarr_level,
            meshing: mesh.clone(),
        }),
        ..fit.clone()
    }
}

/// Whether `path` is a pipeline file rather than a stage's own config: a TOML file with an `[input]`
/// table (neither the model's nor the fit's schema has one). Unreadable or non-TOML files are not;
/// their own loader reports why.
pub fn is_pipeline_file(path: &Path) -> bool {
    crate::io::read_text_capped(path, crate::io::MAX_CONFIG_FILE)
        .is_ok_and(|text| toml::from_str::<toml::Table>(&text).is_ok_and(|t| t.contains_key("input")))
}

/// `input.seed` becomes `mesh.seed` and `fit.optimizer.seed` where those are not given.
fn inject_seed(table: &mut toml::Table) {
    let Some(seed) = table.get("input").and_then(|i| i.get("seed")).cloned() else { return };
    if let Some(toml::Value::Table(mesh)) = table.get_mut("mesh") {
        mesh.entry("seed").or_insert(seed.clone());
    } else if !table.contains_key("mesh") {
        let mut mesh = toml::Table::new();
        mesh.insert("seed".into(), seed.clone());
        table.insert("mesh".into(), toml::Value::Table(mesh));
    }
    if let Some(toml::Value::Table(fit)) = table.get_mut("fit") {
        match fit.get_mut("optimizer") {
            Some(toml::Value::Table(opt)) => {
                opt.entry("seed").or_insert(seed);
            }
            None => {
                let mut opt = toml::Table::new();
                opt.insert("seed".into(), seed);
                fit.insert("optimizer".into(), toml::Value::Table(opt));
            }
            Some(_) => {}
        }
    }
}

/// A TOML or schema error as `FILE:LINE: key `a.b`: message`, with the nearest valid key for an
/// unknown one.
fn describe_toml_error(e: &toml::de::Error, text: &str, origin: &Path) -> PipelineError {
    let message = e.message().trim().to_string();
    let location = e.span().map(|span| {
        let line = text[..span.start.min(text.len())].matches('\n').count() + 1;
        (line, key_at(text, span.start))
    });
    let suggestion =
        unknown_field(&message).map_or(String::new(), |(field, expected)| match nearest(&field, &expected) {
            Some(best) => format!("; did you mean `{best}`?"),
            None => String::new(),
        });
    let text = match location {
        Some((line, Some(key))) => format!("{}:{line}: key `{key}`: {message}{suggestion}", origin.display()),
        Some((line, None)) => format!("{}:{line}: {message}{suggestion}", origin.display()),
        None => format!("{}: {message}{suggestion}", origin.display()),
    };
    PipelineError::Config(text)
}

/// A TOML or schema error's message (without its place) and, for an unknown key, the nearest valid one.
pub(crate) fn schema_message(e: &toml::de::Error) -> String {
    let message = e.message().trim().to_string();
    match unknown_field(&message).and_then(|(field, expected)| nearest(&field, &expected)) {
        Some(best) => format!("{message}; did you mean `{best}`?"),
        None => message,
    }
}

/// The first line (1-based) of `text` whose dotted key ([`key_at`]) is `key`.
fn line_of_key(text: &str, key: &str) -> Option<usize> {
    let mut start = 0;
    for (i, line) in text.split_inclusive('\n').enumerate() {
        if key_at(text, start).as_deref() == Some(key) && !line.trim().is_empty() {
            return Some(i + 1);
        }
        start += line.len();
    }
    None
}

/// The dotted key of the `key = value` line holding byte `at` (its `[table]` header prepended).
fn key_at(text: &str, at: usize) -> Option<String> {
    let at = at.min(text.len());
    let line_start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let line_end = text[at..].find('\n').map_or(text.len(), |i| at + i);
    let line = text[line_start..line_end].trim();
    let header = text[..line_start]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .map(|l| l.trim_matches(|c| c == '[' || c == ']').trim().to_string());
    if line.starts_with('[') {
        return Some(line.trim_matches(|c| c == '[' || c == ']').trim().to_string());
    }
    let key = line.split('=').next()?.trim().trim_matches('"');
    if key.is_empty() {
        return header;
    }
    Some(match header {
        Some(h) => format!("{h}.{key}"),
        None => key.to_string(),
    })
}

/// From serde's "unknown field `x`, expected one of `a`, `b`" (or "expected `a`"): x and the choices.
fn unknown_field(message: &str) -> Option<(String, Vec<String>)> {
    let rest = message.strip_prefix("unknown field `")?;
    let (field, rest) = rest.split_once('`')?;
    let expected: Vec<String> = rest.split('`').skip(1).step_by(2).map(str::to_string).collect();
    Some((field.to_string(), expected))
}

/// The valid key closest to `key` by edit distance, if it is close enough to be a plausible typo
/// (at most a third of the key's length, at least 2 edits allowed).
pub fn nearest(key: &str, valid: &[String]) -> Option<String> {
    let limit = (key.chars().count() / 3).max(2);
    valid
        .iter()
        .map(|v| (strsim::levenshtein(key, v), v))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, v)| (*d, v.as_str()))
        .map(|(_, v)| v.clone())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_key_is_suggested_and_far_ones_are_not() {
        let valid: Vec<String> = ["target_nodes", "l_min", "min_voxels"].iter().map(|s| s.to_string()).collect();
        assert_eq!(nearest("target_node", &valid).as_deref(), Some("target_nodes"));
        assert_eq!(nearest("lmin", &valid).as_deref(), Some("l_min"));
        assert_eq!(nearest("completely_else", &valid), None);
    }

    #[test]
    fn an_unknown_key_names_the_table_key_and_suggestion() {
        let text = "[input]\nlabels = \"x.tif\"\n\n[mesh]\ntarget_node = 200\n";
        let e = PipelineConfig::from_toml_str(text, Path::new("p.toml")).unwrap_err().to_string();
        assert!(e.contains("p.toml:5"), "{e}");
        assert!(e.contains("mesh.target_node"), "{e}");
        assert!(e.contains("did you mean `target_nodes`"), "{e}");
    }

    #[test]
    fn a_series_needs_label_frames_and_a_per_cell_fit() {
        let per_cell = "[fit]\nmode = \"per_cell\"\n";
        let parse = |text: &str| PipelineConfig::from_toml_str(text, Path::new("p.toml"));
        let ok = format!("[input]\nlabels = \"t0.tif\"\n[series]\nframes = [\"t1.tif\", \"t2.tif\"]\n{per_cell}");
        let config = parse(&ok).unwrap();
        let series = config.series.as_ref().unwrap();
        let frames: Vec<&Path> = series.all_frames(&config.input).collect();
        assert_eq!(frames, [Path::new("t0.tif"), Path::new("t1.tif"), Path::new("t2.tif")]);
        for (text, key) in [
            ("[input]\nlabels = \"t0.tif\"\n[series]\nframes = [\"t1.tif\"]\n".to_string(), "add a [fit] section"),
            (
                "[input]\nlabels = \"t0.tif\"\n[series]\nframes = [\"t1.tif\"]\n[fit]\nmode = \"global\"\n\
                 [fit.parameters.surface_tension_lateral]\nbounds = [1e-4, 1e-3]\n"
                    .to_string(),
                "set `mode = \"per_cell\"`",
            ),
            (format!("[input]\nlabels = \"t0.tif\"\n[series]\nframes = []\n{per_cell}"), "series.frames"),
            (format!("[input]\nmesh = \"t0.vtp\"\n[series]\nframes = [\"t1.tif\"]\n{per_cell}"), "input.labels"),
            (
                format!("[input]\nlabels = \"t0.tif\"\n[series]\nframes = [\"t1.tif\"]\nmin_iou = 0.0\n{per_cell}"),
                "series.min_iou",
            ),
            (
                format!("[input]\nlabels = \"t0.tif\"\n[series]\nframe = [\"t1.tif\"]\n{per_cell}"),
                "did you mean `frames`",
            ),
            (format!("{ok}[demo]\ntruth = {{ surface_tension_lateral = 1e-3 }}\n"), "demo:"),
        ] {
            let e = parse(&text).unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        }
    }

    #[test]
    fn a_denoising_width_out_of_range_is_refused_naming_the_key() {
        let ok = "[input]\nlabels = \"x.tif\"\n\n[mesh]\ndenoise_voxels = 1.5\n";
        assert_eq!(PipelineConfig::from_toml_str(ok, Path::new("p.toml")).unwrap().mesh.denoise_voxels, Some(1.5));
        for bad in ["-1.0", "nan", "9.0"] {
            let text = format!("[input]\nlabels = \"x.tif\"\n\n[mesh]\ndenoise_voxels = {bad}\n");
            let e = PipelineConfig::from_toml_str(&text, Path::new("p.toml")).unwrap_err().to_string();
            assert!(e.contains("mesh.denoise_voxels"), "{e}");
        }
    }

    #[test]
    fn the_input_seed_fills_the_sections_that_leave_it_out() {
        let text = "[input]\nlabels = \"x.tif\"\nseed = 7\n[fit.parameters.surface_tension]\nbounds = [1e-4, 1e-3]\n";
        let c = PipelineConfig::from_toml_str(text, Path::new("p.toml")).unwrap();
        assert_eq!(c.mesh.seed, 7);
        assert_eq!(c.fit.unwrap().optimizer.seed, 7);
        let text = "[input]\nlabels = \"x.tif\"\nseed = 7\n[mesh]\nseed = 3\n";
        assert_eq!(PipelineConfig::from_toml_str(text, Path::new("p.toml")).unwrap().mesh.seed, 3);
    }
}
