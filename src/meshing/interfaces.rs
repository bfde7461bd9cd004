//! Each face's neighbour read from the segmentation it was meshed from: the label a few voxels out
//! along the face's normal. Cells meshed one label at a time leave gaps between neighbours wherever
//! the voxels are coarse or anisotropic, so a distance rule reads parts of a shared wall as free
//! surface; the label volume has no such gap and says exactly who is on the other side.

use crate::geometry::{Real, Vec3};
use crate::imaging::LabelVolume;
use crate::mesh::{Tissue, TissueError};

/// How far out (in the smallest voxel side) a face's neighbour is looked for, in steps of a quarter.
const MAX_STEPS: usize = 12;

/// Gives every cell of `tissue` (meshed from `volume`, cell id = label) its interface labels
/// ([`crate::mesh::Cell::interface_labels`]): per face, the first label other than the cell's own met
/// along the outward normal from the face's centre, in quarter-voxel steps up to three voxels; 0 (the
/// medium) for background, outside the volume, or when nothing else is met. Returns how many faces
/// met nothing but their own label.
pub fn label_interfaces(tissue: &mut Tissue, volume: &LabelVolume) -> Result<usize, TissueError> {
    let grid = volume.grid();
    let [sz, sy, sx] = grid.voxel_size;
    let [nz, ny, nx] = grid.shape;
    let step = 0.25 * sx.min(sy).min(sz);
    let labels = volume.labels();
    let label_at = |p: Vec3| -> Option<u32> {
        let q = p - grid.origin;
        let index = |v: Real, s: Real, n: usize| {
            let i = (v / s).round();
            (i >= 0.0 && i < n as Real).then_some(i as usize)
        };
        Some(labels[[index(q.z, sz, nz)?, index(q.y, sy, ny)?, index(q.x, sx, nx)?]])
    };
    let mut unresolved = 0;
    for cell in tissue.cells_mut() {
        let own = cell.id().0;
        let mesh = cell.mesh();
        let p = mesh.positions();
        let vectors = mesh.face_area_vectors();
        let found: Vec<u32> = mesh
            .triangles()
            .iter()
            .zip(&vectors)
            .map(|(t, a)| {
                let centre = (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0;
                let n = a.try_normalize(0.0).unwrap_or_else(Vec3::zeros);
                for k in 1..=MAX_STEPS {
                    match label_at(centre + n * (k as Real * step)) {
                        None => return 0,
                        Some(l) if l != own => return l,
                        Some(_) => {}
                    }
                }
                unresolved += 1;
                0
            })
            .collect();
        cell.set_interface_labels(found)?;
    }
    Ok(unresolved)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::meshing::{LabelMeshingOptions, mesh_labels};
    use ndarray::Array3;

    /// Two 10-voxel cubes side by side along x (labels 1 and 2) in a background margin: the faces of the
    /// shared wall name the other cell, the outer faces the medium.
    #[test]
    fn the_faces_of_a_shared_wall_name_the_neighbour_and_the_others_the_medium() {
        let mut labels = Array3::<u32>::zeros((14, 14, 24));
        for ((z, y, x), l) in labels.indexed_iter_mut() {
            if (2..12).contains(&z) && (2..12).contains(&y) && (2..22).contains(&x) {
                *l = if x < 12 { 1 } else { 2 };
            }
        }
        let volume = LabelVolume::new(labels, [1e-6; 3], Vec3::zeros()).unwrap();
        let mut tissue = mesh_labels(&volume, &LabelMeshingOptions::default()).unwrap().tissue;
        assert_eq!(label_interfaces(&mut tissue, &volume).unwrap(), 0);
        for cell in tissue.cells() {
            let (own, other) = (cell.id().0, 3 - cell.id().0);
            let wall_side = if own == 1 { 1.0 } else { -1.0 };
            let labels = cell.interface_labels().unwrap();
            let p = cell.mesh().positions();
            let (mut wall, mut outer) = (0, 0);
            for ((t, a), &l) in cell.mesh().triangles().iter().zip(cell.mesh().face_area_vectors()).zip(labels) {
                let centre = (p[t[0] as usize] + p[t[1] as usize] + p[t[2] as usize]) / 3.0;
                let n = a.normalize();
                // Well inside the wall (x = 11.5 µm) or on the far end, away from the rims.
                let on_wall = (centre.x - 11.5e-6).abs() < 0.6e-6 && n.x * wall_side > 0.9;
                let central = (centre.y - 6.5e-6).abs() < 3e-6 && (centre.z - 6.5e-6).abs() < 3e-6;
                if on_wall && central {
                    assert_eq!(l, other, "cell {own} wall face at {centre:?}");
                    wall += 1;
                }
                if n.x * wall_side < -0.9 || n.y.abs() > 0.9 && (centre.x - 11.5e-6).abs() > 3e-6 {
                    assert_eq!(l, 0, "cell {own} outer face at {centre:?}");
                    outer += 1;
                }
            }
            assert!(wall > 10 && outer > 10, "cell {own}: {wall} wall and {outer} outer faces checked");
        }
    }
}
