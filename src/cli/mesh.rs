//! `tissuefit mesh LABELS.tif --out TISSUE.vtk|.vtp [--voxel-size Z,Y,X] [--l-min L] [--min-voxels N]
//! [--border drop|static|keep] [--lumen-labels 5,7] [--seed S] [--report PATH]`: mesh every label of a
//! segmented volume into a closed cell surface (see [`crate::meshing::mesh_labels`]) and write the tissue
//! plus a per-label `report.json` (kept/static/dropped and why), both atomically.

use super::Outcome;
use super::label_args::{describe_grid, parse_voxel_size};
use crate::geometry::Real;
use crate::imaging::{LabelReadOptions, read_label_tiff};
use crate::io::{parse_lengths, write_atomically, write_tissue};
use crate::meshing::{
    BorderPolicy, DEFAULT_MIN_VOXELS, DEFAULT_TARGET_NODES, LabelMeshingOptions, LabelReport, LabelStatus,
    mesh_labels_with_progress,
};
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct MeshArgs {
    /// Label TIFF (0 = background; 8/16/32-bit, multi-page, ImageJ/OME voxel size).
    pub labels: PathBuf,
    /// Output tissue: .vtp (ParaView) or .vtk (SimuCell3D legacy).
    #[arg(long)]
    pub out: PathBuf,
    /// Voxel size z,y,x (or one for all) overriding the file's metadata: a unit suffix (0.235um,
    /// 235nm), bare numbers are metres, one trailing unit applies to all (0.235,0.15,0.15um).
    #[arg(long, value_name = "Z,Y,X", value_parser = parse_voxel_size)]
    pub voxel_size: Option<[Real; 3]>,
    /// Minimum edge length of every cell (e.g. 0.4um; bare numbers are metres). Default: chosen so that a
    /// cell of the median volume gets --target-nodes nodes.
    #[arg(long, value_name = "L", value_parser = parse_length)]
    pub l_min: Option<Real>,
    /// Nodes of a median-sized cell when l_min is chosen automatically.
    #[arg(long, default_value_t = DEFAULT_TARGET_NODES, conflicts_with = "l_min")]
    pub target_nodes: usize,
    /// Labels with fewer voxels are dropped (segmentation debris).
    #[arg(long, default_value_t = DEFAULT_MIN_VOXELS)]
    pub min_voxels: u64,
    /// Labels touching the image border: drop them, mesh them as static cells, or keep them as free cells.
    #[arg(long, default_value_t = BorderPolicy::Keep, value_parser = |s: &str| s.parse::<BorderPolicy>())]
    pub border: BorderPolicy,
    /// Labels meshed as lumen cells, comma-separated (e.g. 5,7).
    #[arg(long, value_delimiter = ',', value_name = "LABELS")]
    pub lumen_labels: Vec<u32>,
    /// Seed of the surface sampling (each label gets its own stream from seed and label).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Per-label report (default: beside --out, named after its stem: TISSUE.report.json).
    #[arg(long, value_name = "PATH")]
    pub report: Option<PathBuf>,
}

fn parse_length(s: &str) -> Result<Real, String> {
    match parse_lengths(s)?.as_slice() {
        [l] => Ok(*l),
        _ => Err(format!("`{s}`: give one length, e.g. 0.4um")),
    }
}

/// `report.json`; keys are a stable interface (DESIGN.md §2).
#[derive(serde::Serialize)]
struct MeshReport<'a> {
    input: &'a Path,
    output: &'a Path,
    wall_seconds: f64,
    threads: usize,
    /// m; `null` when no label was meshed.
    l_min: Option<Real>,
    /// [sz, sy, sx] m.
    voxel_size: [Real; 3],
    shape: [usize; 3],
    seed: u64,
    min_voxels: u64,
    border: BorderPolicy,
    kept: usize,
    #[serde(rename = "static")]
    static_cells: usize,
    dropped: usize,
    cells: &'a [LabelReport],
}

/// `DIR/STEM.report.json` for `DIR/STEM.EXT`.
fn default_report_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "tissue".into());
    out.with_file_name(format!("{stem}.report.json"))
}

