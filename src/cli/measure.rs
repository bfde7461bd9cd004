//! `tissuefit measure TISSUE|LABELS.tif --out DIR [--compare TISSUE|LABELS.tif]`: morphology of a
//! tissue mesh, or of a label volume measured on its voxels, into `cells.csv`, `contacts.csv` and
//! `summary.json` (SI units), each written to a temporary name and renamed. With `--compare`, every
//! cell also gets its IoU and χ = 1 − IoU against the same label of the other input. With
//! `--zarr-properties` (an OME-Zarr label input), the cells' rows also go into the label image's
//! NGFF `image-label.properties`, after the files.

use super::label_args::parse_voxel_size;
use super::{InputArgs, Outcome};
use crate::geometry::Real;
use crate::io::{OutputPolicy, OutputUnit, parse_length};
use crate::meshing::{BorderPolicy, DEFAULT_MIN_VOXELS};
use crate::morphology::{ContactRule, Morphology};
use crate::pipeline::{PipelineConfig, describe_morphology as describe, measure_options};
use crate::stages::{
    self,
    measure::{LabelInputOptions, MeasureConfig, MeasureOptions, OUTPUT_FILES, is_labels},
};
use anyhow::bail;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct MeasureArgs {
    /// Tissue file (.vtk, .vtp or .ply). or a label volume (0 = background) measured directly on its voxels
    /// (cell ids = labels): a TIFF stack (.tif/.tiff), an OME-Zarr label or image group (a .zarr
    /// folder), an HDF5 dataset (.h5, e.g. PlantSeg's; FILE.h5/DATASET names one) or a NumPy .npy
    /// array, recognised by content.
    pub tissue: PathBuf,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// A pipeline file: measure TISSUE (its mesh stage's `tissue.vtp`) with the file's `[measure]`
    /// section, exactly as `tissuefit run` does; the measurement options come from the file only.
    #[arg(
        long,
        value_name = "PIPELINE.toml",
        conflicts_with_all = [
            "contact_distance", "distance_contacts", "include_static", "exterior_free_fraction", "length_unit", "orient", "voxel_size",
            "border", "lumen_labels", "min_voxels", "normal_smoothing", "compare", "compare_voxel_size",
            "zarr_level", "output_unit", "zarr_properties",
        ]
    )]
    pub config: Option<PathBuf>,
    /// How the tissue is measured (the pipeline's `[measure]`).
    #[command(flatten)]
    pub settings: MeasureConfig,
    #[command(flatten)]
    pub input: InputArgs,
    /// Label volume only: voxel size z,y,x (or one for all) overriding the file's metadata
    /// (0.235,0.15,0.15um); a .npy file has none, so give it there.
    #[arg(long, value_name = "Z,Y,X", value_parser = parse_voxel_size)]
    pub voxel_size: Option<[Real; 3]>,
    /// OME-Zarr input only: the multiscales scale level to read (0 = full resolution, the default;
    /// level N is usually 2^N times coarser in x and y). The voxel size is that level's.
    #[arg(long, value_name = "N")]
    pub zarr_level: Option<usize>,
    /// Label volume only: labels touching the image border are kept as cells (default, as `mesh`), flagged
    /// static (measured, left out of the statistics), or dropped.
    #[arg(long, default_value_t = BorderPolicy::Keep, value_parser = |s: &str| s.parse::<BorderPolicy>())]
    pub border: BorderPolicy,
    /// Label volume only: labels that are lumen bodies (for the layer count), comma-separated.
    #[arg(long, value_delimiter = ',', value_name = "LABELS")]
    pub lumen_labels: Vec<u32>,
    /// Label volume only: labels with fewer voxels are debris and are dropped (as `mesh`).
    #[arg(long, default_value_t = DEFAULT_MIN_VOXELS)]
    pub min_voxels: u64,
    /// Label volume only: σ of the Gaussian smoothing for surface normals (a length, 0.2um). Default: 2 ×
    /// the largest voxel size.
    #[arg(long, value_name = "LENGTH", value_parser = parse_length)]
    pub normal_smoothing: Option<Real>,
    /// Compare shapes with this tissue or label volume (cells matched by id = label): adds `iou` and `chi`
    /// to cells.csv and `mean_chi` to summary.json. A tissue is voxelised on the label volume's grid; two
    /// label volumes must share a grid; two tissues are voxelised on a common grid (--compare-voxel-size).
    #[arg(long, value_name = "FILE")]
    pub compare: Option<PathBuf>,
    /// Voxel size of the common grid when both inputs are tissues (z,y,x or one). Default: half the
    /// mean edge length of the measured tissue.
    #[arg(long, value_name = "Z,Y,X", value_parser = parse_voxel_size, requires = "compare")]
    pub compare_voxel_size: Option<[Real; 3]>,
    /// Length unit of the written files: m (SI, the default) or um (micrometres: ParaView's axes read
    /// µm; CSV columns become volume_um3, area_um2, centroid_x_um, …). summary.json
    /// then says length_unit = "um" and renames its dimensioned keys the same way.
    #[arg(long, value_name = "UNIT", default_value_t = OutputUnit::Metre)]
    pub output_unit: OutputUnit,
}

