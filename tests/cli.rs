//! The `voltrack` binary end to end on the committed bending-bar fixture, at
//! small settings (each run well under a few seconds): every output format,
//! the JSON of track / metrics / refine, and the error paths (exit codes,
//! messages naming the file and line, nothing left behind).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_voltrack");
const SMALL: [&str; 4] = ["-r", "48", "-n", "120"];
const FRAMES: usize = 8;

fn fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/bending_bar")
}

mod common;
use common::Scratch;

/// Runs the binary in `dir` with `args`.
fn run(dir: &Scratch, args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(&dir.0)
        .env("RUST_LOG", "warn")
        .output()
        .expect("the voltrack binary runs")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Runs and expects success; returns stdout.
fn ok(dir: &Scratch, args: &[&str]) -> String {
    let out = run(dir, args);
    assert!(
        out.status.success(),
        "voltrack {args:?} failed ({:?}):\n{}\n{}",
        out.status,
        text(&out.stdout),
        text(&out.stderr)
    );
    text(&out.stdout)
}

/// Runs and expects failure with `code`; returns stderr.
fn fails(dir: &Scratch, args: &[&str], code: i32) -> String {
    let out = run(dir, args);
    let stderr = text(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(code),
        "voltrack {args:?}: stdout\n{}\nstderr\n{stderr}",
        text(&out.stdout)
    );
    assert!(!stderr.trim().is_empty(), "no message on stderr");
    stderr
}

fn json(stdout: &str) -> serde_json::Value {
    serde_json::from_str(stdout).unwrap_or_else(|e| panic!("not JSON ({e}):\n{stdout}"))
}

fn convert_args<'a>(out: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let fixture: &'static str =
        Box::leak(fixture().to_string_lossy().into_owned().into_boxed_str());
    let mut args = vec!["convert", fixture];
    args.extend(SMALL);
    args.extend(["-o", out]);
    args.extend(extra);
    args
}

/// `(keyframes, targets, interpolation)` of a GLB read with the gltf crate.
fn glb_summary(path: &Path) -> (usize, usize, gltf::animation::Interpolation) {
    let doc = gltf::Gltf::from_slice(&std::fs::read(path).unwrap()).expect("a valid GLB");
    let primitive = doc.meshes().next().unwrap().primitives().next().unwrap();
    let targets = primitive.morph_targets().count();
    let sampler = doc.animations().next().unwrap().samplers().next().unwrap();
    (sampler.input().count(), targets, sampler.interpolation())
}

#[test]
fn help_lists_the_commands() {
    let dir = Scratch::new("cli", "help");
    let help = ok(&dir, &["--help"]);
    for command in ["convert", "track", "refine", "metrics", "voxelize"] {
        assert!(help.contains(command), "{help}");
    }
    assert!(ok(&dir, &["--version"]).contains(env!("CARGO_PKG_VERSION")));
    let convert = ok(&dir, &["convert", "--help"]);
    for flag in [
        "--resolution",
        "--centers",
        "--output",
        "--format",
        "--vat",
        "--basis",
        "--compress",
        "--fps",
        "--no-refine",
        "--report",
        "--checkpoint",
        "--resume",
        "--name",
        "--json",
    ] {
        assert!(convert.contains(flag), "convert --help lacks {flag}");
    }
}

#[test]
fn convert_to_glb() {
    let dir = Scratch::new("cli", "glb");
    std::fs::create_dir(dir.join("tmp")).unwrap();
    let stdout = ok(&dir, &convert_args("tmp/x.glb", &[]));
    assert!(stdout.contains("wrote tmp/x.glb"), "{stdout}");
    assert!(stdout.contains(&format!("{FRAMES} frames")), "{stdout}");
    let (frames, targets, interpolation) = glb_summary(&dir.join("tmp/x.glb"));
    // One key per frame and the closing one that holds the last.
    assert_eq!(
        (frames, targets, interpolation),
        (FRAMES + 1, FRAMES - 1, gltf::animation::Interpolation::Step)
    );
    assert_eq!(dir.files(), ["tmp/x.glb"]);
}

/// Decodes standard base64 (padding optional), as a `data:` URI holds it.
fn unbase64(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {:?}", c as char),
    };
    let digits: Vec<u8> = text.bytes().filter(|&c| c != b'=').map(value).collect();
    digits
        .chunks(4)
        .flat_map(|g| {
            let n = g
                .iter()
                .enumerate()
                .fold(0u32, |n, (k, &d)| n | (d as u32) << (18 - 6 * k));
            (0..g.len() - 1).map(move |k| (n >> (16 - 8 * k)) as u8)
        })
        .collect()
}

#[test]
fn convert_to_text_gltf() {
    let dir = Scratch::new("cli", "gltf");
    for extra in [&[][..], &["--compress"]] {
        ok(&dir, &convert_args("x.glb", extra));
        let stdout = ok(&dir, &convert_args("x.gltf", extra));
        let glb = std::fs::read(dir.join("x.glb")).unwrap();
        let glb = gltf::Glb::from_slice(&glb).expect("a GLB");
        let text = std::fs::read_to_string(dir.join("x.gltf")).unwrap();
        // The size printed is the .gltf file's.
        assert!(
            stdout.contains(&format!("({:.1} KiB", text.len() as f64 / 1024.0)),
            "{stdout}"
        );
        let mut gltf = json(&text);
        let uri = gltf["buffers"][0]
            .as_object_mut()
            .unwrap()
            .remove("uri")
            .expect("the buffer is embedded");
        let data = uri
            .as_str()
            .unwrap()
            .strip_prefix("data:application/octet-stream;base64,")
            .expect("a base64 data URI");
        // The GLB's JSON and BIN chunk, in one text file.
        assert_eq!(
            gltf,
            json(std::str::from_utf8(&glb.json).unwrap()),
            "{extra:?}"
        );
        let length = gltf["buffers"][0]["byteLength"].as_u64().unwrap() as usize;
        assert_eq!(unbase64(data), glb.bin.unwrap()[..length], "{extra:?}");
    }
    assert_eq!(dir.files(), ["x.glb", "x.gltf"]);
}

#[test]
fn convert_with_a_report() {
    let dir = Scratch::new("cli", "report");
    let stdout = ok(&dir, &convert_args("x.glb", &["--report", "x.html"]));
    assert!(
        stdout.contains("fit to the input: mean") && stdout.contains("report: x.html"),
        "{stdout}"
    );
    let html = std::fs::read_to_string(dir.join("x.html")).unwrap();
    assert!(
        html.starts_with("<!DOCTYPE html>") && html.matches("<svg").count() >= 5,
        "a report with its plots"
    );
    assert_eq!(dir.files(), ["x.glb", "x.html"]);
    // A report that cannot be written fails before any work.
    let stderr = fails(
        &dir,
        &convert_args("y.glb", &["--report", "no/such/dir/y.html"]),
        2,
    );
    assert!(stderr.contains("no/such/dir/y.html"), "{stderr}");
    assert_eq!(dir.files(), ["x.glb", "x.html"]);
}

