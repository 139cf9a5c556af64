//! Writing files safely: through a temporary file renamed into place, so a
//! failure never leaves a half-written file, and never over a device.

use crate::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes `path` through a temporary file in the same directory, renamed into
/// place only when `fill` succeeded. A symbolic link is followed (the file it
/// names is replaced, the link stays); a character device or FIFO is written
/// to directly, since renaming over it would replace the device.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
{
    write_to(path, Target::of(path)?, fill)
}

/// [`write_atomic`] for a file inside a folder voltrack fills (a
/// checkpoint): a symbolic link there is replaced, never followed, so a link
/// planted in an output folder cannot lead the write to another file.
pub(crate) fn write_replacing<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
{
    write_to(path, Target::resolved(path, false)?, fill)
}

/// Writes `path`'s `target` as [`write_atomic`] says.
fn write_to<F>(path: &Path, target: Target, fill: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
{
    let target = match target {
        Target::Through(device) => {
            return write_through(&device, fill).map_err(|e| Error::write(path, e))
        }
        Target::Replace(target) => target,
    };
    let tmp = temporary(&target)?;
    if let Err(e) = fill_temporary(&tmp, fill).and_then(|()| std::fs::rename(&tmp, &target)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::write(path, e));
    }
    remove_stale(&target);
    Ok(())
}

/// Where writing `path` goes.
enum Target {
    /// A regular file (or none yet), replaced by a rename.
    Replace(PathBuf),
    /// A character device or FIFO, written to directly.
    Through(PathBuf),
}

impl Target {
    fn of(path: &Path) -> Result<Target> {
        Self::resolved(path, true)
    }

    /// Where writing `path` goes; a symbolic link is replaced rather than
    /// followed unless `follow`.
    fn resolved(path: &Path, follow: bool) -> Result<Target> {
        let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
        if is_link && !follow {
            return Ok(Target::Replace(path.to_path_buf()));
        }
        let target = if is_link {
            std::fs::canonicalize(path)
                .map_err(|e| Error::write(path, format!("a symbolic link to nothing ({e})")))?
        } else {
            path.to_path_buf()
        };
        match std::fs::metadata(&target) {
            Ok(meta) if writes_through(&meta) => Ok(Target::Through(target)),
            Ok(meta) if meta.is_dir() => Err(Error::write(path, "a directory of this name exists")),
            Ok(meta) if !meta.is_file() => Err(Error::write(
                path,
                "not a regular file; voltrack will not replace it",
            )),
            _ => Ok(Target::Replace(target)),
        }
    }
}

/// Whether an existing output is written to in place: character devices
/// (`/dev/null`) and FIFOs, which a rename would replace with a regular file.
pub(crate) fn writes_through(meta: &std::fs::Metadata) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        t.is_char_device() || t.is_fifo()
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        false
    }
}

fn write_through<F>(path: &Path, fill: F) -> std::io::Result<()>
where
    F: FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
{
    let mut w = BufWriter::new(std::fs::OpenOptions::new().write(true).open(path)?);
    fill(&mut w)?;
    w.flush()
}

/// What fills one file of [`write_atomic_all`].
pub type Fill<'a> = Box<dyn FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()> + 'a>;

