//! Triangle kernels: normal, area, area vector, area gradient.

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

/// Gradients of the area of triangle (a, b, c) with respect to its three corners, given its unit
/// normal n̂: ∇_a A = ½ n̂ × (c − b), cyclically. They sum to zero (translation invariance).
#[inline]
pub fn triangle_area_gradients(a: &Vec3, b: &Vec3, c: &Vec3, unit_normal: &Vec3) -> [Vec3; 3] {
    let half_n = 0.5 * unit_normal;
    [half_n.cross(&(c - b)), half_n.cross(&(a - c)), half_n.cross(&(b - a))]
}
