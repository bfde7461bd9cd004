//! Measuring a meshed tissue: per-cell metrics, contacts, contact angles, layers, nuclei, summary.

use super::face_contacts::{FREE, FaceContacts, contact_partition};
use super::layers::count_layers;
use super::nucleus::contains;
use super::rim_angle::{RimEdge, contact_angle, rim_edges, rim_toward};
use super::{CellMorphology, ContactMorphology, ContactRule, ExteriorRule, MorphologyError, MorphologySummary};
use crate::geometry::{Real, Vec3};
use crate::mesh::{CellKind, FaceType, Tissue, sphericity};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;

/// Default contact distance δ as a fraction of the tissue's mean edge length (see [`MeasureSettings`]).
pub const DEFAULT_CONTACT_DISTANCE_FACTOR: Real = 0.25;

/// Default free-area fraction above which a cell faces the exterior when the tissue has no ECM body.
pub const DEFAULT_EXTERIOR_FREE_FRACTION: Real = 0.1;

/// How to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct MeasureSettings {
    /// Contact distance δ (m): a face whose centroid lies within δ of another body's surface is in contact
    /// with it. `None` (default): [`DEFAULT_CONTACT_DISTANCE_FACTOR`] × the mean edge length of the tissue
    /// (nuclei left out). Why a quarter edge: two touching surfaces meshed independently differ by their
    /// chord errors (h²/8R, a few percent of h for cells ten edges across) plus the equilibrium gap of the
    /// spring contact model (0 to c/2, with the paper's cutoff c = l_min ≈ h/2 … h/3), so touching faces lie
    /// well within h/4; while the free faces next to a rim have their centroid about h/3 from the rim, so
    /// they stay free for any contact angle above ~50°.
    pub contact_distance: Option<Real>,
    /// Count static cells in the tissue statistics. Default false (they are boundary conditions).
    pub include_static: bool,
    /// Without an ECM body, a cell faces the exterior when its free area is at least this fraction of its
    /// area. Default [`DEFAULT_EXTERIOR_FREE_FRACTION`].
    pub exterior_free_fraction: Real,
    /// When every cell carries interface labels (a multi-material input, see
    /// [`crate::mesh::Cell::interface_labels`]), take the contacts from them instead of the distance
    /// rule: exact contact areas and rims. Default true. The fit turns it off so that the observed
    /// tissue is measured by the same rule as the simulated ones, which carry no labels.
    pub interface_labels: bool,
}

impl Default for MeasureSettings {
    fn default() -> Self {
        Self {
            contact_distance: None,
            include_static: false,
            exterior_free_fraction: DEFAULT_EXTERIOR_FREE_FRACTION,
            interface_labels: true,
        }
    }
}

/// Everything measured on a tissue.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Morphology {
    /// One row per body, in tissue order.
    pub cells: Vec<CellMorphology>,
    /// One row per touching pair, ordered by `(cell_a, cell_b)`.
    pub contacts: Vec<ContactMorphology>,
    pub summary: MorphologySummary,
}

/// Per-body measures computed in parallel.
struct BodyMeasure {
    volume: Real,
    area: Real,
    centroid: Vec3,
    semi_axes: [Real; 3],
    face_type_area: [Real; 3],
    free_area: Real,
    /// Own area in contact with each partner (tissue index), ascending by partner.
    area_toward: Vec<(u32, Real)>,
    rims: Vec<RimEdge>,
}

/// The tissue's mean edge length (m), nuclei left out: [`Tissue::mean_edge_length`].
pub fn mean_edge_length(tissue: &Tissue) -> Option<Real> {
    tissue.mean_edge_length()
}