#[test]
fn absolute_units_reach_every_stage_with_lengths() {
    let dir = Scratch::new("cli", "absolute");
    ok(
        &dir,
        &convert_args("a.glb", &["--absolute-units", "--report", "a.html"]),
    );
    let html = std::fs::read_to_string(dir.join("a.html")).unwrap();
    // Tracking, refinement and conforming all take lengths in the input's units.
    let row = |v: &str| {
        html.matches(&format!("<tr><th>absolute_units</th><td>{v}</td></tr>"))
            .count()
    };
    assert_eq!((row("true"), row("false")), (3, 0), "{html}");
    // The refine command takes them as the trajectories were tracked.
    let input = fixture().to_string_lossy().into_owned();
    for (flag, absolute) in [(Some("--absolute-units"), true), (None, false)] {
        let mut args = vec!["track", &input];
        args.extend(SMALL);
        args.extend(["-o", "c.exr"]);
        args.extend(flag);
        ok(&dir, &args);
        ok(&dir, &["refine", "c.exr", "--input", &input, "-o", "r.exr"]);
        let (_, attrs) = voltrack::io::exr::read_trajectories_exr(&dir.join("r.exr")).unwrap();
        let refine = attrs.refine.expect("refine attribute");
        assert_eq!(
            refine["absolute_units"],
            serde_json::json!(absolute),
            "{refine}"
        );
    }
}

#[test]
fn convert_to_glb_with_a_compact_basis() {
    let dir = Scratch::new("cli", "glb-basis");
    let stdout = ok(
        &dir,
        &convert_args("b.glb", &["--basis", "3", "--fps", "24"]),
    );
    assert!(stdout.contains("compact basis of 3 components"), "{stdout}");
    let (frames, targets, interpolation) = glb_summary(&dir.join("b.glb"));
    assert_eq!(frames, FRAMES + 1);
    assert!((3..=6).contains(&targets), "{targets}");
    // Held like per-frame targets unless asked otherwise.
    assert_eq!(interpolation, gltf::animation::Interpolation::Step);
    assert_eq!(dir.files(), ["b.glb"]);
}

/// `--interpolation linear` blends captures, per-frame and compact alike;
/// an output without a glTF animation refuses it before any work.
#[test]
fn interpolation_is_one_choice_for_every_glb() {
    let dir = Scratch::new("cli", "interpolation");
    for (name, extra) in [("p.glb", &[][..]), ("b.glb", &["--basis", "3"][..])] {
        let mut args = vec!["--interpolation", "linear"];
        args.extend(extra);
        ok(&dir, &convert_args(name, &args));
        let (_, _, interpolation) = glb_summary(&dir.join(name));
        assert_eq!(
            interpolation,
            gltf::animation::Interpolation::Linear,
            "{name}"
        );
    }
    let out = run(&dir, &convert_args("c.exr", &["--interpolation", "step"]));
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--interpolation"));
}

/// Issue 23: `--compress` writes a smaller GLB that requires the meshopt and
/// quantisation extensions, and reports the decoded positions' error.
#[test]
fn convert_to_a_compressed_glb() {
    let dir = Scratch::new("cli", "glb-compress");
    let plain = json(&ok(
        &dir,
        &convert_args("p.glb", &["--json", "--no-refine"]),
    ));
    assert_eq!(plain["basis"]["compressed"], false);
    let per_frame = ["--compress", "--basis", "per-frame", "--no-refine"];
    let stdout = ok(&dir, &convert_args("c.glb", &per_frame));
    assert!(stdout.contains("compressed (KHR_mesh_quantization + EXT_meshopt_compression, 7 morph targets as steps from frame to frame): reconstruction error max"), "{stdout}");
    // By default the fewest components within the result's own fit.
    let summary = json(&ok(
        &dir,
        &convert_args("c.glb", &["--json", "--compress", "--no-refine"]),
    ));
    assert_eq!(summary["basis"]["chosen_by"], "fit", "{summary}");
    let error = summary["basis"]["reconstruction_error_percent"]["mean"]
        .as_f64()
        .unwrap();
    assert!(
        error <= 1.05 * summary["fit_percent"]["mean"].as_f64().unwrap(),
        "{summary}"
    );
    // The bases tried, by size, each encoded as the file: the one written
    // is the file, the smaller ones err more on average.
    let rows = summary["basis"]["rate_distortion"].as_array().unwrap();
    assert!(rows.len() >= 2, "{summary}");
    let field = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap();
    for pair in rows.windows(2) {
        assert!(
            field(&pair[0], "targets") < field(&pair[1], "targets"),
            "{summary}"
        );
        assert!(
            field(&pair[0], "bytes") < field(&pair[1], "bytes"),
            "{summary}"
        );
    }
    let chosen: Vec<_> = rows.iter().filter(|r| r["chosen"] == true).collect();
    assert_eq!(chosen.len(), 1, "{summary}");
    assert_eq!(chosen[0]["bytes"], summary["bytes"], "{summary}");
    assert_eq!(
        chosen[0]["components"], summary["basis"]["components"],
        "{summary}"
    );
    assert_eq!(
        chosen[0]["error_percent"], summary["basis"]["reconstruction_error_percent"],
        "{summary}"
    );
    for smaller in rows.iter().take_while(|r| r["chosen"] != true) {
        assert!(
            smaller["error_percent"]["mean"].as_f64().unwrap() > error,
            "{summary}"
        );
    }
    let mut args = vec!["--json"];
    args.extend(per_frame);
    let summary = json(&ok(&dir, &convert_args("c.glb", &args)));
    let basis = &summary["basis"];
    assert_eq!(basis["compressed"], true, "{basis}");
    assert_eq!(basis["steps"], true, "{basis}");
    assert_eq!(basis["normals"], true, "{basis}");
    let error = basis["reconstruction_error_percent"]["max"]
        .as_f64()
        .unwrap();
    assert!(error > 0.0 && error < 0.05, "{basis}");
    assert!(
        summary["bytes"].as_u64().unwrap() * 2 < plain["bytes"].as_u64().unwrap(),
        "{summary}\n{plain}"
    );
    let glb = std::fs::read(dir.join("c.glb")).unwrap();
    let doc: serde_json::Value =
        serde_json::from_slice(&gltf::binary::Glb::from_slice(&glb).unwrap().json).unwrap();
    assert_eq!(
        doc["extensionsRequired"],
        serde_json::json!(["EXT_meshopt_compression", "KHR_mesh_quantization"])
    );
    // Without normals: no NORMAL attribute or deltas, the same positions
    // in fewer bytes.
    args.extend(["--normals", "off"]);
    let flat = json(&ok(&dir, &convert_args("f.glb", &args)));
    assert_eq!(flat["basis"]["normals"], false, "{flat}");
    assert_eq!(
        flat["basis"]["reconstruction_error_percent"], basis["reconstruction_error_percent"],
        "{flat}"
    );
    assert!(
        flat["bytes"].as_u64().unwrap() < summary["bytes"].as_u64().unwrap(),
        "{flat}\n{summary}"
    );
    let glb = std::fs::read(dir.join("f.glb")).unwrap();
    let doc: serde_json::Value =
        serde_json::from_slice(&gltf::binary::Glb::from_slice(&glb).unwrap().json).unwrap();
    let primitive = &doc["meshes"][0]["primitives"][0];
    assert!(
        primitive["attributes"].get("NORMAL").is_none(),
        "{primitive}"
    );
    let targets = primitive["targets"].as_array().unwrap();
    assert!(
        targets.iter().all(|t| t.get("NORMAL").is_none()),
        "{primitive}"
    );
    let stderr = fails(&dir, &convert_args("c.pc2", &["--compress"]), 2);
    assert!(stderr.contains("--compress"), "{stderr}");
    let stderr = fails(&dir, &convert_args("n.pc2", &["--normals", "off"]), 2);
    assert!(stderr.contains("--normals"), "{stderr}");
    assert_eq!(dir.files(), ["c.glb", "f.glb", "p.glb"]);
}

