//! What a run will write, checked as a whole before any work: no output may
//! be one of the inputs, be taken as a frame by the next run on the same
//! input, or be another output of the same run; and every output location
//! must take a file now, not after an hour of tracking.

use crate::error::{Error, Result};
use crate::io::would_discover;
use std::path::{Path, PathBuf};

/// One place a run writes.
#[derive(Clone, Debug)]
enum Kind {
    /// A file, written through a temporary file and renamed into place (or
    /// written through when it is a character device or a FIFO).
    File,
    /// A file written beside the named output without being named itself:
    /// it may replace only a file that starts with `mark` (an earlier run's).
    Sidecar { mark: &'static str },
    /// A directory the run creates if needed and fills with files, replaced
    /// as a whole ([`crate::files::replace_dir`]).
    Dir,
    /// A directory the run writes `files` into, one at a time (checkpoints),
    /// leaving everything else there alone: an existing file of one of
    /// those names is replaced only if it starts with `mark`.
    FilesIn {
        files: Vec<PathBuf>,
        mark: &'static [u8],
    },
}

#[derive(Clone, Debug)]
struct Planned {
    path: PathBuf,
    kind: Kind,
    /// For a sidecar: the output it is written beside.
    beside: Option<usize>,
    /// What it is, for messages ("the output", "the report").
    what: String,
}

/// Every file and directory one run will write, with what it reads.
#[derive(Clone, Debug, Default)]
pub struct OutputPlan {
    outputs: Vec<Planned>,
    /// Input arguments as given: directories, patterns, files.
    sources: Vec<PathBuf>,
    /// Every file the run reads (the frames, trajectories).
    inputs: Vec<PathBuf>,
}

impl OutputPlan {
    /// A plan with no output and no input yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// A file the run writes; `what` names it in messages.
    pub fn file(mut self, path: &Path, what: &str) -> Self {
        self.outputs.push(Planned {
            path: path.to_path_buf(),
            kind: Kind::File,
            beside: None,
            what: what.into(),
        });
        self
    }

    /// A file written beside a named output (a texture's JSON, a point
    /// cache's mesh), under a name the user did not give: an existing file
    /// there is replaced only if its first bytes hold `mark`, as voltrack
    /// writes it. It belongs to the last [`file`](Self::file) planned.
    pub fn sidecar(mut self, path: &Path, what: &str, mark: &'static str) -> Self {
        let beside = self
            .outputs
            .iter()
            .rposition(|o| matches!(o.kind, Kind::File));
        self.outputs.push(Planned {
            path: path.to_path_buf(),
            kind: Kind::Sidecar { mark },
            beside,
            what: what.into(),
        });
        self
    }

    /// A directory the run fills with files (created if missing) and
    /// replaces as a whole: it may hold only what voltrack wrote there.
    pub fn dir(mut self, path: &Path, what: &str) -> Self {
        self.outputs.push(Planned {
            path: path.to_path_buf(),
            kind: Kind::Dir,
            beside: None,
            what: what.into(),
        });
        self
    }

    /// Every file `format` writes for output path `out`
    /// ([`OutputFormat::files`](crate::export::OutputFormat::files)).
    pub fn output(self, format: crate::export::OutputFormat, out: &Path) -> Self {
        use crate::export::format::OutputKind;
        format
            .files(out)
            .into_iter()
            .fold(self, |plan, f| match f.kind {
                OutputKind::File => plan.file(&f.path, f.what),
                OutputKind::Sidecar(mark) => plan.sidecar(&f.path, f.what, mark),
                OutputKind::Folder => plan.dir(&f.path, f.what),
            })
    }

    /// The checkpoint folder of `checkpointing` (created if missing): its
    /// files may replace only earlier checkpoints, or links.
    pub fn checkpoints(mut self, checkpointing: &crate::checkpoint::Checkpointing) -> Self {
        let files = vec![checkpointing.path(), checkpointing.refine_path()];
        let kind = Kind::FilesIn {
            files,
            mark: crate::checkpoint::MARK,
        };
        self.outputs.push(Planned {
            path: checkpointing.dir.clone(),
            kind,
            beside: None,
            what: "the checkpoint folder".into(),
        });
        self
    }

