//! Which files make up a sequence, in which order.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// File extensions voltrack reads, lower case.
pub(crate) const EXTENSIONS: [&str; 5] = ["obj", "ply", "gltf", "glb", "binvox"];

pub(crate) fn is_supported(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Expands the command line's inputs into the ordered frame files: a directory
/// gives every supported file in it, a pattern with `*` or `?` in any of its
/// components gives the matching files (wildcards in directory components
/// match directories), any other path is taken as one frame. Hidden files and
/// directories (names starting with '.') are skipped unless the pattern's
/// component itself starts with '.', as in a shell. Directories and patterns
/// are sorted naturally (`mesh_2` before `mesh_10`), component by component;
/// explicit files keep the order given.
pub fn discover_frames(inputs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    if inputs.is_empty() {
        return Err(Error::InvalidInput("no input given".into()));
    }
    let mut frames = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let mut found = list_dir(input, true, |name| {
                !is_hidden(name) && is_supported(Path::new(name))
            })?;
            if found.is_empty() {
                return Err(Error::InvalidInput(format!(
                    "{}: no mesh or voxel files (.obj, .ply, .gltf, .glb, .binvox) in this directory",
                    input.display()
                )));
            }
            sort_natural(&mut found);
            check_numbering(input, input, &found)?;
            frames.extend(found);
        } else if is_pattern(input) {
            let mut found = expand_pattern(input)?;
            if found.is_empty() {
                return Err(Error::InvalidInput(format!(
                    "{}: no file matches this pattern",
                    input.display()
                )));
            }
            sort_natural(&mut found);
            check_numbering(input, &pattern_base(input), &found)?;
            frames.extend(found);
        } else if input.exists() {
            frames.push(input.clone());
        } else {
            return Err(Error::io(
                input,
                std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or directory"),
            ));
        }
    }
    Ok(frames)
}

/// Whether [`discover_frames`] on `input` (a directory or a pattern) would
/// take `file` (a resolved path, existing or not) as a frame: so that an
/// output is never written where the next run on the same input reads it.
pub(crate) fn would_discover(input: &Path, file: &Path) -> bool {
    let (Some(parent), Some(name)) = (file.parent(), file.file_name().and_then(|n| n.to_str()))
    else {
        return false;
    };
    if !is_supported(file) {
        return false;
    }
    if input.is_dir() {
        return !is_hidden(name) && std::fs::canonicalize(input).is_ok_and(|d| d == parent);
    }
    if !is_pattern(input) {
        return false;
    }
    let components: Vec<std::path::Component> = input.components().collect();
    let first_wild = components
        .iter()
        .position(|c| has_wildcard(&c.as_os_str().to_string_lossy()))
        .expect("a pattern has a wildcard");
    let base: PathBuf = components[..first_wild].iter().collect();
    let base = if base.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        base
    };
    let Ok(base) = std::fs::canonicalize(base) else {
        return false;
    };
    let Ok(rest) = file.strip_prefix(&base) else {
        return false;
    };
    let rest: Vec<_> = rest.components().collect();
    rest.len() == components.len() - first_wild
        && components[first_wild..].iter().zip(&rest).all(|(p, c)| {
            let (part, name) = (
                p.as_os_str().to_string_lossy(),
                c.as_os_str().to_string_lossy(),
            );
            if has_wildcard(&part) {
                (!is_hidden(&name) || part.starts_with('.')) && glob_match(&part, &name)
            } else {
                part == name
            }
        })
}

/// The runs of digits in `path` below `base`, as numbers (None when one is
/// too long for a number).
fn digit_runs(base: &Path, path: &Path) -> Option<Vec<u64>> {
    let rel = path
        .strip_prefix(base)
        .unwrap_or(path)
        .to_string_lossy()
        .into_owned();
    rel.split(|c: char| !c.is_ascii_digit())
        .filter(|r| !r.is_empty())
        .map(|r| r.parse().ok())
        .collect()
}