/// Writes files that belong together (a texture and its sidecar, a point
/// cache and its mesh) as one: each through its temporary file, renamed into
/// place only once all are complete. On failure none is left, not even one
/// already renamed.
///
/// Between the renames a journal beside the first file lists them
/// ([`SET_JOURNAL`]): a run killed there leaves its complete temporaries and
/// the journal, and the next write of a set into the same folder first
/// renames the rest into place (`finish_interrupted_sets`), so the set on
/// disk is the old one or the new one, not a mix, once voltrack has run
/// there again. Several renames cannot be one step on a POSIX file system;
/// the journal is how databases make them one.
pub fn write_atomic_all(files: Vec<(&Path, Fill<'_>)>) -> Result<()> {
    let mut dirs: Vec<&Path> = files.iter().map(|(p, _)| folder_of(p)).collect();
    dirs.sort();
    dirs.dedup();
    dirs.iter().for_each(|d| finish_interrupted_sets(d));
    let mut written: Vec<(PathBuf, &Path)> = Vec::with_capacity(files.len());
    let discard = |temps: &[(PathBuf, &Path)]| {
        temps
            .iter()
            .for_each(|(tmp, _)| drop(std::fs::remove_file(tmp)))
    };
    let mut targets: Vec<PathBuf> = Vec::with_capacity(files.len());
    let mut through: Vec<(&Path, Fill<'_>, PathBuf)> = Vec::new();
    for (path, fill) in files {
        let target = match Target::of(path) {
            Ok(Target::Replace(t)) => t,
            Ok(Target::Through(device)) => {
                through.push((path, fill, device));
                continue;
            }
            Err(e) => {
                discard(&written);
                return Err(e);
            }
        };
        targets.push(target);
        let target = targets.last().expect("just pushed").clone();
        let filled = temporary(&target).and_then(|tmp| {
            written.push((tmp.clone(), path));
            fill_temporary(&tmp, fill).map_err(|e| Error::write(path, e))
        });
        if let Err(e) = filled {
            discard(&written);
            return Err(e);
        }
    }
    let pairs: Vec<(PathBuf, PathBuf)> = written
        .iter()
        .zip(&targets)
        .map(|((tmp, _), target)| (tmp.clone(), target.clone()))
        .collect();
    let journal = match (pairs.len() > 1).then(|| write_journal(&pairs)) {
        Some(Err(e)) => {
            discard(&written);
            return Err(e);
        }
        Some(Ok(journal)) => Some(journal),
        None => None,
    };
    for (k, ((tmp, path), target)) in written.iter().zip(&targets).enumerate() {
        #[cfg(test)]
        if k == 1 && tests::KILL_BETWEEN_RENAMES.with(|c| c.get()) {
            // What a kill here leaves: the journal, one file renamed.
            return Err(Error::write(path, "killed between the renames (test)"));
        }
        if let Err(e) = std::fs::rename(tmp, target) {
            discard(&written[k..]);
            targets[..k]
                .iter()
                .for_each(|done| drop(std::fs::remove_file(done)));
            if let Some(j) = &journal {
                let _ = std::fs::remove_file(j);
            }
            return Err(Error::write(path, e));
        }
    }
    if let Some(j) = &journal {
        let _ = std::fs::remove_file(j);
    }
    targets.iter().for_each(|t| remove_stale(t));
    // Devices last: what went to them cannot be taken back.
    for (path, fill, device) in through {
        write_through(&device, fill).map_err(|e| Error::write(path, e))?;
    }
    Ok(())
}

/// The journal [`write_atomic_all`] keeps while it renames a set into
/// place: `.NAME.PID.set` beside the set's first file, holding this line and
/// then each temporary, its target and the target's state before the
/// renames (its inode, size and modification time, or "absent"), separated
/// by NUL bytes.
pub const SET_JOURNAL: &str = "voltrack set of files being renamed into place";

/// The folder `path` is in ("." for a bare name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Writes the journal of `pairs` (temporary, target; at least one) and
/// returns its path.
fn write_journal(pairs: &[(PathBuf, PathBuf)]) -> Result<PathBuf> {
    let first = &pairs[0].1;
    let (dir, name) = check_writable(first)?;
    let journal = own_file(dir, name, "set");
    let tmp = journal.with_extension("set.partial");
    let filled = fill_temporary(&tmp, |w| {
        w.write_all(SET_JOURNAL.as_bytes())?;
        w.write_all(b"\n")?;
        for (a, b) in pairs {
            for field in [path_bytes(a), path_bytes(b), file_state(b).into_bytes()] {
                w.write_all(&field)?;
                w.write_all(b"\0")?;
            }
        }
        Ok(())
    })
    .and_then(|()| std::fs::rename(&tmp, &journal));
    if let Err(e) = filled {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::write(first, e));
    }
    Ok(journal)
}

/// What a file is now, to tell later whether anything replaced it: "absent",
/// or its inode, size and modification time.
fn file_state(path: &Path) -> String {
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return "absent".into();
    };
    let modified = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    #[cfg(unix)]
    let inode = std::os::unix::fs::MetadataExt::ino(&meta);
    #[cfg(not(unix))]
    let inode = 0u64;
    format!("{inode}:{}:{modified}", meta.len())
}

