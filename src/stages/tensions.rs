//! The tensions stage: the direct estimate of every interface's tension and every cell's pressure
//! from a tissue's shapes ([`crate::morphology::tensions`]) into `interfaces.csv`, `cells.csv`,
//! `summary.json`, `tensions.vtp` (per-face tension, per-cell pressure) and `cell_overrides.toml`
//! (the map as per-cell model parameters, [`crate::morphology::tensions::per_cell_tensions`]),
//! written together.
//! `tissuefit tensions` (which reads or meshes its input first) and the Python API both run [`run`].

use super::{StageError, write_csv};
use crate::geometry::Real;
use crate::io::{CellField, OutputGroup, vtp_bytes};
use crate::mesh::Tissue;
use crate::morphology::ContactRule;
use crate::morphology::sheet::{SheetTensionMap, WallTension, estimate_sheet_tensions};
use crate::morphology::tensions::{
    CellPressure, Gauge, PerCellTensions, TensionMap, TensionSettings, estimate_tensions, per_cell_tensions,
};
use serde::Serialize;
use std::io::Write;
use std::path::Path;
use std::time::Instant;

fn err(message: impl Into<String>) -> StageError {
    StageError::new("tensions", message)
}

/// How the input is named in `summary.json`, and whether the gauge's tension was given in mN/m.
pub struct TensionsInput<'a> {
    /// The input as the user gave it (a path, or "the tissue given in Python").
    pub file: &'a str,
    /// "labels" or "tissue".
    pub kind: &'static str,
    /// The gauge's tension was given (in mN/m): tensions in mN/m and pressures in kPa; else relative.
    pub gauge_in_mn_per_m: bool,
}

/// What [`run`] estimated and wrote.
pub struct TensionsOutcome {
    pub map: TensionMap,
    /// The tension of every face's interface, cell after cell in tissue order (NaN where undetermined),
    /// in the summary's `tension_unit`.
    pub face_tension: Vec<Real>,
    /// Every cell's pressure in tissue order (NaN where undetermined), in the summary's `pressure_unit`.
    pub pressure: Vec<Real>,
    /// `summary.json` as written.
    pub summary: Summary,
}

