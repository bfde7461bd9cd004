//! Per-contact morphology: one row of `contacts.csv`.

use crate::geometry::Real;
use crate::mesh::CellKind;
use serde::Serialize;

/// One touching pair of bodies, `cell_a < cell_b`. The first four fields are the stable interface of
/// `contacts.csv` (DESIGN.md §2).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ContactMorphology {
    pub cell_a: u32,
    pub cell_b: u32,
    /// Contact area (m²): the mean of `area_a` and `area_b`.
    pub area: Real,
    /// Mean external angle between the two free surfaces at the contact rim (degrees), for contacts
    /// between two cells that have a free rim (see [`super::rim_angle`]); empty otherwise.
    pub contact_angle_deg: Option<Real>,
    pub kind_a: CellKind,
    pub kind_b: CellKind,
    /// Area of `cell_a`'s faces in contact with `cell_b` (m²), and the converse.
    pub area_a: Real,
    pub area_b: Real,
    /// Number of rim edges that entered the contact angle (0 without a free rim).
    pub rim_edges: usize,
    /// External angle between the two free surfaces read away from the rim (degrees): spheres fitted
    /// to each cell's free faces meeting the plane of the interface (see
    /// [`super::far_field`]); empty where the free surfaces are not spheres or the interface is not
    /// flat, and for label volumes.
    pub far_field_angle_deg: Option<Real>,
}