#[cfg(unix)]
fn path_bytes(p: &Path) -> Vec<u8> {
    use std::os::unix::ffi::OsStrExt;
    p.as_os_str().as_bytes().to_vec()
}

#[cfg(not(unix))]
fn path_bytes(p: &Path) -> Vec<u8> {
    p.to_string_lossy().into_owned().into_bytes()
}

#[cfg(unix)]
fn bytes_path(b: &[u8]) -> PathBuf {
    use std::os::unix::ffi::OsStrExt;
    PathBuf::from(std::ffi::OsStr::from_bytes(b))
}

#[cfg(not(unix))]
fn bytes_path(b: &[u8]) -> PathBuf {
    PathBuf::from(String::from_utf8_lossy(b).into_owned())
}

/// Completes the sets of files that runs killed between their renames left
/// in `dir` ([`write_atomic_all`]'s journals whose process is gone): the
/// temporaries still there are renamed into place, then the journal is
/// removed. A journal of a process still running is left alone, and a
/// target that changed since the journal was written (a file the user put
/// there after the kill) is never replaced: its temporary is removed.
pub(crate) fn finish_interrupted_sets(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = file
            .strip_prefix('.')
            .and_then(|f| f.strip_suffix(".set"))
            .and_then(|f| f.rsplit_once('.'))
            .and_then(|(_, pid)| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if !left_behind(pid) {
            continue;
        }
        let journal = entry.path();
        let Ok(text) = std::fs::read(&journal) else {
            continue;
        };
        let Some(body) = text
            .strip_prefix(SET_JOURNAL.as_bytes())
            .and_then(|b| b.strip_prefix(b"\n"))
        else {
            continue;
        };
        let fields: Vec<&[u8]> = body.split(|&b| b == 0).filter(|p| !p.is_empty()).collect();
        for entry in fields.chunks_exact(3) {
            let (tmp, target) = (bytes_path(entry[0]), bytes_path(entry[1]));
            let (tmp, target) = (&tmp, &target);
            // Only voltrack's own temporaries are moved or removed, never
            // another file a changed journal might name.
            let ours = tmp
                .file_name()
                .is_some_and(|n| is_partial(&n.to_string_lossy()))
                && std::fs::symlink_metadata(tmp).is_ok_and(|m| m.is_file());
            if !ours {
                continue;
            }
            if file_state(target).as_bytes() != entry[2] {
                log::warn!(
                    "{} changed after a run was interrupted while writing it; left as it is",
                    target.display()
                );
                let _ = std::fs::remove_file(tmp);
                continue;
            }
            match std::fs::rename(tmp, target) {
                Ok(()) => log::info!(
                    "completed {}, which an interrupted run left half renamed into place",
                    target.display()
                ),
                Err(e) => log::warn!("could not complete {}: {e}", target.display()),
            }
        }
        let _ = std::fs::remove_file(&journal);
    }
}

/// Checks, before any work, that `path` names a file in an existing
/// directory and is not itself a directory; returns the directory and the
/// file name.
pub(crate) fn check_writable(path: &Path) -> Result<(&Path, &std::ffi::OsStr)> {
    let dir = folder_of(path);
    if !dir.is_dir() {
        let why = if dir.exists() {
            "is not a directory"
        } else {
            "does not exist"
        };
        return Err(Error::write(path, format!("{} {why}", dir.display())));
    }
    if path.is_dir() {
        return Err(Error::write(path, "a directory of this name exists"));
    }
    let name = path
        .file_name()
        .ok_or_else(|| Error::write(path, "not a file name"))?;
    Ok((dir, name))
}

