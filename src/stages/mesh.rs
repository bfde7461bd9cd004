//! The mesh stage: every label of a segmented volume meshed into a closed cell surface (see
//! [`crate::meshing::mesh_cells_and_nuclei`]), or every cell of a tissue file re-triangulated through a
//! voxelisation ([`crate::meshing::retriangulate`]); the tissue and a per-label `report.json`
//! (kept/static/dropped and why) written atomically. `tissuefit mesh` and the pipeline's `[mesh]`
//! both run [`run`]; the pipeline's other inputs (a mesh checked and copied, a generated tissue) are
//! [`check_mesh`] and [`generate`].

use super::{StageError, write_json};
use crate::geometry::Real;
use crate::imaging::{LabelReadOptions, LabelVolume, SUPPORTED_FORMATS, VoxelGrid, is_label_volume, read_labels};
use crate::io::{
    LengthScale, OutputGroup, OutputUnit, Progress, ReadOptions, read_tissue, write_tissue, write_tissue_in,
};
use crate::meshing::{
    BorderPolicy, LabelMeshing, LabelMeshingOptions, LabelReport, LabelStatus, TissueSpec, generate_tissue,
    mesh_cells_and_nuclei, retriangulate,
};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// The stage's settings (the pipeline's `[input]` and `[mesh]`, the flags of `tissuefit mesh`).
#[derive(Clone, Debug, Default)]
pub struct MeshOptions {
    pub meshing: LabelMeshingOptions,
    /// Voxel size `[z, y, x]` (m) overriding the label file's metadata; for a mesh input the voxel
    /// size of the intermediate grid (default l_min/2).
    pub voxel_size: Option<[Real; 3]>,
    /// OME-Zarr: the multiscales level to read (labels and nuclei).
    pub zarr_level: Option<usize>,
    /// Nuclei label volume on the same grid: each nucleus becomes a nucleus cell.
    pub nuclei: Option<PathBuf>,
    /// Mesh input only: the length unit of its coordinates (default metres).
    pub length_unit: Option<LengthScale>,
    /// Length unit of the written tissue (default SI; µm needs a .vtp, which records it). The report
    /// stays in metres.
    pub output_unit: OutputUnit,
}

/// What [`run`] made.
pub struct MeshOutcome {
    pub meshing: LabelMeshing,
    pub wall_seconds: f64,
    pub threads: usize,
}

/// `report.json`; keys are a stable interface (DESIGN.md §2).
#[derive(Serialize)]
struct MeshReport<'a> {
    input: &'a Path,
    /// The tissue: its file name when it lies beside the report, else the path as given.
    output: &'a Path,
    wall_seconds: f64,
    threads: usize,
    /// Length unit of the tissue file when not metres (`um`); the report's lengths are metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    tissue_length_unit: Option<OutputUnit>,
    /// m; `null` when no label was meshed.
    l_min: Option<Real>,
    /// [sz, sy, sx] m.
    voxel_size: [Real; 3],
    shape: [usize; 3],
    seed: u64,
    min_voxels: u64,
    border: BorderPolicy,
    kept: usize,
    #[serde(rename = "static")]
    static_cells: usize,
    dropped: usize,
    cells: &'a [LabelReport],
    /// Mesh input: what the voxelisation found.
    #[serde(skip_serializing_if = "Option::is_none")]
    retriangulated: Option<RetriangulatedFrom>,
    /// With nuclei: the nuclei file and one entry per nucleus label.
    #[serde(skip_serializing_if = "Option::is_none")]
    nuclei_input: Option<&'a Path>,
    #[serde(skip_serializing_if = "Option::is_none")]
    nuclei: Option<&'a [LabelReport]>,
    /// With nuclei: nucleus cell id = nucleus label + this (the largest cell label).
    #[serde(skip_serializing_if = "Option::is_none")]
    nucleus_id_offset: Option<u32>,
}

#[derive(Serialize)]
struct RetriangulatedFrom {
    /// Input cells.
    input_cells: usize,
    /// Rows of the voxelisation that crossed an open input surface an odd number of times.
    odd_rows: u64,
    /// Voxels inside two input cells (kept by the first).
    overlapping_voxels: u64,
}

/// What the input was turned into before writing.
struct Meshed {
    meshing: LabelMeshing,
    /// The label grid (the file's, or the voxelisation's for a mesh input).
    volume_grid: VoxelGrid,
    grid_description: String,
    retriangulated: Option<RetriangulatedFrom>,
}

fn err(message: String) -> StageError {
    StageError::new("mesh", message)
}

