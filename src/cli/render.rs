//! `tissuefit render TISSUE.vtp|.vtk --out VIEW.png [--color-by cell|kind|face-type|tension|pressure|field]
//! [--field NAME] [--range LO,HI] [--view iso|x|y|z] [--size W,H] [--edges]`: a picture of a tissue (see
//! [`crate::render`]); by tension or pressure, the map of `tissuefit tensions` or of a per-cell fit.

use super::{InputArgs, Outcome};
use crate::geometry::Real;
use crate::io::{Format, OutputPolicy, read_tissue, read_vtp_face_values};
use crate::render::{ColorBy, FaceScalars, RenderOptions, View, render_tissue, write_png};
use anyhow::Context;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// Tissue file (.vtk, .vtp or .ply).
    pub tissue: PathBuf,
    /// Output picture (.png).
    #[arg(long, value_name = "VIEW.png")]
    pub out: PathBuf,
    /// Colour faces by cell id, cell kind, face type (apical red, lateral green, basal blue), or by
    /// numbers with a colour bar: the tension or pressure map of `tissuefit tensions` (tensions.vtp)
    /// or of a per-cell fit (fit/tissue.vtp), or any per-face array named with --field (.vtp files).
    #[arg(long, value_enum, default_value_t = ColorBy::Cell)]
    pub color_by: ColorBy,
    /// The per-face array to colour by with --color-by field (e.g. pressure, tension_mn_per_m).
    #[arg(long, value_name = "NAME")]
    pub field: Option<String>,
    /// The values at the ends of the colour scale (default: the smallest and largest value).
    #[arg(long, value_name = "LO,HI", value_parser = parse_range, allow_hyphen_values = true)]
    pub range: Option<(Real, Real)>,
    /// Camera direction (orthographic): iso (from +x, −y, +z), or along an axis.
    #[arg(long, value_enum, default_value_t = View::Iso)]
    pub view: View,
    /// Picture size in pixels, width,height.
    #[arg(long, value_name = "W,H", default_value = "800,600", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Draw the triangle edges.
    #[arg(long)]
    pub edges: bool,
    /// Pull the cells apart by this fraction of their distance from the tissue's centre, so that the
    /// faces between cells show (e.g. 0.6 for a tension map; `tissuefit tensions` and a per-cell fit
    /// draw their maps so).
    #[arg(long, value_name = "F", default_value_t = 0.0, value_parser = parse_explode)]
    pub explode: Real,
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

fn parse_explode(s: &str) -> Result<Real, String> {
    match s.trim().parse::<Real>() {
        Ok(f) if (0.0..=10.0).contains(&f) => Ok(f),
        _ => Err(format!("`{s}`: give the explode fraction as a number from 0 to 10, e.g. 0.6")),
    }
}

fn parse_range(s: &str) -> Result<(Real, Real), String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [lo, hi] = parts.as_slice() else {
        return Err(format!("`{s}`: give the colour range as LO,HI, e.g. 0.5,1.5"));
    };
    let parse =
        |v: &str| v.parse::<Real>().ok().filter(|x| x.is_finite()).ok_or(format!("`{s}`: `{v}` is not a number"));
    let (lo, hi) = (parse(lo)?, parse(hi)?);
    if hi <= lo {
        return Err(format!("`{s}`: the upper end must be above the lower end"));
    }
    Ok((lo, hi))
}

/// The per-face arrays `--color-by` reads, in order of preference, and their colour-bar titles.
fn scalar_arrays(args: &RenderArgs) -> anyhow::Result<Vec<String>> {
    Ok(match (args.color_by, &args.field) {
        (ColorBy::Field, Some(name)) => vec![name.clone()],
        (ColorBy::Field, None) => anyhow::bail!("--color-by field needs --field NAME (a per-face array of the .vtp)"),
        (ColorBy::Tension, None) => vec!["tension_mn_per_m".into(), "tension".into()],
        (ColorBy::Pressure, None) => vec!["pressure".into()],
        (_, Some(_)) => anyhow::bail!("--field names the array of --color-by field; add --color-by field"),
        _ => Vec::new(),
    })
}

