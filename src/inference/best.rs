//! The fit's best point as files: `best.vtp` (the relaxed tissue at the best parameters, in the
//! fit's output unit: metres, or µm with the unit recorded so that it reads back in metres),
//! `best.toml` (the whole model at the best parameters, SI like every model file) and
//! `residuals.csv` (observed vs simulated per moving cell; lengths in both units, named so).
//!
//! The trace keeps an evaluation's metrics, not its tissue, so the best point is relaxed once more
//! after the fit, exactly as an evaluation of the fit is ([`ForwardModel::evaluate`]: a cold start
//! from the observed tissue, the same passes); the forward model is deterministic, so this run is the
//! best evaluation again (a resumed fit, whose best point may come from an earlier session's trace,
//! writes the same files). `best.toml` is the base model with the best parameters written in, as the
//! forward model writes them for an evaluation ([`ParameterSpace::apply`](super::ParameterSpace::apply)),
//! with the forward settings the fit runs under (equilibrium mode, `forward.max_steps`, the mesh's
//! l_min), as `model.toml` is the base model.
//!
//! `residuals.csv` compares the cells one by one. Both sides are measured as the fit measures them:
//! the distance rule with the observed contact distance δ; with `forward.measure_like_data` the
//! relaxed tissue is voxelised on the observed grid as it lies (one placement, not averaged over
//! `forward.measure_shifts`) and meshed again with the observed options, as the observed labels were.
//! The observed side is then what `tissuefit measure` reports for the observed tissue (its default
//! δ is the same quarter of the mean edge length).
//!
//! A relaxation at the best point that fails is never skipped in silence: `result.json`'s
//! `best_relaxation` says so (`failed`, `reason`), a warning is logged, the printed summary line
//! starts with it, no `best.vtp` is left in the folder, and `residuals.csv` has empty simulated
//! columns.

use super::InferenceError;
use super::forward::{Evaluation, ForwardModel, Status};
use crate::geometry::Real;
use crate::io::{OutputUnit, write_bytes_atomically, write_tissue_in};
use crate::morphology::{CellMorphology, MeasureSettings, measure_tissue};
use serde::Serialize;
use std::collections::HashMap;
use std::path::Path;

/// The relaxed tissue at the best parameters.
pub const BEST_TISSUE_FILE: &str = "best.vtp";
/// The model at the best parameters (a `tissuefit simulate --config` parameter file).
pub const BEST_MODEL_FILE: &str = "best.toml";
/// Observed vs simulated per-cell measures at the best parameters.
pub const RESIDUALS_FILE: &str = "residuals.csv";

/// `result.json`'s `best_relaxation`: how the relaxation at the best point behind `best.vtp` and
/// `residuals.csv` ended.
#[derive(Clone, Debug, Serialize)]
pub struct BestRelaxation {
    /// True when it failed or ended unusable (then there is no `best.vtp`; see `reason`).
    pub failed: bool,
    /// How it ended, as an evaluation's status (`converged`, `accepted`, `unconverged`, `failed`).
    pub status: Status,
    /// Its objective; the best evaluation's again (the forward model is deterministic).
    pub objective: Real,
    /// Why it failed (empty otherwise).
    pub reason: String,
    pub steps: u64,
    /// Whether `best.vtp` was written.
    pub tissue_written: bool,
}

impl BestRelaxation {
    /// One loud sentence for a failed relaxation (`None` when it did not fail).
    pub fn failure(&self) -> Option<String> {
        self.failed.then(|| {
            format!(
                "the relaxation at the best point ended {} ({}): {}",
                self.status.name(),
                if self.reason.is_empty() { "no reason recorded" } else { &self.reason },
                if self.tissue_written {
                    "best.vtp holds its unusable tissue and residuals.csv its measures"
                } else {
                    "no best.vtp was written and residuals.csv has no simulated values"
                }
            )
        })
    }
}