    /// The input arguments (directories, patterns or files) and the frame
    /// files they gave.
    pub fn reading(mut self, sources: &[PathBuf], files: &[PathBuf]) -> Self {
        self.sources.extend_from_slice(sources);
        self.inputs.extend_from_slice(files);
        self
    }

    /// Another file the run reads (trajectories to refine).
    pub fn reading_file(mut self, path: &Path) -> Self {
        self.inputs.push(path.to_path_buf());
        self
    }

    /// Checks the plan; the first problem found is the error.
    pub fn check(&self) -> Result<()> {
        let inputs: Vec<(PathBuf, &PathBuf)> = self
            .inputs
            .iter()
            .filter_map(|p| Some((std::fs::canonicalize(p).ok()?, p)))
            .collect();
        // Another name of an input (a hard link) is the input too.
        let input_files: Vec<(FileId, &PathBuf)> = self
            .inputs
            .iter()
            .filter_map(|p| Some((FileId::of(p)?, p)))
            .collect();
        let ids: Vec<PathBuf> = self
            .outputs
            .iter()
            .map(|out| match &out.kind {
                Kind::File => check_file(out),
                Kind::Sidecar { mark } => check_file(out)
                    .and_then(|id| check_ours(out, id, mark))
                    .and_then(|id| self.check_beside_file(out, id)),
                Kind::Dir => check_dir(out).and_then(|id| check_replaceable(out, id)),
                Kind::FilesIn { files, mark } => {
                    check_dir(out).and_then(|id| check_files_in(out, id, files, mark))
                }
            })
            .collect::<Result<_>>()?;
        for (k, (out, id)) in self.outputs.iter().zip(&ids).enumerate() {
            if let Some((_, given)) = inputs.iter().find(|(i, _)| i == id) {
                return Err(Error::refuse(
                    &out.path,
                    format!("{} would replace the input {}; voltrack never writes over its input: choose another name", out.what, given.display()),
                ));
            }
            if let Some((_, given)) = input_files.iter().find(|(f, _)| {
                matches!(out.kind, Kind::File | Kind::Sidecar { .. }) && FileId::of(id) == Some(*f)
            }) {
                return Err(Error::refuse(
                    &out.path,
                    format!("{} is another name (a hard link) of the input {}; voltrack never writes over its input: choose another name", out.what, given.display()),
                ));
            }
            if let Some(first) = (0..k).find(|&j| ids[j] == *id) {
                return Err(Error::refuse(
                    &out.path,
                    format!(
                        "{} and {} would be the same file",
                        self.outputs[first].what, out.what
                    ),
                ));
            }
            let dir_holding = self.outputs.iter().zip(&ids).find(|(o, d)| {
                matches!(o.kind, Kind::Dir | Kind::FilesIn { .. })
                    && Some(d.as_path()) == id.parent()
            });
            if let (Kind::File | Kind::Sidecar { .. }, Some((dir, _))) = (&out.kind, dir_holding) {
                return Err(Error::refuse(
                    &out.path,
                    format!(
                        "{} would be mixed with the files of {}: write it elsewhere",
                        out.what, dir.what
                    ),
                ));
            }
            match out.kind {
                Kind::File | Kind::Sidecar { .. } => self.check_not_picked_up(out, id)?,
                Kind::Dir => self.check_not_an_input_dir(out, id)?,
                Kind::FilesIn { .. } => {}
            }
        }
        Ok(())
    }

    /// An output the next run on the same input would read as a frame:
    /// frames given one by one are read from their folder next time.
    fn check_not_picked_up(&self, out: &Planned, id: &Path) -> Result<()> {
        let folders = self
            .sources
            .iter()
            .filter(|s| s.is_file())
            .map(|s| match s.parent() {
                Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
                _ => PathBuf::from("."),
            });
        let sources: Vec<PathBuf> = self.sources.iter().cloned().chain(folders).collect();
        match sources.iter().find(|source| would_discover(source, id)) {
            Some(source) => Err(Error::refuse(
                &out.path,
                format!(
                    "{} would be written among the input frames of {}, and the next run on them would read it as a frame; write it elsewhere",
                    out.what,
                    source.display()
                ),
            )),
            None => Ok(()),
        }
    }

