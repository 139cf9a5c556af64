//! Mistakes are caught before the work starts, and writing never destroys
//! what is not voltrack's. Each case here once failed only after the whole
//! pipeline had run, or panicked, or replaced something it should not.
//!
//! "Before the work starts" is tested by a sequence whose frame 5 is not a
//! mesh: a command that validated late would stop there, naming that frame
//! (exit 1); one that validates first refuses with exit 2 and never reads it.

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;
use common::Scratch;

const BIN: &str = env!("CARGO_BIN_EXE_voltrack");
const SMALL: [&str; 4] = ["-r", "32", "-n", "20"];

fn run(dir: &Scratch, args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(&dir.0)
        .output()
        .expect("run voltrack")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// An 8-frame bending bar in `seq/`.
fn bar_sequence(dir: &Scratch) {
    let seq = dir.0.join("seq");
    std::fs::create_dir_all(&seq).unwrap();
    for f in 0..8 {
        std::fs::write(
            seq.join(format!("frame_{f}.obj")),
            common::obj_bytes(&voltrack::fixtures::bending_bar(f)),
        )
        .unwrap();
    }
}

/// The bending bar with frame 5 replaced by garbage.
fn poisoned_sequence(dir: &Scratch) {
    bar_sequence(dir);
    std::fs::write(dir.0.join("seq/frame_5.obj"), "v 0 0 0\nf 1 2 3 x\n").unwrap();
}

/// Runs `args` and requires exit 2 with each needle on stderr and without
/// reading frame 5 (which would fail naming it): refused before any frame.
fn refused_up_front(dir: &Scratch, args: &[&str], needles: &[&str]) {
    let out = run(dir, args);
    let err = stderr(&out);
    assert_eq!(
        out.status.code(),
        Some(2),
        "{args:?}: exit {:?}, stderr: {err}",
        out.status.code()
    );
    assert!(
        !err.contains("frame_5"),
        "{args:?} read the frames first: {err}"
    );
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: stderr lacks {n:?}: {err}");
    }
}

#[test]
fn parameters_that_used_to_fail_late_or_panic_are_refused_before_reading() {
    let dir = Scratch::new("early", "refuse-params");
    poisoned_sequence(&dir);
    let cases: &[(&[&str], &[&str])] = &[
        (&["--beta", "1e308"], &["beta"]),
        (&["--beta-hat", "inf"], &["beta_hat"]),
        (&["--fps", "1e-40"], &["frame rate"]),
        (&["--bind-neighbors", "0"], &["centers each vertex follows"]),
        (&["--batches", "0"], &["batches"]),
        (&["--lloyd-iterations", "0"], &["Lloyd iterations"]),
        (
            &["--tracking-over-relaxation", "2"],
            &["tracking over-relaxation"],
        ),
        (&["--rho-gp", "inf"], &["rho_gp"]),
        (&["--remove", "18446744073709551615"], &["cannot remove"]),
        (
            &["--conform-iterations", "18446744073709551615"],
            &["conform iterations"],
        ),
        (&["-n", "1"], &["at least 3 centers"]),
        (&["--cell-memory", "0"], &["memory for kept cells"]),
        (&["--cell-memory", "nan"], &["memory for kept cells"]),
        (&["--screening-block", "9"], &["screening block"]),
        (&["--basis", "many"], &["'many'", "auto"]),
        (
            &["--reference", "8"],
            &["reference frame 8", "past the last frame (7)"],
        ),
        (&["--reference", "middle"], &["'middle'", "auto, first"]),
        (
            &["--reference", "3", "--checkpoint", "ck"],
            &["reference frame 3", "checkpoint"],
        ),
    ];
    for (extra, needles) in cases {
        let mut args = vec!["convert", "seq", "-o", "x.glb"];
        args.extend_from_slice(&SMALL[..2]);
        args.extend_from_slice(extra);
        if !extra.contains(&"-n") {
            args.extend_from_slice(&SMALL[2..]);
        }
        refused_up_front(&dir, &args, needles);
    }
    for extra in [
        &["--beta", "1e308"][..],
        &["--beta-hat", "inf"],
        &["--reference", "9"],
        &["--reference", "1", "--checkpoint", "ck"],
    ] {
        let mut args = vec!["track", "seq", "-o", "t.exr", "--refine"];
        args.extend_from_slice(&SMALL);
        args.extend_from_slice(extra);
        refused_up_front(&dir, &args, &[]);
    }
    assert!(!dir.0.join("x.glb").exists() && !dir.0.join("t.exr").exists());
    assert!(!dir.0.join("ck").exists());
}