/// Estimates the tensions and pressures of `tissue` with `settings` and writes the five files into
/// `out` (created when missing), all or nothing.
pub fn run(
    tissue: &Tissue,
    settings: &TensionSettings,
    input: &TensionsInput<'_>,
    out: &Path,
) -> Result<TensionsOutcome, StageError> {
    if crate::morphology::sheet::is_sheet(tissue) {
        return Err(err(format!(
            "{} is a 2.5-D cell sheet (every cell an open patch of one surface): its wall tensions come from the sheet \
             estimate (`tissuefit tensions` picks it), not the 3-D one",
            input.file
        )));
    }
    let start = Instant::now();
    // 0 is the medium in the maps: a file numbering its cells from 0 (SimuCell3D's) is renumbered.
    let from_zero = tissue.cells().iter().any(|c| c.id().0 == 0);
    let shifted;
    let tissue = if from_zero {
        shifted = tissue
            .with_ids_shifted_by_one()
            .map_err(|e| err(format!("renumbering the cells of {} from 1: {e}", input.file)))?;
        &shifted
    } else {
        tissue
    };
    let mut map =
        estimate_tensions(tissue, settings).map_err(|e| err(format!("estimating tensions in {}: {e}", input.file)))?;
    if from_zero {
        map.warnings.insert(
            0,
            "the file numbers its cells from 0 (SimuCell3D's convention), and 0 is the medium in the maps: every \
             cell id in the outputs is the file's plus 1 (name interfaces for --gauge that way too)"
                .to_string(),
        );
    }
    let wall_seconds = start.elapsed().as_secs_f64();
    for w in &map.warnings {
        tracing::warn!("{}: {w}", input.file);
    }
    std::fs::create_dir_all(out).map_err(|e| err(format!("creating {}: {e}", out.display())))?;
    let (tension_unit, pressure_unit) = if input.gauge_in_mn_per_m { ("mN/m", "kPa") } else { ("gauge", "gauge/um") };
    let gauge = match settings.gauge {
        Gauge::MediumMean if settings.one_medium_tension => "the cell–medium tension (shared)".to_string(),
        Gauge::MediumMean if map.gauge.contains("cell–cell") => {
            "the mean of the cell–cell tensions (no free surface)".to_string()
        }
        Gauge::MediumMean => "the mean of the cell–medium tensions".to_string(),
        Gauge::Interface(a, b) => format!("the tension of interface {a}-{b}"),
    };
    let per_cell = per_cell_tensions(&map);
    let summary = Summary {
        file: input.file.to_string(),
        input: input.kind,
        cells: map.cells.len(),
        interfaces: map.interfaces.len(),
        determined_interfaces: map.interfaces.iter().filter(|f| f.determined).count(),
        determined_pressures: map.cells.iter().filter(|c| c.determined).count(),
        gauge,
        gauge_value: settings.gauge_value,
        tension_unit,
        pressure_unit,
        one_medium_tension: settings.one_medium_tension,
        uncertainty: "tension_sd and pressure_sd: first-order propagation of the force-balance residuals, \
                      cluster-robust by junction line; biases shared by all junctions are not in it",
        contact_distance_um: map.contact_distance * 1e6,
        contact_rule: map.contact_rule,
        junction_samples: map.samples,
        junction_samples_skipped: map.samples_skipped,
        junction_samples_near_vertices: map.samples_near_vertices,
        far_field: settings.far_field.as_str(),
        junction_samples_local: map.samples_local,
        junction_samples_trimmed: map.samples_trimmed,
        junction_lines: map.junction_lines,
        unknowns: map.unknowns,
        condition_number: map.condition_number,
        spectral_gap: map.spectral_gap.filter(|g| g.is_finite()),
        residual_rms: map.residual_rms,
        residual_median: map.residual_median,
        pressure_residual_rms: map.pressure_residual_rms.map(|p| p * 1e-6),
        additive_residual_rms: per_cell.additive_residual_rms,
        lateral_determined: per_cell.cells.iter().filter(|c| c.lateral.is_some()).count(),
        wall_seconds,
        threads: rayon::current_num_threads(),
        warnings: map.warnings.clone(),
    };
    let overrides = cell_overrides_toml(&per_cell, input);
    let Fields { face_tension, pressure } =
        write_outputs(out, tissue, &map, &per_cell, &overrides, &summary).map_err(err)?;
    Ok(TensionsOutcome { map, face_tension, pressure, summary })
}

/// The per-face and per-cell fields written into `tensions.vtp`.
struct Fields {
    face_tension: Vec<Real>,
    pressure: Vec<Real>,
}

/// What the stage writes into its folder, all or nothing.
pub const OUTPUT_FILES: [&str; 6] =
    ["interfaces.csv", "cells.csv", "summary.json", "tensions.vtp", "cell_overrides.toml", "tensions.png"];

/// `cell_overrides.toml`: the per-cell tensions as `[[cell_overrides]]` entries for a model file
/// (free tension on apical and basal faces, a_i on lateral ones, N/m) when the gauge is absolute
/// (`--gauge-tension`); otherwise only a comment saying how to get them.
fn cell_overrides_toml(per_cell: &PerCellTensions, input: &TensionsInput<'_>) -> String {
    use crate::mechanics::{CellOverrideConfig, PerFaceType};
    let mut text = format!(
        "# Per-cell tensions from the direct estimate of `tissuefit tensions` ({}): each cell's free tension\n\
         # (its interface with the medium) on its apical and basal faces, and a lateral tension a_i such\n\
         # that a cell–cell interface pulls with a_i + a_j (coupled contacts), by least squares.\n\
         # Append to a model file to simulate the map forward (see the Per-cell tensions and adhesions\n\
         # section of the simulation guide). Values the map does not determine are left out.\n",
        input.file
    );
    if let Some(rms) = per_cell.additive_residual_rms {
        text.push_str(&format!(
            "# Additive residual: rms of (a_i + a_j - T_ij)/T_ij = {rms:.4} (0: per-cell tensions reproduce the map).\n"
        ));
    }
    if !input.gauge_in_mn_per_m {
        text.push_str(
            "# The tensions are relative to the gauge: rerun with --gauge-tension T (mN/m) for values in N/m.\n",
        );
        return text;
    }
    let entries: Vec<CellOverrideConfig> = per_cell
        .cells
        .iter()
        .filter(|c| c.free.is_some() || c.lateral.is_some())
        .map(|c| {
            let free = c.free.map(|t| t * 1e-3);
            CellOverrideConfig {
                id: c.cell,
                surface_tension: PerFaceType { apical: free, lateral: c.lateral.map(|t| t * 1e-3), basal: free },
                adhesion: PerFaceType::default(),
            }
        })
        .collect();
    #[derive(Serialize)]
    struct Entries {
        cell_overrides: Vec<CellOverrideConfig>,
    }
    if !entries.is_empty() {
        text.push('\n');
        text.push_str(&toml::to_string(&Entries { cell_overrides: entries }).unwrap_or_default());
    }
    text
}

