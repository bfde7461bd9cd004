//! `tissuefit measure TISSUE --out DIR`: morphology of a tissue into `cells.csv`, `contacts.csv` and
//! `summary.json` (SI units), each written to a temporary name and renamed.

use super::{InputArgs, Outcome};
use crate::geometry::Real;
use crate::io::{LengthScale, read_tissue, write_atomically};
use crate::mesh::CellKind;
use crate::morphology::{
    ContactMorphology, DEFAULT_EXTERIOR_FREE_FRACTION, MeasureSettings, Morphology, measure_tissue,
};
use anyhow::Context;
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct MeasureArgs {
    /// Tissue file (.vtk or .vtp).
    pub tissue: PathBuf,
    /// Output directory (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Contact distance δ: a face whose centroid lies within δ of another cell's surface is in contact
    /// with it. A length with unit (0.1um, 1e-7). Default: 0.25 × the tissue's mean edge length.
    #[arg(long, value_name = "LENGTH", value_parser = parse_length)]
    pub contact_distance: Option<Real>,
    /// Count static cells in the tissue statistics (they are left out by default).
    #[arg(long)]
    pub include_static: bool,
    /// Without an ECM body, a cell faces the exterior (for the layer count) when at least this fraction
    /// of its surface is free.
    #[arg(long, value_name = "FRACTION", default_value_t = DEFAULT_EXTERIOR_FREE_FRACTION)]
    pub exterior_free_fraction: Real,
    #[command(flatten)]
    pub input: InputArgs,
}

/// A single length: a number of metres or a number with a unit (m, mm, um, nm).
fn parse_length(s: &str) -> Result<Real, String> {
    let v = s.parse::<LengthScale>()?.0;
    if v.x != v.y || v.y != v.z {
        return Err(format!("`{s}`: give one length, not three"));
    }
    Ok(v.x)
}

#[derive(Serialize)]
struct SummaryFile<'a> {
    file: String,
    wall_seconds: f64,
    threads: usize,
    #[serde(flatten)]
    summary: &'a crate::morphology::MorphologySummary,
}

pub fn run(args: &MeasureArgs) -> anyhow::Result<Outcome> {
    let read = read_tissue(&args.tissue, &args.input.read_options())
        .with_context(|| format!("reading {}", args.tissue.display()))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", args.tissue.display());
    }
    let settings = MeasureSettings {
        contact_distance: args.contact_distance,
        include_static: args.include_static,
        exterior_free_fraction: args.exterior_free_fraction,
    };
    let start = Instant::now();
    let morphology =
        measure_tissue(&read.tissue, &settings).with_context(|| format!("measuring {}", args.tissue.display()))?;
    let wall_seconds = start.elapsed().as_secs_f64();
    let inside_out: Vec<String> =
        morphology.cells.iter().filter(|c| c.volume <= 0.0).map(|c| c.cell.to_string()).collect();
    if !inside_out.is_empty() {
        tracing::warn!(
            "{}: cells {} have no positive volume (inside-out or open surfaces; sphericity reads 0); --orient repairs mixed windings",
            args.tissue.display(),
            inside_out.join(", ")
        );
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    write_outputs(&args.out, &args.tissue, &morphology, wall_seconds)?;
    print_summary(&mut std::io::stdout().lock(), &args.tissue, &morphology, wall_seconds)?;
    Ok(Outcome::Success)
}

fn write_outputs(dir: &Path, input: &Path, m: &Morphology, wall_seconds: f64) -> anyhow::Result<()> {
    if let Some(first) = m.cells.first() {
        write_csv(&dir.join("cells.csv"), &m.cells, first)?;
    }
    let example = ContactMorphology {
        cell_a: 0,
        cell_b: 0,
        area: 0.0,
        contact_angle_deg: None,
        kind_a: CellKind::Epithelial,
        kind_b: CellKind::Epithelial,
        area_a: 0.0,
        area_b: 0.0,
        rim_edges: 0,
    };
    write_csv(&dir.join("contacts.csv"), &m.contacts, &example)?;
    let summary = SummaryFile {
        file: input.display().to_string(),
        wall_seconds,
        threads: rayon::current_num_threads(),
        summary: &m.summary,
    };
    let path = dir.join("summary.json");
    write_atomically(&path, |w| {
        serde_json::to_writer_pretty(&mut *w, &summary).map_err(std::io::Error::other)?;
        writeln!(w)
    })
    .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Writes rows under a header of `T`'s serde field names, in field order; the header comes from
/// `example` (not written) so that a file without rows still has its columns.
fn write_csv<T: Serialize>(path: &Path, rows: &[T], example: &T) -> anyhow::Result<()> {
    write_atomically(path, |w| {
        let mut header = csv::Writer::from_writer(Vec::new());
        header.serialize(example)?;
        let bytes = header.into_inner().map_err(|e| e.into_error())?;
        let first_line = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
        w.write_all(first_line)?;
        w.write_all(b"\n")?;
        let mut csv = csv::WriterBuilder::new().has_headers(false).from_writer(&mut *w);
        for row in rows {
            csv.serialize(row)?;
        }
        csv.flush()
    })
    .with_context(|| format!("writing {}", path.display()))
}

fn print_summary(out: &mut impl Write, input: &Path, m: &Morphology, wall_seconds: f64) -> std::io::Result<()> {
    let s = &m.summary;
    let opt = |v: Option<Real>, digits: usize| v.map_or("n/a".to_string(), |x| format!("{x:.digits$}"));
    writeln!(
        out,
        "{}: {} cells measured ({} bodies), {} cell contacts, δ = {:.3e} m, {:.3} s",
        input.display(),
        s.cells,
        s.bodies.total,
        s.cell_contacts,
        s.contact_distance,
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
    )
}
