//! Checkpoints of a running simulation (`DIR/checkpoint.bin`): everything needed to continue a
//! `tissuefit simulate` run so that it ends with exactly the outputs of an uninterrupted run.
//!
//! Layout (all integers little-endian):
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `TFCKPT\r\n` (the CR LF catches text-mode transfers) |
//! | 4 | format version, [`CHECKPOINT_VERSION`] |
//! | 8 | payload length in bytes |
//! | 8 | checksum of the payload (64-bit multiply–rotate hash, see [`checksum`]) |
//! | n | payload: postcard encoding of ([`RunInfo`], [`SimulationState`]) |
//!
//! postcard (not bincode: unmaintained) is compact (varints) and stable within a major version; the
//! version field changes whenever the payload's structure does, and an older or newer file is
//! refused with a message instead of being misread. The length and checksum catch truncated and
//! corrupted files before decoding. The file is written atomically (temporary name + rename), so a
//! crash while saving leaves the previous checkpoint intact.

use crate::files::write_atomically;
use crate::mechanics::SimulationState;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};

/// File name of the checkpoint inside a simulation's output folder.
pub const CHECKPOINT_FILE: &str = "checkpoint.bin";
/// Version of the payload's structure; bumped on every change to it or to what it means (3:
/// [`RunSettings`] added, and the relaxation's lowest-residual state; 4: the mesh-derived numerics of
/// a simulate run, and coupling ties are groups: parameters written without
/// `numerics.coupling_junctions` would resume with other physics; 5:
/// `simulation.remesh_below_edge_fraction` and the count of out-of-turn remeshing passes; 6: each
/// cell's own tensions and adhesions, [`crate::mesh::CellOverrides`]; 7:
/// `numerics.coupling_persistent_junctions`).
pub const CHECKPOINT_VERSION: u32 = 7;
const MAGIC: [u8; 8] = *b"TFCKPT\r\n";
const HEADER: usize = 8 + 4 + 8 + 8;

/// What the output recorder had written when the checkpoint was taken.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OutputState {
    /// Frames of the ParaView series so far: (label, file relative to the output folder).
    pub frames: Vec<(f64, String)>,
    /// Bytes of `stats.csv.partial` that belong to the saved state; rows past them (written after
    /// the checkpoint by a run that was then killed) are cut off on resume.
    pub stats_bytes: u64,
}

/// The settings of a run that are not simulation parameters but shape how it runs; saved so that a
/// resumed run goes on as the original would have (issue 23: a resume once fell back to the
/// default checkpoint period). An option given again on the `--resume` command line replaces one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunSettings {
    /// Checkpoint every this many steps (0: not by step count), as resolved (command line > config).
    pub checkpoint_every_steps: u64,
    /// Checkpoint every this many seconds of wall time (0: not by time).
    pub checkpoint_every_seconds: f64,
    /// Save and stop at the end of this step (`--stop-at-step`), kept for a run killed before it.
    pub stop_at_step: Option<u64>,
}

/// The run a checkpoint belongs to: command inputs, resolved parameters and settings, output progress.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// tissuefit version that wrote the checkpoint.
    pub version: String,
    /// Input tissue as given on the command line.
    pub input: String,
    /// [`checksum`] of the input file's bytes (checked on resume: the input must not have changed).
    pub input_hash: u64,
    /// Resolved parameters (TOML, exactly what `config.toml` holds).
    pub parameters: String,
    /// Cells and nodes of the input (summary.json reports them).
    pub initial_cells: u64,
    pub initial_nodes: u64,
    /// Rayon threads of the run (results are identical for any count; recorded for the summary).
    pub threads: u64,
    /// Wall time (s) spent before this checkpoint, over all earlier sessions.
    pub wall_seconds: f64,
    /// The numerics derived from the input mesh at the start (summary.json reports them).
    pub mesh_defaults: crate::mechanics::MeshFit,
    pub output: OutputState,
    pub settings: RunSettings,
}

/// A checkpoint that cannot be written or used. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    #[error("cannot read checkpoint {path}: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("cannot write checkpoint {path}: {source}")]
    Write { path: PathBuf, source: Box<super::IoError> },
    #[error("{path} is not a tissuefit checkpoint (wrong magic bytes)")]
    NotACheckpoint { path: PathBuf },
    #[error(
        "{path}: checkpoint format version {found}, this tissuefit reads version {CHECKPOINT_VERSION}; \
         finish the run with the tissuefit that started it, or start it again"
    )]
    Version { path: PathBuf, found: u32 },
    #[error("{path}: checkpoint is truncated ({found} of {expected} bytes); it cannot be resumed")]
    Truncated { path: PathBuf, expected: u64, found: u64 },
    #[error("{path}: checkpoint is corrupt (checksum mismatch); it cannot be resumed")]
    Corrupt { path: PathBuf },
    #[error("{path}: checkpoint cannot be decoded: {message}")]
    Decode { path: PathBuf, message: String },
    #[error("cannot encode the checkpoint for {path}: {message}")]
    Encode { path: PathBuf, message: String },
}