/// A row of `interfaces.csv`.
#[derive(Serialize, Default)]
struct InterfaceRow {
    cell_a: u32,
    cell_b: u32,
    tension: Option<Real>,
    tension_sd: Option<Real>,
    determined: bool,
    area_um2: Real,
    samples: usize,
    mean_curvature_per_um: Option<Real>,
    fit: &'static str,
    fit_rms_um: Option<Real>,
}

/// A row of `cells.csv`.
#[derive(Serialize, Default)]
struct CellRow {
    cell: u32,
    pressure: Option<Real>,
    pressure_sd: Option<Real>,
    determined: bool,
    /// The pressure minus its group's mean (the cells determined interfaces link it to), with its sd;
    /// also where no chain reaches the medium (a dense crop).
    pressure_relative: Option<Real>,
    pressure_relative_sd: Option<Real>,
    free_mean_curvature_per_um: Option<Real>,
    free_area_um2: Real,
    /// The cell's free tension (its interface with the medium) and its lateral tension a_i of the
    /// per-cell decomposition (T_ij ≈ a_i + a_j), in the tension unit; empty when undetermined.
    free_tension: Option<Real>,
    lateral_tension: Option<Real>,
}

/// `summary.json`.
#[derive(Serialize)]
pub struct Summary {
    pub file: String,
    /// `tissue` or `labels` (meshed first).
    pub input: &'static str,
    pub cells: usize,
    pub interfaces: usize,
    pub determined_interfaces: usize,
    pub determined_pressures: usize,
    /// What fixes the scale, and the units of the tension and pressure columns.
    pub gauge: String,
    pub gauge_value: Real,
    pub tension_unit: &'static str,
    pub pressure_unit: &'static str,
    pub one_medium_tension: bool,
    pub uncertainty: &'static str,
    pub contact_distance_um: Real,
    /// How the interfaces were found: `distance` (δ) or `interface_labels` (the input's own).
    pub contact_rule: ContactRule,
    pub junction_samples: usize,
    pub junction_samples_skipped: usize,
    pub junction_samples_near_vertices: usize,
    /// Where the interfaces' surfaces at the junctions came from (`global`, `local`, `auto`).
    pub far_field: &'static str,
    /// Samples whose surfaces were fitted near them (local fits).
    pub junction_samples_local: usize,
    pub junction_samples_trimmed: usize,
    pub junction_lines: usize,
    pub unknowns: usize,
    pub condition_number: Option<Real>,
    /// σ_second-smallest / σ_smallest of the force balance: how clearly the samples single out one
    /// map; null where they balance exactly.
    pub spectral_gap: Option<Real>,
    /// Force imbalance per junction sample, |Σ T_k t_k|, in units of the gauge.
    pub residual_rms: Option<Real>,
    pub residual_median: Option<Real>,
    /// Rms Young–Laplace residual of the pressures (pressure unit).
    pub pressure_residual_rms: Option<Real>,
    /// Per-cell decomposition T_ij ≈ a_i + a_j: rms relative residual over the interfaces it solved,
    /// and how many cells got a lateral tension.
    pub additive_residual_rms: Option<Real>,
    pub lateral_determined: usize,
    pub wall_seconds: f64,
    pub threads: usize,
    pub warnings: Vec<String>,
}

