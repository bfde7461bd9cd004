//! Morphology metrics of a tissue, one definition for simulated and segmented tissues (DESIGN.md §4).
//!
//! Per cell: volume V, area A, sphericity Ψ = π^(1/3)(6V)^(2/3)/A, principal semi-axes and elongation
//! (longest/shortest semi-axis of the equivalent ellipsoid), coordination number z (cells in contact),
//! contact-area fraction φ = (area in contact with other cells)/A (SimuCell3D paper, Fig. 4d,e),
//! apical/lateral/basal areas from the face types, and the nucleus (volume, sphericity, offset from the
//! cell centroid) when a nucleus centroid lies inside the cell. Per contact: area and the rim contact
//! angle. Per tissue: layer count on the contact graph (paper Fig. 3d) and statistics over the cells.
//!
//! Contacts are geometric ([`face_contacts`]): a face touches another body when its centroid lies within
//! the contact distance δ of that body's surface; the contact area of a pair is the mean of the two
//! sides' touching areas. A tissue read from a multi-material mesh, whose faces name the body on
//! their other side, is measured on those interface labels instead
//! ([`face_contacts::labelled_face_contacts`]): exact areas and rims, no δ (`summary.contact_rule`).
//! Units are SI throughout (m, m², m³). This module never depends on
//! `mechanics`: it measures whatever surfaces it is given.
//!
//! Label volumes are measured directly by [`measure_labels()`] (voxel counts, voxel-face adjacency and a
//! staircase-free area, see [the module](mod@measure_labels)), filling the same rows; the two routes
//! agree on smooth shapes (tests/integration/morphology_labels.rs). [`compare_shapes`] and [`compare_tissues`] give the
//! per-cell IoU and χ = 1 − IoU on a common voxel grid.
//!
//! Not here yet: a lumen that is not a body (the background cavity of a segmented organoid) needs a
//! voxel flood fill before layers can be counted; contact angles on label volumes (mesh them first).

mod cell_morphology;
mod compare;
mod contact_morphology;
mod distribution;
pub mod face_contacts;
pub mod far_field;
mod label_surface;
pub mod layers;
mod measure;
pub mod measure_labels;
pub mod nucleus;
pub mod rim_angle;
pub mod sheet;
mod summary;
pub mod tensions;

pub use cell_morphology::CellMorphology;
pub use compare::{compare_shapes, compare_tissues};
pub use contact_morphology::ContactMorphology;
pub use distribution::Distribution;
pub use measure::{
    DEFAULT_CONTACT_DISTANCE_FACTOR, DEFAULT_EXTERIOR_FREE_FRACTION, MeasureSettings, Morphology, mean_edge_length,
    measure_tissue,
};
pub use measure_labels::{
    DEFAULT_NORMAL_SMOOTHING_VOXELS, DroppedLabel, LabelMeasureSettings, LabelMorphology, measure_labels,
};
pub use summary::{BodyCounts, ContactRule, ExteriorRule, MorphologySummary};

use crate::geometry::Real;

/// Why a tissue could not be measured.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MorphologyError {
    #[error("contact distance {value:e} m must be finite, positive and not subnormal")]
    InvalidContactDistance { value: Real },
    #[error("exterior free-area fraction {value} must lie in [0, 1]")]
    InvalidExteriorFraction { value: Real },
    #[error("the tissue has no cells to measure")]
    EmptyTissue,
    #[error("normal smoothing σ = {value:e} m must be finite and not negative")]
    InvalidNormalSmoothing { value: Real },
    #[error("cannot compare shapes: {reason}")]
    Comparison { reason: String },
    #[error(
        "cannot derive the default contact distance: the mean edge length is {mean_edge:e} m; give a contact distance"
    )]
    NoEdgeLength { mean_edge: Real },
    #[error(transparent)]
    Anisotropy(#[from] crate::imaging::AnisotropyError),
}