/// Measures a meshed tissue: see the module docs of [`super`] for every definition.
pub fn measure_tissue(tissue: &Tissue, settings: &MeasureSettings) -> Result<Morphology, MorphologyError> {
    let f = settings.exterior_free_fraction;
    if !(0.0..=1.0).contains(&f) {
        return Err(MorphologyError::InvalidExteriorFraction { value: f });
    }
    if tissue.is_empty() {
        return Err(MorphologyError::EmptyTissue);
    }
    let delta = match settings.contact_distance {
        Some(d) if d.is_finite() && d > 0.0 && (1.0 / d).is_finite() => d,
        Some(d) => return Err(MorphologyError::InvalidContactDistance { value: d }),
        None => match mean_edge_length(tissue) {
            Some(h) if h.is_finite() && h > 0.0 => DEFAULT_CONTACT_DISTANCE_FACTOR * h,
            h => return Err(MorphologyError::NoEdgeLength { mean_edge: h.unwrap_or(0.0) }),
        },
    };
    let clock = std::time::Instant::now();
    let cells = tissue.cells();
    let participates: Vec<bool> = cells.iter().map(|c| c.kind() != CellKind::Nucleus).collect();
    let (partitions, rule) = contact_partition(tissue, &participates, delta, settings.interface_labels);
    tracing::debug!("morphology: face contacts ({rule:?}) in {:.3} s (δ = {delta:e} m)", clock.elapsed().as_secs_f64());
    let measures: Vec<BodyMeasure> =
        cells.par_iter().zip(&partitions).map(|(cell, contacts)| measure_body(cell, contacts)).collect();

    tracing::debug!("morphology: per-body measures and rims at {:.3} s", clock.elapsed().as_secs_f64());
    let kinds: Vec<CellKind> = cells.iter().map(|c| c.kind()).collect();
    let is_cell: Vec<bool> = kinds.iter().map(|&k| CellMorphology::is_cell_kind(k)).collect();

    // Touching pairs by tissue index, and each side's area.
    let mut pairs: BTreeMap<(usize, usize), [Real; 2]> = BTreeMap::new();
    for (i, m) in measures.iter().enumerate() {
        for &(j, area) in &m.area_toward {
            let j = j as usize;
            let (key, side) = if i < j { ((i, j), 0) } else { ((j, i), 1) };
            pairs.entry(key).or_insert([0.0; 2])[side] += area;
        }
    }
    let pair_list: Vec<((usize, usize), [Real; 2])> = pairs.into_iter().collect();
    // Far-field angles skip the free faces within two mean edge lengths of a contact (the rim's
    // rounding spans one or two edges).
    let margin = 2.0 * mean_edge_length(tissue).unwrap_or(0.0);
    let mut contacts: Vec<ContactMorphology> = pair_list
        .par_iter()
        .map(|&((i, j), [area_i, area_j])| {
            let angle = if is_cell[i] && is_cell[j] {
                contact_angle(rim_toward(&measures[i].rims, j as u32), rim_toward(&measures[j].rims, i as u32), delta)
            } else {
                None
            };
            let (ci, cj) = (&cells[i], &cells[j]);
            let far_field = if is_cell[i] && is_cell[j] {
                super::far_field::contact_far_field_angle(
                    ci.mesh(),
                    &partitions[i],
                    i as u32,
                    cj.mesh(),
                    &partitions[j],
                    j as u32,
                    measures[i].centroid,
                    margin,
                )
            } else {
                None
            };
            let (a, b, area_a, area_b) =
                if ci.id() < cj.id() { (ci, cj, area_i, area_j) } else { (cj, ci, area_j, area_i) };
            ContactMorphology {
                cell_a: a.id().0,
                cell_b: b.id().0,
                area: (area_a + area_b) / 2.0,
                contact_angle_deg: angle.map(|(theta, _)| theta.to_degrees()),
                kind_a: a.kind(),
                kind_b: b.kind(),
                area_a,
                area_b,
                rim_edges: angle.map_or(0, |(_, n)| n),
                far_field_angle_deg: far_field.map(Real::to_degrees),
            }
        })
        .collect();
    contacts.sort_by_key(|c| (c.cell_a, c.cell_b));
    tracing::debug!("morphology: contact angles at {:.3} s", clock.elapsed().as_secs_f64());

    // Contact graph over cells.
    let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); cells.len()];
    for &((i, j), [a, b]) in &pair_list {
        if is_cell[i] && is_cell[j] && a + b > 0.0 {
            neighbours[i].push(j);
            neighbours[j].push(i);
        }
    }
    let area_with = |i: usize, want: &dyn Fn(usize) -> bool| -> Real {
        measures[i].area_toward.iter().filter(|(j, _)| want(*j as usize)).fold(0.0, |s, (_, a)| s + a)
    };
    let has_ecm = kinds.contains(&CellKind::Ecm);
    let exterior_rule = if has_ecm { ExteriorRule::TouchesEcm } else { ExteriorRule::FreeSurfaceFraction };
    let lumen_area: Vec<Real> = (0..cells.len()).map(|i| area_with(i, &|j| kinds[j] == CellKind::Lumen)).collect();
    let ecm_area: Vec<Real> = (0..cells.len()).map(|i| area_with(i, &|j| kinds[j] == CellKind::Ecm)).collect();
    let lumen_facing: Vec<bool> = (0..cells.len()).map(|i| is_cell[i] && lumen_area[i] > 0.0).collect();
    let exterior_facing: Vec<bool> = (0..cells.len())
        .map(|i| {
            is_cell[i]
                && if has_ecm {
                    ecm_area[i] > 0.0
                } else {
                    measures[i].area > 0.0 && measures[i].free_area >= f * measures[i].area
                }
        })
        .collect();
    let layers = count_layers(&neighbours, &lumen_facing, &exterior_facing);

    // Nuclei: each one's host is the cell containing its centroid.
    let nucleus_hosts: Vec<(usize, Option<usize>)> = (0..cells.len())
        .into_par_iter()
        .filter(|&n| kinds[n] == CellKind::Nucleus)
        .map(|n| {
            let c = measures[n].centroid;
            (n, (0..cells.len()).find(|&h| is_cell[h] && contains(cells[h].mesh(), &c)))
        })
        .collect();
    let mut nuclei_of: Vec<Vec<usize>> = vec![Vec::new(); cells.len()];
    for &(n, host) in &nucleus_hosts {
        if let Some(h) = host {
            nuclei_of[h].push(n);
        }
    }

    let rows: Vec<CellMorphology> = (0..cells.len())
        .map(|i| {
            let (cell, m) = (&cells[i], &measures[i]);
            let contact_area = area_with(i, &|j| is_cell[j]);
            let nucleus = nuclei_of[i].iter().copied().max_by(|&a, &b| {
                measures[a].volume.total_cmp(&measures[b].volume).then(cells[b].id().cmp(&cells[a].id()))
            });
            let kind = cell.kind();
            CellMorphology {
                cell: cell.id().0,
                kind,
                is_static: kind == CellKind::Static,
                volume: m.volume,
                area: m.area,
                sphericity: sphericity(m.volume.max(0.0), m.area),
                neighbours: neighbours[i].len(),
                contact_fraction: if m.area > 0.0 { contact_area / m.area } else { 0.0 },
                contact_area,
                lumen_contact_area: lumen_area[i],
                ecm_contact_area: ecm_area[i],
                free_area: m.free_area,
                apical_area: Some(m.face_type_area[0]),
                lateral_area: Some(m.face_type_area[1]),
                basal_area: Some(m.face_type_area[2]),
                semi_axis_1: m.semi_axes[0],
                semi_axis_2: m.semi_axes[1],
                semi_axis_3: m.semi_axes[2],
                elongation: m.semi_axes[0] / m.semi_axes[2],
                centroid_x: m.centroid.x,
                centroid_y: m.centroid.y,
                centroid_z: m.centroid.z,
                lumen_facing: lumen_facing[i],
                exterior_facing: exterior_facing[i],
                layer: layers.per_cell[i],
                in_statistics: is_cell[i] && (kind != CellKind::Static || settings.include_static),
                nucleus: nucleus.map(|n| cells[n].id().0),
                nuclei: nuclei_of[i].len(),
                nucleus_volume: nucleus.map(|n| measures[n].volume),
                nucleus_sphericity: nucleus.map(|n| sphericity(measures[n].volume.max(0.0), measures[n].area)),
                nucleus_offset: nucleus.map(|n| (measures[n].centroid - m.centroid).norm()),
                iou: None,
                chi: None,
            }
        })
        .collect();
    let delta_used = (rule == ContactRule::Distance).then_some(delta);
    let summary =
        MorphologySummary::from_rows(&rows, &contacts, rule, delta_used, settings.include_static, exterior_rule);
    Ok(Morphology { cells: rows, contacts, summary })
}

