//! The library's layout, checked from its source: the top-level modules of
//! `src/` (the binary's `cli` and `main.rs` aside) import each other without
//! a cycle, and no stage reads files through `io`: only the pipeline's
//! composition may, and today not even it does (stages take a
//! `FrameSource`), and only the files listed in `FILE_SYSTEM` touch the
//! file system.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// Every `crate::module` a file names (in `use` lines, paths and doc links).
fn referenced_modules(text: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    for (i, _) in text.match_indices("crate::") {
        // `voltrack::crate::` cannot occur; skip `$crate::` in macros.
        if text[..i].ends_with('$') {
            continue;
        }
        let rest = &text[i + "crate::".len()..];
        let name: String = rest
            .chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect();
        if !name.is_empty() {
            found.insert(name);
        }
        // `use crate::{a, b::c}` names several.
        if let Some(group) = rest.strip_prefix('{') {
            let inner = &group[..group.find('}').unwrap_or(0)];
            for item in inner.split(',') {
                let name: String = item
                    .trim()
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    found.insert(name);
                }
            }
        }
    }
    found
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The library's code in `text`, the source of `file`: unit tests are not
/// part of the layering (a stage's tests may build their input with the
/// fixtures, which sit above every stage). A test-only file (`tests.rs`,
/// `*_tests.rs`) holds none; elsewhere a file's `#[cfg(test)] mod tests`,
/// which comes last, ends it.
fn library_code<'a>(file: &Path, text: &'a str) -> &'a str {
    let name = file.file_name().unwrap().to_string_lossy();
    if name == "tests.rs" || name.ends_with("_tests.rs") {
        return "";
    }
    text.find("\n#[cfg(test)]\nmod tests {")
        .map_or(text, |end| &text[..end])
}

/// module -> modules it names, for the library's top-level modules (their
/// unit tests aside).
fn module_graph() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for file in files {
        let rel = file.strip_prefix(&src).unwrap();
        let top = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy()
            .trim_end_matches(".rs")
            .to_string();
        if ["cli", "main", "lib"].contains(&top.as_str()) {
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        let edges = graph.entry(top.clone()).or_default();
        edges.extend(
            referenced_modules(library_code(&file, &text))
                .into_iter()
                .filter(|m| *m != top),
        );
    }
    // Names re-exported at the root (`crate::Error`) are not modules.
    let modules: BTreeSet<String> = graph.keys().cloned().collect();
    graph
        .values_mut()
        .for_each(|uses| uses.retain(|m| modules.contains(m)));
    graph
}

#[test]
fn the_modules_form_no_cycle() {
    let graph = module_graph();
    for (m, uses) in &graph {
        eprintln!(
            "{m} -> {}",
            uses.iter().cloned().collect::<Vec<_>>().join(", ")
        );
    }
    // Depth-first search; a module met again while still on the path closes a cycle.
    fn visit(
        m: &str,
        graph: &BTreeMap<String, BTreeSet<String>>,
        path: &mut Vec<String>,
        done: &mut BTreeSet<String>,
    ) {
        if done.contains(m) {
            return;
        }
        if let Some(k) = path.iter().position(|p| p == m) {
            panic!("module cycle: {} -> {m}", path[k..].join(" -> "));
        }
        path.push(m.to_string());
        for next in graph.get(m).into_iter().flatten() {
            visit(next, graph, path, done);
        }
        path.pop();
        done.insert(m.to_string());
    }
    let mut done = BTreeSet::new();
    for m in graph.keys() {
        visit(m, &graph, &mut Vec::new(), &mut done);
    }
    assert!(
        graph.contains_key("track") && graph.contains_key("io"),
        "the graph was read: {graph:?}"
    );
}

/// Inside `track`, the frame loop saves and restores through `checkpoint`,
/// which needs nothing of the loop.
#[test]
fn the_checkpoint_does_not_import_the_frame_loop() {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("src/track/checkpoint.rs"),
    )
    .unwrap();
    assert!(
        !text.contains("forward"),
        "track/checkpoint.rs names track/forward.rs"
    );
}

#[test]
fn no_stage_reads_files_itself() {
    let graph = module_graph();
    for stage in [
        "voxel", "track", "refine", "deform", "export", "metrics", "spatial", "model",
    ] {
        assert!(
            !graph[stage].contains("io"),
            "{stage} imports io; stages take a FrameSource"
        );
    }
}

/// The library's files that touch the file system themselves (`std::fs`,
/// `File::open`, `OpenOptions`), each with why. Stages take data; a new file
/// here is a stage reading or writing behind its caller's back.
const FILE_SYSTEM: [(&str, &str); 15] = [
    ("io/mod.rs", "reading the input"),
    ("io/sequence.rs", "finding a sequence's frames"),
    ("io/obj.rs", "reading the input (materials beside an OBJ)"),
    ("io/gltf.rs", "reading the input (buffers beside a glTF)"),
    ("io/exr.rs", "reading trajectories"),
    (
        "files.rs",
        "atomic writes, the one place outputs are created",
    ),
    ("checkpoint.rs", "checkpoint files"),
    (
        "track/forward.rs",
        "removing a checkpoint a fresh run makes stale",
    ),
    ("export/gltf.rs", "embedding the texture the mesh names"),
    ("export/pc2.rs", "the writer's file type (through files.rs)"),
    (
        "export/binvox.rs",
        "the writer's file type (through files.rs)",
    ),
    (
        "model/mesh.rs",
        "whether a texture file is an image to embed",
    ),
    (
        "model/positions.rs",
        "spilling a long sequence's frames to disk",
    ),
    (
        "pipeline/guard.rs",
        "the output plan: what each output path is",
    ),
    ("voxel/memory.rs", "the memory available, from /proc"),
];

#[test]
fn only_listed_files_touch_the_file_system() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut touching = BTreeSet::new();
    for path in files {
        let rel = path
            .strip_prefix(&src)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        if rel.starts_with("cli/") || rel == "main.rs" {
            continue; // the binary prints, renders and writes
        }
        let text = std::fs::read_to_string(&path).unwrap();
        if [
            "std::fs",
            "fs::",
            "File::open",
            "File::create",
            "OpenOptions",
        ]
        .iter()
        .any(|s| text.contains(s))
        {
            touching.insert(rel);
        }
    }
    let listed: BTreeSet<String> = FILE_SYSTEM.iter().map(|(f, _)| f.to_string()).collect();
    let unlisted: Vec<_> = touching.difference(&listed).collect();
    assert!(
        unlisted.is_empty(),
        "{unlisted:?} touch the file system; stages take data and options, not paths (or list the file here with why)"
    );
    let stale: Vec<_> = listed.difference(&touching).collect();
    assert!(
        stale.is_empty(),
        "{stale:?} no longer touch the file system: drop them from the list"
    );
}