pub fn run(args: &MeshArgs) -> anyhow::Result<Outcome> {
    let started = Instant::now();
    match args.out.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
        Some("vtp" | "vtk") => {}
        _ => bail!("--out {}: use a .vtp (ParaView) or .vtk (SimuCell3D legacy) file name", args.out.display()),
    }
    let report_path = args.report.clone().unwrap_or_else(|| default_report_path(&args.out));
    let read_options = LabelReadOptions { voxel_size: args.voxel_size, ..Default::default() };
    let read = read_label_tiff(&args.labels, &read_options)
        .with_context(|| format!("reading label volume {}", args.labels.display()))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", args.labels.display());
    }
    let volume = read.volume;
    let options = LabelMeshingOptions {
        l_min: args.l_min,
        target_nodes: args.target_nodes,
        min_voxels: args.min_voxels,
        border: args.border,
        lumen_labels: args.lumen_labels.clone(),
        seed: args.seed,
    };
    let labels = volume.label_stats().len() as u64;
    let bar = ProgressBar::with_draw_target(Some(labels), indicatif::ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{wide_bar}] {pos}/{len} labels, ETA {eta}")
            .expect("valid template"),
    );
    let meshing = mesh_labels_with_progress(&volume, &options, &|_| bar.inc(1))
        .with_context(|| format!("meshing {}", args.labels.display()))?;
    bar.finish_and_clear();
    for label in &options.lumen_labels {
        if !meshing.report.iter().any(|r| r.label == *label) {
            tracing::warn!("--lumen-labels: label {label} is not in {}", args.labels.display());
        }
    }
    let (kept, static_cells, dropped) =
        (meshing.count(LabelStatus::Kept), meshing.count(LabelStatus::Static), meshing.count(LabelStatus::Dropped));
    if !meshing.tissue.is_empty() {
        write_tissue(&args.out, &meshing.tissue, &[]).with_context(|| format!("writing {}", args.out.display()))?;
    }
    let wall_seconds = started.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    let report = MeshReport {
        input: &args.labels,
        output: &args.out,
        wall_seconds,
        threads,
        l_min: meshing.l_min,
        voxel_size: volume.voxel_size(),
        shape: volume.shape(),
        seed: args.seed,
        min_voxels: args.min_voxels,
        border: args.border,
        kept,
        static_cells,
        dropped,
        cells: &meshing.report,
    };
    write_atomically(&report_path, |w| {
        serde_json::to_writer_pretty(&mut *w, &report).map_err(std::io::Error::other)?;
        std::io::Write::write_all(w, b"\n")
    })
    .with_context(|| format!("writing {}", report_path.display()))?;

    for r in meshing.report.iter().filter(|r| r.status == LabelStatus::Dropped) {
        println!("  label {} dropped: {}", r.label, r.reason.as_deref().unwrap_or("?"));
    }
    if meshing.tissue.is_empty() {
        bail!(
            "no cell meshed from {} ({}): all {dropped} labels were dropped ({}); see {}",
            args.labels.display(),
            describe_grid(&volume),
            summarise_reasons(&meshing.report),
            report_path.display()
        );
    }
    let mut nodes: Vec<usize> =
        meshing.report.iter().filter(|r| r.status != LabelStatus::Dropped).map(|r| r.nodes).collect();
    nodes.sort_unstable();
    println!(
        "wrote {} ({} cells, {} nodes) and {}",
        args.out.display(),
        meshing.tissue.len(),
        meshing.tissue.node_count(),
        report_path.display()
    );
    println!(
        "{} labels: {kept} kept, {static_cells} static, {dropped} dropped; nodes per cell min {} / median {} / max {}; \
         l_min {:.4} µm; {wall_seconds:.2} s ({threads} threads)",
        meshing.report.len(),
        nodes[0],
        nodes[nodes.len() / 2],
        nodes[nodes.len() - 1],
        meshing.l_min.unwrap_or(Real::NAN) * 1e6,
    );
    Ok(Outcome::Success)
}

/// `3 with too few voxels, 2 touching the border, 1 failed meshing`.
fn summarise_reasons(report: &[LabelReport]) -> String {
    let (mut small, mut border, mut failed) = (0, 0, 0);
    for r in report {
        match r.reason.as_deref() {
            Some(s) if s.contains("fewer than the minimum") => small += 1,
            Some(s) if s.contains("border") => border += 1,
            _ => failed += 1,
        }
    }
    let mut parts = Vec::new();
    if small > 0 {
        parts.push(format!("{small} with fewer voxels than --min-voxels"));
    }
    if border > 0 {
        parts.push(format!("{border} touching the image border with --border drop"));
    }
    if failed > 0 {
        parts.push(format!("{failed} failed meshing"));
    }
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_report_goes_beside_the_tissue_named_after_its_stem() {
        assert_eq!(default_report_path(Path::new("/tmp/a/ovule.vtp")), PathBuf::from("/tmp/a/ovule.report.json"));
        assert_eq!(default_report_path(Path::new("t.vtk")), PathBuf::from("t.report.json"));
    }
}