#[test]
fn conflicting_flags_are_refused() {
    let dir = Scratch::new("early", "refuse-conflicts");
    poisoned_sequence(&dir);
    for extra in [
        &["--vat", "--format", "glb", "-o", "x.glb"][..],
        &["--no-refine", "--remove", "5", "-o", "x.glb"],
        &["--format", "exr", "-o", "x.glb"],
        &["--vat", "-o", "x.glb"],
        &["--basis", "4", "-o", "x.pc2"],
        &["--basis", "auto", "-o", "x.pc2"],
    ] {
        let mut args = vec!["convert", "seq"];
        args.extend_from_slice(&SMALL);
        args.extend_from_slice(extra);
        refused_up_front(&dir, &args, &[]);
    }
}

#[test]
fn output_locations_that_take_no_file_are_refused_before_reading() {
    let dir = Scratch::new("early", "refuse-places");
    poisoned_sequence(&dir);
    std::fs::write(dir.0.join("a_file"), "not a folder").unwrap();
    // A trailing slash names a folder, not the file it would be renamed to.
    refused_up_front(
        &dir,
        &["convert", "seq", "-r", "32", "-n", "20", "-o", "x.glb/"],
        &["x.glb/"],
    );
    // A checkpoint "folder" that is a file: said plainly, not "File exists".
    refused_up_front(
        &dir,
        &[
            "convert",
            "seq",
            "-r",
            "32",
            "-n",
            "20",
            "-o",
            "x.glb",
            "--checkpoint",
            "a_file",
        ],
        &["a_file", "folder"],
    );
    refused_up_front(
        &dir,
        &[
            "track",
            "seq",
            "-r",
            "32",
            "-n",
            "20",
            "-o",
            "t.exr",
            "--checkpoint",
            "a_file",
        ],
        &["a_file", "folder"],
    );
    // A folder that takes no new file: read-only for a normal user; root
    // writes anywhere on a normal file system, so /proc stands in.
    let ro = dir.0.join("read_only");
    std::fs::create_dir(&ro).unwrap();
    let mut perms = std::fs::metadata(&ro).unwrap().permissions();
    perms.set_readonly(true);
    std::fs::set_permissions(&ro, perms).unwrap();
    let place = if std::fs::write(ro.join("probe"), "").is_ok() {
        "/proc/voltrack-test.glb".to_string()
    } else {
        "read_only/x.glb".to_string()
    };
    refused_up_front(
        &dir,
        &["convert", "seq", "-r", "32", "-n", "20", "-o", &place],
        &["does not take new files"],
    );
    refused_up_front(
        &dir,
        &[
            "convert",
            "seq",
            "-r",
            "32",
            "-n",
            "20",
            "-o",
            "x.glb",
            "--report",
            &place.replace(".glb", ".html"),
        ],
        &["does not take new files"],
    );
}

#[test]
fn a_temporary_folder_that_takes_no_file_is_refused_before_reading() {
    // A long sequence's mesh goes to a temporary file: a TMPDIR that takes
    // none must fail now, not after tracking.
    let dir = Scratch::new("early", "tmpdir");
    poisoned_sequence(&dir);
    let missing = dir.0.join("no_such_folder");
    let out = Command::new(BIN)
        .args(["convert", "seq", "-r", "32", "-n", "20", "-o", "x.glb"])
        .env("TMPDIR", &missing)
        .current_dir(&dir.0)
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("no_such_folder") && err.contains("TMPDIR") && !err.contains("frame_5"),
        "{err}"
    );
    assert!(!dir.0.join("x.glb").exists());
}