/// The tissue, `tissue` or `labels`, and for labels the largest voxel edge (m).
fn write_outputs(
    dir: &Path,
    tissue: &Tissue,
    map: &TensionMap,
    per_cell: &PerCellTensions,
    overrides: &str,
    summary: &Summary,
) -> Result<Fields, String> {
    let interfaces: Vec<InterfaceRow> = map
        .interfaces
        .iter()
        .map(|f| InterfaceRow {
            cell_a: f.cell_a,
            cell_b: f.cell_b,
            tension: f.tension,
            tension_sd: f.tension_sd,
            determined: f.determined,
            area_um2: f.area * 1e12,
            samples: f.samples,
            mean_curvature_per_um: f.mean_curvature.map(|h| h * 1e-6),
            fit: f.fit,
            fit_rms_um: f.fit_rms.map(|r| r * 1e6),
        })
        .collect();
    let cells: Vec<CellRow> = map
        .cells
        .iter()
        .zip(&per_cell.cells)
        .map(|(c, own)| CellRow {
            cell: c.cell,
            pressure: c.pressure.map(|p| p * 1e-6),
            pressure_sd: c.pressure_sd.map(|p| p * 1e-6),
            determined: c.determined,
            pressure_relative: c.pressure_relative.map(|p| p * 1e-6),
            pressure_relative_sd: c.pressure_relative_sd.map(|p| p * 1e-6),
            free_mean_curvature_per_um: c.free_mean_curvature.map(|h| h * 1e-6),
            free_area_um2: c.free_area * 1e12,
            free_tension: own.free,
            lateral_tension: own.lateral,
        })
        .collect();
    // Per-face tension and per-cell pressure for ParaView (NaN where undetermined, and on nuclei,
    // which take no part).
    let mut face_tension: Vec<Real> = Vec::with_capacity(tissue.face_count());
    for (cell, faces) in tissue.cells().iter().zip(&map.face_interface) {
        if faces.len() == cell.mesh().face_count() {
            face_tension.extend(faces.iter().map(|k| k.and_then(|k| map.interfaces[k].tension).unwrap_or(Real::NAN)));
        } else {
            face_tension.extend(std::iter::repeat_n(Real::NAN, cell.mesh().face_count()));
        }
    }
    let by_id: std::collections::BTreeMap<u32, &CellPressure> = map.cells.iter().map(|c| (c.cell, c)).collect();
    let per_cell = |pick: fn(&CellPressure) -> Option<Real>| -> Vec<Real> {
        tissue
            .cells()
            .iter()
            .map(|c| by_id.get(&c.id().0).and_then(|p| pick(p)).map_or(Real::NAN, |p| p * 1e-6))
            .collect()
    };
    let pressure = per_cell(|p| p.pressure);
    let pressure_relative = per_cell(|p| p.pressure_relative);
    if face_tension.len() != tissue.face_count() {
        return Err(format!("internal: {} face tensions for {} faces", face_tension.len(), tissue.face_count()));
    }
    let mut group = OutputGroup::new();
    let io = |path: &Path, e: &dyn std::fmt::Display| format!("writing {}: {e}", path.display());
    write_tables(&mut group, dir, &interfaces, &cells, summary)?;
    let path = dir.join("cell_overrides.toml");
    group.write_bytes(&path, overrides.as_bytes()).map_err(|e| io(&path, &e))?;
    let vtp = dir.join("tensions.vtp");
    let fields = [
        CellField { name: "tension", values: &face_tension },
        CellField { name: "pressure", values: &pressure },
        CellField { name: "pressure_relative", values: &pressure_relative },
    ];
    let bytes = vtp_bytes(&vtp, tissue, &fields, None).map_err(|e| io(&vtp, &e))?;
    group.write_bytes(&vtp, &bytes).map_err(|e| io(&vtp, &e))?;
    let png = dir.join("tensions.png");
    let unit = if summary.tension_unit == "mN/m" { "mN/m" } else { "relative to the gauge" };
    let picture = super::map_png(tissue, face_tension.clone(), &format!("interface tension ({unit})"))
        .map_err(|e| io(&png, &e))?;
    group.write_bytes(&png, &picture).map_err(|e| io(&png, &e))?;
    group.commit().map_err(|e| format!("writing the outputs into {}: {e}", dir.display()))?;
    Ok(Fields { face_tension, pressure })
}

/// What the sheet stage writes into its folder, all or nothing.
pub const SHEET_OUTPUT_FILES: [&str; 6] =
    ["interfaces.csv", "cells.csv", "summary.json", "tensions.vtp", "walls.vtp", "tensions.png"];