fn read_label_volume(path: &Path, options: &MeshOptions, what: &str) -> Result<LabelVolume, StageError> {
    let read_options =
        LabelReadOptions { voxel_size: options.voxel_size, zarr_level: options.zarr_level, ..Default::default() };
    let read = read_labels(path, &read_options).map_err(|e| err(format!("reading {what} {}: {e}", path.display())))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", path.display());
    }
    Ok(read.volume)
}

fn mesh_input(input: &Path, options: &MeshOptions, progress: bool) -> Result<Meshed, StageError> {
    if !is_label_volume(input) {
        match input.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
            Some("vtk" | "vtp") => {}
            _ => {
                return Err(err(format!(
                    "{}: give a label volume ({SUPPORTED_FORMATS}) or a tissue mesh to re-triangulate (.vtk/.vtp)",
                    input.display()
                )));
            }
        }
        if options.nuclei.is_some() {
            return Err(err(format!("--nuclei applies to a label volume input, not to a mesh ({})", input.display())));
        }
        if options.zarr_level.is_some() {
            return Err(err(format!(
                "--zarr-level applies to an OME-Zarr label input, not to a mesh ({})",
                input.display()
            )));
        }
        let read_options = ReadOptions { length_scale: options.length_unit.unwrap_or_default(), orient: true };
        let read =
            read_tissue(input, &read_options).map_err(|e| err(format!("reading tissue {}: {e}", input.display())))?;
        for w in &read.warnings {
            tracing::warn!("{}: {w}", input.display());
        }
        let r = retriangulate(&read.tissue, &options.meshing, options.voxel_size)
            .map_err(|e| err(format!("re-triangulating {}: {e}", input.display())))?;
        if r.odd_rows > 0 {
            tracing::warn!(
                "{}: {} voxel rows crossed an open cell surface an odd number of times; inside/outside may be wrong there",
                input.display(),
                r.odd_rows
            );
        }
        let [nz, ny, nx] = r.grid.shape;
        let [sz, sy, sx] = r.grid.voxel_size.map(|s| s * 1e6);
        return Ok(Meshed {
            grid_description: format!("voxelised on {nz}x{ny}x{nx} (z,y,x), voxel {sz:.6} x {sy:.6} x {sx:.6} µm"),
            volume_grid: r.grid.clone(),
            retriangulated: Some(RetriangulatedFrom {
                input_cells: read.tissue.len(),
                odd_rows: r.odd_rows,
                overlapping_voxels: r.overlapping_voxels,
            }),
            meshing: r.meshing,
        });
    }
    if options.length_unit.is_some() {
        return Err(err(
            "--length-unit applies to a mesh input (.vtk/.vtp); for a label volume use --voxel-size".into()
        ));
    }
    let volume = read_label_volume(input, options, "label volume")?;
    let nuclei = match &options.nuclei {
        Some(path) => Some(read_label_volume(path, options, "nuclei volume")?),
        None => None,
    };
    let label_count = volume.label_stats().len() + nuclei.as_ref().map_or(0, |n| n.label_stats().len());
    let display = Mutex::new(Progress::new(
        format!("mesh {}", input.display()),
        label_count as u64,
        "label",
        "{elapsed_precise} [{wide_bar}] {pos}/{len} labels, ETA {eta}",
        progress,
    ));
    let done = AtomicU64::new(0);
    let on_label = |_| {
        let n = done.fetch_add(1, Ordering::Relaxed) + 1;
        if let Ok(mut p) = display.lock() {
            p.update(n, String::new);
        }
        true
    };
    let meshing = mesh_cells_and_nuclei(&volume, nuclei.as_ref(), &options.meshing, &on_label).map_err(|e| {
        err(match &options.nuclei {
            Some(n) => format!("meshing {} with nuclei {}: {e}", input.display(), n.display()),
            None => format!("meshing {}: {e}", input.display()),
        })
    })?;
    if let Ok(p) = display.lock() {
        p.finish();
    }
    Ok(Meshed { grid_description: volume.describe_grid(), volume_grid: volume.grid(), retriangulated: None, meshing })
}

/// `DIR/STEM.report.json` for `DIR/STEM.EXT`.
pub fn default_report_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "tissue".into());
    out.with_file_name(format!("{stem}.report.json"))
}