/// Names of the node, the mesh and the animation of a GLB.
fn glb_names(path: &Path) -> [Option<String>; 3] {
    let doc = gltf::Gltf::from_slice(&std::fs::read(path).unwrap()).expect("a valid GLB");
    let name = |n: Option<&str>| n.map(String::from);
    [
        name(doc.nodes().next().unwrap().name()),
        name(doc.meshes().next().unwrap().name()),
        name(doc.animations().next().unwrap().name()),
    ]
}

/// Issue 23: `convert --json` says what it did, as `track --json` does, and
/// prints nothing else on stdout.
#[test]
fn convert_prints_a_json_summary() {
    let dir = Scratch::new("cli", "convert-json");
    let summary = json(&ok(
        &dir,
        &convert_args("x.glb", &["--json", "--report", "x.html", "--fps", "24"]),
    ));
    assert_eq!(summary["output"], "x.glb");
    assert_eq!(summary["files"], serde_json::json!(["x.glb"]));
    assert_eq!(
        (summary["format"].as_str(), summary["name"].as_str()),
        (Some("glb"), Some("bending_bar"))
    );
    assert_eq!(
        (
            summary["frames"].as_u64(),
            summary["fps"].as_f64(),
            summary["resolution"].as_u64()
        ),
        (Some(FRAMES as u64), Some(24.0), Some(48))
    );
    // The counts are the file's.
    let doc = gltf::Gltf::from_slice(&std::fs::read(dir.join("x.glb")).unwrap()).unwrap();
    let primitive = doc.meshes().next().unwrap().primitives().next().unwrap();
    assert_eq!(
        summary["vertices"].as_u64(),
        Some(primitive.get(&gltf::Semantic::Positions).unwrap().count() as u64)
    );
    assert_eq!(
        summary["triangles"].as_u64(),
        Some(primitive.indices().unwrap().count() as u64 / 3)
    );
    assert_eq!(
        summary["bytes"].as_u64(),
        Some(std::fs::metadata(dir.join("x.glb")).unwrap().len())
    );
    // 120 centers less the irregular ones refinement removed.
    let removed = summary["removed"].as_array().expect("removed centers");
    assert!(!removed.is_empty());
    assert_eq!(
        summary["centers"].as_u64(),
        Some(120 - removed.len() as u64)
    );
    let basis = &summary["basis"];
    assert_eq!(
        (basis["targets"].as_u64(), basis["components"].is_null()),
        (Some(FRAMES as u64 - 1), true),
        "{basis}"
    );
    assert_eq!(
        basis["reconstruction_error_percent"]["max"].as_f64(),
        Some(0.0)
    );
    let seconds = summary["seconds"].as_object().unwrap();
    for stage in [
        "read", "voxelize", "track", "refine", "deform", "conform", "fit", "export", "total",
    ] {
        assert!(
            seconds
                .get(stage)
                .and_then(|s| s.as_f64())
                .is_some_and(|s| s >= 0.0),
            "{stage}: {seconds:?}"
        );
    }
    let stages: f64 = seconds
        .iter()
        .filter(|(k, _)| *k != "total")
        .map(|(_, v)| v.as_f64().unwrap())
        .sum();
    assert!((stages - seconds["total"].as_f64().unwrap()).abs() < 1e-9);
    // Measured for the report, so in the summary too (percent of the diagonal).
    let fit = &summary["fit_percent"];
    assert!(
        fit["mean"]
            .as_f64()
            .is_some_and(|m| m > 0.0 && m <= fit["max"].as_f64().unwrap()),
        "{fit}"
    );
    assert_eq!(summary["report"], "x.html");

    // A point cache: both files, the frame rate; a compact basis: its size.
    let summary = json(&ok(
        &dir,
        &convert_args("anim.pc2", &["--json", "--no-refine", "--name", "Bar"]),
    ));
    assert_eq!(
        summary["files"],
        serde_json::json!(["anim.pc2", "anim.obj"])
    );
    assert_eq!(
        (
            summary["format"].as_str(),
            summary["name"].as_str(),
            summary["fps"].as_f64()
        ),
        (Some("pc2"), Some("Bar"), Some(30.0))
    );
    assert!(
        summary["removed"].is_null() && summary["basis"].is_null(),
        "{summary}"
    );
    // Measured on every mesh output, report or not, so that lost parts are warned of.
    assert!(
        summary["fit_percent"]["p95"].as_f64().is_some()
            && summary["warnings"].as_array().is_some_and(|w| w.is_empty()),
        "{summary}"
    );
    assert_eq!(summary["centers"].as_u64(), Some(120));
    assert!(summary["seconds"].get("refine").is_none());
    let summary = json(&ok(
        &dir,
        &convert_args("b.glb", &["--json", "--basis", "2"]),
    ));
    assert_eq!(summary["basis"]["components"].as_u64(), Some(2));
    assert_eq!(summary["basis"]["chosen_by"], "components");
    // --basis auto: the fewest components within the result's own fit to
    // the input, or one target per frame where none needs fewer.
    let summary = json(&ok(
        &dir,
        &convert_args("d.glb", &["--json", "--basis", "auto"]),
    ));
    assert_eq!(summary["basis"]["chosen_by"], "fit");
    if summary["basis"]["components"].as_u64().is_some() {
        let fit = summary["fit_percent"]["mean"].as_f64().unwrap();
        let error = summary["basis"]["reconstruction_error_percent"]["mean"]
            .as_f64()
            .unwrap();
        assert!(error <= 1.05 * fit, "{summary}");
    } else {
        assert_eq!(
            summary["basis"]["reconstruction_error_percent"]["max"].as_f64(),
            Some(0.0)
        );
    }
    // Trajectories carry neither a name nor a frame rate.
    let summary = json(&ok(
        &dir,
        &convert_args("c.exr", &["--json", "--no-refine"]),
    ));
    assert!(
        summary["name"].is_null() && summary["fps"].is_null() && summary["basis"].is_null(),
        "{summary}"
    );
    // Trajectories alone: the mesh is not fitted to the input, but its fit
    // is measured, so that a lost part is warned of and attempts compared.
    assert!(
        summary["seconds"].get("conform").is_none()
            && summary["fit_percent"]["p95"].as_f64().is_some()
            && summary["seed"].as_u64() == Some(0),
        "{summary}"
    );
    assert_eq!(
        dir.files(),
        ["anim.obj", "anim.pc2", "b.glb", "c.exr", "d.glb", "x.glb", "x.html"]
    );
}