/// Frames found in a folder or by a pattern (`input`, below `base`), in
/// order: two files of one frame number (a pattern joining two takes, or
/// two sequences in one folder) are an error, since tracking one object
/// through the other's frames cannot be right; a frame number skipped
/// (frame 12 missing between 11 and 13) is warned of. The frame number is
/// the last run of digits that differs between the files
/// (`take_2/frame_0007_lod0.obj`: 7), checked only when every file has as
/// many runs.
fn check_numbering(input: &Path, base: &Path, frames: &[PathBuf]) -> Result<()> {
    let Some(runs) = frames
        .iter()
        .map(|f| digit_runs(base, f))
        .collect::<Option<Vec<_>>>()
    else {
        return Ok(());
    };
    let count = runs.first().map_or(0, Vec::len);
    if count == 0 || runs.iter().any(|r| r.len() != count) {
        return Ok(());
    }
    let Some(varying) = (0..count)
        .rev()
        .find(|&k| runs.iter().any(|r| r[k] != runs[0][k]))
    else {
        return Ok(());
    };
    let mut by_number: Vec<(u64, usize)> = runs
        .iter()
        .enumerate()
        .map(|(k, r)| (r[varying], k))
        .collect();
    by_number.sort();
    if let Some(w) = by_number.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Error::InvalidInput(format!(
            "{}: {} and {} are both frame {}: this joins two sequences; give each take on its own (or list the files in the order meant)",
            input.display(),
            frames[w[0].1].display(),
            frames[w[1].1].display(),
            w[0].0
        )));
    }
    // The step between frames is the most common one (a take may keep every
    // second frame); a longer one is a frame missing.
    let mut steps: Vec<u64> = by_number.windows(2).map(|w| w[1].0 - w[0].0).collect();
    steps.sort_unstable();
    // The most frequent step, the smallest of equally frequent ones.
    let Some((step, _)) = steps
        .chunk_by(|a, b| a == b)
        .map(|run| (run[0], run.len()))
        .max_by_key(|&(s, n)| (n, std::cmp::Reverse(s)))
    else {
        return Ok(());
    };
    let gaps: Vec<String> = by_number
        .windows(2)
        .filter(|w| w[1].0 - w[0].0 > step)
        .map(|w| {
            format!(
                "{} to {} (after {})",
                w[0].0,
                w[1].0,
                frames[w[0].1]
                    .file_name()
                    .unwrap_or_default()
                    .to_string_lossy()
            )
        })
        .collect();
    if !gaps.is_empty() {
        let more = if gaps.len() > 3 {
            format!(" and {} more", gaps.len() - 3)
        } else {
            String::new()
        };
        log::warn!(
            "{}: frames missing: the numbers jump from {}{more}; the missing frames are not read",
            input.display(),
            gaps[..gaps.len().min(3)].join(", ")
        );
    }
    Ok(())
}

/// The literal folder a pattern starts from (before its first wildcard).
fn pattern_base(pattern: &Path) -> PathBuf {
    let components: Vec<std::path::Component> = pattern.components().collect();
    let first_wild = components
        .iter()
        .position(|c| has_wildcard(&c.as_os_str().to_string_lossy()))
        .unwrap_or(components.len());
    components[..first_wild].iter().collect()
}

fn has_wildcard(s: &str) -> bool {
    s.contains('*') || s.contains('?')
}

fn is_pattern(input: &Path) -> bool {
    input
        .components()
        .any(|c| has_wildcard(&c.as_os_str().to_string_lossy()))
}

/// voltrack's own temporary files (`.<name>.<pid>.partial`) are hidden too.
fn is_hidden(name: &str) -> bool {
    name.starts_with('.')
}

/// Every file matching `pattern`: the components before the first wildcard
/// are taken as they are, then each component is matched against the
/// entries of the directories matched so far (directories for all but the
/// last component, files for the last).
fn expand_pattern(pattern: &Path) -> Result<Vec<PathBuf>> {
    let components: Vec<std::path::Component> = pattern.components().collect();
    let first_wild = components
        .iter()
        .position(|c| has_wildcard(&c.as_os_str().to_string_lossy()))
        .expect("a pattern has a wildcard");
    let base: PathBuf = components[..first_wild].iter().collect();
    // A relative pattern starts in the current directory.
    let mut candidates = vec![if base.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        base
    }];
    let last = components.len() - 1;
    for (k, component) in components.iter().enumerate().skip(first_wild) {
        let part = component.as_os_str().to_string_lossy();
        let want_file = k == last;
        let mut next = Vec::new();
        for dir in &candidates {
            if has_wildcard(&part) {
                // Every candidate but the literal base is a directory found
                // here; a base that is missing fails naming it.
                next.extend(list_dir(dir, want_file, |name| {
                    (!is_hidden(name) || part.starts_with('.')) && glob_match(&part, name)
                })?);
            } else {
                // `take_*/mesh.obj` skips a take without the file.
                let p = dir.join(component);
                if if want_file { p.is_file() } else { p.is_dir() } {
                    next.push(p);
                }
            }
        }
        candidates = next;
    }
    Ok(candidates)
}