/// Meshes `input` (a label volume, or a tissue file to re-triangulate) into the tissue `out` (.vtp or
/// .vtk) and the per-label report `report_path`. When every label was dropped the report is still
/// written (it says why) and the stage fails. `progress`: a bar on a terminal, a line every 30 s
/// otherwise.
pub fn run(
    input: &Path,
    options: &MeshOptions,
    out: &Path,
    report_path: &Path,
    progress: bool,
) -> Result<MeshOutcome, StageError> {
    let started = Instant::now();
    let vtk = out.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("vtk"));
    if vtk && !options.output_unit.is_si() {
        return Err(err(format!(
            "{}: a SimuCell3D legacy .vtk is in metres; write a .vtp for lengths in {} (it records its unit)",
            out.display(),
            options.output_unit
        )));
    }
    let Meshed { meshing, volume_grid, grid_description, retriangulated } = mesh_input(input, options, progress)?;
    for label in &options.meshing.lumen_labels {
        if !meshing.report.iter().any(|r| r.label == *label) {
            tracing::warn!("lumen label {label} is not in {}", input.display());
        }
    }
    let (kept, static_cells, dropped) =
        (meshing.count(LabelStatus::Kept), meshing.count(LabelStatus::Static), meshing.count(LabelStatus::Dropped));
    if !meshing.tissue.is_empty() {
        write_tissue_in(out, &meshing.tissue, &[], options.output_unit)
            .map_err(|e| err(format!("writing {}: {e}", out.display())))?;
    }
    let wall_seconds = started.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    let with_nuclei = options.nuclei.is_some();
    let beside = out.parent() == report_path.parent();
    let output = match (beside, out.file_name()) {
        (true, Some(name)) => Path::new(name),
        _ => out,
    };
    let report = MeshReport {
        input,
        output,
        wall_seconds,
        threads,
        tissue_length_unit: (!options.output_unit.is_si()).then_some(options.output_unit),
        l_min: meshing.l_min,
        voxel_size: volume_grid.voxel_size,
        shape: volume_grid.shape,
        seed: options.meshing.seed,
        min_voxels: options.meshing.min_voxels,
        border: options.meshing.border,
        kept,
        static_cells,
        dropped,
        cells: &meshing.report,
        retriangulated,
        nuclei_input: options.nuclei.as_deref(),
        nuclei: with_nuclei.then_some(meshing.nuclei.as_slice()),
        nucleus_id_offset: with_nuclei.then_some(meshing.nucleus_id_offset),
    };
    let mut group = OutputGroup::new();
    write_json(&mut group, report_path, &report)
        .and_then(|()| group.commit())
        .map_err(|e| err(format!("writing {}: {e}", report_path.display())))?;
    if meshing.tissue.is_empty() {
        return Err(err(format!(
            "no cell meshed from {} ({grid_description}): all {dropped} labels were dropped ({}); see {}",
            input.display(),
            summarise_reasons(&meshing.report),
            report_path.display()
        )));
    }
    Ok(MeshOutcome { meshing, wall_seconds, threads })
}

/// The l_min (m) a mesh stage's `report.json` says the labels were meshed at (`None` for a report
/// that has none: a mesh or generated input), read back typed.
pub fn read_report_l_min(path: &Path) -> Result<Option<Real>, StageError> {
    #[derive(serde::Deserialize)]
    struct Head {
        #[serde(default)]
        l_min: Option<Real>,
    }
    let text = crate::io::read_text_capped(path, crate::io::MAX_CONFIG_FILE)
        .map_err(|e| err(format!("reading {}: {e}", path.display())))?;
    let head: Head = serde_json::from_str(&text).map_err(|e| err(format!("reading {}: {e}", path.display())))?;
    Ok(head.l_min)
}

/// `3 with too few voxels, 2 touching the border, 1 failed meshing`.
fn summarise_reasons(report: &[LabelReport]) -> String {
    let (mut small, mut border, mut failed) = (0, 0, 0);
    for r in report {
        match r.reason.as_deref() {
            Some(s) if s.contains("fewer than the minimum") => small += 1,
            Some(s) if s.contains("border") => border += 1,
            _ => failed += 1,
        }
    }
    let mut parts = Vec::new();
    if small > 0 {
        parts.push(format!("{small} with fewer voxels than the minimum (--min-voxels, mesh.min_voxels)"));
    }
    if border > 0 {
        parts.push(format!("{border} touching the image border with border policy drop"));
    }
    if failed > 0 {
        parts.push(format!("{failed} failed meshing"));
    }
    parts.join(", ")
}

/// `report.json` of a mesh input: what was read.
#[derive(Serialize)]
struct MeshInputReport<'a> {
    input: &'a Path,
    length_unit: &'a str,
    cells: usize,
    nodes: usize,
    faces: usize,
    kinds: std::collections::BTreeMap<String, usize>,
}

