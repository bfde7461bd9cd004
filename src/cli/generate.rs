//! `tissuefit generate labels --kind KIND ... --out X.tif`: a synthetic label volume (sphere,
//! ellipsoid, cube, doublet, aggregate with optional lumen) written as an ImageJ TIFF.

use super::Outcome;
use super::label_args::{LabelOutputArgs, describe_grid, parse_shape, parse_voxel_size};
use crate::geometry::Real;
use crate::imaging::{LabelPattern, LabelSpec, generate_labels, generate_nuclei, write_label_tiff};
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Subcommand, Debug)]
pub enum GenerateCommand {
    /// A synthetic label volume: sphere, ellipsoid, cube, doublet (two cells with a flat interface)
    /// or aggregate (a seeded Voronoi packing of --cells cells in a ball, optionally around a lumen).
    Labels(GenerateLabelsArgs),
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
    let GenerateCommand::Labels(args) = cmd;
    if args.lumen && args.kind != LabelPattern::Aggregate {
        anyhow::bail!("--lumen applies to --kind aggregate only");
    }
    let spec = LabelSpec {
        pattern: args.kind,
        shape: args.shape,
        voxel_size: args.voxel_size,
        cells: args.cells,
        seed: args.seed,
        lumen: args.lumen,
    };
    let generated = generate_labels(&spec).context("generating labels")?;
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
