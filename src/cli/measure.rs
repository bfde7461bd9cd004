//! `tissuefit measure TISSUE|LABELS.tif --out DIR [--compare TISSUE|LABELS.tif]`: morphology of a
//! tissue mesh, or of a label volume measured on its voxels, into `cells.csv`, `contacts.csv` and
//! `summary.json` (SI units), each written to a temporary name and renamed. With `--compare`, every
//! cell also gets its IoU and χ = 1 − IoU against the same label of the other input.

use super::label_args::{describe_grid, parse_voxel_size};
use super::{InputArgs, Outcome, write_csv};
use crate::geometry::Real;
use crate::imaging::{LabelOverlap, LabelReadOptions, LabelVolume, is_label_volume, label_overlap, read_labels};
use crate::io::{LengthScale, OutputGroup, OutputPolicy, read_tissue};
use crate::mesh::{CellKind, Tissue};
use crate::meshing::{BorderPolicy, DEFAULT_MIN_VOXELS};
use crate::morphology::{
    ContactMorphology, ContactRule, DEFAULT_EXTERIOR_FREE_FRACTION, DroppedLabel, LabelMeasureSettings,
    MeasureSettings, Morphology, compare_shapes, compare_tissues, mean_edge_length, measure_labels, measure_tissue,
};
use crate::pipeline::{PipelineConfig, run_measure};
use anyhow::{Context, bail};
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct MeasureArgs {
    /// Tissue file (.vtk or .vtp), or a label volume (0 = background) measured directly on its voxels
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
            "zarr_level",
        ]
    )]
    pub config: Option<PathBuf>,
    /// Contact distance δ: a face whose centroid lies within δ of another cell's surface is in contact
    /// with it. A length with unit (0.1um, 1e-7). Default: 0.25 × the tissue's mean edge length. Not
    /// used for the contacts of a multi-material mesh, whose faces name the cells on both sides
    /// (see --distance-contacts).
    #[arg(long, value_name = "LENGTH", value_parser = parse_length)]
    pub contact_distance: Option<Real>,
    /// Find contacts by the contact distance δ even when the input's faces carry interface labels (a
    /// multi-material mesh: label1/label2, or a .vtp with `interface_label`), whose contacts are
    /// otherwise read from the labels: exact areas and rims.
    #[arg(long)]
    pub distance_contacts: bool,
    /// Count static cells in the tissue statistics (they are left out by default).
    #[arg(long)]
    pub include_static: bool,
    /// Without an ECM body, a cell faces the exterior (for the layer count) when at least this fraction
    /// of its surface is free.
    #[arg(long, value_name = "FRACTION", default_value_t = DEFAULT_EXTERIOR_FREE_FRACTION)]
    pub exterior_free_fraction: Real,
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
}

/// Bytes per voxel that measuring a label volume needs besides the volume itself (4 bytes per voxel):
/// the dense relabelled copy (4), label statistics and the per-label smoothed fields (~5); about 13
/// in all. The TIFF reader checks the total against the memory limit before decoding.
const MEASURE_WORK_BYTES_PER_VOXEL: u64 = 9;

/// Whether `path` is a label volume rather than a tissue mesh: a .vtk/.vtp is a tissue; anything else
/// is a label volume when its content or extension says so ([`is_label_volume`]).
pub(super) fn is_labels(path: &Path) -> bool {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    !matches!(ext.as_deref(), Some("vtk" | "vtp")) && is_label_volume(path)
}

/// A measured or compared input.
enum Input {
    Tissue(Tissue),
    Labels(LabelVolume),
}

fn read_input(path: &Path, args: &MeasureArgs) -> anyhow::Result<Input> {
    if is_labels(path) {
        let options = LabelReadOptions {
            voxel_size: args.voxel_size,
            work_bytes_per_voxel: MEASURE_WORK_BYTES_PER_VOXEL,
            zarr_level: args.zarr_level,
            ..Default::default()
        };
        let read = read_labels(path, &options).with_context(|| format!("reading label volume {}", path.display()))?;
        for w in &read.warnings {
            tracing::warn!("{}: {w}", path.display());
        }
        Ok(Input::Labels(read.volume))
    } else {
        let read = read_tissue(path, &args.input.read_options()).with_context(|| super::mesh::reading_tissue(path))?;
        for w in &read.warnings {
            tracing::warn!("{}: {w}", path.display());
        }
        Ok(Input::Tissue(read.tissue))
    }
}

/// A single length: a number of metres or a number with a unit (m, mm, um, nm).
pub(super) fn parse_length(s: &str) -> Result<Real, String> {
    let v = s.parse::<LengthScale>()?.0;
    if v.x != v.y || v.y != v.z {
        return Err(format!("`{s}`: give one length, not three"));
    }
    Ok(v.x)
}