/// What [`run_sheet`] estimated and wrote.
pub struct SheetOutcome {
    pub map: SheetTensionMap,
    /// Per face in tissue order: the tension of the wall it borders, else the mean of its cell's
    /// determined walls (NaN where none), in the summary's `tension_unit`.
    pub face_tension: Vec<Real>,
    /// Every cell's relative in-plane pressure in tissue order (NaN where undetermined).
    pub pressure: Vec<Real>,
    pub summary: SheetSummary,
}

/// `summary.json` of a 2.5-D sheet.
#[derive(Serialize)]
pub struct SheetSummary {
    pub file: String,
    /// Always `sheet`: open cell patches of one surface, line tensions of the walls.
    pub input: &'static str,
    pub method: &'static str,
    pub cells: usize,
    pub cells_on_rim: usize,
    /// Walls (cell pairs) and those with a tension.
    pub interfaces: usize,
    pub determined_interfaces: usize,
    pub determined_pressures: usize,
    pub gauge: String,
    pub gauge_value: Real,
    /// Line tensions relative to the gauge; in-plane pressures in gauge tension per µm.
    pub tension_unit: &'static str,
    pub pressure_unit: &'static str,
    pub uncertainty: &'static str,
    pub junctions: usize,
    pub junctions_on_rim: usize,
    pub non_manifold_edges: usize,
    pub unknowns: usize,
    pub condition_number: Option<Real>,
    pub spectral_gap: Option<Real>,
    pub residual_rms: Option<Real>,
    pub residual_median: Option<Real>,
    pub median_relative_sd: Option<Real>,
    pub wall_seconds: f64,
    pub threads: usize,
    pub warnings: Vec<String>,
}

/// A row of a sheet's `interfaces.csv`.
#[derive(Serialize, Default)]
struct WallRow {
    cell_a: u32,
    cell_b: u32,
    tension: Option<Real>,
    tension_sd: Option<Real>,
    determined: bool,
    length_um: Real,
    junctions: usize,
    curvature_per_um: Option<Real>,
    on_rim: bool,
}

/// A row of a sheet's `cells.csv`.
#[derive(Serialize, Default)]
struct SheetCellRow {
    cell: u32,
    area_um2: Real,
    walls: usize,
    on_rim: bool,
    pressure_relative: Option<Real>,
    pressure_relative_sd: Option<Real>,
}