/// Issue 23: the result is named after the input, or as `--name` says.
#[test]
fn convert_names_the_object_after_the_input() {
    let dir = Scratch::new("cli", "names");
    let bar = Some("bending_bar".to_string());
    ok(&dir, &convert_args("a.glb", &["--no-refine"]));
    assert_eq!(
        glb_names(&dir.join("a.glb")),
        [bar.clone(), bar.clone(), bar]
    );
    let hero = Some("Hero 2".to_string());
    let stdout = ok(
        &dir,
        &convert_args("b.glb", &["--no-refine", "--name", "Hero 2"]),
    );
    assert!(stdout.contains("\"Hero 2\""), "{stdout}");
    assert_eq!(
        glb_names(&dir.join("b.glb")),
        [hero.clone(), hero.clone(), hero]
    );
    // The point cache's OBJ and an OBJ sequence name their object.
    ok(
        &dir,
        &convert_args("c.pc2", &["--no-refine", "--name", "Hero 2"]),
    );
    let obj = std::fs::read_to_string(dir.join("c.obj")).unwrap();
    assert_eq!(
        obj.lines()
            .filter(|l| l.starts_with("o "))
            .collect::<Vec<_>>(),
        ["o Hero 2"]
    );
    let pattern = fixture().join("frame_*.obj").to_string_lossy().into_owned();
    ok(
        &dir,
        &[
            "convert",
            &pattern,
            "-r",
            "32",
            "-n",
            "40",
            "--no-refine",
            "-o",
            "seq",
        ],
    );
    let first = std::fs::read_to_string(dir.join("seq/frame_0000.obj")).unwrap();
    assert_eq!(
        first
            .lines()
            .filter(|l| l.starts_with("o "))
            .collect::<Vec<_>>(),
        ["o frame"]
    );
    // A blank name or one with a line break is refused before any work.
    for bad in ["", " ", "a\nb"] {
        let stderr = fails(&dir, &convert_args("bad.glb", &["--name", bad]), 2);
        assert!(stderr.contains("name"), "{bad:?}: {stderr}");
    }
    assert!(!dir.join("bad.glb").exists());
}

#[test]
fn convert_to_trajectories_exr() {
    let dir = Scratch::new("cli", "exr");
    // By extension, and by --format with another extension.
    ok(&dir, &convert_args("c.exr", &[]));
    ok(
        &dir,
        &convert_args("c.data", &["--format", "exr", "--no-refine"]),
    );
    assert_eq!(dir.files(), ["c.data", "c.exr"]);
    let (traj, attrs) = voltrack::io::exr::read_trajectories_exr(&dir.join("c.exr")).unwrap();
    assert_eq!(traj.frames, FRAMES);
    // Refinement removes at least one of the 120 centers and records which.
    let removed: Vec<usize> = attrs.removed.expect("voltrack.removed");
    assert!(!removed.is_empty() && removed.iter().all(|&i| i < 120));
    assert_eq!(traj.centers, 120 - removed.len());
    let (unrefined, attrs) = voltrack::io::exr::read_trajectories_exr(&dir.join("c.data")).unwrap();
    assert_eq!((unrefined.frames, unrefined.centers), (FRAMES, 120));
    assert_eq!(attrs.resolution, Some(48));
}

#[test]
fn convert_to_vertex_animation_texture() {
    let dir = Scratch::new("cli", "vat");
    ok(&dir, &convert_args("v.exr", &["--vat"]));
    assert_eq!(dir.files(), ["v.exr", "v.glb", "v.json"]);
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("v.json")).unwrap()).unwrap();
    assert_eq!(info["frames"], FRAMES);
    let vertices = info["vertices"].as_u64().unwrap() as usize;
    // Few enough vertices for one row each: one frame per row, as before.
    assert_eq!(
        (info["width"].as_u64(), info["rows_per_frame"].as_u64()),
        (Some(vertices as u64), Some(1))
    );
    let (texture, _) = voltrack::io::exr::read_trajectories_exr(&dir.join("v.exr")).unwrap();
    assert_eq!((texture.frames, texture.centers), (FRAMES, vertices));
    // Frame 0 of the texture is the first input mesh, as loaded.
    let first = voltrack::io::read_mesh(&fixture().join("frame_0.obj")).unwrap();
    assert_eq!(vertices, first.positions.len());
    for (a, b) in texture.frame(0).iter().zip(&first.positions) {
        assert!((a - b).norm() < 1e-6);
    }
    for k in 0..3 {
        let lo = texture
            .positions
            .iter()
            .map(|p| p[k])
            .fold(f64::INFINITY, f64::min);
        assert!((info["bounds_min"][k].as_f64().unwrap() - lo).abs() < 1e-6);
    }
}

#[test]
fn convert_to_point_cache() {
    let dir = Scratch::new("cli", "pc2");
    ok(&dir, &convert_args("anim.pc2", &["--fps", "25"]));
    assert_eq!(dir.files(), ["anim.obj", "anim.pc2"]);
    let bytes = std::fs::read(dir.join("anim.pc2")).unwrap();
    assert_eq!(&bytes[..12], b"POINTCACHE2\0");
    let int = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let points = int(16);
    assert_eq!(int(28), FRAMES);
    assert_eq!(bytes.len(), 32 + 12 * points * FRAMES);
    let obj = std::fs::read_to_string(dir.join("anim.obj")).unwrap();
    assert!(obj.contains("25 fps"));
    assert_eq!(obj.lines().filter(|l| l.starts_with("v ")).count(), points);
}

