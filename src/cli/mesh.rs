//! `tissuefit mesh LABELS.tif --out TISSUE.vtk|.vtp [--voxel-size Z,Y,X] [--l-min L] [--min-voxels N]
//! [--border drop|static|keep] [--lumen-labels 5,7] [--nuclei NUCLEI.tif] [--max-refinements N] [--seed S]
//! [--report PATH]`: mesh every label of a segmented volume into a closed cell surface (see
//! [`crate::meshing::mesh_cells_and_nuclei`]) and write the tissue plus a per-label `report.json`
//! (kept/static/dropped and why), both atomically.
//!
//! `tissuefit mesh TISSUE.vtk|.vtp --out NEW.vtp [--length-unit U] [--l-min L]`: re-triangulate every cell
//! of a tissue file (e.g. a multi-material mesh from an image tool) through a voxelisation at l_min/2
//! ([`crate::meshing::retriangulate`]); the same pipeline, report and options.

use super::Outcome;
use super::label_args::{describe_grid, parse_voxel_size};
use crate::geometry::Real;
use crate::imaging::{LabelReadOptions, LabelVolume, SUPPORTED_FORMATS, is_label_volume, read_labels};
use crate::io::{
    Format, LengthScale, OutputPolicy, ReadOptions, parse_lengths, read_tissue, write_atomically, write_tissue,
};
use crate::meshing::{
    BorderPolicy, DEFAULT_MAX_REFINEMENTS, DEFAULT_MIN_VOXELS, DEFAULT_TARGET_NODES, LabelMeshing, LabelMeshingOptions,
    LabelReport, LabelStatus, mesh_cells_and_nuclei, retriangulate,
};
use crate::pipeline::{PipelineConfig, run_mesh};
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct MeshArgs {
    /// Label volume (0 = background): a TIFF stack (.tif/.tiff, ImageJ/OME voxel size), an OME-Zarr
    /// label or image group (a .zarr folder, NGFF 0.4/0.5), an HDF5 dataset (.h5, e.g. PlantSeg's,
    /// element_size_um voxel size; FILE.h5/DATASET names one) or a NumPy .npy array; or a tissue mesh
    /// (.vtk/.vtp, e.g. a multi-material mesh from an image tool) to re-triangulate.
    /// Not with --config (the pipeline's `[input]` names the labels).
    #[arg(required_unless_present = "config", conflicts_with = "config")]
    pub labels: Option<PathBuf>,
    /// A pipeline file: mesh its `[input]` with its `[mesh]` section, exactly as `tissuefit run` does;
    /// --out is then the stage folder (DIR/tissue.vtp, DIR/report.json) and the meshing options come
    /// from the file only.
    #[arg(
        long,
        value_name = "PIPELINE.toml",
        conflicts_with_all = [
            "voxel_size", "l_min", "target_nodes", "min_voxels", "border", "lumen_labels", "nuclei",
            "max_refinements", "length_unit", "seed", "report", "zarr_level",
        ]
    )]
    pub config: Option<PathBuf>,
    /// Output tissue: .vtp (ParaView) or .vtk (SimuCell3D legacy); with --config, the stage folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Voxel size z,y,x (or one for all) overriding the file's metadata: a unit suffix (0.235um,
    /// 235nm), bare numbers are metres, one trailing unit applies to all (0.235,0.15,0.15um). For a
    /// mesh input: the voxel size of the intermediate grid (default l_min/2).
    #[arg(long, value_name = "Z,Y,X", value_parser = parse_voxel_size)]
    pub voxel_size: Option<[Real; 3]>,
    /// Minimum edge length of every cell (e.g. 0.4um; bare numbers are metres). Default: chosen so that a
    /// cell of the median volume gets --target-nodes nodes.
    #[arg(long, value_name = "L", value_parser = parse_length)]
    pub l_min: Option<Real>,
    /// Nodes of a median-sized cell when l_min is chosen automatically.
    #[arg(long, default_value_t = DEFAULT_TARGET_NODES, conflicts_with = "l_min")]
    pub target_nodes: usize,
    /// Labels with fewer voxels are dropped (segmentation debris).
    #[arg(long, default_value_t = DEFAULT_MIN_VOXELS)]
    pub min_voxels: u64,
    /// Labels touching the image border: drop them, mesh them as static cells, or keep them as free cells.
    #[arg(long, default_value_t = BorderPolicy::Keep, value_parser = |s: &str| s.parse::<BorderPolicy>())]
    pub border: BorderPolicy,
    /// Labels meshed as lumen cells, comma-separated (e.g. 5,7).
    #[arg(long, value_delimiter = ',', value_name = "LABELS")]
    pub lumen_labels: Vec<u32>,
    /// Nuclei label volume (any label format) on the same grid: each nucleus becomes a nucleus cell inside the cell holding
    /// most of its voxels; nuclei outside every meshed cell are reported as dropped.
    #[arg(long, value_name = "NUCLEI.tif")]
    pub nuclei: Option<PathBuf>,
    /// OME-Zarr input only: the multiscales scale level to read (0 = full resolution, the default;
    /// level N is usually 2^N times coarser in x and y), for the labels and --nuclei alike. The voxel
    /// size is that level's.
    #[arg(long, value_name = "N")]
    pub zarr_level: Option<usize>,
    /// Retries of a cell that cannot be made valid at the shared l_min, each at half the previous l_min.
    #[arg(long, default_value_t = DEFAULT_MAX_REFINEMENTS)]
    pub max_refinements: u32,
    /// Mesh input only: length unit of its coordinates (m default, um, or the x,y,z voxel size for
    /// meshes in voxel coordinates, e.g. 0.15,0.15,0.235um).
    #[arg(long, value_name = "UNIT")]
    pub length_unit: Option<LengthScale>,
    /// Seed of the surface sampling (each label gets its own stream from seed and label).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Per-label report (default: beside --out, named after its stem: TISSUE.report.json).
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
}

