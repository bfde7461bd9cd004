//! Errors of writing files and of clearing temporaries. Every variant names the file.

use super::OutputError;
use std::path::PathBuf;

/// A file could not be written (or a folder listed), or the output policy refused it.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    #[error("cannot open {path}: {source}")]
    Open { path: PathBuf, source: std::io::Error },
    #[error("cannot write {path}: {source}")]
    Write { path: PathBuf, source: std::io::Error },
    /// An output the output policy refuses (see [`super::output`]).
    #[error(transparent)]
    Output(#[from] OutputError),
}