#[test]
fn convert_to_obj_sequence() {
    let dir = Scratch::new("cli", "objseq");
    ok(&dir, &convert_args("seq", &[]));
    let want: Vec<String> = (0..FRAMES)
        .map(|f| format!("seq/frame_{f:04}.obj"))
        .collect();
    // And the hidden list of what voltrack wrote there, which lets the next
    // run replace the folder.
    let listed: Vec<String> = std::iter::once("seq/.voltrack-files".to_string())
        .chain(want.iter().cloned())
        .collect();
    assert_eq!(dir.files(), listed);
    let faces = |f: &str| -> Vec<String> {
        std::fs::read_to_string(dir.join(f))
            .unwrap()
            .lines()
            .filter(|l| l.starts_with("f "))
            .map(String::from)
            .collect()
    };
    let first = faces(&want[0]);
    assert!(!first.is_empty());
    assert!(
        want.iter().all(|f| faces(f) == first),
        "face lines differ between frames"
    );
    // The written sequence is itself a valid input.
    ok(
        &dir,
        &["track", "seq", "-r", "32", "-n", "30", "-o", "again.exr"],
    );
}

#[test]
fn track_metrics_and_refine() {
    let dir = Scratch::new("cli", "track");
    let input = fixture().to_string_lossy().into_owned();
    let mut args = vec!["track", &input];
    args.extend(SMALL);
    args.extend(["-o", "c.exr", "--json"]);
    let tracked = json(&ok(&dir, &args));
    assert_eq!(tracked["frames"], FRAMES);
    assert_eq!(tracked["centers"], 120);
    let (pcac, dfu) = (
        tracked["pcac"].as_f64().unwrap(),
        tracked["dfu"].as_f64().unwrap(),
    );
    assert!(pcac > 0.0 && pcac.is_finite(), "{pcac}");
    assert!(dfu > 0.0 && dfu < 1.0, "{dfu}");
    assert_eq!(dir.files(), ["c.exr"]);

    let metrics = json(&ok(
        &dir,
        &[
            "metrics",
            "c.exr",
            "--input",
            &input,
            "--json",
            "--plot",
            "curve.svg",
        ],
    ));
    assert_eq!(metrics["frames"], FRAMES);
    assert_eq!(metrics["centers"], 120);
    assert_eq!(metrics["dfu_per_frame"].as_array().unwrap().len(), FRAMES);
    let irregularity = metrics["irregularity"].as_array().unwrap();
    assert_eq!(irregularity.len(), 120);
    assert!(irregularity
        .iter()
        .all(|v| v.as_f64().is_some_and(|x| x >= 0.0)));
    // The stored (f32) trajectories measure as the tracked (f64) ones did.
    assert!(
        (metrics["pcac"].as_f64().unwrap() - pcac).abs() < 1e-4 * pcac,
        "{} vs {pcac}",
        metrics["pcac"]
    );
    assert!(
        (metrics["dfu"].as_f64().unwrap() - dfu).abs() < 1e-3,
        "{} vs {dfu}",
        metrics["dfu"]
    );
    let svg = std::fs::read_to_string(dir.join("curve.svg")).unwrap();
    assert!(
        svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>") && svg.contains("<polyline")
    );
    assert!(!svg.contains("NaN"));
    // Without --json: a human summary.
    let human = ok(&dir, &["metrics", "c.exr", "--input", &input]);
    assert!(human.contains("PCAC") && human.contains("DFU"), "{human}");

    let refined = json(&ok(
        &dir,
        &[
            "refine", "c.exr", "--input", &input, "-o", "r.exr", "--json", "--remove", "3",
        ],
    ));
    let removed: Vec<usize> = serde_json::from_value(refined["removed"].clone()).unwrap();
    assert_eq!(removed.len(), 3, "{removed:?}");
    let mut unique = removed.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), 3);
    assert!(removed.iter().all(|&i| i < 120));
    for key in ["before", "after"] {
        assert!(
            refined[key]["pcac"].as_f64().is_some() && refined[key]["dfu"].as_f64().is_some(),
            "{key}"
        );
    }
    let (traj, attrs) = voltrack::io::exr::read_trajectories_exr(&dir.join("r.exr")).unwrap();
    assert_eq!((traj.frames, traj.centers), (FRAMES, 117));
    let stored: Vec<usize> = attrs.removed.unwrap();
    assert_eq!(stored, removed);
    // The refined file is measurable in turn.
    let again = json(&ok(
        &dir,
        &["metrics", "r.exr", "--input", &input, "--json"],
    ));
    assert_eq!(again["centers"], 117);
    assert_eq!(dir.files(), ["c.exr", "curve.svg", "r.exr"]);
}

#[test]
fn missing_input_is_named_and_nothing_is_written() {
    let dir = Scratch::new("cli", "missing");
    let stderr = fails(&dir, &["convert", "no_such_frames.obj", "-o", "out.glb"], 1);
    assert!(stderr.contains("no_such_frames.obj"), "{stderr}");
    let stderr = fails(&dir, &["track", "no_such_dir", "-o", "c.exr"], 1);
    assert!(stderr.contains("no_such_dir"), "{stderr}");
    let input = fixture().to_string_lossy().into_owned();
    let stderr = fails(&dir, &["metrics", "absent.exr", "--input", &input], 1);
    assert!(stderr.contains("absent.exr"), "{stderr}");
    let stderr = fails(
        &dir,
        &["refine", "absent.exr", "--input", &input, "-o", "r.exr"],
        1,
    );
    assert!(stderr.contains("absent.exr"), "{stderr}");
    // A pattern that matches nothing, an empty directory.
    let stderr = fails(&dir, &["convert", "frames_*.obj", "-o", "out.glb"], 1);
    assert!(stderr.contains("frames_*.obj"), "{stderr}");
    std::fs::create_dir(dir.join("empty")).unwrap();
    let stderr = fails(&dir, &["convert", "empty", "-o", "out.glb"], 1);
    assert!(stderr.contains("empty"), "{stderr}");
    assert!(dir.files().is_empty(), "{:?}", dir.files());
}