/// One length (l_min); outside 1 nm – 1 mm it is refused as a unit slip, with a hint.
fn parse_length(s: &str) -> Result<Real, String> {
    match parse_lengths(s)?.as_slice() {
        [l] => match crate::io::implausible_length("l_min", *l) {
            Some(bad) => Err(format!("`{s}`: {bad}")),
            None => Ok(*l),
        },
        _ => Err(format!("`{s}`: give one length, e.g. 0.4um")),
    }
}

/// `report.json`; keys are a stable interface (DESIGN.md §2).
#[derive(serde::Serialize)]
struct MeshReport<'a> {
    input: &'a Path,
    output: &'a Path,
    wall_seconds: f64,
    threads: usize,
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
    /// With --nuclei: the nuclei file and one entry per nucleus label.
    #[serde(skip_serializing_if = "Option::is_none")]
    nuclei_input: Option<&'a Path>,
    #[serde(skip_serializing_if = "Option::is_none")]
    nuclei: Option<&'a [LabelReport]>,
    /// With --nuclei: nucleus cell id = nucleus label + this (the largest cell label).
    #[serde(skip_serializing_if = "Option::is_none")]
    nucleus_id_offset: Option<u32>,
}

#[derive(serde::Serialize)]
struct RetriangulatedFrom {
    /// Input cells.
    input_cells: usize,
    /// Rows of the voxelisation that crossed an open input surface an odd number of times.
    odd_rows: u64,
    /// Voxels inside two input cells (kept by the first).
    overlapping_voxels: u64,
}

/// `DIR/STEM.report.json` for `DIR/STEM.EXT`.
fn default_report_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "tissue".into());
    out.with_file_name(format!("{stem}.report.json"))
}

/// What the input was turned into before writing.
struct Meshed {
    meshing: LabelMeshing,
    /// The label grid (the TIFF's, or the voxelisation's for a mesh input).
    volume_grid: crate::imaging::VoxelGrid,
    grid_description: String,
    retriangulated: Option<RetriangulatedFrom>,
}

/// Context for a failed tissue read where a label volume was also possible: names the label formats
/// too when the extension did not say "tissue".
pub(super) fn reading_tissue(path: &Path) -> String {
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("vtk" | "vtp") => format!("reading {}", path.display()),
        _ => format!("reading {} (not a label volume either: those are {SUPPORTED_FORMATS})", path.display()),
    }
}

fn read_label_volume(path: &Path, args: &MeshArgs, what: &str) -> anyhow::Result<LabelVolume> {
    let read_options =
        LabelReadOptions { voxel_size: args.voxel_size, zarr_level: args.zarr_level, ..Default::default() };
    let read = read_labels(path, &read_options).with_context(|| format!("reading {what} {}", path.display()))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", path.display());
    }
    Ok(read.volume)
}

