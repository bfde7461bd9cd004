//! `tissuefit polarize IN --out OUT`: type every face of the epithelial and static cells (apical,
//! lateral, basal) by ray casting (paper mode 2) or from contacts (mode 1), write the tissue (the
//! `.vtp` carries `face_type`, so ParaView colours by it) and print the counts per face type.

use super::{InputArgs, Outcome};
use crate::io::{Format, OutputPolicy, read_tissue, write_tissue};
use crate::mechanics::{
    ContactWorkspace, Parameters, RayCastSettings, TermSet, TissueForces, cell_parameters, polarize_by_ray_casting,
    polarize_from_contacts,
};
use crate::mesh::{FaceType, Tissue};
use anyhow::Context;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct PolarizeArgs {
    /// Input tissue file (.vtk, .vtp or .ply).
    pub input: PathBuf,
    /// Output file: .vtp (ParaView; colour by the face_type cell array: 0 apical, 1 lateral, 2 basal)
    /// or .vtk (SimuCell3D legacy).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Polarisation: ray_casting (paper mode 2) or contacts (mode 1: faces whose three nodes touch
    /// another cell within the contact cutoff are lateral).
    #[arg(long, value_parser = ["ray_casting", "contacts"], default_value = "ray_casting")]
    pub mode: String,
    /// Voxel edge for ray casting, in metres. Default: numerics.polarity_voxel_size of --config when
    /// set, else 1.5·l_min, with l_min from --config or, without it, the median over cells of the
    /// shortest edge.
    #[arg(long, value_name = "METRES")]
    pub voxel_size: Option<f64>,
    /// Ray casting: an enclosed cavity that is no body is a lumen when it holds at least this
    /// fraction of the mean cell volume, else a gap between cells that rays pass through. Default:
    /// numerics.polarity_min_lumen_fraction of --config, else 0.25.
    #[arg(long, value_name = "FRACTION")]
    pub min_lumen_fraction: Option<f64>,
    /// Parameter file: l_min and the voxel size (ray casting); contact cutoff and cell types
    /// (contacts; without it the cutoff is the estimated l_min).
    #[arg(long, value_name = "TOML")]
    pub config: Option<PathBuf>,
    /// Print the report as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    #[command(flatten)]
    pub input_args: InputArgs,
}

/// The median over cells of each cell's shortest edge (m): the l_min the file was meshed with.
fn estimated_min_edge(tissue: &Tissue) -> Option<f64> {
    let mut shortest: Vec<f64> =
        tissue.cells().iter().filter_map(|c| c.mesh().edge_length_stats().map(|s| s.min)).collect();
    shortest.sort_by(f64::total_cmp);
    shortest.get(shortest.len() / 2).copied()
}