fn measure_body(cell: &crate::mesh::Cell, contacts: &FaceContacts) -> BodyMeasure {
    let mesh = cell.mesh();
    let face_areas = mesh.face_areas();
    let mut face_type_area = [0.0; 3];
    for (a, t) in face_areas.iter().zip(cell.face_types()) {
        face_type_area[match t {
            FaceType::Apical => 0,
            FaceType::Lateral => 1,
            FaceType::Basal => 2,
        }] += a;
    }
    let mut toward: BTreeMap<u32, Real> = BTreeMap::new();
    let mut free_area = 0.0;
    for (a, &p) in face_areas.iter().zip(&contacts.partner) {
        if p == FREE {
            free_area += a;
        } else {
            *toward.entry(p).or_insert(0.0) += a;
        }
    }
    let axes = mesh.principal_axes();
    let volume = mesh.signed_volume();
    BodyMeasure {
        volume,
        area: face_areas.iter().fold(0.0, |s, a| s + a),
        centroid: axes.as_ref().map(|a| a.centroid).unwrap_or_else(|| vertex_mean(mesh.positions())),
        semi_axes: axes.map_or([Real::NAN; 3], |a| a.semi_axes),
        face_type_area,
        free_area,
        area_toward: toward.into_iter().collect(),
        rims: if contacts.partner.iter().any(|&p| p != FREE) { rim_edges(mesh, contacts) } else { Vec::new() },
    }
}

fn vertex_mean(points: &[Vec3]) -> Vec3 {
    if points.is_empty() {
        return Vec3::repeat(Real::NAN);
    }
    points.iter().sum::<Vec3>() / points.len() as Real
}
