//! `tissuefit convert IN OUT`: between SimuCell3D legacy VTK, multi-material meshes and ParaView.

use super::{InputArgs, Outcome};
use crate::io::{CellField, Format, OutputPolicy, read_tissue, write_tissue};
use crate::mechanics::Parameters;
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct ConvertArgs {
    /// Input tissue file (.vtk, .vtp or .ply).
    pub input: PathBuf,
    /// Output file: .vtp (ParaView PolyData) or .vtk (SimuCell3D legacy, opens in the reference program).
    pub output: PathBuf,
    /// Parameter file used for the per-cell pressure field (default: built-in defaults).
    #[arg(long, value_name = "TOML")]
    pub config: Option<PathBuf>,
    #[command(flatten)]
    pub input_args: InputArgs,
}

pub fn run(args: &ConvertArgs) -> anyhow::Result<Outcome> {
    OutputPolicy::new().input("INPUT", &args.input).input_opt("--config", args.config.as_deref()).file(
        "OUTPUT",
        &args.output,
        Format::Tissue,
    )?;
    let read = read_tissue(&args.input, &args.input_args.read_options())
        .with_context(|| format!("reading {}", args.input.display()))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", args.input.display());
    }
    let params = match &args.config {
        Some(path) => Parameters::load(path)?,
        None => Parameters::default(),
    };
    let tissue = &read.tissue;
    // Pressure p = min(−K ln(V/V0), p_max) needs each cell's parameter set.
    let pressure: Option<Vec<f64>> = tissue
        .cells()
        .iter()
        .map(|c| params.cell_type(c.cell_type()).map(|t| t.pressure(c.mesh().signed_volume(), c.target_volume())))
        .collect();
    let mut fields = Vec::new();
    match &pressure {
        Some(p) => fields.push(CellField { name: "pressure", values: p }),
        None => tracing::warn!(
            "pressure not written: some cells have a cell type the parameters do not define ({} types); pass --config with matching [[cell_types]]",
            params.cell_types.len()
        ),
    }
    write_tissue(&args.output, tissue, &fields).with_context(|| format!("writing {}", args.output.display()))?;
    tracing::info!(
        "wrote {} ({} cells, {} nodes, {} faces)",
        args.output.display(),
        tissue.len(),
        tissue.node_count(),
        tissue.face_count()
    );
    Ok(Outcome::Success)
}