/// The colour bar's title: the array's name with its unit, for `tension` and `pressure` of a
/// `tensions.vtp` the units its `summary.json` (beside it) records.
fn title_of(name: &str, tissue: &Path) -> String {
    let summary = || -> Option<serde_json::Value> {
        let text = std::fs::read_to_string(tissue.parent()?.join("summary.json")).ok()?;
        serde_json::from_str(&text).ok()
    };
    let unit_of = |key: &str| summary().and_then(|s| s.get(key)?.as_str().map(str::to_owned));
    let with = |what: &str, unit: Option<String>| match unit.as_deref() {
        Some("gauge") => format!("{what} (relative to the gauge)"),
        Some(u) => format!("{what} ({u})"),
        None => what.to_owned(),
    };
    match name {
        "tension_mn_per_m" => "tension (mN/m)".into(),
        "tension" => with("tension", unit_of("tension_unit")),
        // A per-cell fit's tissue.vtp (beside its result.json) holds the simulated pressure in Pa.
        "pressure" if summary().is_none() && tissue.parent().is_some_and(|d| d.join("result.json").is_file()) => {
            "pressure (Pa)".into()
        }
        "pressure" => with("pressure", unit_of("pressure_unit")),
        other => other.replace('_', " "),
    }
}

pub fn run(args: &RenderArgs) -> anyhow::Result<Outcome> {
    OutputPolicy::new().input("TISSUE", &args.tissue).file("--out", &args.out, Format::Png)?;
    let names = scalar_arrays(args)?;
    let (tissue, warnings, scalars) = if names.is_empty() {
        let read = read_tissue(&args.tissue, &args.input.read_options())
            .with_context(|| format!("reading {}", args.tissue.display()))?;
        (read.tissue, read.warnings, None)
    } else {
        let is_vtp = args.tissue.extension().is_some_and(|e| e.eq_ignore_ascii_case("vtp"));
        anyhow::ensure!(
            is_vtp,
            "{}: --color-by {:?} reads per-face values from a .vtp file (tensions.vtp of `tissuefit tensions`, \
             tissue.vtp of a per-cell fit)",
            args.tissue.display(),
            args.color_by
        );
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let (tissue, values) =
            read_vtp_face_values(&args.tissue, &names).with_context(|| format!("reading {}", args.tissue.display()))?;
        let scalars =
            FaceScalars { label: title_of(&values.name, &args.tissue), values: values.values, range: args.range };
        (tissue, Vec::new(), Some(scalars))
    };
    for w in &warnings {
        tracing::warn!("{}: {w}", args.tissue.display());
    }
    let options = RenderOptions {
        width: args.size.0,
        height: args.size.1,
        color_by: args.color_by,
        view: args.view,
        edges: args.edges,
        scalars,
        explode: args.explode,
    };
    let img = render_tissue(&tissue, &options).with_context(|| format!("rendering {}", args.tissue.display()))?;
    write_png(&args.out, &img)?;
    let colour = match &options.scalars {
        Some(s) => {
            let finite: Vec<Real> = s.values.iter().copied().filter(|v| v.is_finite()).collect();
            let (lo, hi) = s.range.unwrap_or_else(|| {
                finite.iter().fold((Real::INFINITY, Real::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)))
            });
            let missing = s.values.len() - finite.len();
            let missing = if missing > 0 { format!("; {missing} faces without a value, grey") } else { String::new() };
            format!("{} on {lo:.4}..{hi:.4}{missing}", s.label)
        }
        None => format!("{:?}", options.color_by),
    };
    println!(
        "wrote {} ({}x{}, {} cells, coloured by {colour}, view {:?})",
        args.out.display(),
        options.width,
        options.height,
        tissue.len(),
        options.view
    );
    Ok(Outcome::Success)
}
