//! Cells that passed through each other: a check after a run.
//!
//! The spring contact model sees a node only within the cutoff c of another surface; deeper inside
//! another cell it feels nothing, and two coincident surfaces sit at the bottom of the adhesion well
//! over their whole area. So a cell pushed through its neighbour can end inside it, at a lower energy
//! than the contact it left, and the overlap volume ([`super::Simulation::overlap_volumes`]) does not
//! see it (only penetrations within c count). A default spring doublet meshed at 1 µm voxels with
//! c = 1.28 µm ended so: two cells of R ≈ 6 µm whose centres lay 0.03 µm apart, reported as
//! overlapping by 0.15 %. The check here is geometric: a body whose volume centroid lies inside
//! another body (winding number > ½) went through it. Nuclei (inside their cells by design) and ECM
//! are left out.

use crate::geometry::{Vec3, bounding_box};
use crate::mesh::{CellKind, Tissue};
use rayon::prelude::*;

/// A cell whose volume centroid lies inside another cell at the end of a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CellInside {
    /// The cell whose centre is inside `host`.
    pub cell: u32,
    pub host: u32,
}

/// Every (cell, host) pair of the tissue's cells (nuclei and ECM left out) in which the cell's volume
/// centroid lies inside the host's closed surface, in tissue order.
pub fn cells_inside_others(tissue: &Tissue) -> Vec<CellInside> {
    let bodies: Vec<_> =
        tissue.cells().iter().filter(|c| !matches!(c.kind(), CellKind::Nucleus | CellKind::Ecm)).collect();
    let boxes: Vec<Option<(Vec3, Vec3)>> = bodies.iter().map(|c| bounding_box(c.mesh().positions())).collect();
    let centroids: Vec<Option<Vec3>> = bodies.iter().map(|c| c.mesh().volume_centroid()).collect();
    let per_cell: Vec<Vec<CellInside>> = (0..bodies.len())
        .into_par_iter()
        .map(|i| {
            let Some(p) = centroids[i] else { return Vec::new() };
            (0..bodies.len())
                .filter(|&j| j != i)
                .filter(|&j| {
                    boxes[j].is_some_and(|(lo, hi)| (0..3).all(|k| p[k] >= lo[k] && p[k] <= hi[k]))
                        && bodies[j].mesh().winding_number(&p) > 0.5
                })
                .map(|j| CellInside { cell: bodies[i].id().0, host: bodies[j].id().0 })
                .collect()
        })
        .collect();
    per_cell.into_iter().flatten().collect()
}

/// The warning for [`cells_inside_others`] (`None` when the list is empty).
pub fn passage_warning(inside: &[CellInside]) -> Option<String> {
    if inside.is_empty() {
        return None;
    }
    let pairs: Vec<String> = inside.iter().take(5).map(|c| format!("cell {} inside cell {}", c.cell, c.host)).collect();
    let more = if inside.len() > 5 { format!(" and {} more", inside.len() - 5) } else { String::new() };
    Some(format!(
        "cells passed through each other: at the end the centre of a cell lies inside another ({}{more}), which the \
         overlap volume does not see (nodes deeper than the contact cutoff feel no contact). The result is not a \
         tissue; with spring contacts raise the repulsion, lower the adhesion or the contact cutoff, or use the \
         coupling contact model; with coupling contacts on coarse meshes of many cells set \
         numerics.coupling_persistent_junctions = true",
        pairs.join(", ")
    ))
}
