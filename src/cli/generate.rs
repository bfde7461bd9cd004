//! `tissuefit generate labels --kind KIND ... --out X.tif`: a synthetic label volume (sphere,
//! ellipsoid, cube, doublet, aggregate with optional lumen) written as an ImageJ TIFF.
//!
//! `tissuefit generate mesh --kind KIND [--cells N] [--cell-size L] [--min-edge-length L] ... --out
//! TISSUE.vtp|.vtk`: a synthetic tissue (sphere, cube, vesicle with lumen and ECM, sheet, tube,
//! spheroid; optional nuclei) meshed at l_min ([`crate::meshing::generate_tissue`]), plus a JSON report
//! beside it (counts by kind, nodes, volumes, geometry), both written atomically.
//!
//! `tissuefit generate noise LABELS --amplitude 1 --out NOISY.tif`: a label volume with
//! segmentation-like noise on its boundaries ([`crate::imaging::perturb_boundaries`]).

use super::Outcome;
use super::label_args::{LabelOutputArgs, describe_grid, parse_shape, parse_voxel_size};
use crate::geometry::Real;
use crate::imaging::{
    BoundaryNoise, LabelPattern, LabelReadOptions, LabelSpec, generate_labels, generate_nuclei, perturb_boundaries,
    read_labels, write_label_tiff,
};
use crate::io::{Format, OutputPolicy, parse_lengths, write_atomically, write_tissue};
use crate::meshing::{GenerationSummary, TissueKind, TissueSpec, generate_tissue};
use anyhow::Context;
use std::path::{Path, PathBuf};

#[derive(clap::Subcommand, Debug)]
pub enum GenerateCommand {
    /// A synthetic label volume: sphere, ellipsoid, cube, doublet (two cells with a flat interface)
    /// or aggregate (a seeded Voronoi packing of --cells cells in a ball, optionally around a lumen).
    Labels(GenerateLabelsArgs),
    /// A synthetic tissue mesh: sphere or cube (one cell), vesicle (columnar cells around a lumen,
    /// encased by an ECM), sheet (flat columnar patch), tube (cylindrical monolayer) or spheroid (bulk
    /// Voronoi ball), at a given minimum edge length, optionally with nuclei.
    Mesh(GenerateMeshArgs),
    /// A copy of a label volume with segmentation-like noise on its boundaries (a smooth random
    /// displacement of --amplitude voxels RMS, bumps --correlation voxels wide), to measure how much a
    /// fit or a measurement depends on where the segmenter put the boundaries.
    Noise(GenerateNoiseArgs),
}

#[derive(clap::Args, Debug)]
pub struct GenerateNoiseArgs {
    /// Label volume to perturb (TIFF, OME-Zarr, HDF5 or .npy).
    pub labels: PathBuf,
    /// Root-mean-square displacement of the boundaries along each axis, in voxels (a segmentation's
    /// error is about 1).
    #[arg(long, default_value_t = 1.0)]
    pub amplitude: Real,
    /// Width (σ, voxels) of the bumps of the displacement field: 0 = independent per voxel
    /// (salt-and-pepper), 1–2 = the wavy boundaries of a segmentation.
    #[arg(long, default_value_t = 1.5)]
    pub correlation: Real,
    /// Seed of the noise.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Voxel size z,y,x of the input, overriding its metadata (e.g. 0.235,0.15,0.15um).
    #[arg(long, value_name = "Z,Y,X", value_parser = parse_voxel_size)]
    pub voxel_size: Option<[Real; 3]>,
    /// Output label TIFF.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub output: LabelOutputArgs,
}

fn run_noise(args: &GenerateNoiseArgs) -> anyhow::Result<Outcome> {
    OutputPolicy::new().input("LABELS", &args.labels).file("--out", &args.out, Format::Tiff)?;
    let options = LabelReadOptions { voxel_size: args.voxel_size, ..Default::default() };
    let read = read_labels(&args.labels, &options)
        .with_context(|| format!("reading label volume {}", args.labels.display()))?;
    let noise = BoundaryNoise { amplitude: args.amplitude, correlation: args.correlation, seed: args.seed };
    let (volume, stats) = perturb_boundaries(&read.volume, &noise)
        .with_context(|| format!("perturbing the boundaries of {}", args.labels.display()))?;
    let dtype = write_label_tiff(&args.out, &volume, &args.output.options())
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!(
        "wrote {}: {}, {}; boundaries displaced by {} voxels RMS (correlation {} voxels, seed {}): {} of {} voxels \
         changed label",
        args.out.display(),
        describe_grid(&volume),
        dtype.name(),
        args.amplitude,
        args.correlation,
        args.seed,
        stats.changed,
        stats.voxels
    );
    Ok(Outcome::Success)
}

