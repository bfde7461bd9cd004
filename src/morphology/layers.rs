//! Number of cell layers between a lumen and the exterior, on the cell contact graph.
//!
//! SimuCell3D paper (Results, "Transition from monolayer to multilayer tissue", Fig. 3d): the tissue is
//! converted "into a graph representing cell connectivity", and the layer number N is the "shortest path
//! percolating from the lumen to the ECM". Here:
//! - nodes are the cells (epithelial and static bodies); edges join cells in contact;
//! - *lumen-facing* cells touch a lumen body;
//! - *exterior-facing* cells touch an ECM body when the tissue has one; without an ECM, they are the cells
//!   whose free (contact-less) surface is at least a given fraction of their area (they face the medium);
//! - for every cell c, N(c) = d_L(c) + d_E(c) + 1, with d_L and d_E the graph distances (in edges) from c
//!   to the nearest lumen-facing and exterior-facing cell: the number of cells on the shortest
//!   lumen→exterior path through c. A monolayer has N(c) = 1 everywhere, a bilayer 2.
//!
//! The tissue's layer count is N = max over cells of N(c) (its thickest place); the mean over
//! lumen-facing cells of the shortest path from that cell to the exterior (d_E + 1) is reported too,
//! as the paper's Fig. 3e plots an average number of layers. Cells that reach no lumen-facing or no
//! exterior-facing cell have no N(c); a tissue without a lumen (or without exterior-facing cells) has
//! no layer count.

use crate::geometry::Real;
use std::collections::VecDeque;

/// Layer count of a tissue; see the module doc.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerCount {
    /// N(c) for every graph node, `None` when c is not on any lumen→exterior path.
    pub per_cell: Vec<Option<u32>>,
    /// max N(c); `None` when no cell has an N(c).
    pub max: Option<u32>,
    /// Mean over lumen-facing cells (that reach the exterior) of d_E + 1.
    pub mean_from_lumen: Option<Real>,
}

/// Graph distances (in edges) from the nearest of `sources`, breadth first; `None` if unreachable.
pub fn graph_distances(neighbours: &[Vec<usize>], sources: &[bool]) -> Vec<Option<u32>> {
    let mut dist = vec![None; neighbours.len()];
    let mut queue = VecDeque::new();
    for (i, &s) in sources.iter().enumerate() {
        if s {
            dist[i] = Some(0);
            queue.push_back(i);
        }
    }
    while let Some(i) = queue.pop_front() {
        let d = dist[i].unwrap_or(0) + 1;
        for &j in &neighbours[i] {
            if dist[j].is_none() {
                dist[j] = Some(d);
                queue.push_back(j);
            }
        }
    }
    dist
}

/// Layer count on the graph `neighbours` (adjacency lists over node indices) with lumen-facing and
/// exterior-facing nodes marked.
pub fn count_layers(neighbours: &[Vec<usize>], lumen_facing: &[bool], exterior_facing: &[bool]) -> LayerCount {
    let from_lumen = graph_distances(neighbours, lumen_facing);
    let from_exterior = graph_distances(neighbours, exterior_facing);
    let per_cell: Vec<Option<u32>> =
        from_lumen.iter().zip(&from_exterior).map(|(l, e)| Some(l.as_ref()? + e.as_ref()? + 1)).collect();
    let max = per_cell.iter().flatten().copied().max();
    let paths: Vec<u32> =
        (0..neighbours.len()).filter(|&i| lumen_facing[i]).filter_map(|i| from_exterior[i].map(|d| d + 1)).collect();
    let mean_from_lumen =
        (!paths.is_empty()).then(|| paths.iter().map(|&d| d as Real).sum::<Real>() / paths.len() as Real);
    LayerCount { per_cell, max, mean_from_lumen }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain lumen-facing 0 – 1 – 2 – 3 exterior-facing: 4 layers everywhere on the path.
    #[test]
    fn a_chain_of_four_cells_is_four_layers() {
        let neighbours = vec![vec![1], vec![0, 2], vec![1, 3], vec![2]];
        let l = count_layers(&neighbours, &[true, false, false, false], &[false, false, false, true]);
        assert_eq!(l.per_cell, vec![Some(4); 4]);
        assert_eq!(l.max, Some(4));
        assert_eq!(l.mean_from_lumen, Some(4.0));
    }

    /// A cell touching both is one layer; a disconnected cell has no N; no lumen gives no count.
    #[test]
    fn monolayer_disconnected_and_missing_lumen() {
        let neighbours = vec![vec![1], vec![0], vec![]];
        let l = count_layers(&neighbours, &[true, true, false], &[true, true, false]);
        assert_eq!(l.per_cell, vec![Some(1), Some(1), None]);
        assert_eq!(l.max, Some(1));
        let none = count_layers(&neighbours, &[false; 3], &[true; 3]);
        assert_eq!((none.max, none.mean_from_lumen), (None, None));
    }
}
