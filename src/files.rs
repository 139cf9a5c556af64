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
    let target = match Target::of(path)? {
        Target::Through(device) => return write_through(&device, fill).map_err(|e| Error::write(path, e)),
        Target::Replace(target) => target,
    };
    let tmp = temporary(&target)?;
    if let Err(e) = fill_temporary(&tmp, fill).and_then(|()| std::fs::rename(&tmp, &target)) {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::write(path, e));
    }
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
        let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
        let target = if is_link { std::fs::canonicalize(path).map_err(|e| Error::write(path, format!("a symbolic link to nothing ({e})")))? } else { path.to_path_buf() };
        match std::fs::metadata(&target) {
            Ok(meta) if writes_through(&meta) => Ok(Target::Through(target)),
            Ok(meta) if meta.is_dir() => Err(Error::write(path, "a directory of this name exists")),
            Ok(meta) if !meta.is_file() => Err(Error::write(path, "not a regular file; voltrack will not replace it")),
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
pub fn write_atomic_all(files: Vec<(&Path, Fill<'_>)>) -> Result<()> {
    let mut written: Vec<(PathBuf, &Path)> = Vec::with_capacity(files.len());
    let discard = |temps: &[(PathBuf, &Path)]| temps.iter().for_each(|(tmp, _)| drop(std::fs::remove_file(tmp)));
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
    for (k, ((tmp, path), target)) in written.iter().zip(&targets).enumerate() {
        if let Err(e) = std::fs::rename(tmp, target) {
            discard(&written[k..]);
            targets[..k].iter().for_each(|done| drop(std::fs::remove_file(done)));
            return Err(Error::write(path, e));
        }
    }
    // Devices last: what went to them cannot be taken back.
    for (path, fill, device) in through {
        write_through(&device, fill).map_err(|e| Error::write(path, e))?;
    }
    Ok(())
}

/// Checks, before any work, that `path` names a file in an existing
/// directory and is not itself a directory; returns the directory and the
/// file name.
pub(crate) fn check_writable(path: &Path) -> Result<(&Path, &std::ffi::OsStr)> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        let why = if dir.exists() { "is not a directory" } else { "does not exist" };
        return Err(Error::write(path, format!("{} {why}", dir.display())));
    }
    if path.is_dir() {
        return Err(Error::write(path, "a directory of this name exists"));
    }
    let name = path.file_name().ok_or_else(|| Error::write(path, "not a file name"))?;
    Ok((dir, name))
}

/// [`write_atomic_all`] for files in `dir`, which is created if needed; on
/// failure neither the files nor a directory this call created are left.
pub(crate) fn write_atomic_into(dir: &Path, files: Vec<(&Path, Fill<'_>)>) -> Result<()> {
    // The directories this call creates, innermost first.
    let created: Vec<&Path> = dir.ancestors().take_while(|a| !a.as_os_str().is_empty() && !a.exists()).collect();
    std::fs::create_dir_all(dir).map_err(|e| Error::write(dir, e))?;
    write_atomic_all(files).inspect_err(|_| created.iter().for_each(|d| drop(std::fs::remove_dir(d))))
}

/// Fails unless `dir` is a directory or can be made one: no file has its
/// name and its nearest existing ancestor is a directory. For checking an
/// output directory before a long run, as [`check_writable`] does for files.
pub(crate) fn check_dir_creatable(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::write(dir, "a file of this name exists"));
    }
    match dir.ancestors().skip(1).find(|a| a.as_os_str().is_empty() || a.exists()) {
        Some(a) if !a.as_os_str().is_empty() && !a.is_dir() => Err(Error::write(dir, format!("{} is not a directory", a.display()))),
        _ => Ok(()),
    }
}

/// The temporary file `path` is written through: beside it, so that the
/// rename stays on one file system.
fn temporary(path: &Path) -> Result<PathBuf> {
    let (dir, name) = check_writable(path)?;
    Ok(dir.join(format!(".{}.{}.partial", name.to_string_lossy(), std::process::id())))
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

