//! The stages, each writing its files into a given (temporary) folder. Data files hold no wall
//! times except where a stage contract asks for them (`summary.json` of simulate, the fit's
//! `trace.csv`/`result.json`), so that reruns are byte-identical elsewhere.

use super::PipelineError;
use super::config::{InputSection, MeasureSection, SimulateSection, fit_config};
use crate::geometry::Real;
use crate::imaging::{LabelReadOptions, read_label_tiff};
use crate::inference::{FitConfig, FitOptions, FitResult, MeshingConfig, Observation, run_fit_observed};
use crate::io::{LengthScale, ReadOptions, read_tissue, write_bytes_atomically, write_simucell3d, write_tissue};
use crate::mechanics::{Observer, Sample, Simulation, SimulationSummary};
use crate::mesh::Tissue;
use crate::meshing::{LabelReport, LabelStatus, mesh_labels};
use crate::morphology::{MeasureSettings, Morphology, measure_tissue};
use serde::Serialize;
use std::path::Path;

/// Name of the mesh stage's tissue file.
pub const MESH_TISSUE: &str = "tissue.vtp";

fn stage_err(stage: &'static str) -> impl Fn(String) -> PipelineError {
    move |message| PipelineError::Stage { stage, message }
}

fn write_json<T: Serialize>(path: &Path, value: &T, stage: &'static str) -> Result<(), PipelineError> {
    let mut json = serde_json::to_string_pretty(value).map_err(|e| stage_err(stage)(e.to_string()))?;
    json.push('\n');
    write_bytes_atomically(path, json.as_bytes()).map_err(|e| stage_err(stage)(e.to_string()))
}

fn write_csv<T: Serialize>(path: &Path, rows: &[T], stage: &'static str) -> Result<(), PipelineError> {
    let err = stage_err(stage);
    let mut w = csv::Writer::from_writer(Vec::new());
    for row in rows {
        w.serialize(row).map_err(|e| err(format!("{}: {e}", path.display())))?;
    }
    let bytes = w.into_inner().map_err(|e| err(format!("{}: {e}", path.display())))?;
    write_bytes_atomically(path, &bytes).map_err(|e| err(e.to_string()))
}

/// `mesh/report.json`: the per-label report of `tissuefit mesh` without wall time.
#[derive(Serialize)]
struct MeshReport<'a> {
    input: &'a Path,
    /// m; `null` when no label was meshed.
    l_min: Option<Real>,
    voxel_size: [Real; 3],
    shape: [usize; 3],
    seed: u64,
    kept: usize,
    #[serde(rename = "static")]
    static_cells: usize,
    dropped: usize,
    cells: &'a [LabelReport],
}

/// Labels → `tissue.vtp` + `report.json`. Returns a one-line summary.
pub fn run_mesh(input: &InputSection, mesh: &MeshingConfig, out: &Path) -> Result<String, PipelineError> {
    let err = stage_err("mesh");
    let path = &input.labels;
    let read = read_label_tiff(path, &LabelReadOptions { voxel_size: input.voxel_size, ..Default::default() })
        .map_err(|e| err(format!("reading {}: {e}", path.display())))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", path.display());
    }
    let options = mesh.options().map_err(|e| err(e.to_string()))?;
    let meshing = mesh_labels(&read.volume, &options).map_err(|e| err(format!("meshing {}: {e}", path.display())))?;
    let (kept, static_cells, dropped) =
        (meshing.count(LabelStatus::Kept), meshing.count(LabelStatus::Static), meshing.count(LabelStatus::Dropped));
    if meshing.tissue.is_empty() {
        return Err(err(format!("{}: all {dropped} labels were dropped; no cell to go on with", path.display())));
    }
    write_tissue(&out.join(MESH_TISSUE), &meshing.tissue, &[]).map_err(|e| err(e.to_string()))?;
    let grid = read.volume.grid();
    let report = MeshReport {
        input: path,
        l_min: meshing.l_min,
        voxel_size: grid.voxel_size,
        shape: grid.shape,
        seed: options.seed,
        kept,
        static_cells,
        dropped,
        cells: &meshing.report,
    };
    write_json(&out.join("report.json"), &report, "mesh")?;
    Ok(format!(
        "{} labels: {kept} kept, {static_cells} static, {dropped} dropped; {} nodes; l_min {:.4} µm",
        meshing.report.len(),
        meshing.tissue.node_count(),
        meshing.l_min.unwrap_or(Real::NAN) * 1e6
    ))
}

fn read_meshed(path: &Path, stage: &'static str) -> Result<Tissue, PipelineError> {
    let options = ReadOptions { length_scale: LengthScale::default(), orient: false };
    let read = read_tissue(path, &options).map_err(|e| stage_err(stage)(format!("reading {}: {e}", path.display())))?;
    Ok(read.tissue)
}

fn write_morphology(out: &Path, m: &Morphology, stage: &'static str) -> Result<(), PipelineError> {
    write_csv(&out.join("cells.csv"), &m.cells, stage)?;
    write_csv(&out.join("contacts.csv"), &m.contacts, stage)?;
    write_json(&out.join("summary.json"), &m.summary, stage)
}

fn describe(m: &Morphology) -> String {
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
    }
}

