//! The stages, each writing its files into a given (temporary) folder. Data files hold no wall
//! times except where a stage contract asks for them (the fit's `trace.csv`/`result.json`), so that
//! reruns are byte-identical elsewhere; the manifest has every stage's wall time.

use super::PipelineError;
use super::config::{InputSection, MeasureSection, OutputSection, PipelineConfig, SimulateSection};
use crate::geometry::Real;
use crate::mechanics::{Parameters, SimulationMode};
use crate::meshing::LabelMeshingOptions;
use crate::meshing::LabelStatus;
use crate::morphology::Morphology;
use crate::stages::simulate::{Model, SimulateOptions, SimulateOutcome};
use crate::stages::{self, StageError, measure::MeasureOptions, mesh::MeshOptions};
use std::path::Path;

/// Name of the mesh stage's tissue file.
pub const MESH_TISSUE: &str = stages::mesh::TISSUE_FILE;

fn stage_err(stage: &'static str) -> impl Fn(String) -> PipelineError {
    move |message| PipelineError::Stage { stage, message }
}

impl From<StageError> for PipelineError {
    fn from(e: StageError) -> Self {
        PipelineError::Stage { stage: e.stage, message: e.message }
    }
}

/// The mesh stage's options from `[input]` and `[mesh]` (a mesh input's length unit only when it is
/// re-triangulated; otherwise it is checked and copied, not meshed).
pub fn mesh_options(input: &InputSection, mesh: &LabelMeshingOptions) -> Result<MeshOptions, String> {
    let length_unit = if input.mesh.is_some() && input.retriangulate { Some(input.length_scale()?) } else { None };
    Ok(MeshOptions {
        meshing: mesh.clone(),
        voxel_size: input.voxel_size,
        zarr_level: input.zarr_level,
        nuclei: input.nuclei.clone(),
        length_unit,
        // The stage's tissue.vtp is read by the later stages: metres (see [`run_mesh`]).
        output_unit: Default::default(),
    })
}

/// Labels, or a mesh input to re-triangulate → `tissue.vtp` + `report.json` ([`stages::mesh::run`],
/// as `tissuefit mesh`), another mesh input checked and copied, or a generated tissue; `tissue.vtp`
/// in metres (the later stages read it), and with another `[output]` unit a copy in it
/// (`tissue_um.vtp`, the same bytes as `tissuefit mesh --output-unit um` writes). Returns a one-line
/// summary.
pub fn run_mesh(
    input: &InputSection,
    mesh: &LabelMeshingOptions,
    output: &OutputSection,
    out: &Path,
    progress: bool,
) -> Result<String, PipelineError> {
    let line = run_mesh_si(input, mesh, out, progress)?;
    stages::mesh::write_tissue_copy(out, output.length_unit)?;
    Ok(line)
}

fn run_mesh_si(
    input: &InputSection,
    mesh: &LabelMeshingOptions,
    out: &Path,
    progress: bool,
) -> Result<String, PipelineError> {
    let err = stage_err("mesh");
    let path = match (&input.labels, &input.mesh) {
        (Some(labels), _) => labels,
        (None, Some(tissue)) if input.retriangulate => tissue,
        (None, Some(tissue)) => {
            let scale = input.length_scale().map_err(&err)?;
            let unit = input.length_unit.as_deref().unwrap_or("m");
            return Ok(stages::mesh::check_mesh(tissue, scale, unit, out)?);
        }
        (None, None) => {
            let spec = input
                .generate_spec()
                .map_err(&err)?
                .ok_or_else(|| err("[input] has none of `labels`, `mesh`, `generate`".into()))?;
            return Ok(stages::mesh::generate(&spec, out)?);
        }
    };
    let options = mesh_options(input, mesh).map_err(&err)?;
    let outcome =
        stages::mesh::run(path, &options, &out.join(MESH_TISSUE), &out.join(stages::mesh::REPORT_FILE), progress)?;
    let m = &outcome.meshing;
    Ok(format!(
        "{} labels: {} kept, {} static, {} dropped; {} nodes; l_min {:.4} µm",
        m.report.len(),
        m.count(LabelStatus::Kept),
        m.count(LabelStatus::Static),
        m.count(LabelStatus::Dropped),
        m.tissue.node_count(),
        m.l_min.unwrap_or(Real::NAN) * 1e6
    ))
}

