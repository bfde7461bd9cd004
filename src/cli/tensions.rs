//! `tissuefit tensions TISSUE|LABELS.tif --out DIR [--gauge medium|A-B] [--gauge-tension T]
//! [--one-medium-tension]`: the direct estimate of every interface's tension and every cell's pressure
//! from the shapes alone (force balance at the junction lines, Young–Laplace on the interfaces; see
//! [`crate::morphology::tensions`]) into `interfaces.csv`, `cells.csv`, `summary.json`, `tensions.vtp`
//! and `cell_overrides.toml`, written together (all or nothing). A label TIFF is meshed first as `tissuefit mesh` meshes it.
//! A 2.5-D cell sheet (open cell patches of one surface) gets the walls' line tensions of
//! [`crate::morphology::sheet`] instead.

use super::label_args::{describe_grid, parse_voxel_size};
use super::{InputArgs, Outcome};
use crate::geometry::Real;
use crate::imaging::{LabelReadOptions, read_labels};
use crate::io::parse_length;
use crate::io::{OutputPolicy, read_tissue};
use crate::mesh::Tissue;
use crate::meshing::{
    BorderPolicy, DEFAULT_MIN_VOXELS, DEFAULT_TARGET_NODES, LabelMeshingOptions, label_interfaces, mesh_labels,
};
use crate::morphology::sheet::is_sheet;
use crate::morphology::tensions::{FarField, FieldOfView, Gauge, TensionMap, TensionSettings};
use crate::stages::measure::is_labels;
use crate::stages::tensions::{OUTPUT_FILES, SHEET_OUTPUT_FILES, Summary, TensionsInput};
use anyhow::{Context, bail};
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
pub struct TensionsArgs {
    /// Tissue file (.vtk, .vtp or .ply, per-cell or multi-material), or a label volume (0 = background:
    /// a TIFF stack, an OME-Zarr .zarr folder, an HDF5 .h5 dataset or a NumPy .npy), meshed first as
    /// `tissuefit mesh` does (cell ids = labels). A 2.5-D cell sheet (every cell an open patch of one
    /// surface, e.g. a PLY epidermis) gets its walls' line tensions from the junctions instead.
    pub tissue: PathBuf,
    /// Output directory (created if missing): interfaces.csv, cells.csv, summary.json, tensions.vtp,
    /// cell_overrides.toml, tensions.png (a 2.5-D sheet: walls.vtp instead of cell_overrides.toml).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Which tension fixes the scale: `medium` (the mean of the cell–medium tensions) or an interface
    /// `A-B` between two labels (0 = the medium, e.g. 3-0 for cell 3's free surface).
    #[arg(long, default_value = "medium", value_parser = parse_gauge)]
    pub gauge: Gauge,
    /// The gauge's tension in mN/m, when known: tensions are then written in mN/m and pressures in kPa
    /// (mN/m per µm). Default: relative tensions (gauge = 1), pressures in gauge tension per µm.
    #[arg(long, value_name = "mN/m", value_parser = parse_tension)]
    pub gauge_tension: Option<Real>,
    /// One tension shared by every cell–medium interface instead of one per cell.
    #[arg(long)]
    pub one_medium_tension: bool,
    /// Contact distance δ: a face whose centroid lies within δ of another cell's surface belongs to the
    /// interface with it. A length with unit (0.1um, 1e-7). Default: 0.25 × the mean edge length.
    #[arg(long, value_name = "LENGTH", value_parser = parse_length)]
    pub contact_distance: Option<Real>,
    /// Find the interfaces by the contact distance even when each face's neighbour is known (a
    /// multi-material mesh's face labels, or a label volume, read along each face's normal), from which
    /// they are otherwise read exactly.
    #[arg(long)]
    pub distance_contacts: bool,
    /// Where each junction's interface surfaces come from: `global` (one sphere or plane per
    /// interface, fitted away from its junctions), `local` (per junction sample, the interface's
    /// faces near it on a sphere of the interface's radius) or `auto` (global, and local where the
    /// global surfaces do not meet at the junction: interfaces that are not one sphere, as in real
    /// embryos pressed by a shell or neighbours).
    #[arg(long, default_value = "auto", value_parser = |s: &str| s.parse::<FarField>())]
    pub far_field: FarField,
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
    /// Label volume only: labels touching the image border are kept as cells (default, as `mesh`), meshed
    /// as static cells (their tensions are estimated all the same), or dropped.
    #[arg(long, default_value_t = BorderPolicy::Keep, value_parser = |s: &str| s.parse::<BorderPolicy>())]
    pub border: BorderPolicy,
    /// Label volume only: labels with fewer voxels are debris and are dropped (as `mesh`).
    #[arg(long, default_value_t = DEFAULT_MIN_VOXELS)]
    pub min_voxels: u64,
    /// Label volume only: nodes of a median-sized cell's mesh (as `mesh --target-nodes`).
    #[arg(long, default_value_t = DEFAULT_TARGET_NODES)]
    pub target_nodes: usize,
}