pub fn run(args: &PolarizeArgs) -> anyhow::Result<Outcome> {
    OutputPolicy::new().input("INPUT", &args.input).input_opt("--config", args.config.as_deref()).file(
        "--out",
        &args.out,
        Format::Tissue,
    )?;
    let read = read_tissue(&args.input, &args.input_args.read_options())
        .with_context(|| format!("reading {}", args.input.display()))?;
    for w in &read.warnings {
        tracing::warn!("{}: {w}", args.input.display());
    }
    let mut tissue = read.tissue;
    let params = match &args.config {
        Some(path) => Some(Parameters::load(path)?),
        None => None,
    };
    let l_min = match &params {
        Some(p) => p.numerics.min_edge_length,
        None => estimated_min_edge(&tissue)
            .with_context(|| format!("{}: no cell has an edge to estimate l_min from", args.input.display()))?,
    };
    if let Some(bad) = tissue.cells().iter().find(|c| c.mesh().validate().is_err()) {
        tracing::warn!(
            "{}: cell {} is not a valid closed surface; its faces may be typed wrongly (`tissuefit inspect` lists the defects)",
            args.input.display(),
            bad.id()
        );
    }
    let mut report = serde_json::Map::new();
    let what = match args.mode.as_str() {
        "contacts" => {
            let params = params.clone().unwrap_or_default();
            let cutoff = if args.config.is_some() { params.numerics.contact_cutoff } else { l_min };
            let cell_params = cell_parameters(&tissue, &params).with_context(|| {
                format!("{}: pass --config with a [[cell_types]] entry for every cell type", args.input.display())
            })?;
            let mut forces = TissueForces::default();
            forces.compute(&tissue, &cell_params, TermSet::ALL);
            let mut contacts = ContactWorkspace::default();
            contacts.set_model(params.numerics.contact_model);
            contacts.set_quadrature(params.numerics.contact_quadrature);
            contacts.add_contacts(&tissue, &cell_params, cutoff, &mut forces.cells);
            let changed = polarize_from_contacts(&mut tissue, &contacts);
            report.insert("contact_cutoff".into(), cutoff.into());
            report.insert("changed".into(), changed.into());
            format!("from contacts within {cutoff:.3e} m")
        }
        _ => {
            let voxel_size = match (args.voxel_size, &params) {
                (Some(h), _) => h,
                (None, Some(p)) if p.numerics.polarity_voxel_size > 0.0 => p.numerics.polarity_voxel_size,
                _ => RayCastSettings::DEFAULT_VOXELS_PER_MIN_EDGE * l_min,
            };
            if !(voxel_size.is_finite() && voxel_size > 0.0) {
                anyhow::bail!("--voxel-size {voxel_size}: give a voxel edge in metres > 0");
            }
            let min_lumen_fraction = match (args.min_lumen_fraction, &params) {
                (Some(f), _) => f,
                (None, Some(p)) => p.numerics.polarity_min_lumen_fraction,
                _ => RayCastSettings::DEFAULT_MIN_LUMEN_FRACTION,
            };
            if !(min_lumen_fraction.is_finite() && min_lumen_fraction >= 0.0) {
                anyhow::bail!("--min-lumen-fraction {min_lumen_fraction}: give a fraction of a cell volume ≥ 0");
            }
            let settings = RayCastSettings { min_lumen_fraction, ..RayCastSettings::new(voxel_size) };
            let r = polarize_by_ray_casting(&mut tissue, &settings)
                .with_context(|| format!("polarising {}", args.input.display()))?;
            if !r.cells_without_cytoplasm.is_empty() {
                tracing::warn!(
                    "cells {:?} have no interior voxel at {:.3e} m; a smaller --voxel-size resolves them",
                    r.cells_without_cytoplasm.iter().map(|c| c.0).collect::<Vec<_>>(),
                    r.voxel_size
                );
            }
            let text = format!(
                "by ray casting, voxel {:.3e} m ({}×{}×{}; clusters: {} cytoplasm, {} lumen, {} exterior, {} ECM, {} gap)",
                r.voxel_size,
                r.dims[0],
                r.dims[1],
                r.dims[2],
                r.cytoplasm_clusters,
                r.lumen_clusters,
                r.exterior_clusters,
                r.ecm_clusters,
                r.gap_clusters
            );
            if let serde_json::Value::Object(fields) = serde_json::to_value(&r)? {
                report.extend(fields);
            }
            text
        }
    };
    write_tissue(&args.out, &tissue, &[]).with_context(|| format!("writing {}", args.out.display()))?;
    let polarised: Vec<_> = tissue.cells().iter().filter(|c| c.kind().is_cell()).collect();
    let counts = FaceType::ALL
        .map(|t| polarised.iter().map(|c| c.face_types().iter().filter(|x| **x == t).count()).sum::<usize>());
    if args.json {
        report.insert("mode".into(), args.mode.clone().into());
        report.insert("output".into(), args.out.display().to_string().into());
        report.insert("cells".into(), polarised.len().into());
        for (t, n) in FaceType::ALL.iter().zip(counts) {
            report.insert(t.name().into(), n.into());
        }
        println!("{}", serde_json::Value::Object(report));
    } else {
        println!(
            "polarised {} cells ({} faces) {what}; wrote {}",
            polarised.len(),
            counts.iter().sum::<usize>(),
            args.out.display()
        );
        for (t, n) in FaceType::ALL.iter().zip(counts) {
            println!("{:>8}: {n}", t.name());
        }
    }
    Ok(Outcome::Success)
}