/// The list of the files voltrack wrote into a folder it fills (an OBJ
/// sequence, voxelised frames): hidden, so that discovery never reads it.
pub const FOLDER_MANIFEST: &str = ".voltrack-files";

/// The manifest's first line.
const MANIFEST_HEAD: &str =
    "voltrack output folder, replaced as a whole by the next run that writes it";

/// Writes the folder `dir` as a whole: `files` (names inside it, each with
/// what fills it) and a [`FOLDER_MANIFEST`], built in a hidden folder beside
/// `dir` and swapped in for it, so that a failure or a kill at any moment
/// leaves either the old folder or the new one, never a mix, and no file of
/// an earlier run stays among the new ones. A link to a folder is followed
/// (the folder it names is replaced); links inside the old folder are
/// removed, never followed. An existing folder is replaced only when it
/// holds nothing but what voltrack wrote there (`foreign_entry`).
/// Missing parent folders are created, and removed again on failure.
pub fn replace_dir(dir: &Path, files: Vec<(String, Fill<'_>)>) -> Result<Vec<PathBuf>> {
    let exists = std::fs::symlink_metadata(dir).is_ok();
    let target = if exists {
        std::fs::canonicalize(dir).map_err(|e| Error::write(dir, e))?
    } else {
        dir.to_path_buf()
    };
    if exists && !target.is_dir() {
        return Err(Error::write(dir, "a file of this name exists"));
    }
    let (Some(parent), Some(name)) = (target.parent(), target.file_name()) else {
        return Err(Error::write(
            dir,
            "cannot be replaced as a whole: name a folder of its own",
        ));
    };
    let parent = if parent.as_os_str().is_empty() {
        Path::new(".")
    } else {
        parent
    };
    // The folders this call creates, innermost first.
    let created: Vec<&Path> = parent
        .ancestors()
        .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
        .collect();
    std::fs::create_dir_all(parent).map_err(|e| Error::write(dir, e))?;
    let remove_created = || created.iter().for_each(|d| drop(std::fs::remove_dir(d)));
    let staging = own_file(parent, name, "partial");
    let _ = std::fs::remove_dir_all(&staging);
    if let Err(e) = std::fs::create_dir(&staging) {
        remove_created();
        return Err(Error::write(dir, e));
    }
    let mut names = Vec::with_capacity(files.len());
    let built = files.into_iter().try_for_each(|(file, fill)| {
        fill_temporary(&staging.join(&file), fill)
            .map_err(|e| Error::write(&dir.join(&file), e))?;
        names.push(file);
        Ok(())
    });
    let built = built.and_then(|()| {
        let manifest = staging.join(FOLDER_MANIFEST);
        fill_temporary(&manifest, |w| {
            writeln!(w, "{MANIFEST_HEAD}\n{}", names.join("\n"))
        })
        .map_err(|e| Error::write(&dir.join(FOLDER_MANIFEST), e))
    });
    let swapped = built.and_then(|()| swap_in(dir, &staging, &target, exists));
    if let Err(e) = swapped {
        let _ = std::fs::remove_dir_all(&staging);
        remove_created();
        return Err(e);
    }
    remove_stale(&target);
    Ok(names.iter().map(|n| dir.join(n)).collect())
}

/// Removes what killed runs left of their writes of `target`: its
/// `.NAME.PID.partial` files and folders and `.NAME.PID.old` folders whose
/// process is gone (a process still running may be writing them).
fn remove_stale(target: &Path) {
    let Some(name) = target.file_name() else {
        return;
    };
    let dir = folder_of(target);
    let prefix = format!(".{}.", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = file.strip_prefix(&prefix) else {
            continue;
        };
        let Some(Ok(pid)) = rest
            .strip_suffix(".set.partial")
            .or_else(|| rest.strip_suffix(".partial"))
            .or_else(|| rest.strip_suffix(".old"))
            .or_else(|| rest.strip_suffix(".set"))
            .map(str::parse::<u32>)
        else {
            continue;
        };
        if !left_behind(pid) {
            continue;
        }
        let path = entry.path();
        match entry.file_type() {
            Ok(t) if t.is_dir() => drop(std::fs::remove_dir_all(&path)),
            Ok(_) => drop(std::fs::remove_file(&path)),
            Err(_) => {}
        }
        log::info!("removed {}, left by an interrupted run", path.display());
    }
}

/// Whether process `pid` runs; where that cannot be known, true.
fn process_alive(pid: u32) -> bool {
    if cfg!(target_os = "linux") {
        Path::new("/proc").join(pid.to_string()).exists()
    } else {
        true
    }
}

/// Puts the complete folder `staging` in the place of `target`, which holds
/// an earlier run's folder if `exists`; that one is then removed.
fn swap_in(dir: &Path, staging: &Path, target: &Path, exists: bool) -> Result<()> {
    if !exists {
        return std::fs::rename(staging, target).map_err(|e| Error::write(dir, e));
    }
    // What is there now is checked again: the run may have taken hours.
    if let Some(entry) = foreign_entry(target) {
        return Err(Error::write(dir, format!("{} appeared during the run and voltrack did not write it; the folder was left as it was", entry.display())));
    }
    if let Ok(meta) = std::fs::metadata(target) {
        let _ = std::fs::set_permissions(staging, meta.permissions());
    }
    if exchange(staging, target).map_err(|e| Error::write(dir, e))? {
        // `staging` now holds the old folder.
        return std::fs::remove_dir_all(staging).map_err(|e| {
            Error::write(
                dir,
                format!("the old folder, now {}: {e}", staging.display()),
            )
        });
    }
    // No atomic exchange on this file system: two renames.
    let old = staging.with_extension("old");
    let _ = std::fs::remove_dir_all(&old);
    std::fs::rename(target, &old).map_err(|e| Error::write(dir, e))?;
    if let Err(e) = std::fs::rename(staging, target) {
        let _ = std::fs::rename(&old, target);
        return Err(Error::write(dir, e));
    }
    std::fs::remove_dir_all(&old)
        .map_err(|e| Error::write(dir, format!("the old folder, now {}: {e}", old.display())))
}

/// Exchanges two paths atomically (Linux's `renameat2` with
/// `RENAME_EXCHANGE`); false where the file system or the system cannot.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> std::io::Result<bool> {
    use std::os::unix::ffi::OsStrExt;
    let c =
        |p: &Path| std::ffi::CString::new(p.as_os_str().as_bytes()).map_err(std::io::Error::other);
    let (a, b) = (c(a)?, c(b)?);
    // SAFETY: both are valid NUL-terminated paths that outlive the call;
    // renameat2 reads them and touches no other memory.
    let r = unsafe {
        libc::syscall(
            libc::SYS_renameat2,
            libc::AT_FDCWD,
            a.as_ptr(),
            libc::AT_FDCWD,
            b.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if r == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    match e.raw_os_error() {
        Some(libc::EINVAL | libc::ENOSYS | libc::EPERM | libc::ENOTSUP) => Ok(false),
        _ => Err(e),
    }
}

#[cfg(not(target_os = "linux"))]
fn exchange(_: &Path, _: &Path) -> std::io::Result<bool> {
    Ok(false)
}

/// The first entry of the folder `dir` that voltrack did not write there
/// and would not replace: anything but the files its [`FOLDER_MANIFEST`]
/// lists, OBJ frames that carry voltrack's header, symbolic links (which a
/// run replaces, never follows) and voltrack's own temporaries. None also
/// when `dir` cannot be listed (the write then fails with its own error).
pub(crate) fn foreign_entry(dir: &Path) -> Option<PathBuf> {
    let listed: Vec<String> = std::fs::read_to_string(dir.join(FOLDER_MANIFEST))
        .ok()
        .filter(|m| m.starts_with(MANIFEST_HEAD))
        .map(|m| m.lines().skip(1).map(str::to_string).collect())
        .unwrap_or_default();
    let entries = std::fs::read_dir(dir).ok()?;
    let mut names: Vec<(String, PathBuf)> = entries
        .filter_map(|e| e.ok())
        .map(|e| (e.file_name().to_string_lossy().into_owned(), e.path()))
        .collect();
    names.sort();
    names
        .into_iter()
        .find(|(name, path)| {
            let Ok(meta) = std::fs::symlink_metadata(path) else {
                return false;
            };
            let ours = meta.file_type().is_symlink()
                || name == FOLDER_MANIFEST
                || is_temporary(name)
                || (meta.is_file() && (listed.contains(name) || starts_with(path, b"# voltrack ")));
            !ours
        })
        .map(|(_, path)| path)
}

/// voltrack's temporaries: `.NAME.PID.partial` files and folders, probes.
/// (The journals of sets, `.NAME.PID.set`, are never written inside a
/// folder voltrack fills.)
fn is_temporary(name: &str) -> bool {
    is_partial(name) || name.starts_with(".voltrack-probe.")
}

/// A `.NAME.PID.partial` temporary's name.
fn is_partial(name: &str) -> bool {
    name.starts_with('.') && name.ends_with(".partial")
}

/// Whether the file at `path` starts with `mark`.
pub(crate) fn starts_with(path: &Path, mark: &[u8]) -> bool {
    let mut head = vec![0u8; mark.len()];
    std::fs::File::open(path)
        .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut head))
        .is_ok()
        && head == mark
}