/// A name for what `inputs` (which gave `frames`, in order) hold, to call the
/// result by: the input directory's name when one directory was given; else
/// the frames' common file-name prefix (without extensions), less the digits
/// where the frame numbers start to differ and trailing separators (`_-. `),
/// so `walk_0001.obj`, `walk_0002.obj`, … give `walk`; else the first
/// frame's stem; else [`DEFAULT_NAME`](crate::model::DEFAULT_NAME). Control
/// characters become `_`, so the name always passes
/// [`check_name`](crate::model::check_name).
pub fn sequence_name(inputs: &[PathBuf], frames: &[PathBuf]) -> String {
    let clean = |s: &str| {
        s.trim()
            .chars()
            .map(|c| if c.is_control() { '_' } else { c })
            .collect::<String>()
    };
    let dir_name = match inputs {
        // "." or "..": the name of the directory it stands for.
        [dir] if dir.is_dir() => dir.file_name().map(|n| n.to_os_string()).or_else(|| {
            std::fs::canonicalize(dir)
                .ok()?
                .file_name()
                .map(|n| n.to_os_string())
        }),
        _ => None,
    };
    let stems: Vec<String> = frames
        .iter()
        .map(|f| {
            f.file_stem()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    let candidates = [
        dir_name.map(|n| n.to_string_lossy().into_owned()),
        Some(common_stem(&stems)),
        stems.first().cloned(),
    ];
    candidates
        .into_iter()
        .flatten()
        .map(|n| clean(&n))
        .find(|n| !n.is_empty())
        .unwrap_or_else(|| crate::model::DEFAULT_NAME.into())
}

/// The common prefix of `stems`, less a trailing run of digits that
/// continues differently in some stem (the start of a frame number), less
/// trailing separators.
fn common_stem(stems: &[String]) -> String {
    let Some(first) = stems.first() else {
        return String::new();
    };
    let mut len = first.len();
    for s in &stems[1..] {
        len = first
            .char_indices()
            .zip(s.chars())
            .find(|((_, a), b)| a != b)
            .map_or(len.min(s.len()), |((i, _), _)| i)
            .min(len);
    }
    let mut prefix = &first[..len];
    let differs_at_digit = stems
        .iter()
        .any(|s| s[len..].starts_with(|c: char| c.is_ascii_digit()));
    if differs_at_digit && stems.len() > 1 {
        prefix = prefix.trim_end_matches(|c: char| c.is_ascii_digit());
    }
    prefix.trim_end_matches(['_', '-', '.', ' ']).to_string()
}

/// The entries of `dir` whose name passes `keep`: regular files (or links
/// to them) if `files`, else directories. With `files`, an entry whose name
/// passes and has a frame's extension but that is not a file (a folder, a FIFO, a socket, a link to
/// nothing) is an error: skipping it would lose a frame without a word.
fn list_dir(dir: &Path, files: bool, keep: impl Fn(&str) -> bool) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut out = Vec::new();
    for entry in entries {
        let p = entry.map_err(|e| Error::io(dir, e))?.path();
        if !p.file_name().and_then(|n| n.to_str()).is_some_and(&keep) {
            continue;
        }
        if !files {
            if p.is_dir() {
                out.push(p);
            }
            continue;
        }
        match std::fs::metadata(&p) {
            Ok(meta) if meta.is_file() => out.push(p),
            // A pattern's `*` may match other things beside the frames.
            _ if !is_supported(&p) => {}
            Ok(meta) => {
                let what = if meta.is_dir() {
                    "a folder"
                } else {
                    "not a regular file (a FIFO, socket or device)"
                };
                return Err(Error::InvalidInput(format!(
                    "{}: named like a frame but {what}; move it out of the folder",
                    p.display()
                )));
            }
            Err(_) => {
                return Err(Error::InvalidInput(format!(
                    "{}: named like a frame but a link to nothing; fix or remove the link",
                    p.display()
                )))
            }
        }
    }
    Ok(out)
}

/// `*` matches any run of characters, `?` any one character.
pub(crate) fn glob_match(pattern: &str, name: &str) -> bool {
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

/// Sorts by path, component by component, with digit runs compared as
/// numbers (of any length).
pub(crate) fn sort_natural(paths: &mut [PathBuf]) {
    paths.sort_by_cached_key(|p| {
        p.components()
            .map(|c| natural_key(&c.as_os_str().to_string_lossy()))
            .collect::<Vec<_>>()
    });
}

/// A run of digits, ordered by value without parsing it (so any length
/// works): fewer significant digits first, then digit by digit, then fewer
/// leading zeros ("1" before "01", so the two stay distinct).
#[derive(PartialEq, Eq, PartialOrd, Ord)]
struct Digits {
    significant: usize,
    value: String,
    leading_zeros: usize,
}

#[derive(PartialEq, Eq, PartialOrd, Ord)]
enum Chunk {
    Number(Digits),
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
            let value = run.trim_start_matches('0');
            Chunk::Number(Digits {
                significant: value.len(),
                value: value.to_string(),
                leading_zeros: run.len() - value.len(),
            })
        } else {
            Chunk::Text(run)
        });
    }
    out
}

