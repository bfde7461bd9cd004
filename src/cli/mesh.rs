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
use super::label_args::parse_voxel_size;
use crate::geometry::Real;
use crate::io::{Format, LengthScale, OutputPolicy, OutputUnit};
use crate::meshing::{
    BorderPolicy, DEFAULT_MAX_REFINEMENTS, DEFAULT_MIN_VOXELS, DEFAULT_TARGET_NODES, LabelMeshingOptions, LabelStatus,
};
use crate::pipeline::{PipelineConfig, run_mesh};
use crate::stages::{
    self,
    mesh::{MeshOptions, MeshOutcome, default_report_path},
};
use anyhow::Context;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct MeshArgs {
    /// Label volume (0 = background): a TIFF stack (.tif/.tiff, ImageJ/OME voxel size), an OME-Zarr
    /// label or image group (a .zarr folder, NGFF 0.4/0.5), an HDF5 dataset (.h5, e.g. PlantSeg's,
    /// element_size_um voxel size; FILE.h5/DATASET names one) or a NumPy .npy array; or a tissue mesh
    /// (.vtk/.vtp/.ply, e.g. a multi-material mesh from an image tool) to re-triangulate.
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
            "max_refinements", "length_unit", "seed", "report", "zarr_level", "output_unit", "denoise_voxels",
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
    /// Denoise the labels before meshing: a Gaussian-weighted vote of σ = this many voxels (about 2
    /// for masks whose boundaries are off by a voxel). Default: none.
    #[arg(long, value_name = "VOXELS")]
    pub denoise_voxels: Option<Real>,
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
    /// Length unit of the written files: m (SI, the default) or um (micrometres: ParaView's axes read
    /// µm; CSV columns become volume_um3, area_um2, centroid_x_um, …). A .vtp records its unit and
    /// tissuefit reads it back in metres.
    /// Only with a .vtp --out (a SimuCell3D .vtk is in metres); the report stays in metres.
    #[arg(long, value_name = "UNIT", default_value_t = OutputUnit::Metre)]
    pub output_unit: OutputUnit,
}

/// One length (l_min); outside 1 nm – 1 mm it is refused as a unit slip, with a hint.
fn parse_length(s: &str) -> Result<Real, String> {
    crate::io::parse_named_length("l_min", s)
}

/// `mesh --config PIPELINE.toml --out DIR`: the pipeline's mesh stage into DIR.
fn run_stage(pipeline: &Path, out: &Path) -> anyhow::Result<Outcome> {
    let config = PipelineConfig::load(pipeline)?;
    OutputPolicy::new()
        .input("--config", pipeline)
        .input_opt("[input] labels", config.input.labels.as_deref())
        .input_opt("[input] mesh", config.input.mesh.as_deref())
        .folder(
            "--out",
            out,
            &[crate::pipeline::MESH_TISSUE, &stages::mesh::tissue_file_in(config.output.length_unit), "report.json"],
        )?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let started = Instant::now();
    let line = run_mesh(&config.input, &config.mesh, &config.output, out, true)?;
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
    let report_path = args.report.clone().unwrap_or_else(|| default_report_path(&args.out));
    let mut outputs = OutputPolicy::new().input("LABELS", labels).input_opt("--nuclei", args.nuclei.as_deref());
    outputs.file("--out", &args.out, Format::Tissue)?;
    outputs.file("--report", &report_path, Format::Json)?;
    let options = MeshOptions {
        meshing: LabelMeshingOptions {
            l_min: args.l_min,
            target_nodes: args.target_nodes,
            min_voxels: args.min_voxels,
            border: args.border,
            lumen_labels: args.lumen_labels.clone(),
            seed: args.seed,
            max_refinements: args.max_refinements,
            denoise_voxels: args.denoise_voxels,
        },
        voxel_size: args.voxel_size,
        zarr_level: args.zarr_level,
        nuclei: args.nuclei.clone(),
        length_unit: args.length_unit,
        output_unit: args.output_unit,
    };
    let MeshOutcome { meshing, wall_seconds, threads } =
        stages::mesh::run(labels, &options, &args.out, &report_path, true)?;
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
    let (kept, static_cells, dropped) =
        (meshing.count(LabelStatus::Kept), meshing.count(LabelStatus::Static), meshing.count(LabelStatus::Dropped));
    let mut nodes: Vec<usize> =
        meshing.report.iter().filter(|r| r.status != LabelStatus::Dropped).map(|r| r.nodes).collect();
    nodes.sort_unstable();
    let unit = if args.output_unit.is_si() { String::new() } else { format!(", lengths in {}", args.output_unit) };
    println!(
        "wrote {}{unit} ({} cells, {} nodes) and {}",
        args.out.display(),
        meshing.tissue.len(),
        meshing.tissue.node_count(),
        report_path.display()
    );
    let refined = meshing.report.iter().filter(|r| r.refined_because.is_some()).count();
    let nuclei_line = if args.nuclei.is_some() {
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