/// One row of `residuals.csv`: a moving cell of the observed tissue, its measures observed and at
/// the best parameters, and the difference (simulated − observed). Empty simulated fields: the
/// relaxation failed, or the cell was lost when measured like the data.
#[derive(Serialize)]
struct ResidualRow {
    /// Cell id (the input label).
    cell: u32,
    volume_m3_observed: Real,
    volume_m3_simulated: Option<Real>,
    volume_m3_difference: Option<Real>,
    volume_um3_observed: Real,
    volume_um3_simulated: Option<Real>,
    volume_um3_difference: Option<Real>,
    area_m2_observed: Real,
    area_m2_simulated: Option<Real>,
    area_m2_difference: Option<Real>,
    area_um2_observed: Real,
    area_um2_simulated: Option<Real>,
    area_um2_difference: Option<Real>,
    sphericity_observed: Real,
    sphericity_simulated: Option<Real>,
    sphericity_difference: Option<Real>,
    contact_fraction_observed: Real,
    contact_fraction_simulated: Option<Real>,
    contact_fraction_difference: Option<Real>,
    free_area_m2_observed: Real,
    free_area_m2_simulated: Option<Real>,
    free_area_m2_difference: Option<Real>,
    free_area_um2_observed: Real,
    free_area_um2_simulated: Option<Real>,
    free_area_um2_difference: Option<Real>,
    neighbours_observed: usize,
    neighbours_simulated: Option<usize>,
    neighbours_difference: Option<i64>,
    elongation_observed: Real,
    elongation_simulated: Option<Real>,
    elongation_difference: Option<Real>,
}

const M3_TO_UM3: Real = 1e18;
const M2_TO_UM2: Real = 1e12;

fn residual_row(o: &CellMorphology, s: Option<&CellMorphology>) -> ResidualRow {
    let sim = |f: fn(&CellMorphology) -> Real| s.map(f);
    let diff = |f: fn(&CellMorphology) -> Real| s.map(|s| f(s) - f(o));
    ResidualRow {
        cell: o.cell,
        volume_m3_observed: o.volume,
        volume_m3_simulated: sim(|c| c.volume),
        volume_m3_difference: diff(|c| c.volume),
        volume_um3_observed: o.volume * M3_TO_UM3,
        volume_um3_simulated: sim(|c| c.volume * M3_TO_UM3),
        volume_um3_difference: diff(|c| c.volume * M3_TO_UM3),
        area_m2_observed: o.area,
        area_m2_simulated: sim(|c| c.area),
        area_m2_difference: diff(|c| c.area),
        area_um2_observed: o.area * M2_TO_UM2,
        area_um2_simulated: sim(|c| c.area * M2_TO_UM2),
        area_um2_difference: diff(|c| c.area * M2_TO_UM2),
        sphericity_observed: o.sphericity,
        sphericity_simulated: sim(|c| c.sphericity),
        sphericity_difference: diff(|c| c.sphericity),
        contact_fraction_observed: o.contact_fraction,
        contact_fraction_simulated: sim(|c| c.contact_fraction),
        contact_fraction_difference: diff(|c| c.contact_fraction),
        free_area_m2_observed: o.free_area,
        free_area_m2_simulated: sim(|c| c.free_area),
        free_area_m2_difference: diff(|c| c.free_area),
        free_area_um2_observed: o.free_area * M2_TO_UM2,
        free_area_um2_simulated: sim(|c| c.free_area * M2_TO_UM2),
        free_area_um2_difference: diff(|c| c.free_area * M2_TO_UM2),
        neighbours_observed: o.neighbours,
        neighbours_simulated: s.map(|s| s.neighbours),
        neighbours_difference: s.map(|s| s.neighbours as i64 - o.neighbours as i64),
        elongation_observed: o.elongation,
        elongation_simulated: sim(|c| c.elongation),
        elongation_difference: diff(|c| c.elongation),
    }
}

/// How the fit measures a tissue cell by cell: the distance rule with the observed δ.
fn cell_settings(model: &ForwardModel) -> MeasureSettings {
    MeasureSettings {
        contact_distance: Some(model.observation.contact_distance),
        interface_labels: false,
        ..MeasureSettings::default()
    }
}

/// Per-cell morphology of a relaxed tissue measured as the fit measures it (see the module doc).
fn measure_simulated(model: &ForwardModel, tissue: &crate::mesh::Tissue) -> Result<Vec<CellMorphology>, String> {
    let obs = &model.observation;
    let settings = cell_settings(model);
    match (&obs.labels, &obs.meshing, model.forward.measure_like_data) {
        (Some(observed), Some(options), true) => {
            let voxels = crate::imaging::voxelize(tissue, &observed.grid())
                .map_err(|e| format!("voxelising the relaxed tissue: {e}"))?;
            let voxels = model.roughen(&voxels, 0)?;
            let meshed = crate::meshing::mesh_labels(&voxels, options)
                .map_err(|e| format!("meshing the relaxed tissue's voxels: {e}"))?;
            if meshed.tissue.is_empty() {
                return Err("meshing the relaxed tissue's voxels kept no cell".into());
            }
            measure_tissue(&meshed.tissue, &settings).map(|m| m.cells).map_err(|e| format!("measuring: {e}"))
        }
        _ => measure_tissue(tissue, &settings).map(|m| m.cells).map_err(|e| format!("measuring: {e}")),
    }
}