#[derive(Serialize)]
struct SummaryFile<'a> {
    file: String,
    /// `tissue` (a mesh) or `labels` (a label volume measured on its voxels).
    input: &'static str,
    /// Seconds spent measuring (and comparing), reading excluded.
    wall_seconds: f64,
    threads: usize,
    /// Label volumes: σ of the normal smoothing (m), and the labels left out as debris or border.
    #[serde(skip_serializing_if = "Option::is_none")]
    normal_smoothing: Option<Real>,
    #[serde(skip_serializing_if = "Option::is_none")]
    dropped_labels: Option<&'a [DroppedLabel]>,
    /// The file compared with (`--compare`) and how many labels were compared.
    #[serde(skip_serializing_if = "Option::is_none")]
    compare: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    compared_cells: Option<usize>,
    #[serde(flatten)]
    summary: &'a crate::morphology::MorphologySummary,
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
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let started = Instant::now();
    let line = run_measure(tissue, &config.measure, out)?;
    println!(
        "measure ({}): {line}; {:.2} s; outputs in {}",
        pipeline.display(),
        started.elapsed().as_secs_f64(),
        out.display()
    );
    Ok(Outcome::Success)
}

/// What `measure` writes into --out.
const OUTPUT_FILES: [&str; 3] = ["cells.csv", "contacts.csv", "summary.json"];

