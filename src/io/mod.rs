//! Tissue files in and out: SimuCell3D legacy VTK (polyhedra), multi-material triangle meshes from
//! image tools (VTK 4.2 and 5.1, PLY), ParaView `.vtp` + `.pvd` series.
//!
//! Lengths inside tissuefit are metres. Files from image tools are in voxels or µm; a
//! [`LengthScale`] converts them on reading.

mod checkpoint;
mod error;
mod legacy_parse;
mod legacy_tissue;
mod legacy_write;
mod ply;
mod progress;
mod pvd;
mod read;
mod simulation_output;
mod units;
mod vtp;

pub use checkpoint::{
    CHECKPOINT_FILE, CHECKPOINT_VERSION, CheckpointError, OutputState, RunInfo, RunSettings, checksum,
    decode_checkpoint, frame_checkpoint, is_checkpoint, read_checkpoint, write_checkpoint,
};
pub use error::IoError;
pub use legacy_tissue::TissueFormat;
pub use legacy_write::write_simucell3d;
pub use progress::{
    DEFAULT_LINE_SECONDS, Heartbeat, LINE_SECONDS_VARIABLE, Progress, Report, Watch, line_interval, set_quiet,
};
pub use pvd::{PvdEntry, write_pvd};
pub use read::{ReadOptions, ReadReport, read_tissue, read_tissue_bytes, write_tissue, write_tissue_in};
pub use simulation_output::{SimulationRecorder, write_events};
pub use units::{LengthScale, OutputUnit, parse_length, parse_lengths, parse_named_length};
pub use vtp::{
    CellField, FaceValues, LENGTH_UNIT_FIELD, read_vtp, read_vtp_face_values, vtp_bytes, vtp_bytes_in, write_vtp,
    write_vtp_in,
};

// The file primitives live a layer down (`crate::files`), where `imaging` and `mechanics` can use
// them too; the commands and stages above `io` keep reaching them here.
pub use crate::files::{
    FileError, Format, MAX_CONFIG_FILE, MAX_TISSUE_FILE, OutputError, OutputGroup, OutputPolicy, PLAUSIBLE_LENGTH,
    PLAUSIBLE_TENSION, UNSIZED_CAP, check_target, implausible_length, implausible_tension, read_capped,
    read_text_capped, remove_stale_temporaries, remove_stale_temporaries_of, replace_with, write_atomically,
    write_bytes_atomically,
};