/// Fails unless `dir` is a directory or can be made one: no file has its
/// name and its nearest existing ancestor is a directory. For checking an
/// output directory before a long run, as [`check_writable`] does for files.
pub(crate) fn check_dir_creatable(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::write(dir, "a file of this name exists"));
    }
    match dir
        .ancestors()
        .skip(1)
        .find(|a| a.as_os_str().is_empty() || a.exists())
    {
        Some(a) if !a.as_os_str().is_empty() && !a.is_dir() => Err(Error::write(
            dir,
            format!("{} is not a directory", a.display()),
        )),
        _ => Ok(()),
    }
}

/// The temporary file `path` is written through: beside it, so that the
/// rename stays on one file system.
fn temporary(path: &Path) -> Result<PathBuf> {
    let (dir, name) = check_writable(path)?;
    Ok(own_file(dir, name, "partial"))
}

/// `dir/.NAME.PID.KIND`: a file this process writes for `name` (a
/// temporary, a journal), which a later run can tell as left by it.
fn own_file(dir: &Path, name: &std::ffi::OsStr, kind: &str) -> PathBuf {
    dir.join(format!(
        ".{}.{}.{kind}",
        name.to_string_lossy(),
        std::process::id()
    ))
}

/// Whether what process `pid` left is no longer being written: the process
/// is gone (and is not this one).
fn left_behind(pid: u32) -> bool {
    pid != std::process::id() && !process_alive(pid)
}