/// `2 cells, ⟨Ψ⟩ = …, ⟨φ⟩ = …, ⟨z⟩ = …`: the one-line summary of a measurement.
pub fn describe_morphology(m: &Morphology) -> String {
    let s = &m.summary;
    let opt = |v: Option<Real>| v.map_or("n/a".to_string(), |x| format!("{x:.4}"));
    format!(
        "{} cells, ⟨Ψ⟩ = {}, ⟨φ⟩ = {}, ⟨z⟩ = {}",
        s.cells,
        opt(s.mean_sphericity),
        opt(s.mean_contact_fraction),
        opt(s.mean_coordination)
    )
}

/// The measure stage's options from `[measure]`, `[input]` and `[output]` (a tissue file in metres,
/// as the mesh stage writes, named in `summary.json` relative to the measure folder; with
/// `zarr_properties`, the cells go into the label image `input.labels`).
pub fn measure_options(measure: &MeasureSection, input: &InputSection, output: &OutputSection) -> MeasureOptions {
    MeasureOptions {
        config: measure.clone(),
        input_name: Some(format!("../mesh/{MESH_TISSUE}")),
        output_unit: output.length_unit,
        label_store: if measure.zarr_properties { input.labels.clone() } else { None },
        ..MeasureOptions::default()
    }
}

/// The meshed tissue → `cells.csv`, `contacts.csv`, `summary.json` ([`stages::measure::run`], as
/// `tissuefit measure`) into `out`, the temporary folder of the stage whose final place is
/// `stage_dir` (named by the `zarr_properties` provenance).
pub fn run_measure(
    tissue: &Path,
    config: &PipelineConfig,
    out: &Path,
    stage_dir: &Path,
) -> Result<String, PipelineError> {
    let mut options = measure_options(&config.measure, &config.input, &config.output);
    options.output_name = Some(stage_dir.display().to_string());
    let report = stages::measure::run(tissue, &options, out)?;
    Ok(describe_morphology(&report.morphology))
}

/// The model of `[simulate]` (its file with its overrides), checked alone first: the warnings it
/// raises then were logged when the pipeline was loaded, and the stage does not repeat them.
fn simulate_model(section: &SimulateSection) -> Result<Model, String> {
    let origin = section.origin();
    let (params, explicit) =
        Parameters::load_with_overrides_explicit(section.model.as_deref(), section.model_overrides.as_ref())
            .map_err(|e| e.to_string())?;
    let reported = params.validate().map_err(|e| format!("{origin}: {e}"))?;
    Ok(Model { params, explicit, origin, reported })
}

/// The meshed tissue simulated with the section's model by [`stages::simulate::run`] (as
/// `tissuefit simulate`: the same files, the final tissue measured with `[measure]`), with the
/// nucleus-free reference of `chi_without_nuclei`. Returns the summary line and whether the run
/// reached what it was asked for (an equilibrium run converged; a time run always; no cell passed
/// through another). `force`: replace an earlier run's files in `out`; `resume`: go on from
/// `out/checkpoint.bin` (an interrupted run's periodic checkpoint); `progress`: show the
/// relaxations' progress on stderr.
#[allow(clippy::too_many_arguments)]
pub fn run_simulate(
    tissue: &Path,
    section: &SimulateSection,
    measure: &MeasureSection,
    output: &OutputSection,
    out: &Path,
    force: bool,
    resume: bool,
    progress: bool,
) -> Result<(String, bool), PipelineError> {
    let options = SimulateOptions {
        input_name: Some(format!("../mesh/{MESH_TISSUE}")),
        measure: measure.settings(),
        output_unit: Some(output.length_unit),
        reference: section
            .chi_without_nuclei
            .then_some(stages::simulate::NucleusFreeReference { voxel_size: section.chi_voxel_size }),
        force,
        progress,
        label: Some("simulate".into()),
        ..SimulateOptions::default()
    };
    let outcome = if resume {
        stages::simulate::resume(out, &options, Some(tissue))?
    } else {
        let model = simulate_model(section).map_err(stage_err("simulate"))?;
        stages::simulate::run(tissue, model, &options, out)?
    };
    let report = match outcome {
        SimulateOutcome::Completed(r) => r,
        SimulateOutcome::Interrupted { step } => {
            return Err(stage_err("simulate")(format!("interrupted at step {step}")));
        }
    };
    Ok((describe_simulation(&report), report.summary.reached_goal()))
}