#[test]
fn a_resolution_that_cannot_fit_in_memory_is_refused_with_one_that_fits() {
    let dir = Scratch::new("early", "refuse-memory");
    bar_sequence(&dir);
    let clock = Instant::now();
    let out = run(
        &dir,
        &[
            "convert",
            "seq",
            "-r",
            "1596",
            "-n",
            "50",
            "-o",
            "x.glb",
            "--max-memory",
            "2",
        ],
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        // Refused before voxelising (which takes minutes at -r 1596): a
        // guard against that, not a speed figure.
        clock.elapsed() < Duration::from_secs(30),
        "took {:?}",
        clock.elapsed()
    );
    assert!(
        err.contains("the largest resolution that fits is about"),
        "{err}"
    );
    // The resolution it names does fit under the same limit.
    let fits: usize = err
        .split("fits is about ")
        .nth(1)
        .unwrap()
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((2..1596).contains(&fits), "{err}");
    let grid = voltrack::model::GridSpec::for_bounds(&bar_bounds(), fits).unwrap();
    let meshes: Vec<_> = (0..8).map(voltrack::fixtures::bending_bar).collect();
    let refs: Vec<_> = meshes.iter().collect();
    let estimate =
        voltrack::voxel::MemoryEstimate::of(&refs, &grid, rayon::current_num_threads().max(2));
    let limit = 2.0 * (1u64 << 30) as f64;
    assert!(
        estimate.total(limit) <= limit,
        "{} bytes at resolution {fits}",
        estimate.total(limit)
    );
    assert!(!dir.0.join("x.glb").exists());
}

fn bar_bounds() -> voltrack::Aabb {
    (0..8)
        .map(|f| voltrack::fixtures::bending_bar(f).bounding_box())
        .fold(voltrack::Aabb::empty(), |a, b| a.union(&b))
}

#[test]
fn the_memory_estimate_is_not_below_what_a_run_holds() {
    // Occupied voxels counted by voxelising must not exceed the estimate's
    // share for them (4 bytes each of its 24 per voxel would be the index alone).
    let meshes: Vec<_> = (0..3).map(voltrack::fixtures::bending_bar).collect();
    let grid = voltrack::model::GridSpec::for_bounds(&bar_bounds(), 64).unwrap();
    let refs: Vec<_> = meshes.iter().collect();
    let full = voltrack::voxel::MemoryEstimate::of(&refs, &grid, 1);
    // The sequence's voxels and the kept assignments.
    let estimate = full.bytes + full.kept_cells;
    let occupied: Vec<usize> = meshes
        .iter()
        .map(|m| voltrack::voxel::voxelize(m, &grid).len())
        .collect();
    let all: usize = occupied.iter().sum();
    assert!(
        estimate >= 16.0 * all as f64,
        "estimate {estimate} for {all} voxels"
    );
    assert!(
        estimate <= 64.0 * all as f64 + 1e6,
        "estimate {estimate} for {all} voxels"
    );
    // The tracker's cells of the largest frame: about 175 bytes a voxel
    // measured (docs/measurements.md), so at least that.
    let largest = *occupied.iter().max().unwrap() as f64;
    assert!(
        full.tracking >= 175.0 * largest && full.tracking <= 512.0 * largest,
        "tracking {} for {largest} voxels",
        full.tracking
    );
    // The result's mesh in every frame, 12 bytes a vertex at the least.
    let vertices = (meshes[0].positions.len() * meshes.len()) as f64;
    assert!(full.mesh_stages >= 12.0 * vertices);
}