/// Creates `tmp`, fills it and syncs it to disk.
fn fill_temporary<F>(tmp: &Path, fill: F) -> std::io::Result<()>
where
    F: FnOnce(&mut BufWriter<std::fs::File>) -> std::io::Result<()>,
{
    let mut w = BufWriter::new(std::fs::File::create(tmp)?);
    fill(&mut w)?;
    w.flush()?;
    w.get_ref().sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    thread_local! {
        /// Makes [`write_atomic_all`] stop after its first rename, as a kill
        /// there would.
        pub(super) static KILL_BETWEEN_RENAMES: Cell<bool> = const { Cell::new(false) };
    }

    fn fill(text: &'static str) -> Fill<'static> {
        Box::new(move |w| w.write_all(text.as_bytes()))
    }

    fn folder(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("voltrack-files-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Renames what a run of process `pid` left to look like that process's.
    fn as_if_from(dir: &Path, pid: u32) {
        let me = format!(".{}.", std::process::id());
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.contains(&me) {
                let renamed = name.replace(&me, &format!(".{pid}."));
                std::fs::rename(e.path(), dir.join(renamed)).unwrap();
            }
        }
        // The journal names the temporaries by path: rewrite it the same way.
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.ends_with(".set") {
                let text = std::fs::read(e.path()).unwrap();
                let fixed = String::from_utf8(text)
                    .unwrap()
                    .replace(&me, &format!(".{pid}."));
                std::fs::write(e.path(), fixed).unwrap();
            }
        }
    }

    /// A process id that no process has now.
    fn gone_pid() -> u32 {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        pid
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut n: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        n.sort();
        n
    }

    #[cfg_attr(not(target_os = "linux"), allow(dead_code))]
    /// Writes the set `x.pc2`, `x.obj` over an old one in `dir` and stops as a
    /// kill between its renames would; returns the two paths.
    fn killed_between_renames(dir: &Path) -> (PathBuf, PathBuf) {
        let (a, b) = (dir.join("x.pc2"), dir.join("x.obj"));
        std::fs::write(&a, "old pc2").unwrap();
        std::fs::write(&b, "old obj").unwrap();
        KILL_BETWEEN_RENAMES.with(|c| c.set(true));
        let killed = write_atomic_all(vec![(&a, fill("new pc2")), (&b, fill("new obj"))]);
        KILL_BETWEEN_RENAMES.with(|c| c.set(false));
        assert!(killed.is_err());
        (a, b)
    }

    #[test]
    fn a_set_is_written_whole_and_leaves_no_journal() {
        let dir = folder("whole");
        let (a, b) = (dir.join("x.pc2"), dir.join("x.obj"));
        write_atomic_all(vec![(&a, fill("new pc2")), (&b, fill("new obj"))]).unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new pc2");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new obj");
        assert_eq!(names(&dir), ["x.obj", "x.pc2"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_set_killed_between_its_renames_is_completed_by_the_next_write() {
        #[cfg(target_os = "linux")]
        {
            let dir = folder("killed");
            let (a, b) = killed_between_renames(&dir);
            // Half old, half new, as a kill leaves it; the journal says what is left.
            assert_eq!(std::fs::read_to_string(&a).unwrap(), "new pc2");
            assert_eq!(std::fs::read_to_string(&b).unwrap(), "old obj");
            as_if_from(&dir, gone_pid());
            // Any later set written there (here another take's) completes it first.
            let (c, d) = (dir.join("y.pc2"), dir.join("y.obj"));
            write_atomic_all(vec![(&c, fill("y pc2")), (&d, fill("y obj"))]).unwrap();
            assert_eq!(std::fs::read_to_string(&a).unwrap(), "new pc2");
            assert_eq!(std::fs::read_to_string(&b).unwrap(), "new obj");
            assert_eq!(names(&dir), ["x.obj", "x.pc2", "y.obj", "y.pc2"]);
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    #[test]
    fn a_file_put_in_place_after_the_kill_is_not_replaced() {
        #[cfg(target_os = "linux")]
        {
            let dir = folder("replaced");
            let (_, b) = killed_between_renames(&dir);
            as_if_from(&dir, gone_pid());
            // The user's own file where the set's second one was to go.
            std::fs::remove_file(&b).unwrap();
            std::fs::write(&b, "the user's").unwrap();
            finish_interrupted_sets(&dir);
            assert_eq!(std::fs::read_to_string(&b).unwrap(), "the user's");
            assert_eq!(names(&dir), ["x.obj", "x.pc2"]);
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }

    #[test]
    fn a_journal_of_a_running_process_or_naming_other_files_moves_nothing() {
        let dir = folder("journal");
        let (a, b) = (dir.join("x.pc2"), dir.join("x.obj"));
        std::fs::write(&a, "user's").unwrap();
        let pairs = vec![(b.clone(), a.clone())];
        let journal = write_journal(&pairs).unwrap();
        // This process is running: left alone.
        finish_interrupted_sets(&dir);
        assert!(journal.exists());
        // A journal of a gone process naming a file that is not a temporary of
        // voltrack's: that file is not moved, the journal goes.
        std::fs::write(&b, "other").unwrap();
        as_if_from(&dir, gone_pid());
        finish_interrupted_sets(&dir);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "user's");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "other");
        assert_eq!(names(&dir), ["x.obj", "x.pc2"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
