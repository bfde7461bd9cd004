//! The stages, each writing its files into a given (temporary) folder. Data files hold no wall
//! times except where a stage contract asks for them (the fit's `trace.csv`/`result.json`), so that
//! reruns are byte-identical elsewhere; the manifest has every stage's wall time.

use super::PipelineError;
use super::config::{InputSection, MeasureSection, SimulateSection, fit_config};
use crate::geometry::Real;
use crate::imaging::read_labels;
use crate::inference::{FitConfig, FitOptions, FitResult, MeshingConfig, Observation, run_fit_observed};
use crate::io::{
    LengthScale, OutputGroup, ReadOptions, read_tissue, write_bytes_atomically, write_events, write_simucell3d,
    write_tissue,
};
use crate::mechanics::{MeshFit, Observer, Parameters, RelaxMethod, Sample, Simulation, SimulationMode};
use crate::mesh::{CellKind, Tissue};
use crate::meshing::LabelStatus;
use crate::morphology::{MeasureSettings, Morphology, compare_tissues, measure_tissue};
use crate::stages::{self, StageError, measure::MeasureOptions, mesh::MeshOptions};
use serde::Serialize;
use std::path::Path;

/// Name of the mesh stage's tissue file.
pub const MESH_TISSUE: &str = stages::mesh::TISSUE_FILE;

fn stage_err(stage: &'static str) -> impl Fn(String) -> PipelineError {
    move |message| PipelineError::Stage { stage, message }
}

fn json_bytes<T: Serialize>(value: &T, stage: &'static str) -> Result<Vec<u8>, PipelineError> {
    let mut json = serde_json::to_string_pretty(value).map_err(|e| stage_err(stage)(e.to_string()))?;
    json.push('\n');
    Ok(json.into_bytes())
}

fn write_json<T: Serialize>(path: &Path, value: &T, stage: &'static str) -> Result<(), PipelineError> {
    write_bytes_atomically(path, &json_bytes(value, stage)?).map_err(|e| stage_err(stage)(e.to_string()))
}

impl From<StageError> for PipelineError {
    fn from(e: StageError) -> Self {
        PipelineError::Stage { stage: e.stage, message: e.message }
    }
}

/// The mesh stage's options from `[input]` and `[mesh]`.
pub fn mesh_options(input: &InputSection, mesh: &MeshingConfig) -> Result<MeshOptions, PipelineError> {
    Ok(MeshOptions {
        meshing: mesh.options().map_err(|e| stage_err("mesh")(e.to_string()))?,
        voxel_size: input.voxel_size,
        zarr_level: input.zarr_level,
        nuclei: input.nuclei.clone(),
        length_unit: None,
    })
}

