//! Issue 22: no command ever modifies its input.
//!
//! Every command and every kind of output (convert to GLB, trajectory EXR,
//! VAT + GLB mesh + JSON sidecar, PC2 + OBJ sidecar, OBJ-sequence directory, HTML
//! report, checkpoint directory; track -o / --checkpoint; refine -o; metrics
//! --plot; voxelize -o) is aimed at the inputs: a frame file directly, the
//! same through `./seq/../seq/`, through a symlink, the input directory
//! (also through `..` and a symlink), a sidecar name that is an input, the
//! trajectories given to refine/metrics, and two outputs of one run aimed at
//! the same file; and (issue 49) output and checkpoint folders holding
//! links to an input under the names voltrack writes there, which must be
//! replaced, never followed, or files of the user's, which must be refused.
//! Then, after every run:
//!
//! * every file of the fixture is byte for byte what it was (symlinks still
//!   symlinks to the same target, nothing deleted);
//! * the input directory holds no new file that directory discovery would
//!   take as a frame (.obj .ply .gltf .glb .binvox, not hidden), so a rerun
//!   reads the same frames; and no `.partial` temporary is left anywhere;
//! * a run whose output clashes with an input, or whose two outputs are one
//!   file, exited non-zero (not 101, not a signal) with a message on stderr
//!   naming the clash (the clashing path's file name), before any work (it
//!   did not log that tracking placed its centers) and leaving nothing
//!   behind. A new file inside the input directory that discovery cannot
//!   pick up may be written.
//!
//! Each case runs in its own copy of the fixture (8 frames of the bending
//! bar, a `frame_2.json` beside them, trajectories tracked once at `-r 32 -n
//! 20`), two at a time. All failures are reported together at the end.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

mod common;
use common::Scratch;

const BIN: &str = env!("CARGO_BIN_EXE_voltrack");
const SMALL: [&str; 4] = ["-r", "32", "-n", "20"];
const FRAMES: usize = 8;
const THREADS: usize = 2;
const KILL_AFTER: Duration = Duration::from_secs(30);

#[derive(Clone, PartialEq, Debug)]
enum Entry {
    File(Vec<u8>),
    Link(PathBuf),
    Dir,
}