fn progress_bar(len: u64) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(len), indicatif::ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{wide_bar}] {pos}/{len} labels, ETA {eta}")
            .expect("valid template"),
    );
    bar
}

fn mesh_input(args: &MeshArgs, labels: &Path, options: &LabelMeshingOptions) -> anyhow::Result<Meshed> {
    if !is_label_volume(labels) {
        match labels.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
            Some("vtk" | "vtp") => {}
            _ => bail!(
                "{}: give a label volume ({SUPPORTED_FORMATS}) or a tissue mesh to re-triangulate (.vtk/.vtp)",
                labels.display()
            ),
        }
        if args.nuclei.is_some() {
            bail!("--nuclei applies to a label volume input, not to a mesh ({})", labels.display());
        }
        if args.zarr_level.is_some() {
            bail!("--zarr-level applies to an OME-Zarr label input, not to a mesh ({})", labels.display());
        }
        let read_options = ReadOptions { length_scale: args.length_unit.unwrap_or_default(), orient: true };
        let read =
            read_tissue(labels, &read_options).with_context(|| format!("reading tissue {}", labels.display()))?;
        for w in &read.warnings {
            tracing::warn!("{}: {w}", labels.display());
        }
        let r = retriangulate(&read.tissue, options, args.voxel_size)
            .with_context(|| format!("re-triangulating {}", labels.display()))?;
        if r.odd_rows > 0 {
            tracing::warn!(
                "{}: {} voxel rows crossed an open cell surface an odd number of times; inside/outside may be wrong there",
                labels.display(),
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
    if args.length_unit.is_some() {
        bail!("--length-unit applies to a mesh input (.vtk/.vtp); for a label volume use --voxel-size");
    }
    let volume = read_label_volume(labels, args, "label volume")?;
    let nuclei = match &args.nuclei {
        Some(path) => Some(read_label_volume(path, args, "nuclei volume")?),
        None => None,
    };
    let label_count = volume.label_stats().len() + nuclei.as_ref().map_or(0, |n| n.label_stats().len());
    let bar = progress_bar(label_count as u64);
    let meshing =
        mesh_cells_and_nuclei(&volume, nuclei.as_ref(), options, &|_| bar.inc(1)).with_context(|| {
            match &args.nuclei {
                Some(n) => format!("meshing {} with nuclei {}", labels.display(), n.display()),
                None => format!("meshing {}", labels.display()),
            }
        })?;
    bar.finish_and_clear();
    Ok(Meshed { grid_description: describe_grid(&volume), volume_grid: volume.grid(), retriangulated: None, meshing })
}

/// `mesh --config PIPELINE.toml --out DIR`: the pipeline's mesh stage into DIR.
fn run_stage(pipeline: &Path, out: &Path) -> anyhow::Result<Outcome> {
    let config = PipelineConfig::load(pipeline)?;
    OutputPolicy::new()
        .input("--config", pipeline)
        .input_opt("[input] labels", config.input.labels.as_deref())
        .input_opt("[input] mesh", config.input.mesh.as_deref())
        .folder("--out", out, &[crate::pipeline::MESH_TISSUE, "report.json"])?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let started = Instant::now();
    let line = run_mesh(&config.input, &config.mesh, out)?;
    println!(
        "mesh ({}): {line}; {:.2} s; outputs in {}",
        pipeline.display(),
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(Outcome::Success)
}

pub fn run(args: &MeshArgs) -> anyhow::Result<Outcome> {
    if let Some(pipeline) = &args.config {
        return run_stage(pipeline, &args.out);
    }
    let labels = args.labels.as_deref().expect("clap requires LABELS without --config");
    let started = Instant::now();
    let report_path = args.report.clone().unwrap_or_else(|| default_report_path(&args.out));
    let mut outputs = OutputPolicy::new().input("LABELS", labels).input_opt("--nuclei", args.nuclei.as_deref());
    outputs.file("--out", &args.out, Format::Tissue)?;
    outputs.file("--report", &report_path, Format::Json)?;
    let options = LabelMeshingOptions {
        l_min: args.l_min,
        target_nodes: args.target_nodes,
        min_voxels: args.min_voxels,
        border: args.border,
        lumen_labels: args.lumen_labels.clone(),
        seed: args.seed,
        max_refinements: args.max_refinements,
    };
    let Meshed { meshing, volume_grid, grid_description, retriangulated } = mesh_input(args, labels, &options)?;
    for label in &options.lumen_labels {
        if !meshing.report.iter().any(|r| r.label == *label) {
            tracing::warn!("--lumen-labels: label {label} is not in {}", labels.display());
        }
    }
    let (kept, static_cells, dropped) =
        (meshing.count(LabelStatus::Kept), meshing.count(LabelStatus::Static), meshing.count(LabelStatus::Dropped));
    if !meshing.tissue.is_empty() {
        write_tissue(&args.out, &meshing.tissue, &[]).with_context(|| format!("writing {}", args.out.display()))?;
    }
    let wall_seconds = started.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    let with_nuclei = args.nuclei.is_some();
    let report = MeshReport {
        input: labels,
        output: &args.out,
        wall_seconds,
        threads,
        l_min: meshing.l_min,
        voxel_size: volume_grid.voxel_size,
        shape: volume_grid.shape,
        seed: args.seed,
        min_voxels: args.min_voxels,
        border: args.border,
        kept,
        static_cells,
        dropped,
        cells: &meshing.report,
        retriangulated,
        nuclei_input: args.nuclei.as_deref(),
        nuclei: with_nuclei.then_some(meshing.nuclei.as_slice()),
        nucleus_id_offset: with_nuclei.then_some(meshing.nucleus_id_offset),
    };
    write_atomically(&report_path, |w| {
        serde_json::to_writer_pretty(&mut *w, &report).map_err(std::io::Error::other)?;
        std::io::Write::write_all(w, b"\n")
    })
    .with_context(|| format!("writing {}", report_path.display()))?;

    for r in meshing.report.iter().filter(|r| r.status == LabelStatus::Dropped) {
        println!("  label {} dropped: {}", r.label, r.reason.as_deref().unwrap_or("?"));
    }
    for r in meshing.report.iter().filter(|r| r.refined_because.is_some()) {
        println!(
            "  label {} meshed at the finer l_min {:.4} µm ({})",
            r.label,
            r.l_min.unwrap_or(Real::NAN) * 1e6,
            r.refined_because.as_deref().unwrap_or("?")
        );
    }
    for r in meshing.nuclei.iter().filter(|r| r.status == LabelStatus::Dropped) {
        println!("  nucleus {} dropped: {}", r.label, r.reason.as_deref().unwrap_or("?"));
    }
    if meshing.tissue.is_empty() {
        bail!(
            "no cell meshed from {} ({grid_description}): all {dropped} labels were dropped ({}); see {}",
            labels.display(),
            summarise_reasons(&meshing.report),
            report_path.display()
        );
    }
    let mut nodes: Vec<usize> =
        meshing.report.iter().filter(|r| r.status != LabelStatus::Dropped).map(|r| r.nodes).collect();
    nodes.sort_unstable();
    println!(
        "wrote {} ({} cells, {} nodes) and {}",
        args.out.display(),
        meshing.tissue.len(),
        meshing.tissue.node_count(),
        report_path.display()
    );
    let refined = meshing.report.iter().filter(|r| r.refined_because.is_some()).count();
    let nuclei_line = if with_nuclei {
        let assigned = meshing.nuclei.iter().filter(|r| r.status != LabelStatus::Dropped).count();
        format!("; nuclei: {assigned} assigned, {} dropped", meshing.nuclei.len() - assigned)
    } else {
        String::new()
    };
    if nodes.is_empty() {
        println!("{} labels: all dropped{nuclei_line}", meshing.report.len());
        return Ok(Outcome::Success);
    }
    println!(
        "{} labels: {kept} kept, {static_cells} static, {dropped} dropped ({refined} at a finer l_min); nodes per cell \
         min {} / median {} / max {}; l_min {:.4} µm{nuclei_line}; {wall_seconds:.2} s ({threads} threads)",
        meshing.report.len(),
        nodes[0],
        nodes[nodes.len() / 2],
        nodes[nodes.len() - 1],
        meshing.l_min.unwrap_or(Real::NAN) * 1e6,
    );
    Ok(Outcome::Success)
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
        parts.push(format!("{small} with fewer voxels than --min-voxels"));
    }
    if border > 0 {
        parts.push(format!("{border} touching the image border with --border drop"));
    }
    if failed > 0 {
        parts.push(format!("{failed} failed meshing"));
    }
    parts.join(", ")
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