/// Labels → `tissue.vtp` + `report.json` ([`stages::mesh::run`], as `tissuefit mesh`), a mesh input
/// checked and copied, or a generated tissue. Returns a one-line summary.
pub fn run_mesh(
    input: &InputSection,
    mesh: &MeshingConfig,
    out: &Path,
    progress: bool,
) -> Result<String, PipelineError> {
    let err = stage_err("mesh");
    let path = match (&input.labels, &input.mesh) {
        (Some(labels), _) => labels,
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
    let options = mesh_options(input, mesh)?;
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

fn read_meshed(path: &Path, stage: &'static str) -> Result<Tissue, PipelineError> {
    let options = ReadOptions { length_scale: LengthScale::default(), orient: false };
    let read = read_tissue(path, &options).map_err(|e| stage_err(stage)(format!("reading {}: {e}", path.display())))?;
    Ok(read.tissue)
}

/// cells.csv, contacts.csv (headers even without rows) and summary.json, all or nothing
/// ([`OutputGroup`]).
fn write_morphology(out: &Path, m: &Morphology, stage: &'static str) -> Result<(), PipelineError> {
    let err = |e: crate::io::IoError| stage_err(stage)(e.to_string());
    let mut group = OutputGroup::new();
    stages::measure::write_tables(&mut group, out, m).map_err(err)?;
    group.write_bytes(&out.join("summary.json"), &json_bytes(&m.summary, stage)?).map_err(err)?;
    group.commit().map_err(err)
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

fn settings(measure: &MeasureSection) -> MeasureSettings {
    MeasureSettings {
        contact_distance: measure.contact_distance,
        include_static: measure.include_static,
        exterior_free_fraction: measure.exterior_free_fraction,
        interface_labels: !measure.distance_contacts,
    }
}

/// The measure stage's options from `[measure]` (a tissue file in metres, as the mesh stage writes,
/// named in `summary.json` relative to the measure folder).
pub fn measure_options(measure: &MeasureSection) -> MeasureOptions {
    MeasureOptions {
        input_name: Some(format!("../mesh/{MESH_TISSUE}")),
        contact_distance: measure.contact_distance,
        distance_contacts: measure.distance_contacts,
        include_static: measure.include_static,
        exterior_free_fraction: measure.exterior_free_fraction,
        ..MeasureOptions::default()
    }
}

/// The meshed tissue → `cells.csv`, `contacts.csv`, `summary.json` ([`stages::measure::run`], as
/// `tissuefit measure`).
pub fn run_measure(tissue: &Path, measure: &MeasureSection, out: &Path) -> Result<String, PipelineError> {
    let report = stages::measure::run(tissue, &measure_options(measure), out)?;
    Ok(describe_morphology(&report.morphology))
}

/// The stage's observer: no samples, progress on stderr (a bar on a terminal, a line every 30 s
/// otherwise; nothing in a sweep).
struct StageProgress(crate::io::Progress);

impl Observer for StageProgress {
    fn sample(&mut self, _sample: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(())
    }

    fn progress(&mut self, step: u64, residual: Real) {
        self.0.step(step, residual);
    }
}

impl StageProgress {
    fn new(label: String, params: &Parameters, enabled: bool) -> Self {
        Self(crate::io::Progress::of_steps(label, params.planned_steps(), enabled))
    }
}

/// `simulate/simulation.json`: how the run went (no wall time: see the manifest).
#[derive(Serialize)]
struct SimulationRecord<'a> {
    mode: SimulationMode,
    method: RelaxMethod,
    steps: u64,
    force_evaluations: u64,
    converged: bool,
    /// Volume by which cells overlap at the end (m³ and µm³; only penetrations within the contact
    /// cutoff are seen), and the largest overlap of one cell as a fraction of its volume.
    overlap_volume: Real,
    overlap_volume_um3: Real,
    max_overlap_fraction: Real,
    /// Why an equilibrium run did not converge (absent when it did).
    #[serde(skip_serializing_if = "Option::is_none")]
    stop_reason: Option<String>,
    /// The step whose state the files hold, when not the last one (a run that did not converge
    /// ends at its lowest-residual state).
    #[serde(skip_serializing_if = "Option::is_none")]
    ended_at_step: Option<u64>,
    residual: Real,
    simulated_time: Real,
    energy: &'a crate::mechanics::EnergyTerms,
    energy_total: Real,
    /// Cells and nodes at the start and at the end (divisions, removals and remeshing change them).
    cells: usize,
    nodes: usize,
    final_cells: usize,
    final_nodes: usize,
    divisions: u64,
    removals: u64,
    topology: &'a crate::mechanics::TopologyStats,
    /// The relaxation without nuclei of `chi_without_nuclei`.
    #[serde(skip_serializing_if = "Option::is_none")]
    reference: Option<ReferenceRecord>,
    /// The numerics derived from the input mesh (l_min, contact cutoff, time step) where the model
    /// leaves them unset, and the model's values that contradict the mesh.
    mesh_defaults: &'a MeshFit,
    /// Cells whose centre lies inside another cell at the end: they passed through each other.
    cells_inside_others: &'a [crate::mechanics::CellInside],
}

/// How the nucleus-free reference relaxation of `chi_without_nuclei` went.
#[derive(Serialize)]
struct ReferenceRecord {
    steps: u64,
    converged: bool,
    residual: Real,
    /// Bodies removed from the input (the nuclei).
    nuclei_removed: usize,
    /// Voxel edge of the χ comparison (m).
    voxel_size: Real,
}

/// The meshed tissue simulated with the section's model (an equilibrium relaxation or a time run, as
/// `simulation.mode` says) → `final.vtp`, `final.vtk` (SimuCell3D legacy), `simulation.json`,
/// `events.csv`, `config.toml`, and the morphology of the final tissue as the measure stage writes it
/// (`cells.csv`, `contacts.csv`, `summary.json`). Returns the summary line and whether the run
/// reached what it was asked for (an equilibrium run converged; a time run always). `progress`:
/// show the relaxations' progress on stderr.
pub fn run_simulate(
    tissue: &Path,
    section: &SimulateSection,
    measure: &MeasureSection,
    out: &Path,
    progress: bool,
) -> Result<(String, bool), PipelineError> {
    let err = stage_err("simulate");
    let t = read_meshed(tissue, "simulate")?;
    let (params, mesh_defaults) = fit_model_to_mesh(section, &t).map_err(&err)?;
    let (cells, nodes) = (t.len(), t.node_count());
    // The nucleus-free input of `chi_without_nuclei`, taken before the run consumes the tissue.
    let without_nuclei = if section.chi_without_nuclei {
        let kept: Vec<_> = t.cells().iter().filter(|c| c.kind() != CellKind::Nucleus).cloned().collect();
        let removed = t.len() - kept.len();
        if removed == 0 {
            return Err(err(format!(
                "simulate.chi_without_nuclei: {} has no nucleus (cell kind 3) to remove; drop the option or give a \
                 tissue with nuclei (e.g. input.generate with nuclei = true)",
                tissue.display()
            )));
        }
        Some((Tissue::from_cells(kept).map_err(|e| err(e.to_string()))?, removed))
    } else {
        None
    };
    let mut sim = Simulation::new(t, &params).map_err(|e| err(format!("{}: {e}", tissue.display())))?;
    for line in sim.repulsion_shortfalls() {
        tracing::warn!("{line}");
    }
    let mut observer = StageProgress::new("simulate".to_string(), &params, progress);
    let result = sim.run(&mut observer);
    observer.0.finish();
    let summary = result.map_err(|e| err(format!("{}: {e}", tissue.display())))?;
    if let Some(warning) = summary.overlap_warning() {
        tracing::warn!("{warning}");
    }
    write_events(&out.join("events.csv"), sim.events()).map_err(|e| err(e.to_string()))?;
    let final_tissue = sim.into_tissue();
    let inside = crate::mechanics::cells_inside_others(&final_tissue);
    if let Some(warning) = crate::mechanics::passage_warning(&inside) {
        tracing::warn!("{}: {warning}", tissue.display());
    }
    write_tissue(&out.join("final.vtp"), &final_tissue, &[]).map_err(|e| err(e.to_string()))?;
    write_simucell3d(&out.join("final.vtk"), &final_tissue, &[]).map_err(|e| err(e.to_string()))?;
    write_bytes_atomically(&out.join("config.toml"), params.to_toml_string().as_bytes())
        .map_err(|e| err(e.to_string()))?;
    let s = &params.simulation;
    let record = SimulationRecord {
        mode: s.mode,
        method: s.method,
        steps: summary.steps,
        force_evaluations: summary.force_evaluations,
        converged: summary.converged,
        overlap_volume: summary.overlap_volume,
        overlap_volume_um3: summary.overlap_volume * 1e18,
        max_overlap_fraction: summary.max_overlap_fraction,
        stop_reason: summary.stop_reason.clone(),
        ended_at_step: summary.ended_at_step,
        residual: summary.residual,
        simulated_time: summary.time,
        energy: &summary.energy,
        energy_total: summary.energy.total(),
        cells,
        nodes,
        final_cells: final_tissue.len(),
        final_nodes: final_tissue.node_count(),
        divisions: summary.topology.divisions,
        removals: summary.topology.removals,
        topology: &summary.topology,
        reference: None,
        mesh_defaults: &mesh_defaults,
        cells_inside_others: &inside,
    };
    let mut m = measure_tissue(&final_tissue, &settings(measure)).map_err(|e| err(format!("measuring: {e}")))?;
    let mut record = record;
    let mut reference_converged = true;
    if let Some((reference, nuclei_removed)) = without_nuclei {
        let mut rsim = Simulation::new(reference, &params)
            .map_err(|e| err(format!("{} without nuclei: {e}", tissue.display())))?;
        let mut observer = StageProgress::new("simulate (without nuclei)".to_string(), &params, progress);
        let result = rsim.run(&mut observer);
        observer.0.finish();
        let rsummary = result.map_err(|e| err(format!("{} without nuclei: {e}", tissue.display())))?;
        let reference = rsim.into_tissue();
        write_tissue(&out.join("reference.vtp"), &reference, &[]).map_err(|e| err(e.to_string()))?;
        let voxel = section.chi_voxel_size.unwrap_or(params.numerics.min_edge_length / 4.0);
        let overlaps = compare_tissues(&final_tissue, &reference, [voxel; 3])
            .map_err(|e| err(format!("comparing with the nucleus-free reference: {e}")))?;
        m.set_overlap(&overlaps);
        reference_converged = s.mode == SimulationMode::Time || rsummary.converged;
        record.reference = Some(ReferenceRecord {
            steps: rsummary.steps,
            converged: rsummary.converged,
            residual: rsummary.residual,
            nuclei_removed,
            voxel_size: voxel,
        });
    }
    write_json(&out.join("simulation.json"), &record, "simulate")?;
    write_morphology(out, &m, "simulate")?;
    let time_run = s.mode == SimulationMode::Time;
    let how = if time_run {
        format!(
            "{:.3e} s simulated, {} divisions, {} removals",
            summary.time, summary.topology.divisions, summary.topology.removals
        )
    } else if summary.converged {
        "converged".to_string()
    } else {
        format!("NOT converged ({})", summary.stop_reason.as_deref().unwrap_or("no reason recorded"))
    };
    let layers = m.summary.layers.map_or(String::new(), |n| format!(", {n} layers"));
    let passed = if inside.is_empty() {
        String::new()
    } else {
        format!(
            "; CELLS PASSED THROUGH EACH OTHER ({} inside another; simulation.json, cells_inside_others)",
            inside.len()
        )
    };
    let derived: Vec<String> = mesh_defaults
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
            "; from the mesh's mean edge length {:.4} µm: {} (see simulation.json, mesh_defaults)",
            mesh_defaults.mesh_mean_edge.unwrap_or(Real::NAN) * 1e6,
            derived.join(", ")
        )
    };
    let chi = match (&record.reference, m.summary.mean_chi) {
        (Some(r), Some(chi)) => format!(
            "; without nuclei {} steps{}, mean χ {chi:.4}",
            r.steps,
            if reference_converged { "" } else { " (NOT converged)" }
        ),
        _ => String::new(),
    };
    Ok((
        format!(
            "{} steps, {how}, residual {:.3e}; final {}{layers}{chi}{passed}{derived}",
            summary.steps,
            summary.residual,
            describe_morphology(&m)
        ),
        (time_run || summary.converged) && reference_converged && inside.is_empty(),
    ))
}