/// The meshed tissue → `cells.csv`, `contacts.csv`, `summary.json`.
pub fn run_measure(tissue: &Path, measure: &MeasureSection, out: &Path) -> Result<String, PipelineError> {
    let t = read_meshed(tissue, "measure")?;
    let m = measure_tissue(&t, &settings(measure))
        .map_err(|e| stage_err("measure")(format!("measuring {}: {e}", tissue.display())))?;
    write_morphology(out, &m, "measure")?;
    Ok(describe(&m))
}

struct Quiet;

impl Observer for Quiet {
    fn sample(&mut self, _sample: &Sample<'_>) -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        Ok(())
    }
}

#[derive(Serialize)]
struct SimulateSummary<'a> {
    #[serde(flatten)]
    run: &'a SimulationSummary,
    cells: usize,
    nodes: usize,
    wall_seconds: f64,
}

/// The meshed tissue relaxed with the section's model → `final.vtk`, `summary.json`, `config.toml`,
/// and the morphology of the final state (`cells.csv`, `contacts.csv`, `morphology.json`).
pub fn run_simulate(
    tissue: &Path,
    section: &SimulateSection,
    measure: &MeasureSection,
    out: &Path,
) -> Result<(String, bool), PipelineError> {
    let err = stage_err("simulate");
    let params = section.parameters().map_err(|e| err(e.to_string()))?;
    let t = read_meshed(tissue, "simulate")?;
    let (cells, nodes) = (t.len(), t.node_count());
    let mut sim = Simulation::new(t, &params).map_err(|e| err(format!("{}: {e}", tissue.display())))?;
    let started = std::time::Instant::now();
    let summary = sim.run(&mut Quiet).map_err(|e| err(format!("{}: {e}", tissue.display())))?;
    let wall_seconds = started.elapsed().as_secs_f64();
    let final_tissue = sim.into_tissue();
    write_simucell3d(&out.join("final.vtk"), &final_tissue, &[]).map_err(|e| err(e.to_string()))?;
    write_bytes_atomically(&out.join("config.toml"), params.to_toml_string().as_bytes())
        .map_err(|e| err(e.to_string()))?;
    write_json(&out.join("summary.json"), &SimulateSummary { run: &summary, cells, nodes, wall_seconds }, "simulate")?;
    let m = measure_tissue(&final_tissue, &settings(measure)).map_err(|e| err(format!("measuring: {e}")))?;
    write_csv(&out.join("cells.csv"), &m.cells, "simulate")?;
    write_csv(&out.join("contacts.csv"), &m.contacts, "simulate")?;
    write_json(&out.join("morphology.json"), &m.summary, "simulate")?;
    Ok((
        format!(
            "{} steps, {}, residual {:.3e}; final {}",
            summary.steps,
            if summary.converged { "converged" } else { "NOT converged" },
            summary.residual,
            describe(&m)
        ),
        summary.converged,
    ))
}

/// The fit of `tissuefit fit` with observed = the input labels meshed like `[mesh]`. The meshed
/// tissue is the mesh stage's `tissue.vtp` (and its `report.json`'s l_min) in `mesh_dir`, read back
/// bit for bit instead of meshing the labels again; the labels are still read, to measure the
/// simulations like the data.
pub fn run_fit_stage(
    input: &InputSection,
    mesh: &MeshingConfig,
    fit: &FitConfig,
    mesh_dir: &Path,
    out: &Path,
    progress: bool,
) -> Result<FitResult, PipelineError> {
    let err = stage_err("fit");
    let config = fit_config(fit, input, mesh);
    let tissue = read_meshed(&mesh_dir.join(MESH_TISSUE), "fit")?;
    let report_path = mesh_dir.join("report.json");
    let report: serde_json::Value = std::fs::read_to_string(&report_path)
        .map_err(|e| e.to_string())
        .and_then(|t| serde_json::from_str(&t).map_err(|e| e.to_string()))
        .map_err(|e| err(format!("reading {}: {e}", report_path.display())))?;
    let path = &input.labels;
    let read = read_label_tiff(path, &LabelReadOptions { voxel_size: input.voxel_size, ..Default::default() })
        .map_err(|e| err(format!("reading {}: {e}", path.display())))?;
    let mut options = mesh.options().map_err(|e| err(e.to_string()))?;
    // Simulations are measured like the data: the meshing's options with the l_min it used.
    options.l_min = report["l_min"].as_f64();
    let observation = Observation::new(tissue, Some(read.volume), Some(options)).map_err(|e| err(e.to_string()))?;
    run_fit_observed(&config, Some(observation), out, &FitOptions { resume: false, progress, plots: true })
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
        let e = run_fit_stage(&input, &mesh, &fit, &mesh_dir, &tmp.path().join("fit"), false).unwrap_err();
        assert!(e.to_string().contains(&mesh_dir.join(MESH_TISSUE).display().to_string()), "{e}");
        // With them, its observation is that tissue: the fit's meshed labels are the mesh stage's.
        std::fs::create_dir_all(&mesh_dir).unwrap();
        run_mesh(&input, &mesh, &mesh_dir).unwrap();
        let written = read_meshed(&mesh_dir.join(MESH_TISSUE), "test").unwrap();
        let observed = crate::inference::load_observation(&fit_config(&fit, &input, &mesh)).unwrap();
        assert_eq!(written.node_count(), observed.tissue.node_count());
        for (a, b) in written.cells().iter().zip(observed.tissue.cells()) {
            assert_eq!(a.id(), b.id());
            assert_eq!(a.mesh().positions(), b.mesh().positions(), "tissue.vtp reads back bit for bit");
        }
    }
}
