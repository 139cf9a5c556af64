//! Long runs: tracking saves its state and resumes from it with the same
//! result, byte for byte, as a run that was never interrupted.

mod common;
use common::{voxel_sequence, Scratch};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use voltrack::error::Saved;
use voltrack::params::{AffinityKind, ConformParams, DeformParams, RefineParams, TrackParams};
use voltrack::pipeline::{convert, ConvertOptions};
use voltrack::progress::ProgressSink;
use voltrack::refine::{refine, refine_with_checkpoints, RefineResult};
use voltrack::track::{track, track_with_checkpoints, Checkpointing, TrackResult};
use voltrack::{Error, Progress, Stage};

const FRAMES: usize = 12;

fn sequence() -> voltrack::voxel::VoxelSequence {
    let meshes: Vec<_> = (0..FRAMES).map(voltrack::fixtures::bending_bar).collect();
    voxel_sequence(&meshes, 40)
}

/// Asks to stop once `stage` reports `after` steps done (frames tracked,
/// refinement iterations), like Ctrl-C would.
struct StopAfter {
    stage: Stage,
    after: usize,
    stop: AtomicBool,
}

impl ProgressSink for StopAfter {
    fn report(&self, stage: Stage, done: usize, _total: usize) {
        if stage == self.stage && done >= self.after {
            self.stop.store(true, Ordering::Relaxed);
        }
    }
    fn cancelled(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

fn assert_same(a: &TrackResult, b: &TrackResult) {
    let bits = |r: &TrackResult| {
        r.trajectories
            .positions
            .iter()
            .flat_map(|p| p.coords.iter().map(|c| c.to_bits()).collect::<Vec<_>>())
            .collect::<Vec<_>>()
    };
    assert!(bits(a) == bits(b), "trajectories differ");
    assert_eq!(a.cell_counts, b.cell_counts);
}

/// Asks to stop from the `after + 1`-th time the tracker polls it once frame
/// 0 is placed (the placement polls too, at every Lloyd step), which is
/// inside a frame's iterations (the damped and the undamped guess both poll,
/// on two threads, but the frame in which the count is reached does not
/// depend on their interleaving). Remembers the last frame count reported.
struct StopAtPoll {
    after: usize,
    polls: AtomicUsize,
    reported: AtomicUsize,
}

impl ProgressSink for StopAtPoll {
    fn report(&self, stage: Stage, done: usize, _total: usize) {
        if stage == Stage::Track {
            self.reported.store(done, Ordering::Relaxed);
        }
    }
    fn cancelled(&self) -> bool {
        self.reported.load(Ordering::Relaxed) >= 1
            && self.polls.fetch_add(1, Ordering::Relaxed) >= self.after
    }
}

/// Runs `params` on `seq` with checkpoints in `ckpt`, expects it to be
/// interrupted by `sink`, and returns the frames the error says are saved.
fn interrupted(
    seq: &voltrack::voxel::VoxelSequence,
    params: &TrackParams,
    ckpt: &Checkpointing,
    sink: &dyn ProgressSink,
) -> usize {
    match track_with_checkpoints(seq, params, Some(ckpt), Progress(Some(sink))) {
        Err(Error::Interrupted {
            saved:
                Some(Saved {
                    path,
                    frames,
                    refine: None,
                }),
        }) => {
            assert_eq!(path, ckpt.path());
            frames
        }
        Err(e) => panic!("expected an interruption, got {e}"),
        Ok(_) => panic!("expected an interruption, the tracking ran to the end"),
    }
}

/// Stopped between frames (after a known frame, through the progress
/// callback the CLI's Ctrl-C handler uses), the tracker saves the frames it
/// finished; resumed (once, or interrupted again and resumed again), it ends
/// with trajectories and cell counts bit-identical to a run never
/// interrupted, whatever the checkpoint interval and affinity kind.
#[test]
fn interrupted_and_resumed_tracking_equals_an_uninterrupted_run() {
    let seq = sequence();
    // (affinity, checkpoint interval, first stop, second stop)
    for (kind, every, first, second) in [
        (AffinityKind::Max, 1, 5, None),
        (AffinityKind::Max, 4, 6, Some(9)),
        (AffinityKind::Iir, 3, 4, Some(7)),
        (AffinityKind::Max, 5, 1, Some(2)),
    ] {
        let params = TrackParams {
            centers: 60,
            affinity: kind,
            seed: 3,
            ..Default::default()
        };
        let whole = track(&seq, &params, Progress::none()).unwrap();

        let dir = Scratch::new("checkpoint", &format!("{kind:?}-{every}-{first}"));
        let ckpt = Checkpointing {
            dir: dir.join("state"),
            every,
            ..Checkpointing::new("")
        };
        let frames = interrupted(
            &seq,
            &params,
            &ckpt,
            &StopAfter {
                stage: Stage::Track,
                after: first,
                stop: AtomicBool::new(false),
            },
        );
        assert_eq!(
            frames, first,
            "the state after the last finished frame is saved"
        );
        assert!(
            dir.files().iter().all(|f| !f.contains("partial")),
            "no temporary file left: {:?}",
            dir.files()
        );

        let resume = Checkpointing {
            resume: true,
            ..ckpt.clone()
        };
        if let Some(second) = second {
            let frames = interrupted(
                &seq,
                &params,
                &resume,
                &StopAfter {
                    stage: Stage::Track,
                    after: second,
                    stop: AtomicBool::new(false),
                },
            );
            assert_eq!(
                frames, second,
                "resumed and interrupted again: the state after frame {second} is saved"
            );
        }
        let resumed =
            track_with_checkpoints(&seq, &params, Some(&resume), Progress::none()).unwrap();
        assert_same(&whole, &resumed);
        // The finished run is saved too: resuming it again tracks nothing and gives the same.
        let again = track_with_checkpoints(&seq, &params, Some(&resume), Progress::none()).unwrap();
        assert_same(&whole, &again);
    }
}

/// Stopped in the middle of a frame's iterations (at a fixed poll count), the
/// tracker abandons that frame, saves the frames before it (the frame count
/// it last reported) and, resumed, ends bit-identical to a run never
/// interrupted: an abandoned frame leaves no trace in the state. With and
/// without the damped second guess (which tracks each frame twice, on copies).
#[test]
fn a_frame_abandoned_midway_leaves_no_trace_after_resuming() {
    let seq = sequence();
    for damped_guess in [Some(0.25), None] {
        let params = TrackParams {
            centers: 60,
            seed: 5,
            damped_guess,
            ..Default::default()
        };
        let whole = track(&seq, &params, Progress::none()).unwrap();
        let mut stopped_in = Vec::new();
        for after in [0, 40, 150, 300] {
            let dir = Scratch::new(
                "checkpoint",
                &format!("midway-{}-{after}", damped_guess.is_some()),
            );
            let ckpt = Checkpointing {
                dir: dir.join("state"),
                every: 100,
                ..Checkpointing::new("")
            };
            let sink = StopAtPoll {
                after,
                polls: AtomicUsize::new(0),
                reported: AtomicUsize::new(0),
            };
            let frames = interrupted(&seq, &params, &ckpt, &sink);
            let reported = sink.reported.load(Ordering::Relaxed);
            assert_eq!(
                frames, reported,
                "damped {damped_guess:?}, stop at poll {after}: the frames reported done are saved"
            );
            assert!(
                (1..FRAMES).contains(&frames),
                "stopped after {frames} of {FRAMES} frames"
            );
            stopped_in.push(frames);
            let resumed = track_with_checkpoints(
                &seq,
                &params,
                Some(&Checkpointing {
                    resume: true,
                    ..ckpt
                }),
                Progress::none(),
            )
            .unwrap();
            assert_same(&whole, &resumed);
        }
        // Poll 0 is the first iteration of frame 1, poll 40 midway through
        // it; 150 and 300 fall in later frames (3 and 5 with the damped
        // guess, 5 and 10 without).
        stopped_in.dedup();
        assert!(
            stopped_in.len() >= 3,
            "damped {damped_guess:?}: stops fell in frames {stopped_in:?}"
        );
    }
}

/// A checkpoint holds no wall-clock or interval state that changes the
/// result: saved every frame and resumed with another interval, the run ends
/// as one never interrupted.
#[test]
fn resuming_with_another_checkpoint_interval_gives_the_same_result() {
    let seq = sequence();
    let params = TrackParams {
        centers: 60,
        seed: 9,
        ..Default::default()
    };
    let whole = track(&seq, &params, Progress::none()).unwrap();
    let dir = Scratch::new("checkpoint", "interval");
    let ckpt = Checkpointing {
        dir: dir.join("state"),
        every: 1,
        ..Checkpointing::new("")
    };
    assert_eq!(
        interrupted(
            &seq,
            &params,
            &ckpt,
            &StopAfter {
                stage: Stage::Track,
                after: 7,
                stop: AtomicBool::new(false)
            }
        ),
        7
    );
    let resumed = track_with_checkpoints(
        &seq,
        &params,
        Some(&Checkpointing {
            every: 3,
            resume: true,
            ..ckpt
        }),
        Progress::none(),
    )
    .unwrap();
    assert_same(&whole, &resumed);
}

/// Resuming refuses, with an error that names the checkpoint file, a
/// checkpoint saved by another run (other seed, number of centers, affinity,
/// resolution or frames) and a damaged one (cut anywhere, with a byte
/// appended, one bit flipped, every byte inverted, another file's content,
/// empty), and leaves the file as it found it. The tests know nothing of the
/// file's layout.
/// Without a checkpoint yet, resuming starts from the first frame.
#[test]
fn a_checkpoint_of_another_run_or_a_damaged_one_is_refused_with_its_name() {
    let seq = sequence();
    let params = TrackParams {
        centers: 60,
        ..Default::default()
    };
    let dir = Scratch::new("checkpoint", "refused");
    let ckpt = Checkpointing {
        dir: dir.0.clone(),
        every: 2,
        ..Checkpointing::new("")
    };
    let whole = track_with_checkpoints(&seq, &params, Some(&ckpt), Progress::none()).unwrap();
    let resume = Checkpointing {
        resume: true,
        ..ckpt.clone()
    };
    let saved = std::fs::read(ckpt.path()).unwrap();
    let refused =
        |seq: &voltrack::voxel::VoxelSequence, params: &TrackParams, what: &str| -> String {
            let before = std::fs::read(ckpt.path()).unwrap();
            let msg = match track_with_checkpoints(seq, params, Some(&resume), Progress::none()) {
                Ok(_) => panic!("{what}: resumed"),
                Err(e @ Error::Interrupted { .. }) => panic!("{what}: {e}"),
                Err(e) => e.to_string(),
            };
            assert!(
                msg.contains("track.ckpt"),
                "{what}: the error does not name the file: {msg}"
            );
            assert!(
                std::fs::read(ckpt.path()).unwrap() == before,
                "{what}: the checkpoint was changed"
            );
            msg
        };

    // Another run's: the checkpoint is intact, the command differs.
    let fewer: Vec<_> = (0..FRAMES - 1)
        .map(voltrack::fixtures::bending_bar)
        .collect();
    let others = [
        (
            "another seed",
            sequence(),
            TrackParams {
                seed: 1,
                ..params.clone()
            },
        ),
        (
            "more centers",
            sequence(),
            TrackParams {
                centers: 61,
                ..params.clone()
            },
        ),
        (
            "the other affinity",
            sequence(),
            TrackParams {
                affinity: AffinityKind::Iir,
                ..params.clone()
            },
        ),
        (
            "another resolution",
            voxel_sequence(
                &(0..FRAMES)
                    .map(voltrack::fixtures::bending_bar)
                    .collect::<Vec<_>>(),
                36,
            ),
            params.clone(),
        ),
        (
            "one frame fewer",
            voxel_sequence(&fewer, 40),
            params.clone(),
        ),
    ];
    for (what, seq, params) in &others {
        let msg = refused(seq, params, what);
        assert!(msg.contains("different input"), "{what}: {msg}");
    }

    // Damaged: whatever the layout, a prefix of the file, a longer file or
    // other bytes are not this run's state.
    let mut damaged: Vec<(String, Vec<u8>)> = Vec::new();
    let stride = (saved.len() / 200).max(1);
    for cut in (0..saved.len()).step_by(stride).chain([saved.len() - 1]) {
        damaged.push((
            format!("cut to {cut} of {} bytes", saved.len()),
            saved[..cut].to_vec(),
        ));
    }
    damaged.push(("one byte appended".into(), [&saved[..], &[0]].concat()));
    // One bit flipped anywhere: the checksum refuses it, where the layout
    // alone would read most such files as a valid state.
    for at in (0..saved.len()).step_by(stride).chain([saved.len() - 1]) {
        let mut flipped = saved.clone();
        flipped[at] ^= 1 << (at % 8);
        damaged.push((format!("bit {} of byte {at} flipped", at % 8), flipped));
    }
    damaged.push((
        "every byte inverted".into(),
        saved.iter().map(|b| !b).collect(),
    ));
    damaged.push((
        "an OBJ file".into(),
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec(),
    ));
    damaged.push(("empty".into(), Vec::new()));
    for (what, bytes) in &damaged {
        std::fs::write(ckpt.path(), bytes).unwrap();
        refused(&seq, &params, what);
    }

    // The intact file still resumes (to the end: nothing left to track).
    std::fs::write(ckpt.path(), &saved).unwrap();
    assert_same(
        &whole,
        &track_with_checkpoints(&seq, &params, Some(&resume), Progress::none()).unwrap(),
    );
    // Without a checkpoint yet, --resume starts from the first frame.
    std::fs::remove_file(ckpt.path()).unwrap();
    let fresh = track_with_checkpoints(&seq, &params, Some(&resume), Progress::none()).unwrap();
    assert_same(&fresh, &whole);
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

fn voltrack(args: &[&str]) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_voltrack"));
    cmd.args(args).stdout(Stdio::null()).stderr(Stdio::piped());
    cmd
}

/// Starts `args` and stops it with `signal` (None: SIGKILL) as soon as its
/// checkpoint file first exists. Whether the signal lands before the end of
/// tracking is not up to the test; the caller checks what must hold either way.
fn stop_when_saved(args: &[&str], ckpt: &Path, signal: Option<&str>) -> std::process::Output {
    let mut child = voltrack(args).spawn().unwrap();
    while !ckpt.exists() {
        // Every frame is saved: a run that ends without a checkpoint is a failure, not a slow machine.
        if child.try_wait().unwrap().is_some() {
            let out = child.wait_with_output().unwrap();
            panic!(
                "ended ({}) without writing {}: {}",
                out.status,
                ckpt.display(),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    match signal {
        None => child.kill().unwrap(),
        Some(s) => assert!(Command::new("kill")
            .args([s, &child.id().to_string()])
            .status()
            .unwrap()
            .success()),
    }
    child.wait_with_output().unwrap()
}

/// Runs `args` with `--checkpoint` `state` (and `extra`), stops it with
/// `signal` (None: SIGKILL) once `state/file` exists, and checks what must
/// hold either way: finished, it wrote `whole` (then removed for the rerun);
/// stopped, no output, and after SIGINT exit status 130 and a message that
/// `interrupted` checks. Returns the arguments to resume with.
#[allow(clippy::too_many_arguments)]
fn stop_once_saved(
    mut args: Vec<String>,
    state: &Path,
    extra: &[&str],
    file: &str,
    signal: Option<&str>,
    target: &str,
    whole: &[u8],
    interrupted: impl Fn(&str),
) -> Vec<String> {
    args.extend(["--checkpoint".into(), state.to_string_lossy().into_owned()]);
    args.extend(extra.iter().map(|a| a.to_string()));
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let stopped = stop_when_saved(&argv, &state.join(file), signal);
    let err = String::from_utf8_lossy(&stopped.stderr);
    if stopped.status.success() {
        // The signal landed after the stage (or after the process ended).
        println!("{target}: the run had finished the stage before the signal");
        assert!(
            std::fs::read(target).unwrap() == whole,
            "{target}, not stopped: differs from the uninterrupted run"
        );
        std::fs::remove_file(target).unwrap();
    } else {
        assert!(
            !Path::new(target).exists(),
            "{target}: no output from a stopped run"
        );
        if signal.is_some() {
            assert_eq!(
                stopped.status.code(),
                Some(130),
                "{target}: exit status; {err}"
            );
            assert!(err.contains("--resume"), "{target}: {err}");
            interrupted(&err);
        }
        println!("{target}: stopped ({})", stopped.status);
    }
    args.push("--resume".into());
    args
}

/// The command killed (SIGKILL) or interrupted (SIGINT, as Ctrl-C) once its
/// checkpoint file exists, then rerun with --resume, writes an EXR
/// byte-identical to an uninterrupted run's. The signal is sent after the
/// first checkpoint is saved but may land at any later point, so both
/// outcomes are accepted and checked: stopped (no output written; after
/// SIGINT, exit status 130 and a message naming --resume, the checkpoint and
/// the frames it holds, fewer than all) or finished (exit 0, the same EXR).
/// Either way the checkpoint left behind is complete (saves are atomic), and
/// the rerun resumes from it rather than starting over.
#[test]
fn a_killed_or_interrupted_command_resumes_to_the_same_bytes() {
    const LONG: usize = 60;
    let dir = Scratch::new("checkpoint", "cli");
    let input = dir.join("frames");
    std::fs::create_dir(&input).unwrap();
    for f in 0..LONG {
        write_obj(
            &input.join(format!("frame_{f:03}.obj")),
            &voltrack::fixtures::bending_bar(f % 16),
        );
    }
    let out = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let input = input.to_string_lossy().into_owned();
    let base = |o: &str| -> Vec<String> {
        ["track", &input, "-r", "48", "-n", "100", "-o", o]
            .map(String::from)
            .to_vec()
    };
    let run = |args: &[String]| {
        let o = voltrack(&args.iter().map(String::as_str).collect::<Vec<_>>())
            .env("RUST_LOG", "info")
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };

    let whole = out("whole.exr");
    run(&base(&whole));
    let whole = std::fs::read(whole).unwrap();

    for (signal, name) in [(None, "killed"), (Some("-INT"), "interrupted")] {
        let state: PathBuf = dir.join(&format!("{name}-state"));
        let target = out(&format!("{name}.exr"));
        let args = stop_once_saved(
            base(&target),
            &state,
            &["--checkpoint-every", "1"],
            "track.ckpt",
            signal,
            &target,
            &whole,
            |err| {
                let k: usize = err
                    .split("the first ")
                    .nth(1)
                    .and_then(|rest| rest.split(' ').next())
                    .and_then(|k| k.parse().ok())
                    .unwrap_or_else(|| panic!("{name}: no frame count in: {err}"));
                assert!(err.contains("track.ckpt"), "{name}: {err}");
                assert!((1..LONG).contains(&k), "{name}: {k} frames saved of {LONG}");
            },
        );
        let log = run(&args);
        assert!(
            log.contains("resuming from") && !log.contains("starts from the first frame"),
            "{name}: the rerun did not resume: {log}"
        );
        assert!(
            std::fs::read(&target).unwrap() == whole,
            "{name}, resumed: EXR differs from the uninterrupted run"
        );
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

/// Interrupted once tracking is done (when conforming starts), a conversion
/// reports the checkpoint holding every tracked frame; resumed from it, it
/// ends with the same mesh frames as a conversion never interrupted.
#[test]
fn interrupted_while_conforming_names_the_finished_tracking_and_resumes() {
    let inputs = [PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/bending_bar"
    ))];
    let voxel = voltrack::voxel::VoxelParams {
        resolution: 48,
        ..Default::default()
    };
    let track = TrackParams {
        centers: 100,
        ..Default::default()
    };
    let (refine, deform, conform) = (
        RefineParams::default(),
        DeformParams::default(),
        ConformParams::default(),
    );
    let files = voltrack::io::FrameFiles::discover(&inputs).unwrap();
    let run = |ckpt: Option<&Checkpointing>, progress| {
        let options = ConvertOptions {
            voxel: voxel.clone(),
            track: track.clone(),
            refine: Some(refine.clone()),
            deform: deform.clone(),
            conform: conform.clone(),
            checkpoint: ckpt.cloned(),
            ..Default::default()
        };
        convert(&files, &options, progress)
    };
    let dir = Scratch::new("checkpoint", "conform");
    let ckpt = Checkpointing {
        dir: dir.join("state"),
        every: 4,
        ..Checkpointing::new("")
    };
    let sink = StopAt(Stage::Conform, AtomicBool::new(false));
    match run(Some(&ckpt), Progress(Some(&sink)))
        .map(|_| ())
        .unwrap_err()
    {
        Error::Interrupted {
            saved:
                Some(Saved {
                    path,
                    frames,
                    refine: batches,
                }),
        } => {
            assert_eq!(path, ckpt.path());
            assert_eq!(
                batches,
                Some((refine.batches, refine.batches)),
                "refinement had finished"
            );
            assert_eq!(
                frames,
                voltrack::fixtures::BENDING_BAR_FRAMES,
                "every frame was tracked"
            );
        }
        other => panic!("expected an interruption naming the checkpoint, got {other}"),
    }
    // Resumed, it ends as a run that was never interrupted.
    let resumed = run(
        Some(&Checkpointing {
            resume: true,
            ..ckpt
        }),
        Progress::none(),
    )
    .unwrap();
    let whole = run(None, Progress::none()).unwrap();
    assert_eq!(
        resumed.mesh.frames.to_vec().unwrap(),
        whole.mesh.frames.to_vec().unwrap()
    );
}

/// `voltrack refine --checkpoint`: killed (SIGKILL) or interrupted (SIGINT)
/// once its refinement checkpoint exists, then rerun with --resume, writes
/// the EXR an uninterrupted refine writes, byte for byte. As above, the
/// signal may land after the end; both outcomes are checked.
#[test]
fn the_refine_command_killed_or_interrupted_resumes_to_the_same_bytes() {
    let dir = Scratch::new("checkpoint", "refine-cli");
    let input = dir.join("frames");
    std::fs::create_dir(&input).unwrap();
    for f in 0..24 {
        write_obj(
            &input.join(format!("frame_{f:03}.obj")),
            &voltrack::fixtures::bending_bar(f % 16),
        );
    }
    let out = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let input = input.to_string_lossy().into_owned();
    let tracked = out("tracked.exr");
    let ok = |args: &[&str]| {
        let o = voltrack(args).env("RUST_LOG", "info").output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    ok(&["track", &input, "-r", "48", "-n", "100", "-o", &tracked]);
    let base = |o: &str| -> Vec<String> {
        [
            "refine",
            &tracked,
            "--input",
            &input,
            "--batches",
            "4",
            "-o",
            o,
        ]
        .map(String::from)
        .to_vec()
    };
    let whole = out("whole.exr");
    ok(&base(&whole).iter().map(String::as_str).collect::<Vec<_>>());
    let whole = std::fs::read(whole).unwrap();

    for (signal, name) in [(None, "killed"), (Some("-INT"), "interrupted")] {
        let state = dir.join(&format!("{name}-state"));
        let target = out(&format!("{name}.exr"));
        let args = stop_once_saved(
            base(&target),
            &state,
            &[],
            "refine.ckpt",
            signal,
            &target,
            &whole,
            |err| {
                assert!(
                    err.contains("batches done") && err.contains("state"),
                    "{name}: {err}"
                );
            },
        );
        let log = ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(
            log.contains("resuming refinement from"),
            "{name}: the rerun did not resume: {log}"
        );
        assert!(
            std::fs::read(&target).unwrap() == whole,
            "{name}, resumed: EXR differs from the uninterrupted run"
        );
    }
}

/// A refinement's positions, removed and kept centers and cells, floats as bits.
type RefinedBits = (Vec<u64>, Vec<usize>, Vec<usize>, Vec<Vec<[u64; 4]>>);

/// Everything a refinement returns but its timing, floats as bits.
fn refined_bits(r: &RefineResult) -> RefinedBits {
    let positions = r
        .trajectories
        .positions
        .iter()
        .flat_map(|p| p.coords.iter().map(|c| c.to_bits()).collect::<Vec<_>>())
        .collect();
    let r2 = &r.refinement;
    let histories = r2
        .batches
        .iter()
        .map(|h| {
            h.iter()
                .map(|i| [i.energy, i.smooth, i.data, i.lambda].map(f64::to_bits))
                .collect()
        })
        .collect();
    (positions, r2.removed.clone(), r2.kept.clone(), histories)
}

fn tracked_bar() -> (voltrack::voxel::VoxelSequence, TrackResult) {
    let seq = sequence();
    let tracked = track(
        &seq,
        &TrackParams {
            centers: 60,
            seed: 3,
            ..Default::default()
        },
        Progress::none(),
    )
    .unwrap();
    (seq, tracked)
}

/// Stopped within a batch of the global optimisation, at a batch's end, or
/// twice, refinement saves its state beside the tracking's and says so;
/// resumed, it ends bit-identical to a refinement never interrupted
/// (trajectories, removed and kept centers, energy histories), and resuming
/// the finished state again changes nothing.
#[test]
fn interrupted_and_resumed_refinement_equals_an_uninterrupted_run() {
    let (seq, tracked) = tracked_bar();
    let params = RefineParams {
        batches: 3,
        max_iterations: 6,
        ..Default::default()
    };
    let whole = refine(
        tracked.trajectories.clone(),
        &seq,
        &params,
        Progress::none(),
    )
    .unwrap();
    let batches = &whole.refinement.batches;
    assert!(
        batches.iter().all(|h| h.len() > 2),
        "every batch takes steps: {:?}",
        batches.iter().map(Vec::len).collect::<Vec<_>>()
    );
    for (first, second) in [(2, None), (6, Some(9)), (15, None), (1, Some(2))] {
        let dir = Scratch::new("checkpoint", &format!("refine-{first}"));
        let ckpt = Checkpointing {
            dir: dir.join("state"),
            ..Checkpointing::new("")
        };
        let stop = |after: usize, ckpt: &Checkpointing| {
            let sink = StopAfter {
                stage: Stage::Refine,
                after,
                stop: AtomicBool::new(false),
            };
            match refine_with_checkpoints(
                tracked.trajectories.clone(),
                &seq,
                &params,
                Some(ckpt),
                Progress(Some(&sink)),
            ) {
                Err(
                    e @ Error::Interrupted {
                        saved:
                            Some(Saved {
                                refine: Some((done, 3)),
                                ..
                            }),
                    },
                ) => {
                    assert_eq!(
                        done,
                        (after - 1) / params.max_iterations,
                        "stopped at step {after}"
                    );
                    let message = e.to_string();
                    assert!(
                        message.contains(&format!("{done} of 3 batches"))
                            && message.contains("state"),
                        "{message}"
                    );
                }
                Err(e) => panic!(
                    "stop at {after}: expected an interruption saving the refinement, got {e}"
                ),
                Ok(_) => panic!("stop at {after}: the refinement ran to the end"),
            }
            assert!(ckpt.refine_path().exists());
        };
        stop(first, &ckpt);
        let resume = Checkpointing {
            resume: true,
            ..ckpt.clone()
        };
        if let Some(second) = second {
            stop(second, &resume);
        }
        let resumed = refine_with_checkpoints(
            tracked.trajectories.clone(),
            &seq,
            &params,
            Some(&resume),
            Progress::none(),
        )
        .unwrap();
        assert!(
            refined_bits(&resumed) == refined_bits(&whole),
            "stopped at {first} then {second:?}: the resumed refinement differs"
        );
        let again = refine_with_checkpoints(
            tracked.trajectories.clone(),
            &seq,
            &params,
            Some(&resume),
            Progress::none(),
        )
        .unwrap();
        assert!(
            refined_bits(&again) == refined_bits(&whole),
            "resuming the finished refinement changed it"
        );
        assert!(
            dir.files().iter().all(|f| !f.contains("partial")),
            "no temporary file left: {:?}",
            dir.files()
        );
    }
}

/// Saving within a batch (here after every iteration) leaves a state a
/// killed run resumes from: the file as it was at some iteration, resumed,
/// ends as the run that was never stopped.
#[test]
fn a_refinement_killed_within_a_batch_resumes_from_its_last_save() {
    let (seq, tracked) = tracked_bar();
    let params = RefineParams {
        batches: 2,
        max_iterations: 6,
        ..Default::default()
    };
    let whole = refine(
        tracked.trajectories.clone(),
        &seq,
        &params,
        Progress::none(),
    )
    .unwrap();
    let dir = Scratch::new("checkpoint", "refine-killed");
    let ckpt = Checkpointing {
        dir: dir.join("state"),
        refine_save_seconds: 0.0,
        ..Checkpointing::new("")
    };
    /// Copies the refinement checkpoint aside when step `at` is reported:
    /// the state saved after the step before.
    struct CopyAt<'a>(usize, &'a Checkpointing, PathBuf);
    impl ProgressSink for CopyAt<'_> {
        fn report(&self, stage: Stage, done: usize, _total: usize) {
            if stage == Stage::Refine && done == self.0 {
                std::fs::copy(self.1.refine_path(), &self.2).unwrap();
            }
        }
    }
    for at in [3, 8] {
        let kept_aside = dir.join(&format!("at-{at}.ckpt"));
        let full = refine_with_checkpoints(
            tracked.trajectories.clone(),
            &seq,
            &params,
            Some(&ckpt),
            Progress(Some(&CopyAt(at, &ckpt, kept_aside.clone()))),
        )
        .unwrap();
        assert!(
            refined_bits(&full) == refined_bits(&whole),
            "saving changed the refinement"
        );
        std::fs::rename(&kept_aside, ckpt.refine_path()).unwrap();
        let resumed = refine_with_checkpoints(
            tracked.trajectories.clone(),
            &seq,
            &params,
            Some(&Checkpointing {
                resume: true,
                ..ckpt.clone()
            }),
            Progress::none(),
        )
        .unwrap();
        assert!(
            refined_bits(&resumed) == refined_bits(&whole),
            "killed at step {at}: the resumed refinement differs"
        );
    }
}

/// A refinement checkpoint saved with other parameters, or for other
/// tracking, or damaged, is refused with its name and left as it was.
#[test]
fn a_refinement_checkpoint_of_another_run_or_a_damaged_one_is_refused() {
    let (seq, tracked) = tracked_bar();
    let params = RefineParams {
        batches: 2,
        max_iterations: 4,
        ..Default::default()
    };
    let dir = Scratch::new("checkpoint", "refine-refused");
    let ckpt = Checkpointing {
        dir: dir.join("state"),
        ..Checkpointing::new("")
    };
    let sink = StopAfter {
        stage: Stage::Refine,
        after: 5,
        stop: AtomicBool::new(false),
    };
    assert!(refine_with_checkpoints(
        tracked.trajectories.clone(),
        &seq,
        &params,
        Some(&ckpt),
        Progress(Some(&sink))
    )
    .is_err());
    let resume = Checkpointing {
        resume: true,
        ..ckpt.clone()
    };
    let saved = std::fs::read(ckpt.refine_path()).unwrap();
    let refused =
        |traj: &voltrack::model::Trajectories, params: &RefineParams, what: &str| -> String {
            let message = match refine_with_checkpoints(
                traj.clone(),
                &seq,
                params,
                Some(&resume),
                Progress::none(),
            ) {
                Ok(_) => panic!("{what}: resumed"),
                Err(e) => e.to_string(),
            };
            assert!(
                message.contains("refine.ckpt"),
                "{what}: the error does not name the file: {message}"
            );
            assert!(
                std::fs::read(ckpt.refine_path()).unwrap() == saved,
                "{what}: the checkpoint was changed"
            );
            message
        };
    let mut moved = tracked.trajectories.clone();
    moved.positions[7].x += 1e-9;
    for (what, traj, params) in [
        (
            "other refinement parameters",
            &tracked.trajectories,
            RefineParams {
                beta_hat: params.beta_hat * 2.0,
                ..params.clone()
            },
        ),
        (
            "more batches",
            &tracked.trajectories,
            RefineParams {
                batches: 3,
                ..params.clone()
            },
        ),
        ("other tracking", &moved, params.clone()),
    ] {
        let message = refused(traj, &params, what);
        assert!(
            message.contains("different tracking or refinement parameters"),
            "{what}: {message}"
        );
    }
    for at in [3, saved.len() / 2, saved.len() - 1] {
        let mut damaged = saved.clone();
        damaged[at] ^= 0x10;
        std::fs::write(ckpt.refine_path(), &damaged).unwrap();
        let message = match refine_with_checkpoints(
            tracked.trajectories.clone(),
            &seq,
            &params,
            Some(&resume),
            Progress::none(),
        ) {
            Ok(_) => panic!("byte {at} flipped: resumed"),
            Err(e) => e.to_string(),
        };
        assert!(
            message.contains("refine.ckpt")
                && (message.contains("damaged") || message.contains("not a voltrack")),
            "byte {at}: {message}"
        );
    }
    std::fs::write(ckpt.refine_path(), &saved).unwrap();
    assert!(refine_with_checkpoints(
        tracked.trajectories.clone(),
        &seq,
        &params,
        Some(&resume),
        Progress::none()
    )
    .is_ok());
}

/// A conversion interrupted in refinement names the folder holding the
/// tracking and the refinement so far; resumed, it ends with the mesh of a
/// conversion never interrupted. A run that starts over removes the stale
/// refinement state, which belongs to the tracking it replaces.
#[test]
fn a_conversion_interrupted_in_refinement_resumes_there() {
    let inputs = [PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/fixtures/bending_bar"
    ))];
    let files = voltrack::io::FrameFiles::discover(&inputs).unwrap();
    let refine = RefineParams {
        batches: 2,
        max_iterations: 5,
        ..Default::default()
    };
    let run = |ckpt: Option<&Checkpointing>, progress| {
        let options = ConvertOptions {
            voxel: voltrack::voxel::VoxelParams {
                resolution: 48,
                ..Default::default()
            },
            track: TrackParams {
                centers: 100,
                ..Default::default()
            },
            refine: Some(refine.clone()),
            conform: ConformParams {
                iterations: 5,
                ..Default::default()
            },
            checkpoint: ckpt.cloned(),
            ..Default::default()
        };
        convert(&files, &options, progress)
    };
    let dir = Scratch::new("checkpoint", "convert-refine");
    let ckpt = Checkpointing {
        dir: dir.join("state"),
        ..Checkpointing::new("")
    };
    let sink = StopAfter {
        stage: Stage::Refine,
        after: 7,
        stop: AtomicBool::new(false),
    };
    match run(Some(&ckpt), Progress(Some(&sink)))
        .map(|_| ())
        .unwrap_err()
    {
        Error::Interrupted {
            saved:
                Some(Saved {
                    path,
                    frames,
                    refine: Some((1, 2)),
                }),
        } => {
            assert_eq!(path, ckpt.path());
            assert_eq!(frames, voltrack::fixtures::BENDING_BAR_FRAMES);
        }
        other => panic!("expected an interruption in the second batch, got {other}"),
    }
    let resumed = run(
        Some(&Checkpointing {
            resume: true,
            ..ckpt.clone()
        }),
        Progress::none(),
    )
    .unwrap();
    let whole = run(None, Progress::none()).unwrap();
    assert_eq!(
        resumed.mesh.frames.to_vec().unwrap(),
        whole.mesh.frames.to_vec().unwrap()
    );
    assert!(
        ckpt.refine_path().exists(),
        "the finished refinement is saved"
    );
    // Starting over: the stale refinement state goes once tracking starts.
    let sink = StopAfter {
        stage: Stage::Track,
        after: 2,
        stop: AtomicBool::new(false),
    };
    assert!(run(Some(&ckpt), Progress(Some(&sink))).is_err());
    assert!(
        !ckpt.refine_path().exists(),
        "the refinement of the replaced tracking is gone"
    );
}