/// 64-bit hash for corruption detection (not cryptographic): 8-byte words folded by multiply,
/// rotate and xor, the tail and the length mixed in last. Any single flipped bit changes it.
pub fn checksum(bytes: &[u8]) -> u64 {
    const K: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut h: u64 = 0xCBF2_9CE4_8422_2325;
    let mut words = bytes.chunks_exact(8);
    for w in &mut words {
        let v = u64::from_le_bytes(w.try_into().expect("8-byte chunk"));
        h = (h ^ v).wrapping_mul(K).rotate_left(29);
    }
    let mut tail = [0u8; 8];
    tail[..words.remainder().len()].copy_from_slice(words.remainder());
    h = (h ^ u64::from_le_bytes(tail)).wrapping_mul(K).rotate_left(29);
    (h ^ bytes.len() as u64).wrapping_mul(K) ^ (h >> 31)
}

/// Writes `path` atomically; returns the file's size in bytes.
pub fn write_checkpoint(path: &Path, info: &RunInfo, state: &SimulationState) -> Result<u64, CheckpointError> {
    let payload = postcard::to_stdvec(&(info, state))
        .map_err(|e| CheckpointError::Encode { path: path.to_path_buf(), message: e.to_string() })?;
    let bytes = frame_checkpoint(&payload);
    write_atomically(path, |w| w.write_all(&bytes))
        .map_err(|e| CheckpointError::Write { path: path.to_path_buf(), source: Box::new(e.into()) })?;
    Ok(bytes.len() as u64)
}

/// A checkpoint file's bytes around an encoded payload: magic, version, length, checksum, payload.
pub fn frame_checkpoint(payload: &[u8]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(HEADER + payload.len());
    bytes.extend_from_slice(&MAGIC);
    bytes.extend_from_slice(&CHECKPOINT_VERSION.to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&checksum(payload).to_le_bytes());
    bytes.extend_from_slice(payload);
    bytes
}

/// Whether `bytes` begin like a checkpoint file (its magic number).
pub fn is_checkpoint(bytes: &[u8]) -> bool {
    bytes.starts_with(&MAGIC)
}

/// Reads and checks a checkpoint written by [`write_checkpoint`].
pub fn read_checkpoint(path: &Path) -> Result<(RunInfo, SimulationState), CheckpointError> {
    let bytes = std::fs::read(path).map_err(|source| CheckpointError::Read { path: path.to_path_buf(), source })?;
    decode_checkpoint(&bytes, path)
}

/// Decodes checkpoint bytes; `path` names the file in errors.
pub fn decode_checkpoint(bytes: &[u8], path: &Path) -> Result<(RunInfo, SimulationState), CheckpointError> {
    let path = || path.to_path_buf();
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
        return Err(CheckpointError::NotACheckpoint { path: path() });
    }
    if bytes.len() < HEADER {
        return Err(CheckpointError::Truncated { path: path(), expected: HEADER as u64, found: bytes.len() as u64 });
    }
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if version != CHECKPOINT_VERSION {
        return Err(CheckpointError::Version { path: path(), found: version });
    }
    let (length, sum) = (word(12), word(20));
    let payload = &bytes[HEADER..];
    let expected = (HEADER as u64).saturating_add(length);
    if (payload.len() as u64) < length {
        return Err(CheckpointError::Truncated { path: path(), expected, found: bytes.len() as u64 });
    }
    if payload.len() as u64 != length || checksum(payload) != sum {
        return Err(CheckpointError::Corrupt { path: path() });
    }
    postcard::from_bytes(payload).map_err(|e| CheckpointError::Decode { path: path(), message: e.to_string() })
}

#[cfg(test)]
mod tests {
    use crate::geometry::{Real, Vec3};
    use crate::mechanics::{
        CellData, CellForcesState, CellState, EnergyTerms, Phase, RunProgress, SimulationState, TopologyEvent,
        TopologyEventKind, TopologyStats,
    };
    use crate::mesh::{CellId, CellKind, CellOverrides, FaceType};
    use serde::{Deserialize, Serialize};

    /// [`SimulationState`] as format 5 first laid it out (its cells as format 6 has them), every
    /// field at the top level.
    #[derive(Serialize, Deserialize)]
    struct FlatFormat5 {
        cells: Vec<CellState>,
        next_id: CellId,
        momenta: Vec<Vec<Vec3>>,
        growth_rates: Vec<Real>,
        division_volumes: Vec<Real>,
        remesh_idle: Vec<u32>,
        last_good: Vec<Vec<Vec3>>,
        forces: Vec<CellForcesState>,
        coupled: Vec<((u32, u32), (u32, u32))>,
        events: Vec<TopologyEvent>,
        topology: TopologyStats,
        node_evaluations: u64,
        force_scale: Real,
        energy_scale: Real,
        time: Real,
        step: u64,
        force_evaluations: u64,
        phase: Phase,
    }

