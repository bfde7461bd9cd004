//! `tissuefit voxelize TISSUE --out LABELS.tif (--like LABELS.tif | --voxel-size Z,Y,X [--shape Z,Y,X])`:
//! rasterise the cells of a tissue file into a label TIFF (labels = cell ids) with ImageJ metadata,
//! on the grid of an existing label volume or on a grid around the tissue.

use super::label_args::{LabelOutputArgs, describe_grid, parse_shape, parse_voxel_size};
use super::{InputArgs, Outcome};
use crate::geometry::{Real, Vec3, bounding_box};
use crate::imaging::{LabelReadOptions, VoxelGrid, read_labels, voxelize_with_stats, write_label_tiff};
use crate::io::{Format, OutputPolicy, read_tissue};
use anyhow::{Context, bail};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct VoxelizeArgs {
    /// Tissue file (.vtk, .vtp or .ply).
    pub tissue: PathBuf,
    /// Output label TIFF.
    #[arg(long)]
    pub out: PathBuf,
    /// Use the grid (shape, voxel size, origin) of this label volume (TIFF, OME-Zarr, HDF5 or .npy), e.g.
    /// the segmentation the tissue was meshed from, so the two overlay voxel for voxel.
    #[arg(long, value_name = "LABELS", conflicts_with = "shape")]
    pub like: Option<PathBuf>,
    /// With an OME-Zarr --like: the scale level whose grid to use (0 = full resolution, the default).
    #[arg(long, value_name = "N", requires = "like")]
    pub zarr_level: Option<usize>,
    /// Voxel size z,y,x (or one for all): a unit suffix (0.235um, 235nm, 2.35e-7m), bare numbers
    /// are metres, one trailing unit applies to all (0.235,0.15,0.15um). With --like it overrides the
    /// voxel size of that file.
    #[arg(long, value_name = "Z,Y,X", value_parser = parse_voxel_size)]
    pub voxel_size: Option<[Real; 3]>,
    /// Grid shape z,y,x in voxels, centred on the tissue (default: the tissue's bounding box plus
    /// --margin voxels on each side).
    #[arg(long, value_name = "Z,Y,X", value_parser = parse_shape)]
    pub shape: Option<[usize; 3]>,
    /// Background voxels around the tissue when the grid is sized automatically.
    #[arg(long, default_value_t = 2)]
    pub margin: usize,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub output: LabelOutputArgs,
}

pub fn run(args: &VoxelizeArgs) -> anyhow::Result<Outcome> {
    OutputPolicy::new().input("TISSUE", &args.tissue).input_opt("--like", args.like.as_deref()).file(
        "--out",
        &args.out,
        Format::Tiff,
    )?;
    let t0 = Instant::now();
    let read = read_tissue(&args.tissue, &args.input.read_options())
        .with_context(|| format!("reading {}", args.tissue.display()))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", args.tissue.display());
    }
    let tissue = read.tissue;
    let read_seconds = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let grid = match (&args.like, args.voxel_size) {
        (Some(like), voxel_size) => {
            let options = LabelReadOptions { voxel_size, zarr_level: args.zarr_level, ..Default::default() };
            let labels = read_labels(like, &options)
                .with_context(|| format!("reading the grid of label volume {}", like.display()))?;
            labels.volume.grid()
        }
        (None, Some(voxel_size)) => {
            let points: Vec<Vec3> = tissue.cells().iter().flat_map(|c| c.mesh().positions().iter().copied()).collect();
            let Some((lo, hi)) = bounding_box(&points) else {
                bail!("{} holds no cells to voxelise", args.tissue.display());
            };
            match args.shape {
                None => VoxelGrid::covering(lo, hi, voxel_size, args.margin)
                    .with_context(|| format!("--voxel-size {voxel_size:?} (z,y,x) m around the tissue"))?,
                Some(shape) => {
                    let [sz, sy, sx] = voxel_size;
                    let half = Vec3::new(
                        (shape[2] - 1) as Real * sx,
                        (shape[1] - 1) as Real * sy,
                        (shape[0] - 1) as Real * sz,
                    ) / 2.0;
                    VoxelGrid::new(shape, voxel_size, (lo + hi) / 2.0 - half)
                        .with_context(|| format!("--shape {shape:?} with --voxel-size {voxel_size:?} (z,y,x)"))?
                }
            }
        }
        (None, None) => bail!("give the grid: --like LABELS.tif, or --voxel-size Z,Y,X (with optional --shape)"),
    };
    let grid_seconds = t1.elapsed().as_secs_f64();
    let t2 = Instant::now();
    let (volume, stats) = voxelize_with_stats(&tissue, &grid).with_context(|| match (&args.like, args.shape) {
        (Some(like), _) => format!("voxelising onto the grid of --like {}", like.display()),
        (None, Some(shape)) => format!("voxelising onto --shape {shape:?} (z,y,x)"),
        (None, None) => format!("voxelising with --voxel-size {:?} m (z,y,x) around the tissue", grid.voxel_size),
    })?;
    let voxelize_seconds = t2.elapsed().as_secs_f64();
    // An all-background volume is no label image of the tissue: refuse it rather than write it.
    if stats.voxels.iter().all(|(_, n)| *n == 0) {
        let [sz, sy, sx] = grid.voxel_size;
        bail!(
            "no voxel of the grid ({:?} voxels of {sz:e},{sy:e},{sx:e} m, z,y,x) lies inside a cell of {}, so {} would \
             hold no label; the voxels are too coarse for the cells (or the grid misses them): give a smaller \
             --voxel-size (a bare number is metres: 0.5 is 0.5 m, 0.5um is 0.5 µm), or --like a label volume of \
             this tissue",
            grid.shape,
            args.tissue.display(),
            args.out.display()
        );
    }
    let t3 = Instant::now();
    let dtype = write_label_tiff(&args.out, &volume, &args.output.options())
        .with_context(|| format!("writing {}", args.out.display()))?;
    let write_seconds = t3.elapsed().as_secs_f64();

    println!("wrote {}: {}, {}, {} cells", args.out.display(), describe_grid(&volume), dtype.name(), tissue.len());
    println!(
        "times: read tissue {read_seconds:.3} s, grid {grid_seconds:.3} s, voxelise {voxelize_seconds:.3} s, write {write_seconds:.3} s ({} threads)",
        rayon::current_num_threads()
    );
    let voxel_volume = volume.voxel_volume();
    for ((id, voxels), cell) in stats.voxels.iter().zip(tissue.cells()) {
        let v = *voxels as Real * voxel_volume;
        let mesh = cell.mesh().signed_volume();
        println!(
            "  label {id}: {voxels} voxels, {v:.4e} m³ (mesh {mesh:.4e} m³, {:+.2} %)",
            if mesh != 0.0 { 100.0 * (v - mesh) / mesh } else { 0.0 }
        );
    }
    if stats.overlapping_voxels > 0 {
        tracing::warn!(
            "{} voxels lie inside more than one cell; each went to the cell listed first",
            stats.overlapping_voxels
        );
    }
    if stats.odd_rows > 0 {
        tracing::warn!("{} rows crossed an open surface; run `tissuefit inspect` on the tissue", stats.odd_rows);
    }
    Ok(Outcome::Success)
}
