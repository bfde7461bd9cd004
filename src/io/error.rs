//! Errors of reading and writing tissue files. Every variant names the file; parse errors also the
//! line (1-based) where the problem was found.

use crate::files::{FileError, OutputError};
use crate::mesh::{CellId, MeshError, TissueError};
use std::path::PathBuf;

/// A file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    #[error("cannot open {path}: {source}")]
    Open { path: PathBuf, source: std::io::Error },
    #[error("cannot write {path}: {source}")]
    Write { path: PathBuf, source: std::io::Error },
    #[error("{path}{}: {message}", line.map(|l| format!(":{l}")).unwrap_or_default())]
    Parse { path: PathBuf, line: Option<usize>, message: String },
    #[error("{path}: {message}")]
    Unsupported { path: PathBuf, message: String },
    #[error("{path}: cell {cell}: {source}")]
    Mesh { path: PathBuf, cell: CellId, source: MeshError },
    #[error("{path}: {source}")]
    Tissue { path: PathBuf, source: TissueError },
    /// An output the output policy refuses (see [`crate::files::OutputPolicy`]).
    #[error(transparent)]
    Output(#[from] OutputError),
}

impl IoError {
    /// A parse error at `line` (1-based) of `path`.
    pub fn parse(path: impl Into<PathBuf>, line: Option<usize>, message: impl Into<String>) -> Self {
        IoError::Parse { path: path.into(), line, message: message.into() }
    }
}

impl From<FileError> for IoError {
    /// The same error with the same message: the file primitives of [`crate::files`] have their own
    /// error type because they sit below the meshes that [`IoError`] names.
    fn from(e: FileError) -> Self {
        match e {
            FileError::Open { path, source } => IoError::Open { path, source },
            FileError::Write { path, source } => IoError::Write { path, source },
            FileError::Output(e) => IoError::Output(e),
        }
    }
}
