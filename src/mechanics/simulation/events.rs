//! Topology events (divisions and removals) and the counts of topology changes and remeshing.

use crate::geometry::Real;
use crate::mesh::CellId;
use crate::mesh::remesh::RemeshReport;
use serde::{Deserialize, Serialize};

/// What happened to a cell's identity.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TopologyEventKind {
    /// The cell divided into `daughters`.
    Division,
    /// The cell was removed (volume below V_min).
    Removal,
}

/// One division or removal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TopologyEvent {
    pub step: u64,
    /// Simulated time (s).
    pub time: Real,
    pub kind: TopologyEventKind,
    /// The mother (division) or the removed cell.
    pub cell: CellId,
    /// The two daughters of a division.
    pub daughters: Option<[CellId; 2]>,
    /// Volume (m³) of the cell's surface at the event.
    pub volume: Real,
    /// Volumes (m³) of the two daughters' surfaces right after the cut (division only); they sum to
    /// `volume` up to round-off.
    pub daughter_volumes: Option<[Real; 2]>,
}

/// Counts of topology changes and remeshing over a run (all summed over steps and cells).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TopologyStats {
    pub divisions: u64,
    pub removals: u64,
    /// Division steps where no attempted plane gave a valid cut; the cell divides at a later step.
    pub division_failures: u64,
    /// Remeshing passes run (one per moving cell and remeshing step that needed work).
    pub remesh_passes: u64,
    pub splits: u64,
    pub collapses: u64,
    pub flips: u64,
    /// Operations refused as illegal and skipped.
    pub skipped_splits: u64,
    pub skipped_collapses: u64,
    pub skipped_flips: u64,
    /// Passes whose result would not have been a valid surface, discarded (the cell kept its mesh).
    pub rejected_passes: u64,
    /// Steps at which edges of a fixed mesh (no scheduled remeshing) were collapsed out of turn
    /// because they had shrunk below `simulation.remesh_below_edge_fraction`·l_min.
    pub need_passes: u64,
}

impl TopologyStats {
    pub(super) fn add_remesh(&mut self, r: &RemeshReport) {
        self.remesh_passes += 1;
        self.splits += r.splits as u64;
        self.collapses += r.collapses as u64;
        self.flips += r.flips as u64;
        self.skipped_splits += r.skipped_splits as u64;
        self.skipped_collapses += r.skipped_collapses as u64;
        self.skipped_flips += r.skipped_flips as u64;
    }
}