#[test]
fn unwritable_outputs_fail_and_leave_nothing() {
    let dir = Scratch::new("cli", "unwritable");
    std::fs::write(dir.join("plain"), b"a file").unwrap();
    std::fs::create_dir(dir.join("taken.glb")).unwrap();
    // A parent directory that does not exist, a parent that is a file, and an
    // output that is an existing directory.
    for out in ["no/such/dir/x.glb", "plain/x.glb", "taken.glb"] {
        let stderr = fails(&dir, &convert_args(out, &["--no-refine"]), 2);
        assert!(
            stderr.contains(out.split('/').next().unwrap()),
            "{out}: {stderr}"
        );
    }
    let input = fixture().to_string_lossy().into_owned();
    let stderr = fails(
        &dir,
        &[
            "track",
            &input,
            "-r",
            "32",
            "-n",
            "20",
            "-o",
            "missing/c.exr",
        ],
        2,
    );
    assert!(stderr.contains("missing"), "{stderr}");
    let stderr = fails(
        &dir,
        &convert_args("no/such/v.exr", &["--vat", "--no-refine"]),
        2,
    );
    assert!(
        stderr.contains("v.exr") || stderr.contains("no/such"),
        "{stderr}"
    );
    assert_eq!(dir.files(), ["plain"], "something was left behind");
    assert!(dir.join("taken.glb").is_dir());
}

#[test]
fn invalid_parameters_exit_with_2() {
    let dir = Scratch::new("cli", "params");
    let input = fixture().to_string_lossy().into_owned();
    let cases: [(Vec<&str>, &str); 10] = [
        (
            vec![
                "convert",
                &input,
                "-r",
                "32",
                "--centers",
                "0",
                "-o",
                "x.glb",
            ],
            "centers",
        ),
        (
            vec!["track", &input, "-r", "32", "-n", "0", "-o", "c.exr"],
            "centers",
        ),
        (
            vec!["track", &input, "-r", "1", "-n", "10", "-o", "c.exr"],
            "resolution",
        ),
        (
            vec![
                "track", &input, "-r", "32", "-n", "10", "--mu", "1.5", "-o", "c.exr",
            ],
            "mu",
        ),
        (
            vec![
                "convert",
                &input,
                "-r",
                "32",
                "-n",
                "20",
                "--no-refine",
                "--basis",
                "0",
                "-o",
                "x.glb",
            ],
            "component",
        ),
        (
            vec![
                "convert",
                &input,
                "-r",
                "32",
                "-n",
                "20",
                "--no-refine",
                "--fps",
                "0",
                "-o",
                "x.pc2",
            ],
            "frame rate",
        ),
        (
            vec![
                "convert",
                &input,
                "-r",
                "32",
                "-n",
                "20",
                "--conform-stiffness",
                "0",
                "-o",
                "x.glb",
            ],
            "stiffness",
        ),
        (
            vec![
                "convert",
                &input,
                "-r",
                "32",
                "-n",
                "20",
                "--conform-bend-strain=-1",
                "-o",
                "x.glb",
            ],
            "bend strain",
        ),
        (
            vec![
                "convert",
                &input,
                "-r",
                "32",
                "-n",
                "20",
                "--conform-joint-strain=-1",
                "-o",
                "x.glb",
            ],
            "joint strain",
        ),
        (
            vec![
                "track",
                &input,
                "-r",
                "32",
                "-n",
                "10",
                "--damped-guess",
                "1",
                "-o",
                "c.exr",
            ],
            "damped guess",
        ),
    ];
    for (args, what) in cases {
        let stderr = fails(&dir, &args, 2);
        assert!(stderr.contains(what), "{args:?}: {stderr}");
    }
    // Flags clap rejects: also 2.
    fails(
        &dir,
        &["convert", &input, "--no-such-flag", "-o", "x.glb"],
        2,
    );
    fails(&dir, &["convert", &input, "-n", "many", "-o", "x.glb"], 2);
    fails(
        &dir,
        &["convert", &input, "--format", "fbx", "-o", "x.fbx"],
        2,
    );
    fails(
        &dir,
        &[
            "track",
            &input,
            "--single-guess",
            "--damped-guess",
            "0.5",
            "-o",
            "c.exr",
        ],
        2,
    );
    fails(&dir, &["convert", &input], 2);
    assert!(dir.files().is_empty(), "{:?}", dir.files());
    // A failed run leaves an existing output as it was.
    std::fs::write(dir.join("keep.glb"), b"previous result").unwrap();
    fails(
        &dir,
        &[
            "convert",
            &input,
            "-r",
            "32",
            "-n",
            "20",
            "--no-refine",
            "--basis",
            "0",
            "-o",
            "keep.glb",
        ],
        2,
    );
    assert_eq!(
        std::fs::read(dir.join("keep.glb")).unwrap(),
        b"previous result"
    );
    assert_eq!(dir.files(), ["keep.glb"]);
}

#[test]
fn unknown_output_extension_is_a_bad_parameter() {
    let dir = Scratch::new("cli", "extension");
    let stderr = fails(&dir, &convert_args("x.txt", &[]), 2);
    assert!(
        stderr.contains("x.txt") && stderr.contains("--format"),
        "{stderr}"
    );
    assert!(dir.files().is_empty());
}

#[test]
fn unknown_output_extension_fails_early_naming_the_file() {
    let dir = Scratch::new("cli", "extension-early");
    let out = run(&dir, &convert_args("x.txt", &[]));
    assert!(!out.status.success());
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains("x.txt") && stderr.contains("--format"),
        "{stderr}"
    );
    assert!(dir.files().is_empty());
}

