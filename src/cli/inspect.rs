//! `tissuefit inspect FILE [--json]`: what a tissue file holds and whether every cell is valid.

use super::{InputArgs, Outcome};
use crate::io::{TissueFormat, read_tissue};
use crate::mesh::CellSummary;
use anyhow::Context;
use rayon::prelude::*;
use serde::Serialize;
use std::io::Write;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct InspectArgs {
    /// Tissue file (.vtk, .vtp or .ply).
    pub file: PathBuf,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub input: InputArgs,
}

#[derive(Serialize)]
struct Totals {
    cells: usize,
    nodes: usize,
    faces: usize,
    valid_cells: usize,
}

#[derive(Serialize)]
struct Report {
    file: String,
    format: TissueFormat,
    /// Metres per file unit along x, y, z.
    length_scale: [f64; 3],
    warnings: Vec<String>,
    cells: Vec<CellSummary>,
    totals: Totals,
}

pub fn run(args: &InspectArgs) -> anyhow::Result<Outcome> {
    let read = read_tissue(&args.file, &args.input.read_options())
        .with_context(|| format!("reading {}", args.file.display()))?;
    let cells: Vec<CellSummary> = read.tissue.cells().par_iter().map(CellSummary::of).collect();
    let totals = Totals {
        cells: cells.len(),
        nodes: cells.iter().map(|c| c.nodes).sum(),
        faces: cells.iter().map(|c| c.faces).sum(),
        valid_cells: cells.iter().filter(|c| c.valid).count(),
    };
    let all_valid = totals.valid_cells == totals.cells;
    let s = args.input.length_unit.0;
    let report = Report {
        file: args.file.display().to_string(),
        format: read.format,
        length_scale: [s.x, s.y, s.z],
        warnings: read.warnings,
        cells,
        totals,
    };
    let mut out = std::io::stdout().lock();
    if args.json {
        serde_json::to_writer_pretty(&mut out, &report)?;
        writeln!(out)?;
    } else {
        for w in &report.warnings {
            tracing::warn!("{w}");
        }
        print_table(&mut out, &report)?;
    }
    Ok(if all_valid { Outcome::Success } else { Outcome::CheckFailed })
}

fn format_name(f: TissueFormat) -> &'static str {
    match f {
        TissueFormat::Simucell3d => "SimuCell3D legacy VTK (polyhedra)",
        TissueFormat::MultiMaterial => "multi-material triangle mesh (label1/label2)",
        TissueFormat::FaceLabelled => "face-labelled surface mesh",
        TissueFormat::Vtp => "ParaView PolyData",
    }
}

fn print_table(out: &mut impl Write, r: &Report) -> std::io::Result<()> {
    let t = &r.totals;
    writeln!(
        out,
        "{}: {}, {} cells, {} nodes, {} faces, {}/{} cells valid",
        r.file,
        format_name(r.format),
        t.cells,
        t.nodes,
        t.faces,
        t.valid_cells,
        t.cells
    )?;
    writeln!(
        out,
        "{:>8} {:<10} {:>4} {:>7} {:>7} {:>11} {:>11} {:>6} {:>27}  status",
        "id", "kind", "type", "nodes", "faces", "volume m³", "area m²", "Ψ", "edge min/mean/max m"
    )?;
    for c in &r.cells {
        let status = match &c.defect {
            None => "valid".to_string(),
            Some(d) if c.defect_count > 1 => format!("{d} (+{} more defects)", c.defect_count - 1),
            Some(d) => d.clone(),
        };
        writeln!(
            out,
            "{:>8} {:<10} {:>4} {:>7} {:>7} {:>11.4e} {:>11.4e} {:>6.4} {:>8.2e}/{:>8.2e}/{:>8.2e}  {}",
            c.id,
            c.kind,
            c.cell_type,
            c.nodes,
            c.faces,
            c.volume,
            c.area,
            c.sphericity,
            c.edge_min,
            c.edge_mean,
            c.edge_max,
            status
        )?;
    }
    Ok(())
}