/// The stage's model with the mesh-dependent numerics it leaves unset derived from the tissue `t`
/// ([`Parameters::fit_to_mesh`]), validated. Logs the warnings of the contradictions, and those of
/// validation that the model alone did not raise (the pipeline's loading logged those).
fn fit_model_to_mesh(section: &SimulateSection, t: &Tissue) -> Result<(Parameters, MeshFit), String> {
    let origin = section.origin();
    let (mut params, explicit) =
        Parameters::load_with_overrides_explicit(section.model.as_deref(), section.model_overrides.as_ref())
            .map_err(|e| e.to_string())?;
    let before = params.validate().map_err(|e| format!("{origin}: {e}"))?;
    let fit = params.fit_to_tissue(&explicit, t);
    for w in &fit.warnings {
        tracing::warn!("{origin}: {w}");
    }
    let after = params.validate().map_err(|e| {
        format!("{origin} with the numerics derived from the input mesh ({}): {e}", fit.lines().join("; "))
    })?;
    for w in after.iter().filter(|w| !before.contains(w)) {
        tracing::warn!("{origin}: {w}");
    }
    Ok((params, fit))
}

/// The fit of `tissuefit fit` with observed = the input labels meshed like `[mesh]`. The meshed
/// tissue is the mesh stage's `tissue.vtp` (and its `report.json`'s l_min) in `mesh_dir`, read back
/// bit for bit instead of meshing the labels again; the labels are still read, to measure the
/// simulations like the data. `resume`: go on from `out/trace.csv` (an interrupted fit's).
pub fn run_fit_stage(
    input: &InputSection,
    mesh: &MeshingConfig,
    fit: &FitConfig,
    mesh_dir: &Path,
    out: &Path,
    resume: bool,
    progress: bool,
) -> Result<FitResult, PipelineError> {
    let err = stage_err("fit");
    let config = fit_config(fit, input, mesh);
    let tissue = read_meshed(&mesh_dir.join(MESH_TISSUE), "fit")?;
    let l_min =
        stages::mesh::read_report_l_min(&mesh_dir.join(stages::mesh::REPORT_FILE)).map_err(|e| err(e.message))?;
    let observation = match &input.labels {
        Some(path) => {
            let read = read_labels(path, &input.read_options())
                .map_err(|e| err(format!("reading {}: {e}", path.display())))?;
            let mut options = mesh.options().map_err(|e| err(e.to_string()))?;
            // Simulations are measured like the data: the meshing's options with the l_min it used.
            options.l_min = l_min;
            Observation::new(tissue, Some(read.volume), Some(options))
        }
        // A mesh input: the observation is the tissue alone, as `tissuefit fit` with `observed.tissue`.
        None => Observation::new(tissue, None, None),
    }
    .map_err(|e| err(e.to_string()))?;
    run_fit_observed(&config, Some(observation), out, &FitOptions { resume, progress, plots: true })
        .map_err(|e| err(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn demo_input() -> InputSection {
        let labels = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/demo/doublet.tif");
        toml::from_str(&format!("labels = {:?}", labels.display().to_string())).unwrap()
    }

    #[test]
    fn the_fit_stage_starts_from_the_mesh_stage_tissue_instead_of_meshing_again() {
        let tmp = tempfile::tempdir().unwrap();
        let mesh_dir = tmp.path().join("mesh");
        let input = demo_input();
        let mesh = MeshingConfig { target_nodes: 60, ..Default::default() };
        let fit: FitConfig = toml::from_str("[parameters.surface_tension_lateral]\nbounds = [2e-4, 1e-3]\n").unwrap();
        // Without the mesh stage's outputs the fit stage has nothing to start from, and says which file.
        let e = run_fit_stage(&input, &mesh, &fit, &mesh_dir, &tmp.path().join("fit"), false, false).unwrap_err();
        assert!(e.to_string().contains(&mesh_dir.join(MESH_TISSUE).display().to_string()), "{e}");
        // With them, its observation is that tissue: the fit's meshed labels are the mesh stage's.
        std::fs::create_dir_all(&mesh_dir).unwrap();
        run_mesh(&input, &mesh, &mesh_dir, false).unwrap();
        let written = read_meshed(&mesh_dir.join(MESH_TISSUE), "test").unwrap();
        let observed = crate::inference::load_observation(&fit_config(&fit, &input, &mesh)).unwrap();
        assert_eq!(written.node_count(), observed.tissue.node_count());
        for (a, b) in written.cells().iter().zip(observed.tissue.cells()) {
            assert_eq!(a.id(), b.id());
            assert_eq!(a.mesh().positions(), b.mesh().positions(), "tissue.vtp reads back bit for bit");
        }
    }
}