#[test]
fn malformed_obj_is_named_with_its_line() {
    let dir = Scratch::new("cli", "garbage");
    std::fs::create_dir(dir.join("seq")).unwrap();
    std::fs::copy(fixture().join("frame_0.obj"), dir.join("seq/frame_0.obj")).unwrap();
    // Line 4 of frame_1.obj is the bad one.
    std::fs::write(
        dir.join("seq/frame_1.obj"),
        "# broken\nv 0 0 0\nv 1 0 0\nv 1 oops 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\n",
    )
    .unwrap();
    let stderr = fails(
        &dir,
        &["convert", "seq", "-r", "32", "-n", "20", "-o", "x.glb"],
        1,
    );
    assert!(stderr.contains("frame_1.obj:4"), "{stderr}");
    // A face referring past the vertices, on line 5.
    std::fs::write(
        dir.join("seq/frame_1.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 9\n",
    )
    .unwrap();
    let stderr = fails(
        &dir,
        &["track", "seq", "-r", "32", "-n", "20", "-o", "c.exr"],
        1,
    );
    assert!(stderr.contains("frame_1.obj:5"), "{stderr}");
    // A non-EXR given as trajectories.
    let input = fixture().to_string_lossy().into_owned();
    std::fs::write(dir.join("fake.exr"), "not an image").unwrap();
    let stderr = fails(&dir, &["metrics", "fake.exr", "--input", &input], 1);
    assert!(stderr.contains("fake.exr"), "{stderr}");
    assert_eq!(
        dir.files(),
        ["fake.exr", "seq/frame_0.obj", "seq/frame_1.obj"]
    );
}

#[test]
fn non_finite_vertex_is_named_at_its_own_line() {
    let dir = Scratch::new("cli", "nan");
    std::fs::create_dir(dir.join("seq")).unwrap();
    std::fs::copy(fixture().join("frame_0.obj"), dir.join("seq/frame_0.obj")).unwrap();
    // The NaN is on line 1 (the file's vertex 1), but the first face does not
    // use it, so tobj puts it 4th in its own vertex order.
    std::fs::write(
        dir.join("seq/frame_1.obj"),
        "v 0 0 nan\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 2 3 4\nf 1 2 3\n",
    )
    .unwrap();
    let stderr = fails(
        &dir,
        &["track", "seq", "-r", "32", "-n", "20", "-o", "c.exr"],
        1,
    );
    assert!(stderr.contains("frame_1.obj:1:"), "{stderr}");
}

/// An RGB float EXR read with the exr crate alone: (width, height, texels
/// row by row, row 0 first as stored).
fn exr_texels(path: &Path) -> (usize, usize, Vec<[f32; 3]>) {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .specific_channels()
        .required("R")
        .required("G")
        .required("B")
        .collect_pixels(
            |size: Vec2<usize>, _| {
                (
                    size.width(),
                    size.height(),
                    vec![[0f32; 3]; size.width() * size.height()],
                )
            },
            |(w, _, px): &mut (usize, usize, Vec<[f32; 3]>),
             p: Vec2<usize>,
             (r, g, b): (f32, f32, f32)| px[p.y() * *w + p.x()] = [r, g, b],
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .unwrap();
    image.layer_data.channel_data.pixels
}

/// Every frame of a morph-target GLB: base + Σ weight · target at each
/// frame's key (f / fps), and its triangle indices.
fn glb_frames(path: &Path) -> (Vec<Vec<[f64; 3]>>, Vec<u32>) {
    let doc = gltf::Gltf::from_slice(&std::fs::read(path).unwrap()).expect("a valid GLB");
    let blob = doc.blob.as_deref().unwrap();
    let primitive = doc.meshes().next().unwrap().primitives().next().unwrap();
    let reader = primitive.reader(|_| Some(blob));
    let base: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let targets: Vec<Vec<[f32; 3]>> = reader
        .read_morph_targets()
        .map(|(p, _, _)| p.unwrap().collect())
        .collect();
    let channel = doc.animations().next().unwrap().channels().next().unwrap();
    let weights: Vec<f32> = match channel.reader(|_| Some(blob)).read_outputs().unwrap() {
        gltf::animation::util::ReadOutputs::MorphTargetWeights(w) => w.into_f32().collect(),
        _ => panic!("not morph weights"),
    };
    let frames = weights
        .chunks(targets.len())
        .take(FRAMES)
        .map(|w| {
            (0..base.len())
                .map(|v| {
                    std::array::from_fn(|a| {
                        base[v][a] as f64
                            + targets
                                .iter()
                                .zip(w)
                                .map(|(t, &w)| w as f64 * t[v][a] as f64)
                                .sum::<f64>()
                    })
                })
                .collect()
        })
        .collect();
    (frames, reader.read_indices().unwrap().into_u32().collect())
}

/// Issue 23: the vertex-animation texture decoded as a shader does, through
/// the sidecar's layout and the mesh's TEXCOORD_1, is the GLB's animation.
#[test]
fn vat_decoded_through_sidecar_and_mesh_uvs_replays_the_glb() {
    let dir = Scratch::new("cli", "vat_round_trip");
    ok(&dir, &convert_args("anim.exr", &["--vat", "--fps", "24"]));
    ok(&dir, &convert_args("morph.glb", &["--fps", "24"]));
    assert_eq!(
        dir.files(),
        ["anim.exr", "anim.glb", "anim.json", "morph.glb"]
    );
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("anim.json")).unwrap()).unwrap();
    let int = |k: &str| info[k].as_u64().unwrap_or_else(|| panic!("{k} in {info}")) as usize;
    let (width, height, rows_per_frame) = (int("width"), int("height"), int("rows_per_frame"));
    assert_eq!((info["fps"].as_f64(), int("frames")), (Some(24.0), FRAMES));
    assert_eq!(
        (
            info["texture"].as_str(),
            info["mesh"].as_str(),
            info["uv_set"].as_str()
        ),
        (Some("anim.exr"), Some("anim.glb"), Some("TEXCOORD_1"))
    );

    let (w, h, texels) = exr_texels(&dir.join("anim.exr"));
    assert_eq!((w, h), (width, height));
    assert!(width <= 8192 && height >= FRAMES * rows_per_frame);

    // The mesh beside the texture: frame 0, the GLB's connectivity, and one
    // texel address per vertex.
    let (frames, indices) = glb_frames(&dir.join("morph.glb"));
    let doc = gltf::Gltf::from_slice(&std::fs::read(dir.join("anim.glb")).unwrap()).unwrap();
    let blob = doc.blob.as_deref().unwrap();
    assert_eq!(doc.animations().count(), 0);
    let primitive = doc.meshes().next().unwrap().primitives().next().unwrap();
    let reader = primitive.reader(|_| Some(blob));
    assert_eq!(
        reader
            .read_indices()
            .unwrap()
            .into_u32()
            .collect::<Vec<_>>(),
        indices
    );
    let uv1: Vec<[f32; 2]> = reader
        .read_tex_coords(1)
        .expect("TEXCOORD_1")
        .into_f32()
        .collect();
    assert_eq!(uv1.len(), int("vertices"));
    assert_eq!(uv1.len(), frames[0].len());
    let rest: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();

    let diagonal = {
        let all = frames.iter().flatten();
        let lo: [f64; 3] =
            std::array::from_fn(|a| all.clone().map(|p| p[a]).fold(f64::INFINITY, f64::min));
        let hi: [f64; 3] =
            std::array::from_fn(|a| all.clone().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max));
        (0..3).map(|a| (hi[a] - lo[a]).powi(2)).sum::<f64>().sqrt()
    };
    let mut worst: f64 = 0.0;
    let mut seen = std::collections::HashSet::new();
    for (v, uv) in uv1.iter().enumerate() {
        // As a shader samples: the texel under the UV, glTF's origin top-left.
        let (column, row) = (
            (uv[0] as f64 * width as f64).floor() as usize,
            (uv[1] as f64 * height as f64).floor() as usize,
        );
        assert!(
            column < width && row < rows_per_frame,
            "vertex {v}: uv {uv:?}"
        );
        assert!(seen.insert((column, row)), "vertex {v} shares its texel");
        for (f, frame) in frames.iter().enumerate() {
            let texel = texels[(row + f * rows_per_frame) * width + column];
            if f == 0 {
                assert_eq!(texel, rest[v], "vertex {v}: the mesh is not frame 0");
            }
            worst = worst.max(
                (0..3)
                    .map(|a| (texel[a] as f64 - frame[v][a]).powi(2))
                    .sum::<f64>()
                    .sqrt(),
            );
        }
    }
    assert!(
        worst <= 1e-6 * diagonal,
        "largest difference {worst} (diagonal {diagonal})"
    );
}