/// Estimates the wall tensions of a 2.5-D cell sheet ([`crate::morphology::sheet`]) and writes
/// [`SHEET_OUTPUT_FILES`] into `out`, all or nothing. Tensions are relative: the gauge's is 1.
pub fn run_sheet(tissue: &Tissue, gauge: Gauge, file: &str, out: &Path) -> Result<SheetOutcome, StageError> {
    let start = Instant::now();
    let gauge_value = 1.0;
    let map = estimate_sheet_tensions(tissue, gauge, gauge_value)
        .map_err(|e| err(format!("estimating the wall tensions of the sheet {file}: {e}")))?;
    let wall_seconds = start.elapsed().as_secs_f64();
    let mut warnings = map.warnings.clone();
    let mut relative: Vec<Real> =
        map.walls.iter().filter_map(|w| Some(w.tension_sd? / w.tension?.abs())).filter(|x| x.is_finite()).collect();
    relative.sort_by(|a, b| a.total_cmp(b));
    let median_relative_sd = (!relative.is_empty()).then(|| relative[relative.len() / 2]);
    if let Some(m) = median_relative_sd
        && m > crate::morphology::tensions::POOR_RELATIVE_SD
    {
        warnings.push(format!(
            "the map is poorly determined: the median relative tension sd is {:.0} % (the junctions do not balance \
             consistently; walls on a coarse or noisy mesh)",
            100.0 * m
        ));
    }
    if map.walls.iter().all(|w| w.curvature.is_none()) {
        warnings.push(format!(
            "no wall piece has the {} vertices a curvature needs (walls drawn as one to three straight edges): no \
             in-plane pressures",
            crate::morphology::sheet::MIN_CURVATURE_POINTS
        ));
    }
    for w in &warnings {
        tracing::warn!("{file}: {w}");
    }
    let (tension_unit, pressure_unit) = ("gauge", "gauge/um");
    let summary = SheetSummary {
        file: file.to_string(),
        input: "sheet",
        method: "2.5-D: line tensions of the walls from the force balance at the tricellular junctions in the \
                 surface's tangent plane (circle-fitted wall tangents); relative in-plane pressures from the walls' \
                 geodesic curvature",
        cells: map.cells.len(),
        cells_on_rim: map.cells.iter().filter(|c| c.on_rim).count(),
        interfaces: map.walls.len(),
        determined_interfaces: map.walls.iter().filter(|w| w.determined).count(),
        determined_pressures: map.cells.iter().filter(|c| c.pressure_relative.is_some()).count(),
        gauge: map.gauge.clone(),
        gauge_value,
        tension_unit,
        pressure_unit,
        uncertainty: "tension_sd: first-order propagation of an isotropic vertex noise, its size estimated from the \
                      junctions' force residuals (walls shared by two junctions correlate them); on analytic sheets \
                      with noisy vertices 46-67 % of the truths lie within one sd on straight walls, 16-45 % on curved \
                      ones (docs: Tension and pressure maps, 2.5-D cell sheets)",
        junctions: map.junctions,
        junctions_on_rim: map.junctions_on_rim,
        non_manifold_edges: map.non_manifold_edges,
        unknowns: map.walls.len(),
        condition_number: map.condition_number,
        spectral_gap: map.spectral_gap.filter(|g| g.is_finite()),
        residual_rms: map.residual_rms,
        residual_median: map.residual_median,
        median_relative_sd,
        wall_seconds,
        threads: rayon::current_num_threads(),
        warnings,
    };
    // Per-face tension: the wall a face borders, else its cell's mean determined wall.
    let mut cell_mean: std::collections::BTreeMap<u32, (Real, usize)> = std::collections::BTreeMap::new();
    for w in &map.walls {
        if let Some(t) = w.tension {
            for c in [w.cell_a, w.cell_b] {
                let e = cell_mean.entry(c).or_default();
                e.0 += t;
                e.1 += 1;
            }
        }
    }
    let mut face_tension = Vec::with_capacity(map.face_wall.len());
    let mut at = 0;
    for cell in tissue.cells() {
        let mean = cell_mean.get(&cell.id().0).map_or(Real::NAN, |&(s, n)| s / n as Real);
        for k in 0..cell.mesh().face_count() {
            face_tension.push(map.face_wall[at + k].and_then(|w| map.walls[w].tension).unwrap_or(mean));
        }
        at += cell.mesh().face_count();
    }
    let by_id: std::collections::BTreeMap<u32, &crate::morphology::sheet::SheetCell> =
        map.cells.iter().map(|c| (c.cell, c)).collect();
    let pressure: Vec<Real> = tissue
        .cells()
        .iter()
        .map(|c| by_id.get(&c.id().0).and_then(|p| p.pressure_relative).map_or(Real::NAN, |p| p * 1e-6))
        .collect();
    write_sheet_outputs(out, tissue, &map, &face_tension, &pressure, &summary).map_err(err)?;
    Ok(SheetOutcome { map, face_tension, pressure, summary })
}

fn write_sheet_outputs(
    dir: &Path,
    tissue: &Tissue,
    map: &SheetTensionMap,
    face_tension: &[Real],
    pressure: &[Real],
    summary: &SheetSummary,
) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("creating {}: {e}", dir.display()))?;
    let walls: Vec<WallRow> = map
        .walls
        .iter()
        .map(|w| WallRow {
            cell_a: w.cell_a,
            cell_b: w.cell_b,
            tension: w.tension,
            tension_sd: w.tension_sd,
            determined: w.determined,
            length_um: w.length * 1e6,
            junctions: w.junctions,
            curvature_per_um: w.curvature.map(|k| k * 1e-6),
            on_rim: w.on_rim,
        })
        .collect();
    let cells: Vec<SheetCellRow> = map
        .cells
        .iter()
        .map(|c| SheetCellRow {
            cell: c.cell,
            area_um2: c.area * 1e12,
            walls: c.walls,
            on_rim: c.on_rim,
            pressure_relative: c.pressure_relative.map(|p| p * 1e-6),
            pressure_relative_sd: c.pressure_relative_sd.map(|p| p * 1e-6),
        })
        .collect();
    let mut group = OutputGroup::new();
    let io = |path: &Path, e: &dyn std::fmt::Display| format!("writing {}: {e}", path.display());
    write_tables(&mut group, dir, &walls, &cells, summary)?;
    let vtp = dir.join("tensions.vtp");
    let fields = [
        CellField { name: "tension", values: face_tension },
        CellField { name: "pressure_relative", values: pressure },
    ];
    let bytes = vtp_bytes(&vtp, tissue, &fields, None).map_err(|e| io(&vtp, &e))?;
    group.write_bytes(&vtp, &bytes).map_err(|e| io(&vtp, &e))?;
    let path = dir.join("walls.vtp");
    group.write_bytes(&path, walls_vtp(map).as_bytes()).map_err(|e| io(&path, &e))?;
    let png = dir.join("tensions.png");
    let picture = super::map_png(tissue, face_tension.to_vec(), "wall line tension (relative to the gauge)")
        .map_err(|e| io(&png, &e))?;
    group.write_bytes(&png, &picture).map_err(|e| io(&png, &e))?;
    group.commit().map_err(|e| format!("writing the outputs into {}: {e}", dir.display()))
}