    /// A sidecar beside an output that is a device or a FIFO would be a
    /// new file beside the device (`/dev/null.obj`).
    fn check_beside_file(&self, out: &Planned, id: PathBuf) -> Result<PathBuf> {
        let Some(main) = out.beside.map(|k| &self.outputs[k]) else {
            return Ok(id);
        };
        if std::fs::metadata(&main.path).is_ok_and(|m| crate::files::writes_through(&m)) {
            return Err(Error::refuse(
                &main.path,
                format!("{} would be written beside {}, which is not a regular file ({}): name a file for {}", out.what, main.what, out.path.display(), main.what),
            ));
        }
        Ok(id)
    }

    /// A directory of outputs that holds input files (or is an input
    /// directory) would mix the two and could overwrite inputs.
    fn check_not_an_input_dir(&self, out: &Planned, id: &Path) -> Result<()> {
        let holds_input = self.inputs.iter().find(|i| {
            std::fs::canonicalize(i)
                .ok()
                .and_then(|c| c.parent().map(Path::to_path_buf))
                .as_deref()
                == Some(id)
        });
        let is_source = self
            .sources
            .iter()
            .find(|s| s.is_dir() && std::fs::canonicalize(s).ok().as_deref() == Some(id));
        match holds_input.or(is_source) {
            Some(input) => Err(Error::refuse(
                &out.path,
                format!(
                    "{} would be written into the folder of the input {}: choose another folder",
                    out.what,
                    input.display()
                ),
            )),
            None => Ok(()),
        }
    }
}

/// A file's identity on its file system, the same for all its hard links.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct FileId(u64, u64);

impl FileId {
    /// None when `path` does not exist (or off Unix).
    fn of(path: &Path) -> Option<FileId> {
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            std::fs::metadata(path)
                .ok()
                .filter(|m| m.is_file())
                .map(|m| FileId(m.dev(), m.ino()))
        }
        #[cfg(not(unix))]
        {
            let _ = path;
            None
        }
    }
}

/// A folder replaced as a whole must hold only what voltrack wrote there,
/// and must not be the root, the current folder or one holding it.
fn check_replaceable(out: &Planned, id: PathBuf) -> Result<PathBuf> {
    let holds_cwd = std::env::current_dir()
        .ok()
        .and_then(|d| std::fs::canonicalize(d).ok())
        .is_some_and(|cwd| cwd.starts_with(&id));
    if id.parent().is_none() || holds_cwd {
        return Err(Error::refuse(&out.path, format!("{} is replaced as a whole, and this folder holds the current one: name a folder of its own", out.what)));
    }
    if let Some(entry) = crate::files::foreign_entry(&id) {
        return Err(Error::refuse(
            &out.path,
            format!(
                "{} is replaced as a whole, and {} in it was not written by voltrack: move it, or name an empty or new folder",
                out.what,
                entry.file_name().unwrap_or_default().to_string_lossy()
            ),
        ));
    }
    Ok(id)
}

/// Each of `files` may be missing, a link (replaced, not followed) or a
/// file that starts with `mark` (written by an earlier run).
fn check_files_in(out: &Planned, id: PathBuf, files: &[PathBuf], mark: &[u8]) -> Result<PathBuf> {
    for file in files {
        let Ok(meta) = std::fs::symlink_metadata(file) else {
            continue;
        };
        if meta.file_type().is_symlink()
            || (meta.is_file() && crate::files::starts_with(file, mark))
        {
            continue;
        }
        return Err(Error::refuse(file, format!("{} would replace this, which voltrack did not write: move it or choose another folder", out.what)));
    }
    Ok(id)
}

/// What a path names once symlinks and `..` are resolved; for a file that
/// does not exist yet, its resolved folder joined with its name.
fn identity(path: &Path) -> Result<PathBuf> {
    if let Ok(id) = std::fs::canonicalize(path) {
        return Ok(id);
    }
    if std::fs::symlink_metadata(path).is_ok() {
        return Err(Error::refuse(path, "is a symbolic link to nothing"));
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| Error::refuse(path, "not a file name"))?;
    let dir = std::fs::canonicalize(dir)
        .map_err(|e| Error::refuse(path, format!("{}: {e}", dir.display())))?;
    Ok(dir.join(name))
}

