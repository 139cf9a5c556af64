//! The library's one error type.

use std::path::{Path, PathBuf};

/// Everything that can go wrong in voltrack. Every variant that concerns a file
/// names it, and a line where the format has lines.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    Parse {
        path: PathBuf,
        line: Option<usize>,
        message: String,
    },
    #[error("{}: unsupported file type (expected .obj, .ply, .gltf, .glb or .binvox)", path.display())]
    UnsupportedFormat { path: PathBuf },
    #[error("{}: {message}", path.display())]
    InvalidMesh { path: PathBuf, message: String },
    /// Input that is readable but cannot be processed as a sequence.
    #[error("{0}")]
    InvalidInput(String),
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    #[error("{}: cannot write: {message}", path.display())]
    Write { path: PathBuf, message: String },
    /// An output the run refuses to write, found before any work: it would
    /// replace an input or another output, or its place takes no file.
    #[error("{}: cannot write: {message}", path.display())]
    OutputRefused { path: PathBuf, message: String },
    /// Stopped on request (Ctrl-C). `saved` names the checkpoint file and the
    /// frames it holds when tracking state was saved.
    #[error("interrupted{}", saved.as_ref().map(|(p, k)| format!(
        "; the first {k} tracked frames are saved in {}: resume from it to continue", p.display())).unwrap_or_default())]
    Interrupted { saved: Option<(PathBuf, usize)> },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io { path: path.to_path_buf(), source }
    }
    pub(crate) fn parse(path: &Path, line: Option<usize>, message: impl Into<String>) -> Self {
        Error::Parse { path: path.to_path_buf(), line, message: message.into() }
    }
    pub(crate) fn mesh(path: &Path, message: impl Into<String>) -> Self {
        Error::InvalidMesh { path: path.to_path_buf(), message: message.into() }
    }
    pub(crate) fn refuse(path: &Path, message: impl std::fmt::Display) -> Self {
        Error::OutputRefused { path: path.to_path_buf(), message: message.to_string() }
    }
    pub(crate) fn write(path: &Path, message: impl std::fmt::Display) -> Self {
        Error::Write { path: path.to_path_buf(), message: message.to_string() }
    }
}