/// `measure TISSUE --config PIPELINE.toml --out DIR`: the pipeline's measure stage into DIR.
fn run_stage(tissue: &Path, pipeline: &Path, out: &Path) -> anyhow::Result<Outcome> {
    let config = PipelineConfig::load(pipeline)?;
    OutputPolicy::new().input("TISSUE", tissue).input("--config", pipeline).folder("--out", out, &OUTPUT_FILES)?;
    if is_labels(tissue) {
        bail!(
            "{}: with a pipeline file ({}), measure takes the mesh stage's tissue (e.g. runs/NAME/mesh/tissue.vtp), \
             not a label volume",
            tissue.display(),
            pipeline.display()
        );
    }
    let started = Instant::now();
    let mut options = measure_options(&config.measure, &config.input, &config.output);
    // summary.json names the tissue as a run directory does (`../mesh/tissue.vtp`) only where it
    // lies there.
    let beside = out.parent().map(|run| run.join("mesh").join(crate::pipeline::MESH_TISSUE));
    let in_run_layout =
        beside.is_some_and(|beside| matches!((beside.canonicalize(), tissue.canonicalize()), (Ok(a), Ok(b)) if a == b));
    if !in_run_layout {
        options.input_name = None;
    }
    let report = stages::measure::run(tissue, &options, out)?;
    let line = describe(&report.morphology);
    println!(
        "measure ({}): {line}; {:.2} s; outputs in {}",
        pipeline.display(),
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(Outcome::Success)
}

pub fn run(args: &MeasureArgs) -> anyhow::Result<Outcome> {
    if let Some(pipeline) = &args.config {
        return run_stage(&args.tissue, pipeline, &args.out);
    }
    OutputPolicy::new().input("TISSUE", &args.tissue).input_opt("--compare", args.compare.as_deref()).folder(
        "--out",
        &args.out,
        &OUTPUT_FILES,
    )?;
    let options = MeasureOptions {
        config: args.settings.clone(),
        read: args.input.read_options(),
        labels: LabelInputOptions {
            voxel_size: args.voxel_size,
            zarr_level: args.zarr_level,
            border: args.border,
            lumen_labels: args.lumen_labels.clone(),
            min_voxels: args.min_voxels,
            normal_smoothing: args.normal_smoothing,
        },
        compare: args.compare.clone(),
        compare_voxel_size: args.compare_voxel_size,
        input_name: None,
        output_unit: args.output_unit,
        label_store: None,
        output_name: None,
    };
    let report = stages::measure::run(&args.tissue, &options, &args.out)?;
    print_summary(&mut std::io::stdout().lock(), &args.tissue, &report.morphology, report.wall_seconds)?;
    Ok(Outcome::Success)
}

fn print_summary(out: &mut impl Write, input: &Path, m: &Morphology, wall_seconds: f64) -> std::io::Result<()> {
    let s = &m.summary;
    let opt = |v: Option<Real>, digits: usize| v.map_or("n/a".to_string(), |x| format!("{x:.digits$}"));
    writeln!(
        out,
        "{}: {} cells measured ({} bodies), {} cell contacts, {}, {:.3} s",
        input.display(),
        s.cells,
        s.bodies.total,
        s.cell_contacts,
        match (s.contact_rule, s.contact_distance) {
            (ContactRule::Distance, Some(d)) => format!("δ = {d:.3e} m"),
            (ContactRule::InterfaceLabels, _) => "contacts from interface labels".to_string(),
            _ => "voxel-face contacts".to_string(),
        },
        wall_seconds
    )?;
    writeln!(
        out,
        "  sphericity ⟨Ψ⟩ = {}, contact fraction ⟨φ⟩ = {}, coordination ⟨z⟩ = {}, contact angle ⟨θ⟩ = {}, layers N = {}",
        opt(s.mean_sphericity, 4),
        opt(s.mean_contact_fraction, 4),
        opt(s.mean_coordination, 2),
        s.mean_contact_angle_deg.map_or("n/a".to_string(), |a| format!("{a:.1}°")),
        s.layers.map_or("n/a".to_string(), |n| n.to_string())
    )?;
    if let Some(chi) = s.mean_chi {
        writeln!(out, "  shape deformation ⟨χ⟩ = 1 − ⟨IoU⟩ = {chi:.4}")?;
    }
    Ok(())
}