/// A mesh input of the pipeline: read in `length_unit` (`unit` names it in the report), every cell
/// checked to be a valid closed surface, written as `DIR/tissue.vtp` in metres, plus
/// `DIR/report.json`. Returns a one-line summary.
pub fn check_mesh(path: &Path, length_unit: LengthScale, unit: &str, dir: &Path) -> Result<String, StageError> {
    let read = read_tissue(path, &ReadOptions { length_scale: length_unit, orient: false })
        .map_err(|e| err(format!("reading {}: {e}", path.display())))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", path.display());
    }
    let tissue = read.tissue;
    if tissue.is_empty() {
        return Err(err(format!("{}: the tissue has no cells", path.display())));
    }
    let mut kinds = std::collections::BTreeMap::new();
    for cell in tissue.cells() {
        if let Err(defect) = cell.mesh().validate() {
            return Err(err(format!(
                "{}: cell {}: {defect}; repair the file (`tissuefit inspect` lists every defect, `tissuefit mesh` \
                 re-triangulates a tissue) or give the label volume as input.labels",
                path.display(),
                cell.id().0
            )));
        }
        let kind = serde_json::to_value(cell.kind()).ok().and_then(|v| v.as_str().map(str::to_string));
        *kinds.entry(kind.unwrap_or_else(|| format!("{:?}", cell.kind()))).or_insert(0) += 1;
    }
    let tissue_path = dir.join(TISSUE_FILE);
    write_tissue(&tissue_path, &tissue, &[]).map_err(|e| err(format!("writing {}: {e}", tissue_path.display())))?;
    let faces = tissue.cells().iter().map(|c| c.mesh().triangles().len()).sum();
    let report = MeshInputReport {
        input: path,
        length_unit: unit,
        cells: tissue.len(),
        nodes: tissue.node_count(),
        faces,
        kinds,
    };
    write_report(dir, &report)?;
    Ok(format!(
        "{} cells, {} nodes read from {}; every cell a valid closed surface",
        tissue.len(),
        tissue.node_count(),
        path.display()
    ))
}

/// The pipeline's generated input: the tissue of `generate mesh` as `DIR/tissue.vtp`, its report
/// (without timing) as `DIR/report.json`. Returns a one-line summary.
pub fn generate(spec: &TissueSpec, dir: &Path) -> Result<String, StageError> {
    let generated =
        generate_tissue(spec).map_err(|e| err(format!("input.generate: generating a {}: {e}", spec.kind)))?;
    let tissue_path = dir.join(TISSUE_FILE);
    write_tissue(&tissue_path, &generated.tissue, &[])
        .map_err(|e| err(format!("writing {}: {e}", tissue_path.display())))?;
    let summary = generated.summary();
    write_report(dir, &summary)?;
    let counts: Vec<String> = summary.kinds.iter().map(|(name, k)| format!("{} {name}", k.bodies)).collect();
    Ok(format!(
        "generated a {}: {}; {} nodes; l_min {:.4} µm, l = {:.4} µm",
        spec.kind,
        counts.join(", "),
        summary.nodes,
        spec.l_min * 1e6,
        summary.length_scale * 1e6
    ))
}

/// Name of the stage's tissue file in a stage folder (always in metres: the later stages read it).
pub const TISSUE_FILE: &str = "tissue.vtp";

/// The stage's tissue in another output unit, beside [`TISSUE_FILE`] (`tissue_um.vtp`): for people
/// and ParaView; no stage reads it.
pub fn tissue_file_in(unit: OutputUnit) -> String {
    format!("tissue_{}.vtp", unit.name())
}

/// Writes `DIR/tissue_UNIT.vtp`, the stage's tissue `DIR/tissue.vtp` in `unit` (nothing in SI).
pub fn write_tissue_copy(dir: &Path, unit: OutputUnit) -> Result<(), StageError> {
    if unit.is_si() {
        return Ok(());
    }
    let si = dir.join(TISSUE_FILE);
    let read = read_tissue(&si, &ReadOptions::default()).map_err(|e| err(format!("reading {}: {e}", si.display())))?;
    let path = dir.join(tissue_file_in(unit));
    write_tissue_in(&path, &read.tissue, &[], unit).map_err(|e| err(format!("writing {}: {e}", path.display())))
}
/// Name of the stage's report in a stage folder.
pub const REPORT_FILE: &str = "report.json";

fn write_report<T: Serialize>(dir: &Path, report: &T) -> Result<(), StageError> {
    let path = dir.join(REPORT_FILE);
    let mut group = OutputGroup::new();
    write_json(&mut group, &path, report)
        .and_then(|()| group.commit())
        .map_err(|e| err(format!("writing {}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_report_goes_beside_the_tissue_named_after_its_stem() {
        assert_eq!(default_report_path(Path::new("/tmp/a/ovule.vtp")), PathBuf::from("/tmp/a/ovule.report.json"));
        assert_eq!(default_report_path(Path::new("t.vtk")), PathBuf::from("t.report.json"));
    }
}