#[cfg(test)]
mod tests {
    /// The frame number is the run of digits that varies: a suffix that does
    /// not is no clash; two takes numbered alike are; one take split over two
    /// folders is not.
    #[test]
    fn frame_numbers_are_the_digits_that_vary() {
        let paths = |v: &[&str]| v.iter().map(PathBuf::from).collect::<Vec<_>>();
        let check =
            |base: &str, v: &[&str]| check_numbering(Path::new(base), Path::new(base), &paths(v));
        assert!(check(
            "d",
            &[
                "d/f_0001_lod0.obj",
                "d/f_0002_lod0.obj",
                "d/f_0003_lod0.obj"
            ]
        )
        .is_ok());
        let e = check(
            "t",
            &[
                "t/take_1/f_0.obj",
                "t/take_1/f_1.obj",
                "t/take_2/f_0.obj",
                "t/take_2/f_1.obj",
            ],
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("take_1/f_0.obj") && e.contains("take_2/f_0.obj"),
            "{e}"
        );
        assert!(check(
            "t",
            &["t/a/f_0.obj", "t/a/f_1.obj", "t/b/f_2.obj", "t/b/f_3.obj"]
        )
        .is_ok());
        assert!(check("d", &["d/walk.obj", "d/run.obj"]).is_ok());
    }

    use super::*;

    fn sorted(names: &[&str]) -> Vec<String> {
        let mut paths: Vec<PathBuf> = names.iter().map(PathBuf::from).collect();
        sort_natural(&mut paths);
        paths
            .iter()
            .map(|p| p.to_string_lossy().into_owned())
            .collect()
    }

    #[test]
    fn digit_runs_of_any_length_keep_their_order() {
        let big = "1".repeat(40);
        let bigger = format!("{}2", "1".repeat(39));
        let longer = format!("2{}", "0".repeat(40));
        let names = [
            format!("f_{longer}.obj"),
            format!("f_{bigger}.obj"),
            format!("f_{big}.obj"),
            "f_9.obj".into(),
        ];
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        assert_eq!(
            sorted(&names),
            [
                "f_9.obj".to_string(),
                format!("f_{big}.obj"),
                format!("f_{bigger}.obj"),
                format!("f_{longer}.obj")
            ]
        );
        // Leading zeros: by value first, then fewer zeros first.
        assert_eq!(
            sorted(&["f_010.obj", "f_2.obj", "f_01.obj", "f_1.obj", "f_0010.obj"]),
            ["f_1.obj", "f_01.obj", "f_2.obj", "f_010.obj", "f_0010.obj"]
        );
    }

    #[test]
    fn paths_sort_component_by_component() {
        assert_eq!(
            sorted(&[
                "take_10/frame_1.obj",
                "take_2/frame_10.obj",
                "take_2/frame_9.obj",
                "take_1/frame_3.obj"
            ]),
            [
                "take_1/frame_3.obj",
                "take_2/frame_9.obj",
                "take_2/frame_10.obj",
                "take_10/frame_1.obj"
            ]
        );
    }

    #[test]
    fn glob() {
        assert!(glob_match("frame_*.obj", "frame_12.obj"));
        assert!(glob_match("take_?", "take_3"));
        assert!(!glob_match("take_?", "take_10"));
        assert!(glob_match("*", ".hidden"));
    }
}