/// The texture's shape from the command line: powers of two, the widest row,
/// `--fps` in the sidecar; a height that cannot fit is refused before any
/// work when the frames alone exceed it, with the numbers once the mesh is
/// known; the flags are refused for other formats.
#[test]
fn vat_options_on_the_command_line() {
    let dir = Scratch::new("cli", "vat_options");
    let out = json(&ok(
        &dir,
        &convert_args(
            "p.exr",
            &[
                "--vat",
                "--vat-power-of-two",
                "--vat-max-width",
                "100",
                "--fps",
                "12",
                "--json",
            ],
        ),
    ));
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("p.json")).unwrap()).unwrap();
    let (width, height, rows) = (
        info["width"].as_u64().unwrap(),
        info["height"].as_u64().unwrap(),
        info["rows_per_frame"].as_u64().unwrap(),
    );
    assert!(
        width == 64 && height.is_power_of_two() && height >= FRAMES as u64 * rows,
        "{info}"
    );
    assert_eq!(
        (info["fps"].as_f64(), out["fps"].as_f64()),
        (Some(12.0), Some(12.0))
    );
    assert_eq!(
        out["vat"],
        serde_json::json!({"width": width, "height": height, "rows_per_frame": rows})
    );
    assert_eq!(
        out["files"],
        serde_json::json!(["p.exr", "p.glb", "p.json"])
    );

    let stderr = fails(
        &dir,
        &convert_args("short.exr", &["--vat", "--vat-max-height", "4"]),
        2,
    );
    assert!(
        stderr.contains("8 frames") && stderr.contains("--vat-max-height"),
        "{stderr}"
    );
    let stderr = fails(
        &dir,
        &convert_args(
            "narrow.exr",
            &["--vat", "--vat-max-width", "100", "--vat-max-height", "20"],
        ),
        2,
    );
    assert!(
        stderr.contains("rows per frame") && stderr.contains("--vat-max-width"),
        "{stderr}"
    );
    let stderr = fails(&dir, &convert_args("x.glb", &["--vat-power-of-two"]), 2);
    assert!(stderr.contains("vertex-animation texture"), "{stderr}");
    assert_eq!(dir.files(), ["p.exr", "p.glb", "p.json"]);
}

/// Piped to a log (as in CI), a run still shows it is alive: one line as
/// each stage begins, in pipeline order, on stderr; stdout keeps only the
/// summary (issue 48).
#[test]
fn a_run_logged_to_a_file_prints_a_line_per_stage() {
    let dir = Scratch::new("cli", "plain-progress");
    let out = run(&dir, &convert_args("a.glb", &[]));
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stderr = text(&out.stderr);
    let stages: Vec<&str> = stderr
        .lines()
        .filter_map(|l| l.strip_prefix("voltrack: ")?.strip_suffix(" ..."))
        .collect();
    assert_eq!(
        stages,
        ["read", "voxelize", "track", "refine", "deform", "conform", "fit", "export"],
        "{stderr}"
    );
    assert!(
        !text(&out.stdout).contains("voltrack: "),
        "progress on stdout"
    );
}

/// Per-frame morph targets are named after the input files (issue 48):
/// `walk_0002.obj`'s target is `walk_0002`, not the index `frame_0001`.
#[test]
fn morph_targets_are_named_after_the_input_files() {
    let dir = Scratch::new("cli", "target-names");
    std::fs::create_dir_all(dir.join("seq")).unwrap();
    for f in 0..FRAMES {
        std::fs::copy(
            fixture().join(format!("frame_{f}.obj")),
            dir.join(&format!("seq/walk_{:04}.obj", f + 1)),
        )
        .unwrap();
    }
    let mut args = vec!["convert", "seq", "-o", "a.glb"];
    args.extend(SMALL);
    ok(&dir, &args);
    let doc = gltf::Gltf::from_slice(&std::fs::read(dir.join("a.glb")).unwrap()).unwrap();
    let extras = doc
        .meshes()
        .next()
        .unwrap()
        .extras()
        .as_ref()
        .map(|e| e.get().to_string())
        .unwrap();
    let names: Vec<String> = serde_json::from_value(json(&extras)["targetNames"].clone()).unwrap();
    let want: Vec<String> = (2..=FRAMES).map(|f| format!("walk_{f:04}")).collect();
    assert_eq!(names, want);
}

/// Issue 48: `convert -h` shows what users need first, the tuning
/// parameters after, under headings.
#[test]
fn convert_help_puts_the_output_options_first_and_groups_the_rest() {
    let dir = Scratch::new("cli", "help");
    let help = ok(&dir, &["convert", "-h"]);
    let at = |needle: &str| {
        help.find(needle)
            .unwrap_or_else(|| panic!("{needle} not in:\n{help}"))
    };
    let headings = [
        "Vertex-animation texture:",
        "Tracking:",
        "Refinement:",
        "Mesh:",
    ];
    let first_heading = headings.iter().map(|h| at(h)).min().unwrap();
    for user in [
        "--output",
        "--fps",
        "--basis",
        "--compress",
        "--report",
        "--json",
    ] {
        assert!(
            at(user) < first_heading,
            "{user} after the headings:\n{help}"
        );
    }
    assert!(at("Tracking:") < at("--rho-p") && at("--rho-p") < at("Refinement:"));
    assert!(at("Refinement:") < at("--beta-hat") && at("--beta-hat") < at("Mesh:"));
    assert!(at("Mesh:") < at("--conform-stiffness"));
}

/// Issue 48: after `--resume`, the stages' seconds are this run's, not
/// copied from the interrupted run's checkpoint (the total would exceed the
/// process's time).
#[test]
fn resumed_runs_report_their_own_seconds() {
    let dir = Scratch::new("cli", "resume-seconds");
    let first = json(&ok(
        &dir,
        &convert_args("a.glb", &["--json", "--checkpoint", "ck"]),
    ));
    let again = json(&ok(
        &dir,
        &convert_args("b.glb", &["--json", "--checkpoint", "ck", "--resume"]),
    ));
    let refine = |s: &serde_json::Value| s["seconds"]["refine"].as_f64().unwrap();
    // The finished refinement is only read back: far quicker than it ran.
    assert!(
        refine(&again) < 0.5 * refine(&first),
        "{}\n{}",
        first["seconds"],
        again["seconds"]
    );
}