/// `medium` or `A-B`.
fn parse_gauge(s: &str) -> Result<Gauge, String> {
    if s == "medium" {
        return Ok(Gauge::MediumMean);
    }
    let parsed =
        s.split_once('-').and_then(|(a, b)| Some((a.trim().parse::<u32>().ok()?, b.trim().parse::<u32>().ok()?)));
    match parsed {
        Some((a, b)) if a != b => Ok(Gauge::Interface(a, b)),
        _ => Err(format!("`{s}`: give `medium` or an interface as two different labels A-B (0 = medium), e.g. 1-2")),
    }
}

/// A tension in mN/m: a positive number, optionally followed by `mN/m`.
fn parse_tension(s: &str) -> Result<Real, String> {
    let number = s.trim().strip_suffix("mN/m").unwrap_or(s.trim()).trim();
    match number.parse::<Real>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("`{s}`: give a positive tension in mN/m, e.g. 0.5 or 0.5mN/m")),
    }
}

/// What `tensions` writes into --out.
/// A label volume's largest voxel side (m) and imaged box.
type LabelGrid = Option<(Real, FieldOfView)>;

fn read_input(args: &TensionsArgs) -> anyhow::Result<(Tissue, &'static str, LabelGrid)> {
    let path = &args.tissue;
    if is_labels(path) {
        let options =
            LabelReadOptions { voxel_size: args.voxel_size, zarr_level: args.zarr_level, ..Default::default() };
        let read = read_labels(path, &options).with_context(|| format!("reading label volume {}", path.display()))?;
        for w in &read.warnings {
            tracing::warn!("{}: {w}", path.display());
        }
        let options = LabelMeshingOptions {
            target_nodes: args.target_nodes,
            min_voxels: args.min_voxels,
            border: args.border,
            ..Default::default()
        };
        let mut meshing = mesh_labels(&read.volume, &options)
            .with_context(|| format!("meshing {} ({})", path.display(), describe_grid(&read.volume)))?;
        // Who is on the other side of each face, read from the labels (exact, no contact distance).
        let unresolved = label_interfaces(&mut meshing.tissue, &read.volume)?;
        if unresolved > 0 {
            tracing::info!(
                "{}: {unresolved} faces met only their own label along their normal; read as free surface",
                path.display()
            );
        }
        for r in meshing.report.iter().filter(|r| r.cell_id.is_none()) {
            tracing::warn!(
                "{}: label {} not meshed: {}",
                path.display(),
                r.label,
                r.reason.as_deref().unwrap_or("dropped")
            );
        }
        let voxel = read.volume.grid().voxel_size.iter().copied().fold(0.0, Real::max);
        return Ok((meshing.tissue, "labels", Some((voxel, FieldOfView::of_volume(&read.volume)))));
    }
    if args.voxel_size.is_some()
        || args.zarr_level.is_some()
        || args.border != BorderPolicy::Keep
        || args.min_voxels != DEFAULT_MIN_VOXELS
        || args.target_nodes != DEFAULT_TARGET_NODES
    {
        bail!(
            "{} is a tissue mesh: --voxel-size, --zarr-level, --border, --min-voxels and --target-nodes apply to label \
             volumes",
            path.display()
        );
    }
    let read =
        read_tissue(path, &args.input.read_options()).with_context(|| crate::stages::measure::reading_tissue(path))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", path.display());
    }
    Ok((read.tissue, "tissue", None))
}

