//! Long runs: tracking saves its state and resumes from it with the same
//! result, byte for byte, as a run that was never interrupted.

mod common;
use common::{voxel_sequence, Scratch};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use voltrack::params::{AffinityKind, ConformParams, DeformParams, RefineParams, TrackParams};
use voltrack::pipeline::{convert, ConvertOptions};
use voltrack::progress::ProgressSink;
use voltrack::track::{track, track_with_checkpoints, Checkpointing, TrackResult};
use voltrack::{Error, Progress, Stage};

const FRAMES: usize = 12;

fn sequence() -> voltrack::voxel::VoxelSequence {
    let meshes: Vec<_> = (0..FRAMES).map(voltrack::fixtures::bending_bar).collect();
    voxel_sequence(&meshes, 40)
}

/// Asks to stop once `after` frames are tracked, like Ctrl-C would.
struct StopAfter {
    after: usize,
    stop: AtomicBool,
}

impl ProgressSink for StopAfter {
    fn report(&self, stage: Stage, done: usize, _total: usize) {
        if stage == Stage::Track && done >= self.after {
            self.stop.store(true, Ordering::Relaxed);
        }
    }
    fn cancelled(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

fn assert_same(a: &TrackResult, b: &TrackResult) {
    let bits = |r: &TrackResult| r.trajectories.positions.iter().flat_map(|p| p.coords.iter().map(|c| c.to_bits()).collect::<Vec<_>>()).collect::<Vec<_>>();
    assert!(bits(a) == bits(b), "trajectories differ");
    assert_eq!(a.cell_counts, b.cell_counts);
}

#[test]
fn interrupted_and_resumed_tracking_equals_an_uninterrupted_run() {
    let seq = sequence();
    for (kind, every, stop_after) in [(AffinityKind::Max, 1, 5), (AffinityKind::Max, 4, 6), (AffinityKind::Iir, 3, 4), (AffinityKind::Max, 5, 1)] {
        let params = TrackParams { centers: 60, affinity: kind, seed: 3, ..Default::default() };
        let whole = track(&seq, &params, Progress::none()).unwrap();

        let dir = Scratch::new("checkpoint", &format!("{kind:?}-{every}-{stop_after}"));
        let ckpt = Checkpointing { dir: dir.join("state"), every, resume: false };
        let sink = StopAfter { after: stop_after, stop: AtomicBool::new(false) };
        let err = track_with_checkpoints(&seq, &params, Some(&ckpt), Progress(Some(&sink))).unwrap_err();
        match err {
            Error::Interrupted { saved: Some((path, frames)) } => {
                assert_eq!(path, ckpt.path());
                assert_eq!(frames, stop_after, "the state after the last finished frame is saved");
            }
            e => panic!("expected an interruption, got {e}"),
        }
        assert!(dir.files().iter().all(|f| !f.contains("partial")), "no temporary file left: {:?}", dir.files());

        let resumed = track_with_checkpoints(&seq, &params, Some(&Checkpointing { resume: true, ..ckpt.clone() }), Progress::none()).unwrap();
        assert_same(&whole, &resumed);
        // The finished run is saved too: resuming it again tracks nothing and gives the same.
        let again = track_with_checkpoints(&seq, &params, Some(&Checkpointing { resume: true, ..ckpt }), Progress::none()).unwrap();
        assert_same(&whole, &again);
    }
}

#[test]
fn a_checkpoint_of_another_run_or_a_damaged_one_is_refused_with_its_name() {
    let seq = sequence();
    let params = TrackParams { centers: 60, ..Default::default() };
    let dir = Scratch::new("checkpoint", "refused");
    let ckpt = Checkpointing { dir: dir.0.clone(), every: 2, resume: false };
    track_with_checkpoints(&seq, &params, Some(&ckpt), Progress::none()).unwrap();
    let resume = Checkpointing { resume: true, ..ckpt.clone() };

    let other = TrackParams { seed: 1, ..params.clone() };
    let msg = track_with_checkpoints(&seq, &other, Some(&resume), Progress::none()).unwrap_err().to_string();
    assert!(msg.contains("track.ckpt") && msg.contains("different input"), "{msg}");

    let bytes = std::fs::read(ckpt.path()).unwrap();
    for cut in [0, 10, 30, bytes.len() / 2, bytes.len() - 1] {
        std::fs::write(ckpt.path(), &bytes[..cut]).unwrap();
        let msg = track_with_checkpoints(&seq, &params, Some(&resume), Progress::none()).unwrap_err().to_string();
        assert!(msg.contains("track.ckpt"), "cut at {cut}: {msg}");
    }
    // Without a checkpoint yet, --resume starts from the first frame.
    std::fs::remove_file(ckpt.path()).unwrap();
    let fresh = track_with_checkpoints(&seq, &params, Some(&resume), Progress::none()).unwrap();
    assert_same(&fresh, &track(&seq, &params, Progress::none()).unwrap());
}

fn write_obj(path: &Path, mesh: &voltrack::TriangleMesh) {
    let mut s = String::new();
    for p in &mesh.positions {
        s += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for t in &mesh.triangles {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, s).unwrap();
}

/// Frames tracked in a checkpoint file (its header: magic, fingerprint, frames, centers, frames done).
fn frames_done(path: &Path) -> Option<u64> {
    let bytes = std::fs::read(path).ok()?;
    Some(u64::from_le_bytes(bytes.get(40..48)?.try_into().ok()?))
}

fn voltrack(args: &[&str]) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_voltrack"));
    cmd.args(args).stdout(Stdio::null()).stderr(Stdio::piped());
    cmd
}

/// Starts `args`, waits for its first checkpoint and stops it with `signal`
/// (None: SIGKILL).
fn stop_when_saved(args: &[&str], ckpt: &Path, signal: Option<&str>) -> std::process::Output {
    let mut child = voltrack(args).spawn().unwrap();
    let start = Instant::now();
    while !ckpt.exists() {
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint written");
        std::thread::sleep(Duration::from_millis(2));
    }
    match signal {
        None => child.kill().unwrap(),
        Some(s) => assert!(Command::new("kill").args([s, &child.id().to_string()]).status().unwrap().success()),
    }
    child.wait_with_output().unwrap()
}

#[test]
fn a_killed_or_interrupted_command_resumes_to_the_same_bytes() {
    const LONG: usize = 60;
    let dir = Scratch::new("checkpoint", "cli");
    let input = dir.join("frames");
    std::fs::create_dir(&input).unwrap();
    for f in 0..LONG {
        write_obj(&input.join(format!("frame_{f:03}.obj")), &voltrack::fixtures::bending_bar(f % 16));
    }
    let out = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let input = input.to_string_lossy().into_owned();
    let base = |o: &str| -> Vec<String> { ["track", &input, "-r", "48", "-n", "100", "-o", o].map(String::from).to_vec() };
    let run = |args: &[String]| {
        let o = voltrack(&args.iter().map(String::as_str).collect::<Vec<_>>()).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };

    let whole = out("whole.exr");
    run(&base(&whole));
    let whole = std::fs::read(whole).unwrap();

    for (signal, name) in [(None, "killed"), (Some("-INT"), "interrupted")] {
        let state: PathBuf = dir.join(&format!("{name}-state"));
        let target = out(&format!("{name}.exr"));
        let mut args = base(&target);
        args.extend(["--checkpoint".into(), state.to_string_lossy().into_owned(), "--checkpoint-every".into(), "1".into()]);
        let argv: Vec<&str> = args.iter().map(String::as_str).collect();
        let stopped = stop_when_saved(&argv, &state.join("track.ckpt"), signal);
        assert!(!Path::new(&target).exists(), "{name}: no output from a stopped run");
        if signal.is_some() {
            assert_eq!(stopped.status.code(), Some(130), "{name}: exit status");
            let err = String::from_utf8_lossy(&stopped.stderr);
            assert!(err.contains("--resume") && err.contains("track.ckpt"), "{name}: {err}");
        }
        let k = frames_done(&state.join("track.ckpt")).expect("a complete checkpoint");
        assert!(k >= 2 && k < LONG as u64, "{name}: stopped after frame {k} of {LONG}");

        args.push("--resume".into());
        run(&args);
        assert!(std::fs::read(&target).unwrap() == whole, "{name} after frame {k} and resumed: EXR differs from the uninterrupted run");
    }
}

/// Asks to stop as soon as its stage starts, like Ctrl-C would.
struct StopAt(Stage, AtomicBool);

impl ProgressSink for StopAt {
    fn report(&self, stage: Stage, _done: usize, _total: usize) {
        if stage == self.0 {
            self.1.store(true, Ordering::Relaxed);
        }
    }
    fn cancelled(&self) -> bool {
        self.1.load(Ordering::Relaxed)
    }
}

#[test]
fn interrupted_while_conforming_names_the_finished_tracking_and_resumes() {
    let inputs = [PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/bending_bar"))];
    let voxel = voltrack::voxel::VoxelParams { resolution: 48, ..Default::default() };
    let track = TrackParams { centers: 100, ..Default::default() };
    let (refine, deform, conform) = (RefineParams::default(), DeformParams::default(), ConformParams::default());
    let files = voltrack::io::FrameFiles::discover(&inputs).unwrap();
    let run = |ckpt: Option<&Checkpointing>, progress| {
        let options = ConvertOptions { voxel: voxel.clone(), track: track.clone(), refine: Some(refine.clone()), deform: deform.clone(), conform: conform.clone(), checkpoint: ckpt.cloned(), ..Default::default() };
        convert(&files, &options, progress)
    };
    let dir = Scratch::new("checkpoint", "conform");
    let ckpt = Checkpointing { dir: dir.join("state"), every: 4, resume: false };
    let sink = StopAt(Stage::Conform, AtomicBool::new(false));
    match run(Some(&ckpt), Progress(Some(&sink))).map(|_| ()).unwrap_err() {
        Error::Interrupted { saved: Some((path, frames)) } => {
            assert_eq!(path, ckpt.path());
            assert_eq!(frames, voltrack::fixtures::BENDING_BAR_FRAMES, "every frame was tracked");
        }
        other => panic!("expected an interruption naming the checkpoint, got {other}"),
    }
    // Resumed, it ends as a run that was never interrupted.
    let resumed = run(Some(&Checkpointing { resume: true, ..ckpt }), Progress::none()).unwrap();
    let whole = run(None, Progress::none()).unwrap();
    assert_eq!(resumed.mesh.frames, whole.mesh.frames);
}