/// Relaxes the best point once more as an evaluation of the fit does and writes `best.vtp`,
/// `best.toml` and `residuals.csv` into `out` (see the module doc; `best.vtp` in `unit`). A failed relaxation is
/// reported in the returned [`BestRelaxation`] (and logged), not as an error; errors are files that
/// could not be written.
pub fn write_best_outputs(
    model: &ForwardModel,
    best: &Evaluation,
    out: &Path,
    unit: OutputUnit,
) -> Result<BestRelaxation, InferenceError> {
    let output_err = |p: &Path, e: &dyn std::fmt::Display| InferenceError::Output(format!("{}: {e}", p.display()));
    let params = model.params_at(&best.x);
    let model_path = out.join(BEST_MODEL_FILE);
    write_bytes_atomically(&model_path, params.to_toml_string().as_bytes()).map_err(|e| output_err(&model_path, &e))?;

    let (evaluation, tissue) = model.evaluate_from(&best.x, &model.observation.tissue);
    let mut reason = evaluation.reason.clone();
    let tissue_path = out.join(BEST_TISSUE_FILE);
    let tissue_written = match &tissue {
        Some(t) if evaluation.status.usable() => {
            write_tissue_in(&tissue_path, t, &[], unit).map_err(|e| output_err(&tissue_path, &e))?;
            true
        }
        _ => {
            // Never leave an earlier session's best.vtp that would look like this fit's.
            match std::fs::remove_file(&tissue_path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(output_err(&tissue_path, &e)),
                _ => {}
            }
            false
        }
    };
    let observed = measure_tissue(&model.observation.tissue, &cell_settings(model))
        .map_err(|e| InferenceError::Observed(format!("measuring the observed cells: {e}")))?
        .cells;
    let simulated = match &tissue {
        Some(t) if tissue_written => match measure_simulated(model, t) {
            Ok(cells) => cells,
            Err(e) => {
                reason = format!("measuring the relaxed tissue per cell: {e}");
                Vec::new()
            }
        },
        _ => Vec::new(),
    };
    let by_id: HashMap<u32, &CellMorphology> = simulated.iter().map(|c| (c.cell, c)).collect();
    let moving = &model.observation.cell_labels;
    let rows: Vec<ResidualRow> = observed
        .iter()
        .filter(|o| moving.contains(&o.cell))
        .map(|o| residual_row(o, by_id.get(&o.cell).copied()))
        .collect();
    let residuals_path = out.join(RESIDUALS_FILE);
    let mut buf = Vec::new();
    {
        let mut w = csv::Writer::from_writer(&mut buf);
        for row in &rows {
            w.serialize(row).map_err(|e| output_err(&residuals_path, &e))?;
        }
        w.flush().map_err(|e| output_err(&residuals_path, &e))?;
    }
    write_bytes_atomically(&residuals_path, &buf).map_err(|e| output_err(&residuals_path, &e))?;

    let relaxation = BestRelaxation {
        failed: !tissue_written || !reason.is_empty(),
        status: evaluation.status,
        objective: evaluation.objective,
        reason,
        steps: evaluation.steps,
        tissue_written,
    };
    if let Some(failure) = relaxation.failure() {
        tracing::warn!("{failure}");
    } else if relaxation.objective != best.objective {
        tracing::warn!(
            "the relaxation at the best point scored {:.6e}, the best evaluation {:.6e}: the forward model is not \
             reproducible here",
            relaxation.objective,
            best.objective
        );
    }
    Ok(relaxation)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A failed relaxation at the best point is said with its status, its reason and what is missing;
    /// a good one says nothing.
    #[test]
    fn a_failed_best_relaxation_is_said_with_its_status_reason_and_missing_files() {
        let ok = BestRelaxation {
            failed: false,
            status: Status::Converged,
            objective: 0.5,
            reason: String::new(),
            steps: 10,
            tissue_written: true,
        };
        assert_eq!(ok.failure(), None);
        let failed = BestRelaxation {
            failed: true,
            status: Status::Failed,
            objective: 1e6,
            reason: "simulation (pass 0): non-finite force".into(),
            steps: 3,
            tissue_written: false,
        };
        let said = failed.failure().expect("a failure is said");
        assert!(said.contains("ended failed") && said.contains("non-finite force"), "{said}");
        assert!(said.contains("no best.vtp") && said.contains("no simulated values"), "{said}");
    }
}
