//! `tissuefit render TISSUE.vtp|.vtk --out VIEW.png [--color-by cell|kind|face-type] [--view iso|x|y|z]
//! [--size W,H] [--edges]`: a picture of a tissue (see [`crate::render`]).

use super::{InputArgs, Outcome};
use crate::io::{Format, OutputPolicy, read_tissue};
use crate::render::{ColorBy, RenderOptions, View, render_tissue, write_png};
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Tissue file (.vtk or .vtp).
    pub tissue: PathBuf,
    /// Output picture (.png).
    #[arg(long, value_name = "VIEW.png")]
    pub out: PathBuf,
    /// Colour faces by cell id, cell kind or face type (apical red, lateral green, basal blue).
    #[arg(long, value_enum, default_value_t = ColorBy::Cell)]
    pub color_by: ColorBy,
    /// Camera direction (orthographic): iso (from +x, −y, +z), or along an axis.
    #[arg(long, value_enum, default_value_t = View::Iso)]
    pub view: View,
    /// Picture size in pixels, width,height.
    #[arg(long, value_name = "W,H", default_value = "800,600", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Draw the triangle edges.
    #[arg(long)]
    pub edges: bool,
    #[command(flatten)]
    pub input: InputArgs,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let parts: Vec<&str> = s.split([',', 'x']).map(str::trim).collect();
    let [w, h] = parts.as_slice() else {
        return Err(format!("`{s}`: give the size as W,H in pixels, e.g. 800,600"));
    };
    let parse = |v: &str| v.parse::<u32>().map_err(|_| format!("`{s}`: `{v}` is not a whole number of pixels"));
    Ok((parse(w)?, parse(h)?))
}

pub fn run(args: &RenderArgs) -> anyhow::Result<Outcome> {
    OutputPolicy::new().input("TISSUE", &args.tissue).file("--out", &args.out, Format::Png)?;
    let read = read_tissue(&args.tissue, &args.input.read_options())
        .with_context(|| format!("reading {}", args.tissue.display()))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", args.tissue.display());
    }
    let options = RenderOptions {
        width: args.size.0,
        height: args.size.1,
        color_by: args.color_by,
        view: args.view,
        edges: args.edges,
    };
    let img = render_tissue(&read.tissue, &options).with_context(|| format!("rendering {}", args.tissue.display()))?;
    write_png(&args.out, &img)?;
    println!(
        "wrote {} ({}x{}, {} cells, coloured by {:?}, view {:?})",
        args.out.display(),
        options.width,
        options.height,
        read.tissue.len(),
        options.color_by,
        options.view
    );
    Ok(Outcome::Success)
}