/// The one-line summary of a simulate stage: steps, verdict, residual, the final morphology, the
/// reference, cells that passed through others, and the numerics derived from the mesh.
fn describe_simulation(report: &stages::simulate::SimulateReport) -> String {
    let (s, m) = (&report.summary, &report.morphology);
    let how = if s.mode == SimulationMode::Time {
        format!("{:.3e} s simulated, {} divisions, {} removals", s.simulated_time, s.divisions, s.removals)
    } else {
        s.verdict()
    };
    let layers = m.summary.layers.map_or(String::new(), |n| format!(", {n} layers"));
    let passed = if s.cells_inside_others.is_empty() {
        String::new()
    } else {
        format!(
            "; CELLS PASSED THROUGH EACH OTHER ({} inside another; summary.json, cells_inside_others)",
            s.cells_inside_others.len()
        )
    };
    let fit = &s.mesh_defaults;
    let derived: Vec<String> = fit
        .derived
        .iter()
        .map(|d| {
            let name = d.key.trim_start_matches("numerics.");
            if d.key == "numerics.time_step" {
                format!("{name} {:.3e} s", d.value)
            } else {
                format!("{name} {:.4} µm", d.value * 1e6)
            }
        })
        .collect();
    let derived = if derived.is_empty() {
        String::new()
    } else {
        format!(
            "; from the mesh's mean edge length {:.4} µm: {} (see summary.json, mesh_defaults)",
            fit.mesh_mean_edge.unwrap_or(Real::NAN) * 1e6,
            derived.join(", ")
        )
    };
    let chi = match (&s.reference, m.summary.mean_chi) {
        (Some(r), Some(chi)) => format!(
            "; without nuclei {} steps{}, mean χ {chi:.4}",
            r.steps,
            if r.converged || s.mode == SimulationMode::Time { "" } else { " (NOT converged)" }
        ),
        _ => String::new(),
    };
    format!(
        "{} steps, {how}, residual {:.3e}; final {}{layers}{chi}{passed}{derived}",
        s.steps,
        s.residual,
        describe_morphology(m)
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::inference::FitConfig;
    use crate::io::{LengthScale, ReadOptions, read_tissue};
    use crate::stages::fit::{Observed, run as run_fit};

    fn demo_input() -> InputSection {
        let labels = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/doublet.tif");
        toml::from_str(&format!("labels = {:?}", labels.display().to_string())).unwrap()
    }

    #[test]
    fn the_fit_stage_starts_from_the_mesh_stage_tissue_instead_of_meshing_again() {
        let tmp = tempfile::tempdir().unwrap();
        let mesh_dir = tmp.path().join("mesh");
        let input = demo_input();
        let mesh = LabelMeshingOptions { target_nodes: 60, ..Default::default() };
        let fit: FitConfig = toml::from_str("[parameters.surface_tension_lateral]\nbounds = [2e-4, 1e-3]\n").unwrap();
        let config = super::super::fit_config(&fit, &input, &mesh);
        // Without the mesh stage's outputs the fit stage has nothing to start from, and says which file.
        let e =
            run_fit(&config, Observed::MeshStage(&mesh_dir), &tmp.path().join("fit"), &Default::default()).unwrap_err();
        assert!(e.to_string().contains(&mesh_dir.join(MESH_TISSUE).display().to_string()), "{e}");
        // With them, its observation is that tissue: the fit's meshed labels are the mesh stage's.
        std::fs::create_dir_all(&mesh_dir).unwrap();
        run_mesh(&input, &mesh, &OutputSection::default(), &mesh_dir, false).unwrap();
        let options = ReadOptions { length_scale: LengthScale::default(), orient: false };
        let written = read_tissue(&mesh_dir.join(MESH_TISSUE), &options).unwrap().tissue;
        let observed = crate::inference::load_observation(&config).unwrap();
        assert_eq!(written.node_count(), observed.tissue.node_count());
        for (a, b) in written.cells().iter().zip(observed.tissue.cells()) {
            assert_eq!(a.id(), b.id());
            assert_eq!(a.mesh().positions(), b.mesh().positions(), "tissue.vtp reads back bit for bit");
        }
    }
}
