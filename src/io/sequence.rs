//! Which files make up a sequence, in which order.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// File extensions voltrack reads, lower case.
pub const EXTENSIONS: [&str; 5] = ["obj", "ply", "gltf", "glb", "binvox"];

pub fn is_supported(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Expands the command line's inputs into the ordered frame files: a directory
/// gives every supported file in it, a pattern with `*` or `?` in its file name
/// gives the matching files, any other path is taken as one frame. Directories
/// and patterns are sorted naturally (`mesh_2` before `mesh_10`); explicit
/// files keep the order given.
pub fn discover_frames(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    if inputs.is_empty() {
        return Err(Error::InvalidInput("no input given".into()));
    }
    let mut frames = Vec::new();
    for input in inputs {
        let name = input.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if input.is_dir() {
            let mut found = list_dir(input, |p| is_supported(p))?;
            if found.is_empty() {
                return Err(Error::InvalidInput(format!(
                    "{}: no mesh or voxel files (.obj, .ply, .gltf, .glb, .binvox) in this directory",
                    input.display()
                )));
            }
            sort_natural(&mut found);
            frames.extend(found);
        } else if name.contains('*') || name.contains('?') {
            let dir = match input.parent() {
                Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
                _ => PathBuf::from("."),
            };
            let mut found = list_dir(&dir, |p| {
                p.file_name().and_then(|n| n.to_str()).is_some_and(|n| glob_match(name, n))
            })?;
            if found.is_empty() {
                return Err(Error::InvalidInput(format!("{}: no file matches this pattern", input.display())));
            }
            sort_natural(&mut found);
            frames.extend(found);
        } else if input.exists() {
            frames.push(input.clone());
        } else {
            return Err(Error::io(input, std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or directory")));
        }
    }
    Ok(frames)
}

fn list_dir(dir: &Path, keep: impl Fn(&Path) -> bool) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut out = Vec::new();
    for entry in entries {
        let p = entry.map_err(|e| Error::io(dir, e))?.path();
        if p.is_file() && keep(&p) {
            out.push(p);
        }
    }
    Ok(out)
}

/// `*` matches any run of characters, `?` any one character.
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    let (mut pi, mut ni, mut star, mut mark) = (0, 0, None, 0);
    while ni < n.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == n[ni]) {
            pi += 1;
            ni += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ni;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ni = mark;
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

/// Sorts by file name with digit runs compared as numbers.
pub fn sort_natural(paths: &mut [PathBuf]) {
    paths.sort_by_cached_key(|p| natural_key(&p.file_name().unwrap_or_default().to_string_lossy()));
}

#[derive(PartialEq, Eq, PartialOrd, Ord)]
enum Chunk {
    Number(u128, usize),
    Text(String),
}

fn natural_key(s: &str) -> Vec<Chunk> {
    let mut out = Vec::new();
    let mut chars = s.chars().peekable();
    while let Some(&c) = chars.peek() {
        let digit = c.is_ascii_digit();
        let mut run = String::new();
        while let Some(&c) = chars.peek() {
            if c.is_ascii_digit() != digit {
                break;
            }
            run.push(c);
            chars.next();
        }
        out.push(if digit {
            // Leading zeros break ties so "01" and "1" stay distinct.
            Chunk::Number(run.parse().unwrap_or(u128::MAX), run.len())
        } else {
            Chunk::Text(run)
        });
    }
    out
}
