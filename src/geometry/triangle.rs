//! Triangle kernels: normal, area, area vector.

use super::{Real, Vec3};

/// Unnormalised normal `(b − a) × (c − a)`; its length is twice the area, its direction follows the
/// right-hand rule of the vertex order.
#[inline]
pub fn triangle_normal(a: &Vec3, b: &Vec3, c: &Vec3) -> Vec3 {
    (b - a).cross(&(c - a))
}

/// Area vector `½ (b − a) × (c − a)`: the area times the unit normal.
#[inline]
pub fn triangle_area_vector(a: &Vec3, b: &Vec3, c: &Vec3) -> Vec3 {
    0.5 * triangle_normal(a, b, c)
}

/// Triangle area.
#[inline]
pub fn triangle_area(a: &Vec3, b: &Vec3, c: &Vec3) -> Real {
    0.5 * triangle_normal(a, b, c).norm()
}