/// `interfaces.csv`, `cells.csv` and `summary.json` into `group` (the 3-D map's and a sheet's).
fn write_tables<I: Serialize + Default, C: Serialize + Default>(
    group: &mut OutputGroup,
    dir: &Path,
    interfaces: &[I],
    cells: &[C],
    summary: &impl Serialize,
) -> Result<(), String> {
    let io = |path: &Path, e: &dyn std::fmt::Display| format!("writing {}: {e}", path.display());
    let path = dir.join("interfaces.csv");
    write_csv(group, &path, interfaces, &I::default()).map_err(|e| io(&path, &e))?;
    let path = dir.join("cells.csv");
    write_csv(group, &path, cells, &C::default()).map_err(|e| io(&path, &e))?;
    let path = dir.join("summary.json");
    group
        .write(&path, |w| {
            serde_json::to_writer_pretty(&mut *w, summary).map_err(std::io::Error::other)?;
            writeln!(w)
        })
        .map_err(|e| io(&path, &e))
}

/// The wall pieces as ParaView PolyData lines (µm, recorded as the file's length unit) with each
/// wall's cells, tension and sd (NaN where undetermined).
fn walls_vtp(map: &SheetTensionMap) -> String {
    let points: usize = map.pieces.iter().map(|(_, p)| p.len()).sum();
    let mut s = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">\n<PolyData>\n",
    );
    s.push_str(&format!(
        "<FieldData><Array type=\"String\" name=\"length_unit\" NumberOfTuples=\"1\" format=\"ascii\">um</Array></FieldData>\n\
         <Piece NumberOfPoints=\"{points}\" NumberOfVerts=\"0\" NumberOfLines=\"{}\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n",
        map.pieces.len()
    ));
    s.push_str("<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n");
    for (_, piece) in &map.pieces {
        for p in piece {
            s.push_str(&format!("{:e} {:e} {:e}\n", p.x * 1e6, p.y * 1e6, p.z * 1e6));
        }
    }
    s.push_str("</DataArray></Points>\n<Lines><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    let (mut at, mut offsets) = (0usize, Vec::new());
    for (_, piece) in &map.pieces {
        let ids: Vec<String> = (at..at + piece.len()).map(|i| i.to_string()).collect();
        s.push_str(&ids.join(" "));
        s.push('\n');
        at += piece.len();
        offsets.push(at.to_string());
    }
    s.push_str("</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    s.push_str(&offsets.join(" "));
    s.push_str("\n</DataArray></Lines>\n<CellData Scalars=\"tension\">\n");
    let column = |name: &str, value: &dyn Fn(&WallTension) -> Real| {
        let values: Vec<String> = map.pieces.iter().map(|(w, _)| format!("{:e}", value(&map.walls[*w]))).collect();
        format!("<DataArray type=\"Float64\" Name=\"{name}\" format=\"ascii\">\n{}\n</DataArray>\n", values.join(" "))
    };
    s.push_str(&column("tension", &|w| w.tension.unwrap_or(Real::NAN)));
    s.push_str(&column("tension_sd", &|w| w.tension_sd.unwrap_or(Real::NAN)));
    s.push_str(&column("cell_a", &|w| w.cell_a.into()));
    s.push_str(&column("cell_b", &|w| w.cell_b.into()));
    s.push_str("</CellData>\n</Piece>\n</PolyData>\n</VTKFile>\n");
    s
}
