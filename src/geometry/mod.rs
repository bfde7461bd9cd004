//! Math aliases, triangle kernels, exact closest-point queries (point–triangle, segment–segment,
//! triangle–triangle), a sparse uniform spatial grid and voxel kernels (ray walk, triangle–box
//! overlap): the geometry shared by every other module.
//!
//! Only this module names `nalgebra` types; everyone else uses [`Real`], [`Vec3`] and [`Mat3`].
//! Everything is `f64`: the model works in SI units (lengths ~1e-6 m, moduli up to 1e9), where `f32`
//! loses too much precision in volumes and energies.

mod closest_point;
mod spatial_grid;
mod triangle;
mod voxel_ray;

pub use closest_point::*;
pub use spatial_grid::*;
pub use triangle::{triangle_area, triangle_area_gradients, triangle_area_vector, triangle_normal};
pub use voxel_ray::{VoxelWalk, triangle_box_overlap};

/// Scalar type of every physical quantity.
pub type Real = f64;
/// A 3-vector: positions, forces, normals.
pub type Vec3 = nalgebra::Vector3<Real>;
/// A 3×3 matrix: covariances, inertia tensors.
pub type Mat3 = nalgebra::Matrix3<Real>;

/// Eigen-decomposition of a symmetric 3×3 matrix, eigenvalues sorted in decreasing order.
///
/// Returns `(values, vectors)` where `vectors[i]` is the unit eigenvector of `values[i]`.
pub fn symmetric_eigen(m: &Mat3) -> ([Real; 3], [Vec3; 3]) {
    let eig = nalgebra::SymmetricEigen::new(*m);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let values = order.map(|i| eig.eigenvalues[i]);
    let vectors = order.map(|i| eig.eigenvectors.column(i).into_owned());
    (values, vectors)
}

/// Axis-aligned bounding box of a point set; `None` when empty.
pub fn bounding_box(points: &[Vec3]) -> Option<(Vec3, Vec3)> {
    let first = *points.first()?;
    Some(points.iter().fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))))
}