/// A file output: its folder exists and takes files, and what is there now
/// (if anything) may be replaced or written through.
fn check_file(out: &Planned) -> Result<PathBuf> {
    let path = &out.path;
    if path.as_os_str().is_empty() {
        return Err(Error::refuse(
            path,
            format!("{} has an empty name", out.what),
        ));
    }
    if path.as_os_str().as_encoded_bytes().ends_with(b"/") {
        return Err(Error::refuse(
            path,
            format!(
                "{} ends in '/', which names a folder; give a file name",
                out.what
            ),
        ));
    }
    crate::files::check_writable(path).map_err(refused)?;
    let id = identity(path)?;
    match std::fs::metadata(&id) {
        Ok(meta) if meta.is_dir() => {
            return Err(Error::refuse(path, "a directory of this name exists"))
        }
        Ok(meta) if !meta.is_file() && !crate::files::writes_through(&meta) => {
            return Err(Error::refuse(
                path,
                "not a regular file, a character device or a FIFO; voltrack will not replace it",
            ))
        }
        Ok(meta) if crate::files::writes_through(&meta) => return Ok(id),
        _ => {}
    }
    probe(id.parent().unwrap_or(Path::new("/")), path)?;
    Ok(id)
}

/// A sidecar may replace only what an earlier run wrote.
fn check_ours(out: &Planned, id: PathBuf, mark: &str) -> Result<PathBuf> {
    let Ok(file) = std::fs::File::open(&id) else {
        return Ok(id);
    };
    if !std::fs::metadata(&id).is_ok_and(|m| m.is_file()) {
        return Ok(id);
    }
    let mut head = Vec::with_capacity(4096);
    std::io::Read::read_to_end(&mut std::io::Read::take(file, 4096), &mut head)
        .map_err(|e| Error::refuse(&out.path, e))?;
    if String::from_utf8_lossy(&head).contains(mark) {
        Ok(id)
    } else {
        Err(Error::refuse(&out.path, format!("{} would replace this file, which voltrack did not write as such: move it or name the output otherwise", out.what)))
    }
}

/// A directory output: it is a directory or can be made one, and takes files.
fn check_dir(out: &Planned) -> Result<PathBuf> {
    let path = &out.path;
    if path.as_os_str().is_empty() {
        return Err(Error::refuse(
            path,
            format!("{} has an empty name", out.what),
        ));
    }
    if path.exists() && !path.is_dir() {
        return Err(Error::refuse(
            path,
            format!(
                "{} must be a folder, and a file of this name exists",
                out.what
            ),
        ));
    }
    crate::files::check_dir_creatable(path).map_err(refused)?;
    let existing = path
        .ancestors()
        .find(|a| a.as_os_str().is_empty() || a.exists())
        .unwrap_or(Path::new("."));
    let existing = if existing.as_os_str().is_empty() {
        Path::new(".")
    } else {
        existing
    };
    probe(existing, path)?;
    if path.exists() {
        return std::fs::canonicalize(path).map_err(|e| Error::refuse(path, e));
    }
    // Not there yet: its resolved nearest ancestor and the rest of the path.
    let base = std::fs::canonicalize(existing).map_err(|e| Error::refuse(path, e))?;
    let rest = path.strip_prefix(existing).unwrap_or(path);
    Ok(base.join(rest))
}

/// Creates and removes a file in `dir`, so that a folder that refuses files
/// (read-only, full, no permission) fails now.
fn probe(dir: &Path, output: &Path) -> Result<()> {
    let name = dir.join(format!(".voltrack-probe.{}", std::process::id()));
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&name)
    {
        Ok(_) => {
            let _ = std::fs::remove_file(&name);
            Ok(())
        }
        Err(e) => Err(Error::refuse(
            output,
            format!("{} does not take new files: {e}", dir.display()),
        )),
    }
}

/// A location check's failure, found before any work: a refusal.
fn refused(e: Error) -> Error {
    match e {
        Error::Write { path, message } => Error::OutputRefused { path, message },
        e => e,
    }
}