#[derive(clap::Args, Debug)]
pub struct GenerateMeshArgs {
    /// sphere, cube, vesicle, sheet, tube or spheroid.
    #[arg(long, value_parser = |s: &str| s.parse::<TissueKind>())]
    pub kind: TissueKind,
    /// Number of cells (default: 1 for sphere and cube, 100 for a vesicle, 37 for a sheet, 60 for a tube,
    /// 30 for a spheroid). The paper's Fig. 3a vesicle has 432.
    #[arg(long)]
    pub cells: Option<usize>,
    /// Cube root of the mean cell volume, l (e.g. 8um; bare numbers are metres).
    #[arg(long, value_name = "L", default_value = "8um", value_parser = parse_length)]
    pub cell_size: Real,
    /// Minimum edge length l_min of every surface (e.g. 0.8um). Default: cell size / 8 (about 300 nodes
    /// per cell).
    #[arg(long, value_name = "L", value_parser = parse_length)]
    pub min_edge_length: Option<Real>,
    /// Height / width of the columnar cells of a vesicle, sheet or tube.
    #[arg(long, default_value_t = 1.5)]
    pub aspect: Real,
    /// Seed of the cell centres and of the surface sampling.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Put a nucleus (kind nucleus) inside every epithelial cell.
    #[arg(long)]
    pub nuclei: bool,
    /// Nucleus radius as a fraction of its cell's equivalent-sphere radius (capped to stay 1.25·l_min
    /// inside the cell).
    #[arg(long, default_value_t = 0.5, requires = "nuclei")]
    pub nucleus_radius: Real,
    /// Elongation of each nucleus along its cell's longest principal axis: an ellipsoid whose semi-axis
    /// along it is this × its radius (≥ 1; 1 = a sphere).
    #[arg(long, default_value_t = 1.0, requires = "nuclei")]
    pub nucleus_aspect: Real,
    /// Sheet only: the outer ring of cells is static (never moves), as the imaged patch of the paper's
    /// Application 2.
    #[arg(long)]
    pub static_border: bool,
    /// Tube only: fill the tube with a lumen.
    #[arg(long)]
    pub lumen: bool,
    /// Vesicle only: room inside the ECM as a multiple of the cells' volume (1: the ECM touches the
    /// cells; 2: the cells can grow to twice their volume, as in the paper's Application 1).
    #[arg(long, default_value_t = 1.0)]
    pub ecm_room: Real,
    /// Output tissue: .vtp (ParaView) or .vtk (SimuCell3D legacy).
    #[arg(long)]
    pub out: PathBuf,
    /// JSON report (default: beside --out, named after its stem: TISSUE.report.json).
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
}

fn parse_length(s: &str) -> Result<Real, String> {
    match parse_lengths(s)?.as_slice() {
        [l] if l.is_finite() && *l > 0.0 => Ok(*l),
        [_] => Err(format!("`{s}`: the length must be positive")),
        _ => Err(format!("`{s}`: give one length, e.g. 0.8um")),
    }
}

#[derive(serde::Serialize)]
struct GenerateReport<'a> {
    output: &'a Path,
    wall_seconds: f64,
    threads: usize,
    #[serde(flatten)]
    summary: GenerationSummary,
}

fn run_mesh(args: &GenerateMeshArgs) -> anyhow::Result<Outcome> {
    let started = std::time::Instant::now();
    let report_path = args.report.clone().unwrap_or_else(|| {
        let stem = args.out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "tissue".into());
        args.out.with_file_name(format!("{stem}.report.json"))
    });
    let mut outputs = OutputPolicy::new();
    outputs.file("--out", &args.out, Format::Tissue)?;
    outputs.file("--report", &report_path, Format::Json)?;
    let cells = args.cells.unwrap_or(args.kind.default_cells());
    let spec = TissueSpec {
        kind: args.kind,
        cells,
        cell_size: args.cell_size,
        l_min: args.min_edge_length.unwrap_or(args.cell_size / 8.0),
        aspect: args.aspect,
        seed: args.seed,
        nucleus_radius: args.nuclei.then_some(args.nucleus_radius),
        nucleus_aspect: args.nucleus_aspect,
        static_border: args.static_border,
        lumen: args.lumen,
        ecm_room: args.ecm_room,
    };
    let generated = generate_tissue(&spec).with_context(|| format!("generating a {}", args.kind))?;
    let tissue = &generated.tissue;
    write_tissue(&args.out, tissue, &[]).with_context(|| format!("writing {}", args.out.display()))?;
    let wall_seconds = started.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    let report = GenerateReport { output: &args.out, wall_seconds, threads, summary: generated.summary() };
    let (mean_cell_volume, max_penetration) = (report.summary.mean_cell_volume, report.summary.max_penetration);
    write_atomically(&report_path, |w| {
        serde_json::to_writer_pretty(&mut *w, &report).map_err(std::io::Error::other)?;
        std::io::Write::write_all(w, b"\n")
    })
    .with_context(|| format!("writing {}", report_path.display()))?;
    let counts: Vec<String> = report.summary.kinds.iter().map(|(name, k)| format!("{} {name}", k.bodies)).collect();
    println!(
        "wrote {} ({}: {}; {} nodes) and {}",
        args.out.display(),
        args.kind,
        counts.join(", "),
        report.summary.nodes,
        report_path.display()
    );
    println!(
        "l_min {:.4} µm; mean cell volume {:.4e} m³ (l = {:.4} µm); deepest node inside another body {:.4} µm; \
         {wall_seconds:.2} s ({threads} threads)",
        spec.l_min * 1e6,
        mean_cell_volume,
        report.summary.length_scale * 1e6,
        max_penetration * 1e6,
    );
    Ok(Outcome::Success)
}