pub fn run(args: &TensionsArgs) -> anyhow::Result<Outcome> {
    // A sheet writes walls.vtp instead of cell_overrides.toml: check the files of both.
    let mut files = OUTPUT_FILES.to_vec();
    files.extend(SHEET_OUTPUT_FILES.iter().filter(|n| !OUTPUT_FILES.contains(n)));
    OutputPolicy::new().input("TISSUE", &args.tissue).folder("--out", &args.out, &files)?;
    let (tissue, input, grid) = read_input(args)?;
    if grid.is_none() && is_sheet(&tissue) {
        return run_sheet(args, &tissue);
    }
    let (voxel, field_of_view) = grid.unzip();
    let settings = TensionSettings {
        contact_distance: args.contact_distance,
        one_medium_tension: args.one_medium_tension,
        gauge: args.gauge,
        gauge_value: args.gauge_tension.unwrap_or(1.0),
        rounding_scale: voxel,
        interface_labels: !args.distance_contacts,
        field_of_view,
        far_field: args.far_field,
    };
    let file = args.tissue.display().to_string();
    let described = TensionsInput { file: &file, kind: input, gauge_in_mn_per_m: args.gauge_tension.is_some() };
    let outcome = crate::stages::tensions::run(&tissue, &settings, &described, &args.out)?;
    print_summary(&mut std::io::stdout().lock(), &args.tissue, &outcome.map, &outcome.summary)?;
    Ok(Outcome::Success)
}

/// A 2.5-D sheet (open cell patches of one surface): the walls' line tensions.
fn run_sheet(args: &TensionsArgs, tissue: &Tissue) -> anyhow::Result<Outcome> {
    let given: Vec<&str> = [
        (args.gauge_tension.is_some(), "--gauge-tension"),
        (args.one_medium_tension, "--one-medium-tension"),
        (args.contact_distance.is_some(), "--contact-distance"),
        (args.distance_contacts, "--distance-contacts"),
    ]
    .iter()
    .filter(|(set, _)| *set)
    .map(|(_, name)| *name)
    .collect();
    if !given.is_empty() {
        bail!(
            "{} is a 2.5-D cell sheet (every cell an open patch of one surface): its walls carry line tensions,              estimated relative to the gauge (the mean wall tension, or --gauge A-B); {} apply to 3-D cells. Leave them              out",
            args.tissue.display(),
            given.join(", ")
        );
    }
    tracing::info!(
        "{}: a 2.5-D cell sheet ({} open cell patches): estimating the walls' line tensions at the junctions",
        args.tissue.display(),
        tissue.len()
    );
    let file = args.tissue.display().to_string();
    let outcome = crate::stages::tensions::run_sheet(tissue, args.gauge, &file, &args.out)?;
    let s = &outcome.summary;
    let opt = |v: Option<Real>| v.map_or("n/a".to_string(), |x| format!("{x:.3}"));
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{}: 2.5-D sheet, {} cells ({} on the rim), {} walls ({} determined), {} junctions ({} on the rim left out), \
         {:.3} s",
        args.tissue.display(),
        s.cells,
        s.cells_on_rim,
        s.interfaces,
        s.determined_interfaces,
        s.junctions,
        s.junctions_on_rim,
        s.wall_seconds
    )?;
    writeln!(
        out,
        "  gauge: {} = 1; force-balance residual rms {} (median {}); median relative sd {}; relative in-plane \
         pressures for {} cells",
        s.gauge,
        opt(s.residual_rms),
        opt(s.residual_median),
        s.median_relative_sd.map_or("n/a".to_string(), |m| format!("{:.1} %", 100.0 * m)),
        s.determined_pressures
    )?;
    if !s.warnings.is_empty() {
        writeln!(out, "  {} warning(s) in summary.json", s.warnings.len())?;
    }
    Ok(Outcome::Success)
}

fn print_summary(out: &mut impl Write, input: &Path, map: &TensionMap, s: &Summary) -> std::io::Result<()> {
    writeln!(
        out,
        "{}: {} cells, {} interfaces ({} determined), {} junction samples on {} lines, {:.3} s",
        input.display(),
        s.cells,
        s.interfaces,
        s.determined_interfaces,
        s.junction_samples,
        s.junction_lines,
        s.wall_seconds
    )?;
    let opt = |v: Option<Real>| v.map_or("n/a".to_string(), |x| format!("{x:.3}"));
    writeln!(
        out,
        "  gauge: {} = {}; force-balance residual rms {} (median {}); condition number {}; spectral gap {}",
        s.gauge,
        s.gauge_value,
        opt(map.residual_rms),
        opt(map.residual_median),
        map.condition_number.map_or("n/a".to_string(), |c| format!("{c:.1}")),
        map.spectral_gap.map_or("n/a".to_string(), |g| if g.is_finite() {
            format!("{g:.1}")
        } else {
            "exact".to_string()
        })
    )?;
    if !map.warnings.is_empty() {
        writeln!(out, "  {} warning(s) in summary.json", map.warnings.len())?;
    }
    Ok(())
}