pub fn run(args: &MeasureArgs) -> anyhow::Result<Outcome> {
    if let Some(pipeline) = &args.config {
        return run_stage(&args.tissue, pipeline, &args.out);
    }
    OutputPolicy::new().input("TISSUE", &args.tissue).input_opt("--compare", args.compare.as_deref()).folder(
        "--out",
        &args.out,
        &OUTPUT_FILES,
    )?;
    let input = read_input(&args.tissue, args)?;
    let labels_only = args.voxel_size.is_some()
        || args.zarr_level.is_some()
        || args.border != BorderPolicy::Keep
        || !args.lumen_labels.is_empty()
        || args.min_voxels != DEFAULT_MIN_VOXELS
        || args.normal_smoothing.is_some();
    if matches!(input, Input::Tissue(_)) && labels_only {
        bail!(
            "{} is a tissue mesh: --voxel-size, --zarr-level, --border, --lumen-labels, --min-voxels and --normal-smoothing \
             apply to label volumes",
            args.tissue.display()
        );
    }
    if matches!(input, Input::Labels(_)) && args.contact_distance.is_some() {
        bail!(
            "{} is a label volume: contacts are voxel-face adjacency, --contact-distance applies to meshes",
            args.tissue.display()
        );
    }
    let other = args.compare.as_deref().map(|p| read_input(p, args)).transpose()?;
    let start = Instant::now();
    let (mut morphology, label_route) = match &input {
        Input::Tissue(tissue) => {
            let settings = MeasureSettings {
                contact_distance: args.contact_distance,
                include_static: args.include_static,
                exterior_free_fraction: args.exterior_free_fraction,
                interface_labels: !args.distance_contacts,
            };
            let m =
                measure_tissue(tissue, &settings).with_context(|| format!("measuring {}", args.tissue.display()))?;
            if m.summary.contact_rule == ContactRule::InterfaceLabels && args.contact_distance.is_some() {
                tracing::warn!(
                    "{}: contacts were read from the file's interface labels, so --contact-distance only bounds \
                     the rim search; add --distance-contacts to find contacts by distance",
                    args.tissue.display()
                );
            }
            (m, None)
        }
        Input::Labels(volume) => {
            let settings = LabelMeasureSettings {
                include_static: args.include_static,
                exterior_free_fraction: args.exterior_free_fraction,
                border: args.border,
                lumen_labels: args.lumen_labels.clone(),
                min_voxels: args.min_voxels,
                normal_smoothing: args.normal_smoothing,
            };
            let m = measure_labels(volume, &settings)
                .with_context(|| format!("measuring {} ({})", args.tissue.display(), describe_grid(volume)))?;
            for label in &args.lumen_labels {
                if !m.morphology.cells.iter().any(|c| c.cell == *label) {
                    tracing::warn!("--lumen-labels: label {label} is not measured in {}", args.tissue.display());
                }
            }
            (m.morphology, Some((m.dropped, m.normal_smoothing)))
        }
    };
    let compared = match (&input, &other) {
        (_, None) => None,
        (input, Some(other)) => {
            let path = args.compare.as_deref().unwrap_or(Path::new(""));
            let overlaps = compare_inputs(input, other, args)
                .with_context(|| format!("comparing {} with {}", args.tissue.display(), path.display()))?;
            morphology.set_overlap(&overlaps);
            Some((path.display().to_string(), overlaps.iter().filter(|o| o.voxels_a > 0 && o.voxels_b > 0).count()))
        }
    };
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
    if let Some((dropped, _)) = &label_route {
        for d in dropped {
            tracing::info!("{}: label {} left out: {}", args.tissue.display(), d.label, d.reason);
        }
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let summary = SummaryFile {
        file: args.tissue.display().to_string(),
        input: if label_route.is_some() { "labels" } else { "tissue" },
        wall_seconds,
        threads: rayon::current_num_threads(),
        normal_smoothing: label_route.as_ref().map(|r| r.1),
        dropped_labels: label_route.as_ref().map(|r| r.0.as_slice()),
        compare: compared.as_ref().map(|c| c.0.clone()),
        compared_cells: compared.as_ref().map(|c| c.1),
        summary: &morphology.summary,
    };
    write_outputs(&args.out, &morphology, &summary)?;
    print_summary(&mut std::io::stdout().lock(), &args.tissue, &morphology, wall_seconds)?;
    Ok(Outcome::Success)
}

/// Per-label overlap of the measured input (`voxels_a`) with the compared one (`voxels_b`).
fn compare_inputs(input: &Input, other: &Input, args: &MeasureArgs) -> anyhow::Result<Vec<LabelOverlap>> {
    let swap = |o: Vec<LabelOverlap>| -> Vec<LabelOverlap> {
        o.into_iter().map(|o| LabelOverlap { voxels_a: o.voxels_b, voxels_b: o.voxels_a, ..o }).collect()
    };
    Ok(match (input, other) {
        (Input::Labels(a), Input::Labels(b)) => label_overlap(a, b)?,
        (Input::Tissue(a), Input::Labels(b)) => swap(compare_shapes(a, b)?),
        (Input::Labels(a), Input::Tissue(b)) => compare_shapes(b, a)?,
        (Input::Tissue(a), Input::Tissue(b)) => {
            let voxel_size = match args.compare_voxel_size {
                Some(v) => v,
                None => match mean_edge_length(a) {
                    Some(h) if h.is_finite() && h > 0.0 => [h / 2.0; 3],
                    _ => bail!("cannot derive a comparison grid from the tissue's edges; give --compare-voxel-size"),
                },
            };
            compare_tissues(a, b, voxel_size)?
        }
    })
}

/// The three files all or nothing ([`OutputGroup`]): a full disk leaves none of them, never two.
fn write_outputs(dir: &Path, m: &Morphology, summary: &SummaryFile<'_>) -> anyhow::Result<()> {
    let mut group = OutputGroup::new();
    if let Some(first) = m.cells.first() {
        write_csv(&mut group, &dir.join("cells.csv"), &m.cells, first)?;
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
        far_field_angle_deg: None,
    };
    write_csv(&mut group, &dir.join("contacts.csv"), &m.contacts, &example)?;
    let path = dir.join("summary.json");
    group
        .write(&path, |w| {
            serde_json::to_writer_pretty(&mut *w, summary).map_err(std::io::Error::other)?;
            writeln!(w)
        })
        .with_context(|| format!("writing {}", path.display()))?;
    group.commit().with_context(|| format!("writing the outputs into {}", dir.display()))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use crate::imaging::{LabelWriteOptions, write_label_tiff};

    #[test]
    fn label_volumes_are_told_by_content_or_extension() {
        let dir = tempfile::tempdir().unwrap();
        let volume = LabelVolume::new(ndarray::Array3::from_elem((2, 3, 4), 1u32), [1e-6; 3], Vec3::zeros()).unwrap();
        let unnamed = dir.path().join("labels.data");
        write_label_tiff(&unnamed, &volume, &LabelWriteOptions::default()).unwrap();
        assert!(is_labels(&unnamed));
        assert!(is_labels(Path::new("missing.TIF")));
        assert!(is_labels(Path::new("missing.npy")));
        assert!(is_labels(Path::new("missing.zarr")));
        assert!(is_labels(dir.path()), "a folder is an OME-Zarr store");
        let npy = dir.path().join("labels.raw");
        std::fs::write(&npy, b"\x93NUMPY\x01\x00").unwrap();
        assert!(is_labels(&npy));
        let text = dir.path().join("tissue.mesh");
        std::fs::write(&text, "# vtk DataFile Version 4.2\n").unwrap();
        assert!(!is_labels(&text));
        assert!(!is_labels(&dir.path().join("missing")));
        assert!(!is_labels(Path::new("missing.vtp")));
    }
}