#[cfg(unix)]
#[test]
fn devices_and_fifos_are_written_through_not_replaced() {
    use std::os::unix::fs::FileTypeExt;
    let dir = Scratch::new("early", "special-outputs");
    bar_sequence(&dir);
    // /dev/null stays a device (as root the rename used to replace it).
    if std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/null")
        .is_ok()
    {
        let out = run(
            &dir,
            &[
                "convert",
                "seq",
                "-r",
                "32",
                "-n",
                "20",
                "--conform-iterations",
                "0",
                "-o",
                "/dev/null",
                "--format",
                "glb",
            ],
        );
        assert!(out.status.success(), "{}", stderr(&out));
        assert!(std::fs::metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device());
    }
    // A FIFO gets the file's bytes and stays a FIFO.
    let fifo = dir.0.join("pipe.glb");
    if !Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        return;
    }
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(&fifo).unwrap())
    };
    let out = run(
        &dir,
        &[
            "convert",
            "seq",
            "-r",
            "32",
            "-n",
            "20",
            "--conform-iterations",
            "0",
            "-o",
            "pipe.glb",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let bytes = reader.join().unwrap();
    assert!(bytes.starts_with(b"glTF"), "{} bytes", bytes.len());
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
    // A symlinked output replaces the file it names and keeps the link.
    std::fs::write(dir.0.join("target.glb"), "old").unwrap();
    std::os::unix::fs::symlink("target.glb", dir.0.join("link.glb")).unwrap();
    let out = run(
        &dir,
        &[
            "convert",
            "seq",
            "-r",
            "32",
            "-n",
            "20",
            "--conform-iterations",
            "0",
            "-o",
            "link.glb",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(std::fs::symlink_metadata(dir.0.join("link.glb"))
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(std::fs::read(dir.0.join("target.glb"))
        .unwrap()
        .starts_with(b"glTF"));
}

#[test]
fn a_texture_glb_cannot_carry_is_left_out_at_once_not_failed_at_export() {
    let dir = Scratch::new("early", "tga-texture");
    bar_sequence(&dir);
    let seq = dir.0.join("seq");
    // Frame 0 gets UVs and a TGA texture through its MTL.
    let obj = std::fs::read_to_string(seq.join("frame_0.obj")).unwrap();
    let vertices = obj.lines().filter(|l| l.starts_with("v ")).count();
    let mut text = String::from("mtllib skin.mtl\nusemtl skin\n");
    for k in 0..vertices {
        text.push_str(&format!("vt {} 0.5\n", k as f64 / vertices as f64));
    }
    for line in obj.lines() {
        if let Some(rest) = line.strip_prefix("f ") {
            let corners: Vec<String> = rest
                .split_whitespace()
                .map(|c| format!("{c}/{c}"))
                .collect();
            text.push_str(&format!("f {}\n", corners.join(" ")));
        } else {
            text.push_str(line);
            text.push('\n');
        }
    }
    std::fs::write(seq.join("frame_0.obj"), text).unwrap();
    std::fs::write(seq.join("skin.mtl"), "newmtl skin\nmap_Kd skin.tga\n").unwrap();
    std::fs::write(
        seq.join("skin.tga"),
        [
            0u8, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 1, 0, 24, 0, 255, 255, 255,
        ],
    )
    .unwrap();
    let out = run(
        &dir,
        &[
            "convert",
            "seq",
            "-r",
            "32",
            "-n",
            "20",
            "--conform-iterations",
            "0",
            "-o",
            "x.glb",
        ],
    );
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("skin.tga") && err.contains("neither PNG nor JPEG"),
        "{err}"
    );
    assert!(Path::new(&dir.0.join("x.glb")).exists());
}

#[test]
fn an_output_a_rerun_would_read_as_a_frame_is_refused_for_patterns_too() {
    let dir = Scratch::new("early", "pattern-pickup");
    bar_sequence(&dir);
    // One take in two folders of four frames each, read through a wildcard
    // directory.
    for take in 0..2 {
        let t = dir.0.join(format!("takes/take_{take}"));
        std::fs::create_dir_all(&t).unwrap();
        for f in 4 * take..4 * take + 4 {
            std::fs::copy(
                dir.0.join(format!("seq/frame_{f}.obj")),
                t.join(format!("frame_{f}.obj")),
            )
            .unwrap();
        }
    }
    let pattern = "takes/take_*/*.obj";
    // The point cache's OBJ would land among the frames the pattern takes.
    refused_up_front(
        &dir,
        &[
            "convert",
            pattern,
            "-r",
            "32",
            "-n",
            "20",
            "-o",
            "takes/take_1/anim.pc2",
        ],
        &["takes/take_1/anim.obj", "next run"],
    );
    // Not matched by the pattern: written.
    let out = run(
        &dir,
        &[
            "convert",
            pattern,
            "-r",
            "32",
            "-n",
            "20",
            "--conform-iterations",
            "0",
            "-o",
            "takes/take_1/anim.glb",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(!dir.0.join("takes/take_1/anim.obj").exists());
}
