//! Helpers shared by the integration tests.

// Each test file is its own crate and uses only some of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// A fresh, empty directory for one test, removed when dropped.
pub struct Scratch(pub PathBuf);

impl Scratch {
    /// `group` and `name` make the directory unique among the tests.
    pub fn new(group: &str, name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!(
            "voltrack-test-{group}-{}-{name}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }

    pub fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }

    /// Every file under the directory (recursively), relative, sorted.
    pub fn files(&self) -> Vec<String> {
        fn walk(dir: &Path, prefix: &str, out: &mut Vec<String>) {
            for e in std::fs::read_dir(dir).unwrap().flatten() {
                let name = format!("{prefix}{}", e.file_name().to_string_lossy());
                if e.path().is_dir() {
                    walk(&e.path(), &format!("{name}/"), out);
                } else {
                    out.push(name);
                }
            }
        }
        let mut out = Vec::new();
        walk(&self.0, "", &mut out);
        out.sort();
        out
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A sequence voxelised in memory from one mesh per frame, on the common grid
/// of their bounding box (frame f named `frame{f}.obj`).
pub fn voxel_sequence(
    meshes: &[voltrack::TriangleMesh],
    resolution: usize,
) -> voltrack::voxel::VoxelSequence {
    let bounds = meshes
        .iter()
        .map(|m| m.bounding_box())
        .reduce(|a, b| a.union(&b))
        .unwrap();
    let grid = voltrack::model::GridSpec::for_bounds(&bounds, resolution).unwrap();
    voltrack::voxel::VoxelSequence {
        frames: meshes
            .iter()
            .map(|m| voltrack::voxel::voxelize(m, &grid).into())
            .collect(),
        grid,
        names: (0..meshes.len()).map(|f| format!("frame{f}.obj")).collect(),
        bounds,
        first_mesh: Some(meshes[0].clone()),
        read_seconds: 0.0,
        voxelize_seconds: 0.0,
    }
}

/// Checks that an HTML or SVG document nests: every tag opened is closed in order
/// (void elements written as `<meta .../>`), attributes are quoted,
/// and text holds no raw `<` nor an `&` that starts no entity.
pub fn assert_well_formed(html: &str) -> usize {
    let mut stack: Vec<String> = Vec::new();
    let mut rest = html;
    let mut elements = 0;
    while let Some(open) = rest.find('<') {
        let text = &rest[..open];
        for (i, _) in text.match_indices('&') {
            let entity = &text[i + 1..];
            let end = entity
                .find(';')
                .unwrap_or_else(|| panic!("bare & in text: {text}"));
            let name = &entity[..end];
            let numeric = name
                .strip_prefix('#')
                .is_some_and(|n| !n.is_empty() && n.chars().all(|c| c.is_ascii_digit()));
            assert!(
                numeric || ["amp", "lt", "gt", "quot", "apos"].contains(&name),
                "unknown entity &{name}; in {text}"
            );
        }
        let close = rest[open..].find('>').expect("unclosed tag") + open;
        let tag = &rest[open + 1..close];
        assert!(!tag.contains('<'), "'<' inside a tag: {tag}");
        assert_eq!(
            tag.matches('"').count() % 2,
            0,
            "unbalanced quotes in {tag}"
        );
        if let Some(name) = tag.strip_prefix('/') {
            assert_eq!(
                stack.pop().as_deref(),
                Some(name.trim()),
                "mismatched </{name}>"
            );
        } else if !tag.ends_with('/') && !tag.starts_with('!') && !tag.starts_with('?') {
            stack.push(tag.split_whitespace().next().unwrap().to_string());
            elements += 1;
        }
        rest = &rest[close + 1..];
    }
    assert!(
        rest.trim().is_empty(),
        "text after the root element: {rest}"
    );
    assert!(stack.is_empty(), "unclosed elements: {stack:?}");
    elements
}

/// Waits for `child` until `limit` after `started`, then kills it: its exit
/// code, or what ended it otherwise (a signal, the limit).
pub fn wait_or_kill(
    child: &mut std::process::Child,
    started: std::time::Instant,
    limit: std::time::Duration,
) -> Result<i32, String> {
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            use std::os::unix::process::ExitStatusExt;
            return match (s.code(), s.signal()) {
                (Some(c), _) => Ok(c),
                (None, Some(sig)) => Err(format!("signal {sig}")),
                _ => Err(format!("{s}")),
            };
        }
        if started.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("killed after {} s", limit.as_secs()));
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// `m` as OBJ text.
pub fn obj_bytes(m: &voltrack::TriangleMesh) -> Vec<u8> {
    let mut out = Vec::new();
    voltrack::export::obj::write_obj(&mut out, m, &m.positions).unwrap();
    out
}

/// `m` as PLY in `encoding`.
pub fn ply_bytes(
    m: &voltrack::TriangleMesh,
    encoding: voltrack::export::ply::PlyEncoding,
) -> Vec<u8> {
    let mut out = Vec::new();
    voltrack::export::ply::write_ply(&mut out, m, encoding).unwrap();
    out
}

/// Counts its polls and asks to stop from the `after`-th on.
pub struct StopAfterPolls {
    polls: std::sync::atomic::AtomicUsize,
    after: usize,
}

impl StopAfterPolls {
    pub fn new(after: usize) -> Self {
        StopAfterPolls {
            polls: 0.into(),
            after,
        }
    }
    pub fn polls(&self) -> usize {
        self.polls.load(std::sync::atomic::Ordering::Relaxed)
    }
}

impl voltrack::progress::ProgressSink for StopAfterPolls {
    fn report(&self, _: voltrack::Stage, _: usize, _: usize) {}
    fn cancelled(&self) -> bool {
        self.polls
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed)
            >= self.after
    }
}