/// Every entry under `root` (not following symlinks), by relative path.
fn snapshot(root: &Path) -> BTreeMap<String, Entry> {
    fn walk(dir: &Path, prefix: &str, out: &mut BTreeMap<String, Entry>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let name = format!("{prefix}{}", e.file_name().to_string_lossy());
            let meta = std::fs::symlink_metadata(e.path()).unwrap();
            if meta.file_type().is_symlink() {
                out.insert(name, Entry::Link(std::fs::read_link(e.path()).unwrap()));
            } else if meta.is_dir() {
                out.insert(name.clone(), Entry::Dir);
                walk(&e.path(), &format!("{name}/"), out);
            } else {
                out.insert(
                    name,
                    Entry::File(std::fs::read(e.path()).unwrap_or_default()),
                );
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(root, "", &mut out);
    out
}

/// Recreates `snap` in the empty directory `root`.
fn materialize(root: &Path, snap: &BTreeMap<String, Entry>) {
    for (name, e) in snap {
        let p = root.join(name);
        match e {
            Entry::Dir => std::fs::create_dir_all(&p).unwrap(),
            Entry::File(bytes) => std::fs::write(&p, bytes).unwrap(),
            Entry::Link(target) => std::os::unix::fs::symlink(target, &p).unwrap(),
        }
    }
}

/// The fixture: `seq/` (8 OBJ frames and a user's `frame_2.json`),
/// `traj.exr` tracked from it, symlinks `link3.obj` → `seq/frame_3.obj`,
/// `link_seq` → `seq`, `link_traj.exr` → `traj.exr`, and an empty `out/`.
fn make_fixture(root: &Path) -> BTreeMap<String, Entry> {
    let seq = root.join("seq");
    std::fs::create_dir_all(&seq).unwrap();
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/bending_bar");
    for f in 0..FRAMES {
        let name = format!("frame_{f}.obj");
        std::fs::copy(committed.join(&name), seq.join(&name)).unwrap();
    }
    std::fs::write(
        seq.join("frame_2.json"),
        b"{\"note\": \"the user's file, not a voltrack sidecar\"}\n",
    )
    .unwrap();
    let out = Command::new(BIN)
        .args(["track", "seq"])
        .args(SMALL)
        .args(["-o", "traj.exr"])
        .current_dir(root)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "tracking the fixture failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::os::unix::fs::symlink("seq/frame_3.obj", root.join("link3.obj")).unwrap();
    std::os::unix::fs::symlink("seq", root.join("link_seq")).unwrap();
    std::os::unix::fs::symlink("traj.exr", root.join("link_traj.exr")).unwrap();
    // An existing output directory (for an OBJ sequence): not an input.
    std::fs::create_dir_all(root.join("out")).unwrap();
    // Output and checkpoint folders with links to inputs planted under the
    // names voltrack writes (replaced, never followed), and with files of
    // the user's (refused).
    for (dir, name) in PLANTED {
        std::fs::create_dir_all(root.join(dir)).unwrap();
        std::os::unix::fs::symlink("../seq/frame_3.obj", root.join(dir).join(name)).unwrap();
    }
    for (dir, name) in FOREIGN {
        std::fs::create_dir_all(root.join(dir)).unwrap();
        std::fs::write(root.join(dir).join(name), b"the user's own file\n").unwrap();
    }
    snapshot(root)
}

/// Links to `seq/frame_3.obj` planted in output folders: (folder, name).
const PLANTED: [(&str, &str); 5] = [
    ("ck_links", "track.ckpt"),
    ("ck_links", "refine.ckpt"),
    ("objs_links", "frame_0003.obj"),
    ("objs_links", "frame_0001.obj"),
    ("vox_links", "frame_3.binvox"),
];

/// The user's own files in output folders: (folder, name).
const FOREIGN: [(&str, &str); 4] = [
    ("ck_foreign", "refine.ckpt"),
    ("ck_foreign2", "track.ckpt"),
    ("objs_foreign", "frame_0001.obj"),
    ("vox_foreign", "notes.txt"),
];

/// What a case must do.
#[derive(Clone, Copy, PartialEq)]
enum Expect {
    /// An output is an input, or two outputs are one file: refuse.
    Refuse,
    /// A new file beside the inputs: fine if discovery cannot pick it up.
    NotPickedUp,
}

struct Case {
    name: String,
    argv: Vec<String>,
    expect: Expect,
    /// The message must mention one of these (the clash's file names).
    needles: Vec<&'static str>,
    /// Runs of the same command line (2: a rerun must see the same input).
    runs: usize,
    /// A folder whose planted links the run replaces.
    replaces_in: Option<&'static str>,
}

fn case(
    name: impl Into<String>,
    argv: Vec<String>,
    expect: Expect,
    needles: &[&'static str],
) -> Case {
    Case {
        name: name.into(),
        argv,
        expect,
        needles: needles.to_vec(),
        runs: 1,
        replaces_in: None,
    }
}

/// `convert seq -r 32 -n 20` followed by `extra`.
fn convert(extra: &[&str]) -> Vec<String> {
    ["convert", "seq"]
        .iter()
        .chain(SMALL.iter())
        .chain(extra)
        .map(|s| s.to_string())
        .collect()
}

/// An input frame file, three ways.
const FILE_TARGETS: [(&str, &str, &[&str]); 3] = [
    ("frame file", "seq/frame_3.obj", &["frame_3.obj"]),
    (
        "frame file via ..",
        "./seq/../seq/frame_3.obj",
        &["frame_3.obj"],
    ),
    (
        "frame file via symlink",
        "link3.obj",
        &["link3.obj", "frame_3.obj"],
    ),
];

/// The input directory, three ways.
const DIR_TARGETS: [(&str, &str, &[&str]); 3] = [
    ("input dir", "seq", &["seq"]),
    ("input dir via ..", "./seq/../seq", &["seq"]),
    ("input dir via symlink", "link_seq", &["link_seq", "seq"]),
];

/// The trajectories given to refine and metrics, three ways.
const TRAJ_TARGETS: [(&str, &str, &[&str]); 3] = [
    ("centers exr", "traj.exr", &["traj.exr"]),
    ("centers exr via ..", "./seq/../traj.exr", &["traj.exr"]),
    (
        "centers exr via symlink",
        "link_traj.exr",
        &["link_traj.exr", "traj.exr"],
    ),
];

fn cases() -> Vec<Case> {
    use Expect::*;
    let mut out = Vec::new();
    let is_dir = |target: &str| DIR_TARGETS.iter().any(|d| d.1 == target);

    // convert: every output kind at every input path.
    let kinds: [(&str, &[&str]); 7] = [
        ("glb", &["--format", "glb", "-o"]),
        ("exr", &["--format", "exr", "-o"]),
        ("vat", &["--vat", "-o"]),
        ("pc2", &["--format", "pc2", "-o"]),
        ("obj-sequence", &["--format", "obj-sequence", "-o"]),
        ("report", &["-o", "out.glb", "--report"]),
        ("checkpoint", &["-o", "out.glb", "--checkpoint"]),
    ];
    for (kind, flags) in kinds {
        for (what, target, needles) in FILE_TARGETS.iter().chain(&DIR_TARGETS) {
            // A checkpoint directory may be the input directory: its file is not a frame.
            let expect = if kind == "checkpoint" && is_dir(target) {
                NotPickedUp
            } else {
                Refuse
            };
            let extra: Vec<&str> = flags.iter().copied().chain([*target]).collect();
            out.push(case(
                format!("convert {kind} -> {what}"),
                convert(&extra),
                expect,
                needles,
            ));
        }
    }
    // The input given as a pattern and as a list of files.
    let mut pattern = strings(&["convert", "seq/frame_*.obj"]);
    pattern.extend(strings(&SMALL).into_iter().chain(strings(&[
        "--format",
        "glb",
        "-o",
        "seq/frame_3.obj",
    ])));
    out.push(case(
        "convert glb -> frame file (pattern input)",
        pattern,
        Refuse,
        &["frame_3.obj"],
    ));
    let mut list = strings(&["convert"]);
    list.extend((0..FRAMES).map(|f| format!("seq/frame_{f}.obj")));
    list.extend(strings(&SMALL).into_iter().chain(strings(&[
        "--format",
        "glb",
        "-o",
        "seq/frame_3.obj",
    ])));
    out.push(case(
        "convert glb -> frame file (file list input)",
        list,
        Refuse,
        &["frame_3.obj"],
    ));

    // convert: a sidecar that is an input.
    out.push(case(
        "convert pc2 sidecar -> frame file",
        convert(&["-o", "seq/frame_3.pc2"]),
        Refuse,
        &["frame_3.obj"],
    ));
    out.push(case(
        "convert vat sidecar -> user json",
        convert(&["--vat", "-o", "seq/frame_2.exr"]),
        Refuse,
        &["frame_2.json"],
    ));

    // convert: two outputs of one run are one file.
    for (name, extra, needle) in [
        (
            "report = output",
            &["-o", "x.glb", "--report", "x.glb"][..],
            "x.glb",
        ),
        (
            "report = ./output",
            &["-o", "./x.glb", "--report", "x.glb"][..],
            "x.glb",
        ),
        (
            "report = pc2 sidecar",
            &["-o", "x.pc2", "--report", "x.obj"][..],
            "x.obj",
        ),
        (
            "report = vat sidecar",
            &["--vat", "-o", "v.exr", "--report", "v.json"][..],
            "v.json",
        ),
        (
            "report inside obj-sequence output",
            &["-o", "out", "--report", "out/frame_0000.obj"][..],
            "frame_0000.obj",
        ),
        (
            "checkpoint dir = output",
            &["-o", "x.glb", "--checkpoint", "x.glb"][..],
            "x.glb",
        ),
    ] {
        out.push(case(
            format!("convert {name}"),
            convert(extra),
            Refuse,
            &[needle],
        ));
    }

    // convert: new files inside the input directory.
    let mut rerun = case(
        "convert -o seq/anim.pc2, twice",
        convert(&["-o", "seq/anim.pc2"]),
        NotPickedUp,
        &[],
    );
    rerun.runs = 2;
    out.push(rerun);
    out.push(case(
        "convert -o seq/anim.glb",
        convert(&["-o", "seq/anim.glb"]),
        NotPickedUp,
        &[],
    ));
    // The texture's mesh, seq/anim.glb, would be read as a frame.
    out.push(case(
        "convert --vat -o seq/anim.exr",
        convert(&["--vat", "-o", "seq/anim.exr"]),
        Refuse,
        &["anim.glb"],
    ));
    out.push(case(
        "convert --report seq/report.html",
        convert(&["-o", "out.glb", "--report", "seq/report.html"]),
        NotPickedUp,
        &[],
    ));
    out.push(case(
        "convert obj-sequence -o seq/objs",
        convert(&["-o", "seq/objs"]),
        NotPickedUp,
        &[],
    ));

    // track: -o and --checkpoint.
    let track = |extra: &[&str]| {
        strings(&["track", "seq"])
            .into_iter()
            .chain(strings(&SMALL))
            .chain(strings(extra))
            .collect::<Vec<_>>()
    };
    for (what, target, needles) in FILE_TARGETS.iter().chain(&DIR_TARGETS) {
        out.push(case(
            format!("track -o -> {what}"),
            track(&["-o", target]),
            Refuse,
            needles,
        ));
        let expect = if is_dir(target) { NotPickedUp } else { Refuse };
        out.push(case(
            format!("track --checkpoint -> {what}"),
            track(&["-o", "t.exr", "--checkpoint", target]),
            expect,
            needles,
        ));
    }
    out.push(case(
        "track checkpoint dir = output",
        track(&["-o", "t.exr", "--checkpoint", "t.exr"]),
        Refuse,
        &["t.exr"],
    ));
    out.push(case(
        "track -o seq/t.exr",
        track(&["-o", "seq/t.exr"]),
        NotPickedUp,
        &[],
    ));

    // refine -o and metrics --plot, also at the trajectories they read.
    for (what, target, needles) in FILE_TARGETS.iter().chain(&DIR_TARGETS).chain(&TRAJ_TARGETS) {
        out.push(case(
            format!("refine -o -> {what}"),
            strings(&["refine", "traj.exr", "--input", "seq", "-o", target]),
            Refuse,
            needles,
        ));
        out.push(case(
            format!("metrics --plot -> {what}"),
            strings(&["metrics", "traj.exr", "--input", "seq", "--plot", target]),
            Refuse,
            needles,
        ));
    }
    out.push(case(
        "metrics --plot seq/plot.svg",
        strings(&[
            "metrics",
            "traj.exr",
            "--input",
            "seq",
            "--plot",
            "seq/plot.svg",
        ]),
        NotPickedUp,
        &[],
    ));

    // voxelize -o.
    let voxelize = |target: &str| strings(&["voxelize", "seq", "-r", "32", "-o", target]);
    for (what, target, needles) in FILE_TARGETS.iter().chain(&DIR_TARGETS) {
        out.push(case(
            format!("voxelize -o -> {what}"),
            voxelize(target),
            Refuse,
            needles,
        ));
    }
    out.push(case(
        "voxelize -o seq/vox",
        voxelize("seq/vox"),
        NotPickedUp,
        &[],
    ));

    // Links planted in output and checkpoint folders are replaced, not
    // followed; files of the user's there are refused.
    let refine = |extra: &[&str]| {
        strings(&["refine", "traj.exr", "--input", "seq", "-o", "r.exr"])
            .into_iter()
            .chain(strings(extra))
            .collect::<Vec<_>>()
    };
    for (name, argv, folder) in [
        (
            "convert --checkpoint",
            convert(&["-o", "out.glb", "--checkpoint", "ck_links"]),
            "ck_links",
        ),
        (
            "track --refine --checkpoint",
            track(&["-o", "t.exr", "--refine", "--checkpoint", "ck_links"]),
            "ck_links",
        ),
        (
            "refine --checkpoint",
            refine(&["--checkpoint", "ck_links"]),
            "ck_links",
        ),
        (
            "convert obj-sequence",
            convert(&["-o", "objs_links"]),
            "objs_links",
        ),
        ("voxelize", voxelize("vox_links"), "vox_links"),
    ] {
        let mut c = case(
            format!("{name} -> a folder with planted links"),
            argv,
            NotPickedUp,
            &[],
        );
        c.replaces_in = Some(folder);
        out.push(c);
    }
    for (name, argv, needles) in [
        (
            "convert --checkpoint",
            convert(&["-o", "out.glb", "--checkpoint", "ck_foreign"]),
            &["refine.ckpt"],
        ),
        (
            "track --checkpoint",
            track(&["-o", "t.exr", "--checkpoint", "ck_foreign2"]),
            &["track.ckpt"],
        ),
        (
            "refine --checkpoint",
            refine(&["--checkpoint", "ck_foreign"]),
            &["refine.ckpt"],
        ),
        (
            "convert obj-sequence",
            convert(&["-o", "objs_foreign"]),
            &["frame_0001.obj"],
        ),
        ("voxelize", voxelize("vox_foreign"), &["notes.txt"]),
    ] {
        out.push(case(
            format!("{name} -> a folder with the user's files"),
            argv,
            Refuse,
            needles,
        ));
    }
    out
}

fn strings(s: &[&str]) -> Vec<String> {
    s.iter().map(|s| s.to_string()).collect()
}

/// Whether directory discovery would take `name` (a file directly in the
/// input directory) as a frame.
fn frame_like(name: &str) -> bool {
    let ext = Path::new(name)
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    !name.starts_with('.') && ["obj", "ply", "gltf", "glb", "binvox"].contains(&ext.as_str())
}

fn kind(e: &Entry) -> String {
    match e {
        Entry::File(b) => format!("file of {} bytes", b.len()),
        Entry::Link(t) => format!("symlink to {}", t.display()),
        Entry::Dir => "directory".into(),
    }
}

/// stderr without the log lines (`[... INFO ...] ...`).
fn message(stderr: &str) -> String {
    stderr
        .lines()
        .filter(|l| !l.starts_with('['))
        .collect::<Vec<_>>()
        .join("\n")
}

/// Runs `argv` in `dir`, killed after [`KILL_AFTER`]: (status, stdout, stderr).
fn run(dir: &Path, argv: &[String]) -> (Result<i32, String>, String, String) {
    let out_path = dir.with_extension("stdout");
    let err_path = dir.with_extension("stderr");
    let mut child = Command::new(BIN)
        .args(argv)
        .current_dir(dir)
        // Tracking logs "frame 0: N centers placed": the sign that work began.
        .env("RUST_LOG", "voltrack=info")
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_path).unwrap())
        .stderr(std::fs::File::create(&err_path).unwrap())
        .spawn()
        .unwrap();
    let status = common::wait_or_kill(&mut child, Instant::now(), KILL_AFTER);
    let read = |p: &Path| std::fs::read_to_string(p).unwrap_or_default();
    (status, read(&out_path), read(&err_path))
}

/// What went wrong in one run of `case` (empty: nothing).
fn check(
    case: &Case,
    before: &BTreeMap<String, Entry>,
    dir: &Path,
    status: &Result<i32, String>,
    stdout: &str,
    stderr: &str,
) -> Vec<String> {
    let mut problems = Vec::new();
    let after = snapshot(dir);
    for (name, old) in before {
        if case.replaces_in.is_some_and(|dir| {
            name.strip_prefix(dir)
                .is_some_and(|rest| rest.starts_with('/'))
        }) && matches!(old, Entry::Link(_))
        {
            // Replaced by the run's own file, gone with the old folder, or
            // left alone where the run writes no file of its name; never
            // followed (the inputs it names are checked as every input is).
            if matches!(after.get(name), Some(Entry::Link(t)) if Some(&Entry::Link(t.clone())) != Some(old))
            {
                problems.push(format!("{name}: the planted link was relinked"));
            }
            continue;
        }
        match (old, after.get(name)) {
            (_, None) => problems.push(format!("{name} deleted")),
            (Entry::File(a), Some(Entry::File(b))) if a != b => problems.push(format!(
                "{name} modified ({} -> {} bytes)",
                a.len(),
                b.len()
            )),
            (a, Some(b)) if std::mem::discriminant(a) != std::mem::discriminant(b) => {
                problems.push(format!("{name} replaced: {} -> {}", kind(a), kind(b)))
            }
            (Entry::Link(a), Some(Entry::Link(b))) if a != b => {
                problems.push(format!("{name} relinked to {}", b.display()))
            }
            _ => {}
        }
    }
    let refused = matches!(status, Ok(c) if *c != 0 && *c != 101);
    let mut frames = Vec::new();
    for name in after.keys().filter(|n| !before.contains_key(*n)) {
        // Only the outermost new entry: a new directory's files are its own.
        let outermost = name
            .rsplit_once('/')
            .is_none_or(|(parent, _)| before.contains_key(parent));
        if refused && outermost {
            problems.push(format!(
                "left behind after refusing: {name}{}",
                if dir.join(name).is_dir() { "/" } else { "" }
            ));
        }
        if let Some(file) = name.strip_prefix("seq/") {
            if !file.contains('/') && frame_like(file) {
                frames.push(file);
            }
        }
        if name.ends_with(".partial") {
            problems.push(format!("temporary left: {name}"));
        }
    }
    if !frames.is_empty() {
        let shown = if frames.len() > 3 {
            format!(
                "{} … {} ({} files)",
                frames[0],
                frames[frames.len() - 1],
                frames.len()
            )
        } else {
            frames.join(", ")
        };
        problems.push(format!("new frame-like file in seq/: {shown}"));
    }
    match status {
        Ok(101) => problems.push("panicked (exit 101)".into()),
        Err(e) => problems.push(e.clone()),
        Ok(0) if case.expect == Expect::Refuse => problems.push("not refused (exit 0)".into()),
        Ok(0) => {
            // A convert that ran must have read the same 8 frames.
            if case.argv[0] == "convert" && !stdout.starts_with(&format!("{FRAMES} frames")) {
                problems.push(format!("read {}", stdout.lines().next().unwrap_or("?")));
            }
        }
        Ok(_) if case.expect == Expect::Refuse => {
            if !case.needles.iter().any(|n| message(stderr).contains(n)) {
                problems.push(format!(
                    "refused, but the message names none of {:?}",
                    case.needles
                ));
            }
            if stderr.contains("centers placed") {
                problems.push(
                    "refused only after the work began (tracking had placed its centers)".into(),
                );
            }
        }
        Ok(_) => {}
    }
    problems
}

#[test]
fn no_command_modifies_its_inputs() {
    let scratch = Scratch::new("inputs-untouched", "all");
    let template = scratch.0.join("template");
    std::fs::create_dir_all(&template).unwrap();
    let before = make_fixture(&template);
    let cases = cases();
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    let clock = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..THREADS {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(case) = cases.get(k) else { break };
                let dir = scratch.0.join(format!("case{k:03}"));
                std::fs::create_dir_all(&dir).unwrap();
                materialize(&dir, &before);
                for run_no in 1..=case.runs {
                    let (status, stdout, stderr) = run(&dir, &case.argv);
                    let problems = check(case, &before, &dir, &status, &stdout, &stderr);
                    if !problems.is_empty() {
                        let code = match &status {
                            Ok(c) => c.to_string(),
                            Err(e) => e.clone(),
                        };
                        let first = message(&stderr)
                            .lines()
                            .map(str::trim)
                            .find(|l| !l.is_empty())
                            .unwrap_or("")
                            .chars()
                            .take(120)
                            .collect::<String>();
                        let name = if case.runs > 1 {
                            format!("{} (run {run_no})", case.name)
                        } else {
                            case.name.clone()
                        };
                        failures.lock().unwrap().push((
                            k,
                            name,
                            case.argv.join(" "),
                            code,
                            first,
                            problems,
                        ));
                    }
                }
                let _ = std::fs::remove_dir_all(&dir);
            });
        }
    });
    let seconds = clock.elapsed().as_secs_f64();
    let runs: usize = cases.iter().map(|c| c.runs).sum();
    eprintln!(
        "inputs untouched: {} cases ({runs} runs) in {seconds:.1} s",
        cases.len()
    );
    let mut failures = failures.into_inner().unwrap();
    failures.sort_by_key(|f| f.0);
    if !failures.is_empty() {
        let table = failures
            .iter()
            .map(|(_, name, argv, code, first, problems)| {
                format!(
                    "{name}\n    voltrack {argv}\n    exit {code}: {first}\n    - {}",
                    problems.join("\n    - ")
                )
            })
            .collect::<Vec<_>>()
            .join("\n");
        panic!(
            "{} of {} cases failed:\n{table}",
            failures.len(),
            cases.len()
        );
    }
}
