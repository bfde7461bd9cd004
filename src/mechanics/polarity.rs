//! Polarisation from contacts (paper Methods, "Cell membrane polarization", mode 1); mode 2, by
//! ray casting through a voxelised domain, is in [`ray_casting`].
//!
//! Every face of an epithelial or static cell is typed by what its three nodes touch (a node
//! touches the cell whose surface lies within the contact cutoff; of several, the nearest):
//! all three another epithelial or static cell (not necessarily the same one, as at a tricellular
//! junction) → lateral; all three the lumen → apical; anything else (the ECM, the medium, a rim face
//! half in contact) → basal. Nuclei lie inside their cell and do not count. So per-face-type
//! tension, bending and adhesion act where they should: lateral on cell–cell interfaces, apical
//! towards the lumen, basal towards the ECM or the medium.
//!
//! Requiring all three nodes (as the reference does for coupled nodes) keeps the rim faces free, so
//! the interface is not wider than the contact.

mod ray_casting;

pub use ray_casting::{RayCastError, RayCastReport, RayCastSettings, Region, polarize_by_ray_casting};

use super::ContactWorkspace;
use crate::mesh::{CellKind, FaceType, Tissue};

/// What a node touches.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Touch {
    Nothing,
    Cell,
    Lumen,
    Ecm,
}

/// Re-types the faces of epithelial and static cells from the contacts of the last evaluation
/// (`contacts` must have been evaluated on this tissue's current topology). Returns how many faces
/// changed type.
pub fn polarize_from_contacts(tissue: &mut Tissue, contacts: &ContactWorkspace) -> usize {
    let kinds: Vec<CellKind> = tissue.cells().iter().map(|c| c.kind()).collect();
    let mut changed = 0;
    let mut touch: Vec<(Touch, f64)> = Vec::new();
    for (c, cell) in tissue.cells_mut().iter_mut().enumerate() {
        if !cell.kind().is_cell() {
            continue;
        }
        touch.clear();
        touch.resize(cell.mesh().node_count(), (Touch::Nothing, f64::INFINITY));
        for (node, other, d) in contacts.node_contacts(c) {
            let what = match kinds[other as usize] {
                CellKind::Epithelial | CellKind::Static => Touch::Cell,
                CellKind::Lumen => Touch::Lumen,
                CellKind::Ecm => Touch::Ecm,
                CellKind::Nucleus => continue,
            };
            let slot = &mut touch[node as usize];
            if d.abs() < slot.1 {
                *slot = (what, d.abs());
            }
        }
        let (mesh, face_types) = cell.mesh_and_face_types_mut();
        for (t, face_type) in mesh.triangles().iter().zip(face_types) {
            let [a, b, c] = t.map(|n| touch[n as usize].0);
            let new = match (a == b && b == c, a) {
                (true, Touch::Cell) => FaceType::Lateral,
                (true, Touch::Lumen) => FaceType::Apical,
                _ => FaceType::Basal,
            };
            if *face_type != new {
                *face_type = new;
                changed += 1;
            }
        }
    }
    changed
}