    /// A state with a distinct value in every field.
    fn state() -> SimulationState {
        let x = |k: Real| Vec3::new(k, -2.0 * k, 0.5 + k);
        let cell = CellState {
            id: CellId(7),
            kind: CellKind::Epithelial,
            cell_type: 2,
            parent: Some(CellId(3)),
            target_volume: 1.25e-16,
            positions: vec![x(1.0), x(2.0), x(3.0), x(4.0)],
            triangles: vec![[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]],
            face_types: vec![FaceType::Apical, FaceType::Lateral, FaceType::Basal, FaceType::Lateral],
            overrides: CellOverrides { surface_tension: [None, Some(2.5e-4), None], adhesion: [Some(3e9), None, None] },
        };
        let energy = EnergyTerms { pressure: 1.5, area_elasticity: -2.0, tension: 3e-12, bending: 0.0, contact: 7.25 };
        SimulationState {
            cells: vec![cell],
            next_id: CellId(11),
            cell_data: CellData {
                momenta: vec![vec![x(5.0), x(6.0), x(7.0), x(8.0)]],
                growth_rates: vec![3e-18],
                division_volumes: vec![Real::INFINITY],
                remesh_idle: vec![4],
                last_good: vec![vec![x(9.0); 4]],
            },
            forces: vec![CellForcesState { forces: vec![x(-1.0); 4], pressure: 812.5, energy }],
            coupled: vec![((0, 1), (0, 2))],
            progress: RunProgress {
                events: vec![TopologyEvent {
                    step: 40,
                    time: 0.5,
                    kind: TopologyEventKind::Division,
                    cell: CellId(3),
                    daughters: Some([CellId(7), CellId(8)]),
                    volume: 2.5e-16,
                    daughter_volumes: Some([1.2e-16, 1.3e-16]),
                }],
                topology: TopologyStats { divisions: 1, splits: 17, need_passes: 2, ..TopologyStats::default() },
                node_evaluations: 123_456,
                force_scale: 6e-10,
                energy_scale: 4.5e-15,
                time: 0.75,
                step: 60,
                force_evaluations: 61,
            },
            phase: Phase::Relax { fire: None, best: None, previous: Some((1e-15, vec![2e-16])), residual: 0.03 },
        }
    }

    /// Issue 21 item 4 grouped the state's per-cell data and run progress into [`CellData`] and
    /// [`RunProgress`]: postcard writes nested structs as their fields in order, so the bytes are those
    /// of the flat layout of format 5, both ways.
    #[test]
    fn the_grouped_state_encodes_as_the_flat_layout_of_format_5() {
        let s = state();
        let flat = FlatFormat5 {
            cells: s.cells.clone(),
            next_id: s.next_id,
            momenta: s.cell_data.momenta.clone(),
            growth_rates: s.cell_data.growth_rates.clone(),
            division_volumes: s.cell_data.division_volumes.clone(),
            remesh_idle: s.cell_data.remesh_idle.clone(),
            last_good: s.cell_data.last_good.clone(),
            forces: s.forces.clone(),
            coupled: s.coupled.clone(),
            events: s.progress.events.clone(),
            topology: s.progress.topology,
            node_evaluations: s.progress.node_evaluations,
            force_scale: s.progress.force_scale,
            energy_scale: s.progress.energy_scale,
            time: s.progress.time,
            step: s.progress.step,
            force_evaluations: s.progress.force_evaluations,
            phase: s.phase.clone(),
        };
        let bytes = postcard::to_stdvec(&s).unwrap();
        assert_eq!(bytes, postcard::to_stdvec(&flat).unwrap());
        let back: SimulationState = postcard::from_bytes(&bytes).unwrap();
        assert_eq!((back.cells, back.cell_data, back.progress), (s.cells, s.cell_data, s.progress));
        let back: FlatFormat5 = postcard::from_bytes(&bytes).unwrap();
        assert_eq!((back.step, back.last_good), (60, vec![vec![Vec3::new(9.0, -18.0, 9.5); 4]]));
    }

    /// A cell's energies are stored as a struct since format 5 stored them as `[f64; 5]`: postcard
    /// encodes both as the same five numbers, so the format (and its version) did not change.
    #[test]
    fn energies_encode_as_the_array_of_format_5() {
        let e = EnergyTerms { pressure: 1.5, area_elasticity: -2.0, tension: 3e-12, bending: 0.0, contact: 7.25 };
        let as_array = postcard::to_stdvec(&e.values()).unwrap();
        assert_eq!(postcard::to_stdvec(&e).unwrap(), as_array);
        assert_eq!(postcard::from_bytes::<EnergyTerms>(&as_array).unwrap(), e);
    }
}