#[derive(clap::Args, Debug)]
pub struct GenerateLabelsArgs {
    /// sphere, ellipsoid, cube, doublet or aggregate.
    #[arg(long, value_parser = |s: &str| s.parse::<LabelPattern>())]
    pub kind: LabelPattern,
    /// Cells of an aggregate.
    #[arg(long, default_value_t = 8)]
    pub cells: usize,
    /// Voxel size z,y,x (or one for all), e.g. 0.5um or 0.235,0.15,0.15um; bare numbers are metres.
    #[arg(long, value_name = "Z,Y,X", default_value = "0.5um", value_parser = parse_voxel_size)]
    pub voxel_size: [Real; 3],
    /// Grid shape z,y,x in voxels (or one for all).
    #[arg(long, value_name = "Z,Y,X", default_value = "64", value_parser = parse_shape)]
    pub shape: [usize; 3],
    /// Seed of the aggregate's random cell centres.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Give an aggregate a central lumen (its label is the largest, printed on output).
    #[arg(long)]
    pub lumen: bool,
    /// Output label TIFF.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write a nuclei label TIFF on the same grid: one ball per cell around its centroid, radius
    /// --nucleus-radius × the cell's equivalent-sphere radius, labelled like its cell (lumen excluded).
    #[arg(long, value_name = "NUCLEI.tif")]
    pub nuclei: Option<PathBuf>,
    /// Nucleus radius as a fraction of the cell's equivalent-sphere radius.
    #[arg(long, default_value_t = 0.5, requires = "nuclei")]
    pub nucleus_radius: Real,
    #[command(flatten)]
    pub output: LabelOutputArgs,
}

pub fn run(cmd: &GenerateCommand) -> anyhow::Result<Outcome> {
    let args = match cmd {
        GenerateCommand::Labels(args) => args,
        GenerateCommand::Mesh(args) => return run_mesh(args),
        GenerateCommand::Noise(args) => return run_noise(args),
    };
    if args.lumen && args.kind != LabelPattern::Aggregate {
        anyhow::bail!("--lumen applies to --kind aggregate only");
    }
    let mut outputs = OutputPolicy::new();
    outputs.file("--out", &args.out, Format::Tiff)?;
    if let Some(nuclei) = &args.nuclei {
        outputs.file("--nuclei", nuclei, Format::Tiff)?;
    }
    let spec = LabelSpec {
        pattern: args.kind,
        shape: args.shape,
        voxel_size: args.voxel_size,
        cells: args.cells,
        seed: args.seed,
        lumen: args.lumen,
    };
    let generated = generate_labels(&spec).with_context(|| {
        format!("generating labels on --shape {:?} (z,y,x) with --voxel-size {:?} m", spec.shape, spec.voxel_size)
    })?;
    // Both volumes are made before either is written, so an error leaves neither file.
    let nuclei = match &args.nuclei {
        Some(_) => Some(
            generate_nuclei(&generated.volume, &generated.cells, args.nucleus_radius).context("generating nuclei")?,
        ),
        None => None,
    };
    let dtype = write_label_tiff(&args.out, &generated.volume, &args.output.options())
        .with_context(|| format!("writing {}", args.out.display()))?;
    let cells = &generated.cells;
    let labels = match (cells.first(), cells.last()) {
        (Some(a), Some(b)) if a != b => format!("labels {a}-{b}"),
        (Some(a), _) => format!("label {a}"),
        _ => "no labels".into(),
    };
    let lumen = generated.lumen.map(|l| format!(", lumen label {l}")).unwrap_or_default();
    println!(
        "wrote {}: {}, {}, {}, {} cells ({labels}){lumen}",
        args.out.display(),
        args.kind,
        describe_grid(&generated.volume),
        dtype.name(),
        cells.len()
    );
    if let (Some(path), Some(nuclei)) = (&args.nuclei, &nuclei) {
        write_label_tiff(path, nuclei, &args.output.options())
            .with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}: {} nuclei", path.display(), nuclei.label_stats().len());
    }
    Ok(Outcome::Success)
}
