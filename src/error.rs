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
    /// Writing to a caller's writer (not a file of ours) failed.
    #[error("cannot write the output: {0}")]
    WriteStream(#[source] std::io::Error),
    /// An output the run refuses to write, found before any work: it would
    /// replace an input or another output, or its place takes no file.
    #[error("{}: cannot write: {message}", path.display())]
    OutputRefused { path: PathBuf, message: String },
    /// Stopped on request (Ctrl-C). `saved` says what a resumed run will
    /// not do again, when state was saved.
    #[error("interrupted{}", saved.as_ref().map(|s| format!("; {s}: resume from it to continue")).unwrap_or_default())]
    Interrupted { saved: Option<Saved> },
}

/// What an interrupted run saved for a resumed one.
#[derive(Clone, Debug, PartialEq)]
pub struct Saved {
    /// The tracking checkpoint file.
    pub path: PathBuf,
    /// Tracked frames it holds.
    pub frames: usize,
    /// Refinement batches finished and in all, when refinement saved its
    /// state beside it (`Checkpointing::refine_path`).
    pub refine: Option<(usize, usize)>,
}

impl std::fmt::Display for Saved {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.refine {
            None => write!(
                f,
                "the first {} tracked frames are saved in {}",
                self.frames,
                self.path.display()
            ),
            Some((done, all)) => {
                write!(
                    f,
                    "the refinement ({done} of {all} batches done) is saved in {}",
                    self.path.parent().unwrap_or(&self.path).display()
                )
            }
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io {
            path: path.to_path_buf(),
            source,
        }
    }
    pub(crate) fn parse(path: &Path, line: Option<usize>, message: impl Into<String>) -> Self {
        Error::Parse {
            path: path.to_path_buf(),
            line,
            message: message.into(),
        }
    }
    pub(crate) fn mesh(path: &Path, message: impl Into<String>) -> Self {
        Error::InvalidMesh {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
    pub(crate) fn refuse(path: &Path, message: impl std::fmt::Display) -> Self {
        Error::OutputRefused {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
    pub(crate) fn write(path: &Path, message: impl std::fmt::Display) -> Self {
        Error::Write {
            path: path.to_path_buf(),
            message: message.to_string(),
        }
    }
}
