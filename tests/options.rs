//! Issue 22: every option of every command, fed 0, -1, 1e308, inf, NaN,
//! u64::MAX, 1e-40 and the numbers of its documented `(range: ...)`, exits 0
//! or 2 within seconds and never panics (101), dies of a signal or hangs.
//!
//! The options are not listed here: they are walked from the binary's own
//! clap definitions (`src/cli` included below), so a new option is covered
//! the day it is added. Each case is one run of the real binary on a tiny
//! generated sequence (3 frames of the bending bar), in its own scratch
//! directory, with a 5 s kill timer and a 3 GB address-space limit. All
//! failures are gathered into one table.
//!
//! Path-valued arguments get hostile paths instead of numbers (an existing
//! directory, a trailing '/', a link to /dev/null, a missing directory's
//! child, ''); for those 0, 1 or 2 are fine, never 101. The literal
//! `/dev/null` is only fed when this process cannot write into /dev: as root,
//! today's atomic writer would rename its temporary file over the device.

#[path = "../src/cli/mod.rs"]
#[allow(dead_code, unused_imports)]
mod cli;

use clap::{Arg, ArgAction, Command as ClapCommand, CommandFactory, ValueHint};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

// The CLI, included above, brings the shared helpers with it.
use cli::test_support as common;
use common::Scratch;

const BIN: &str = env!("CARGO_BIN_EXE_voltrack");
/// Every run ends within this. A run on the 3-frame fixture takes about a
/// tenth of a second; the bound catches a value that starts work at scale
/// (a huge resolution or count taken at its word), with room for a loaded
/// 2-core machine: it guards against hangs, it is not a speed figure.
const TIME_LIMIT: f64 = 3.0;
/// Runs still going after this are killed (and reported as hangs).
const KILL_AFTER: Duration = Duration::from_secs(5);
/// Address-space limit of each run, KiB: a run that tries to allocate more
/// aborts (and is reported) instead of starving the machine.
const MEMORY_LIMIT_KB: u64 = 3 << 20;
const THREADS: usize = 2;
/// Numbers fed to every value-taking option.
const HOSTILE_NUMBERS: [&str; 7] = [
    "0",
    "-1",
    "1e308",
    "inf",
    "NaN",
    "18446744073709551615",
    "1e-40",
];

/// Writes frames 0..3 of the bending bar as OBJ into `dir/seq` and tracks
/// them once into `dir/centers.exr` (for refine and metrics).
fn make_fixture(dir: &Path) {
    let seq = dir.join("seq");
    std::fs::create_dir_all(&seq).unwrap();
    for f in 0..3 {
        let m = voltrack::fixtures::bending_bar(f);
        let mut obj = Vec::new();
        voltrack::export::obj::write_obj(&mut obj, &m, &m.positions).unwrap();
        std::fs::write(seq.join(format!("frame_{f}.obj")), obj).unwrap();
    }
    let out = Command::new(BIN)
        .args(["track", "seq", "-r", "16", "-n", "8", "-o", "centers.exr"])
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "tracking the fixture failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// One argument of a baseline command line: its clap id and its values.
type Setting = (String, Vec<String>);

/// A valid, fast command line for each subcommand, by clap id. Paths are
/// relative to a case's directory, where `seq` and `centers.exr` link to the
/// fixture.
fn baseline(sub: &str) -> Vec<Setting> {
    let s = |id: &str, v: &str| (id.to_string(), vec![v.to_string()]);
    match sub {
        "convert" => vec![
            s("input", "seq"),
            s("resolution", "16"),
            s("centers", "8"),
            s("output", "out.glb"),
        ],
        "voxelize" => vec![s("input", "seq"), s("resolution", "16"), s("output", "vox")],
        // With --refine, so that track's refinement options are exercised too.
        "track" => vec![
            s("input", "seq"),
            s("resolution", "16"),
            s("centers", "8"),
            s("output", "out.exr"),
            ("refine".into(), vec![]),
        ],
        "refine" => vec![
            s("centers", "centers.exr"),
            s("input", "seq"),
            s("output", "out.exr"),
        ],
        "metrics" => vec![s("centers", "centers.exr"), s("input", "seq")],
        other => panic!("no baseline for the new subcommand '{other}': add one to baseline()"),
    }
}

/// The argv (without the program name) for `settings` of subcommand `sub`.
fn render(sub: &ClapCommand, settings: &[Setting]) -> Vec<String> {
    let mut argv = vec![sub.get_name().to_string()];
    let find = |id: &str| {
        sub.get_arguments()
            .find(|a| a.get_id() == id)
            .unwrap_or_else(|| panic!("{}: no argument '{id}'", sub.get_name()))
    };
    // Positionals first, in their order; then options as --long=value.
    let mut positionals: Vec<(usize, &Setting)> = settings
        .iter()
        .filter_map(|s| {
            find(&s.0)
                .get_index()
                .filter(|_| find(&s.0).is_positional())
                .map(|i| (i, s))
        })
        .collect();
    positionals.sort_by_key(|p| p.0);
    for (_, (_, values)) in positionals {
        argv.extend(values.iter().cloned());
    }
    for (id, values) in settings {
        let arg = find(id);
        if arg.is_positional() {
            continue;
        }
        let flag = match (arg.get_long(), arg.get_short()) {
            (Some(l), _) => format!("--{l}"),
            (None, Some(s)) => format!("-{s}"),
            (None, None) => panic!("{id}: neither long nor short"),
        };
        if takes_value(arg) {
            argv.extend(values.iter().map(|v| format!("{flag}={v}")));
        } else {
            argv.push(flag);
        }
    }
    argv
}

fn takes_value(arg: &Arg) -> bool {
    arg.get_action().takes_values()
}

fn is_path(arg: &Arg) -> bool {
    matches!(
        arg.get_value_hint(),
        ValueHint::AnyPath | ValueHint::FilePath | ValueHint::DirPath
    )
}

/// Whether `arg` takes fractions (its own value parser accepts "0.5").
fn takes_fractions(arg: &Arg) -> bool {
    let probe = ClapCommand::new("probe").arg(
        Arg::new("x")
            .long("x")
            .value_parser(arg.get_value_parser().clone()),
    );
    probe.try_get_matches_from(["probe", "--x=0.5"]).is_ok()
}

/// Every number in the `(range: ...)` notes of `arg`'s help, each also
/// nudged by a small step either side: ±1 for whole numbers, relative 1e-6
/// for fractions (`fractional`: the option takes them).
fn range_values(arg: &Arg, fractional: bool) -> Vec<String> {
    let help = [arg.get_help(), arg.get_long_help()]
        .into_iter()
        .flatten()
        .map(|h| h.to_string())
        .collect::<Vec<_>>()
        .join(" ");
    let mut out = Vec::new();
    let mut rest = help.as_str();
    while let Some(start) = rest.find("(range:") {
        let note = &rest[start + "(range:".len()..];
        let end = note.find(')').unwrap_or(note.len());
        for token in number_tokens(&note[..end]) {
            let integer = !fractional && !token.contains(['.', 'e', 'E']);
            out.push(token.clone());
            if integer {
                if let Ok(n) = token.parse::<i128>() {
                    out.push((n - 1).to_string());
                    out.push((n + 1).to_string());
                }
            } else if let Ok(x) = token.parse::<f64>() {
                // Relative, so that it survives an f32 and means something near 1e-9.
                let step = if x == 0.0 { 1e-6 } else { 1e-6 * x.abs() };
                out.push(format!("{}", x - step));
                out.push(format!("{}", x + step));
            }
        }
        rest = &note[end..];
    }
    out
}

/// Numbers in `s`: `-1`, `0.5`, `1e-3`; `0.0..1.0` is two numbers.
fn number_tokens(s: &str) -> Vec<String> {
    let b = s.as_bytes();
    let digit = |i: usize| b.get(i).is_some_and(|c| c.is_ascii_digit());
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let start = i;
        if b[i] == b'-' && digit(i + 1) && (i == 0 || !b[i - 1].is_ascii_alphanumeric()) {
            i += 1;
        } else if !digit(i) || (i > 0 && (b[i - 1].is_ascii_alphabetic() || b[i - 1] == b'_')) {
            i += 1;
            continue;
        }
        while digit(i) {
            i += 1;
        }
        if b.get(i) == Some(&b'.') && digit(i + 1) {
            i += 1;
            while digit(i) {
                i += 1;
            }
        }
        if matches!(b.get(i), Some(b'e' | b'E'))
            && (digit(i + 1) || (matches!(b.get(i + 1), Some(b'-' | b'+')) && digit(i + 2)))
        {
            i += 2;
            while digit(i) {
                i += 1;
            }
        }
        out.push(s[start..i].to_string());
    }
    out
}

/// Hostile values of a path-valued argument whose baseline value (if any)
/// ends in `ext` (".glb", or "").
fn hostile_paths(ext: &str) -> Vec<String> {
    let mut v = vec![
        "existing_dir".to_string(),
        "existing_dir/".to_string(),
        format!("fresh{ext}/"),
        "dev_null".to_string(), // a symlink to /dev/null
        format!("missing_dir/child{ext}"),
        String::new(),
    ];
    if !dev_writable() {
        v.push("/dev/null".into());
    }
    v
}

/// Whether this process may create files in /dev (root may).
fn dev_writable() -> bool {
    let probe = Path::new("/dev").join(format!(".voltrack-options-probe-{}", std::process::id()));
    let ok = std::fs::File::create(&probe).is_ok();
    let _ = std::fs::remove_file(&probe);
    ok
}

#[derive(Clone)]
struct Case {
    sub: String,
    /// Clap id of the argument under test ("(conflict)" for the fixed ones).
    option: String,
    /// The value fed, or "(flag)".
    value: String,
    argv: Vec<String>,
    /// Path-valued: exit 1 (a refused path) is fine too.
    path: bool,
}

/// In-process parse of `argv` by the same clap definitions.
fn parses(cmd: &ClapCommand, argv: &[String]) -> Result<(), clap::Error> {
    cmd.clone()
        .try_get_matches_from(std::iter::once("voltrack".to_string()).chain(argv.iter().cloned()))
        .map(|_| ())
}

/// `settings` plus whatever other argument the one under test `requires`
/// (found by asking clap: the first absent optional argument whose addition
/// makes a plausible value parse). `probe` is that plausible value.
fn with_requirements(
    cmd: &ClapCommand,
    sub: &ClapCommand,
    mut settings: Vec<Setting>,
    id: &str,
    probe: &str,
) -> Vec<Setting> {
    let mut trial = settings.clone();
    set(&mut trial, id, probe);
    match parses(cmd, &render(sub, &trial)) {
        Err(e) if e.kind() == clap::error::ErrorKind::MissingRequiredArgument => {}
        _ => return settings,
    }
    for other in sub.get_arguments() {
        let oid = other.get_id().as_str();
        if oid == id || settings.iter().any(|s| s.0 == oid) || other.is_positional() {
            continue;
        }
        let value = if is_path(other) {
            "companion_dir".to_string()
        } else {
            "1".to_string()
        };
        let mut t = trial.clone();
        set(&mut t, oid, &value);
        if parses(cmd, &render(sub, &t)).is_ok() {
            set(&mut settings, oid, &value);
            return settings;
        }
    }
    panic!(
        "{} --{id}: clap wants another argument and none found makes the command line parse",
        sub.get_name()
    );
}

fn set(settings: &mut Vec<Setting>, id: &str, value: &str) {
    match settings.iter_mut().find(|s| s.0 == id) {
        Some(s) => s.1 = vec![value.to_string()],
        None => settings.push((id.to_string(), vec![value.to_string()])),
    }
}

/// Every case, generated from the clap definitions.
fn cases() -> Vec<Case> {
    let mut cmd = cli::Cli::command();
    cmd.build();
    let mut out = Vec::new();
    for sub in cmd.get_subcommands() {
        let name = sub.get_name();
        if name == "help" {
            continue;
        }
        let base = baseline(name);
        assert!(
            parses(&cmd, &render(sub, &base)).is_ok(),
            "the baseline of {name} does not parse: {:?}",
            parses(&cmd, &render(sub, &base))
        );
        for arg in sub.get_arguments() {
            let id = arg.get_id().as_str();
            if matches!(
                arg.get_action(),
                ArgAction::Help | ArgAction::HelpShort | ArgAction::HelpLong | ArgAction::Version
            ) {
                continue;
            }
            let mut push = |value: &str, path: bool| {
                let settings = with_requirements(
                    &cmd,
                    sub,
                    base.clone(),
                    id,
                    if path { "probe_path" } else { "1" },
                );
                let mut settings = settings;
                let shown = if takes_value(arg) {
                    set(&mut settings, id, value);
                    value.to_string()
                } else if let Some(k) = settings.iter().position(|s| s.0 == id) {
                    // Already in the baseline (track --refine): the case is its absence.
                    settings.remove(k);
                    "(flag removed)".to_string()
                } else {
                    settings.push((id.to_string(), Vec::new()));
                    "(flag)".to_string()
                };
                out.push(Case {
                    sub: name.into(),
                    option: id.into(),
                    value: shown,
                    argv: render(sub, &settings),
                    path,
                });
            };
            if !takes_value(arg) {
                push("", false);
            } else if is_path(arg) {
                let ext = base
                    .iter()
                    .find(|s| s.0 == id)
                    .and_then(|s| {
                        Path::new(&s.1[0])
                            .extension()
                            .map(|e| format!(".{}", e.to_string_lossy()))
                    })
                    .unwrap_or_default();
                for v in hostile_paths(&ext) {
                    push(&v, true);
                }
            } else {
                let mut values: Vec<String> =
                    HOSTILE_NUMBERS.iter().map(|s| s.to_string()).collect();
                values.extend(
                    arg.get_possible_values()
                        .iter()
                        .map(|p| p.get_name().to_string()),
                );
                values.extend(range_values(arg, takes_fractions(arg)));
                let mut seen = std::collections::HashSet::new();
                for v in values.into_iter().filter(|v| seen.insert(v.clone())) {
                    push(&v, false);
                }
            }
        }
    }
    out
}

struct Outcome {
    /// Exit code, or a description ("signal 6", "killed after 5 s").
    status: Result<i32, String>,
    seconds: f64,
    stderr: String,
}

/// Runs `argv` in a fresh directory under `root`, which links to the fixture.
fn run(root: &Path, fixture: &Path, k: usize, argv: &[String]) -> Outcome {
    let dir = root.join(format!("case{k:04}"));
    std::fs::create_dir_all(dir.join("existing_dir")).unwrap();
    std::os::unix::fs::symlink(fixture.join("seq"), dir.join("seq")).unwrap();
    std::os::unix::fs::symlink(fixture.join("centers.exr"), dir.join("centers.exr")).unwrap();
    std::os::unix::fs::symlink("/dev/null", dir.join("dev_null")).unwrap();
    let stdout = std::fs::File::create(root.join(format!("case{k:04}.stdout"))).unwrap();
    let stderr_path = root.join(format!("case{k:04}.stderr"));
    let stderr = std::fs::File::create(&stderr_path).unwrap();
    let clock = Instant::now();
    // `exec` keeps the pid: the status (and the kill) are voltrack's own.
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {MEMORY_LIMIT_KB}; exec \"$0\" \"$@\""))
        .arg(BIN)
        .args(argv)
        .current_dir(&dir)
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(stderr)
        .spawn()
        .unwrap();
    let status = common::wait_or_kill(&mut child, clock, KILL_AFTER);
    let seconds = clock.elapsed().as_secs_f64();
    let stderr = std::fs::read_to_string(&stderr_path).unwrap_or_default();
    let _ = std::fs::remove_dir_all(&dir);
    Outcome {
        status,
        seconds,
        stderr,
    }
}

/// Runs every case on [`THREADS`] threads; returns the failures as table rows.
fn run_all(
    cases: &[Case],
    name: &str,
    allowed: impl Fn(&Case) -> &'static [i32] + Sync,
) -> (Vec<String>, f64) {
    let scratch = Scratch::new("options", name);
    let fixture = scratch.0.join("fixture");
    make_fixture(&fixture);
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    let slowest = Mutex::new((0.0f64, String::new()));
    // VOLTRACK_OPTIONS_LOG=prefix: one line per case in prefix.NAME, for reading the whole run.
    let log = std::env::var("VOLTRACK_OPTIONS_LOG")
        .ok()
        .map(|p| Mutex::new(std::fs::File::create(format!("{p}.{name}")).unwrap()));
    let clock = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..THREADS {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(case) = cases.get(k) else { break };
                let o = run(&scratch.0, &fixture, k, &case.argv);
                let ok_code = matches!(o.status, Ok(c) if allowed(case).contains(&c));
                {
                    let mut slow = slowest.lock().unwrap();
                    if ok_code && o.seconds > slow.0 {
                        *slow = (o.seconds, case.argv.join(" "));
                    }
                }
                if let Some(log) = &log {
                    use std::io::Write;
                    let first = o.stderr.lines().next().unwrap_or("");
                    writeln!(
                        log.lock().unwrap(),
                        "{:?}\t{:.3}\t{}\t{}",
                        o.status,
                        o.seconds,
                        case.argv.join(" "),
                        first
                    )
                    .unwrap();
                }
                if !ok_code || o.seconds > TIME_LIMIT {
                    let code = match &o.status {
                        Ok(c) => c.to_string(),
                        Err(e) => e.clone(),
                    };
                    let first = o
                        .stderr
                        .lines()
                        .map(str::trim)
                        .find(|l| !l.is_empty())
                        .unwrap_or("")
                        .chars()
                        .take(110)
                        .collect::<String>();
                    failures
                        .lock()
                        .unwrap()
                        .push((k, case.clone(), code, o.seconds, first));
                }
            });
        }
    });
    let slowest = slowest.into_inner().unwrap();
    if !slowest.1.is_empty() {
        eprintln!(
            "{name}: slowest passing run {:.2} s: {}",
            slowest.0, slowest.1
        );
    }
    let mut failures = failures.into_inner().unwrap();
    failures.sort_by_key(|f| f.0);
    let rows = failures
        .iter()
        .map(|(_, c, code, secs, first)| {
            format!(
                "{:<9} {:<20} {:<24} {:<16} {:>6.2}  {}\n          argv: {}",
                c.sub,
                c.option,
                format!("{:?}", c.value),
                code,
                secs,
                first,
                c.argv.join(" ")
            )
        })
        .collect();
    (rows, clock.elapsed().as_secs_f64())
}

fn report(title: &str, want: &str, cases: usize, seconds: f64, rows: &[String]) {
    eprintln!(
        "{title}: {cases} cases in {seconds:.1} s, {} failing",
        rows.len()
    );
    if !rows.is_empty() {
        let table = rows.join("\n");
        panic!(
            "{title}: {} of {cases} cases failed (want {want}; within {TIME_LIMIT} s)\n\
             {:<9} {:<20} {:<24} {:<16} {:>6}  first stderr line\n{table}",
            rows.len(),
            "command",
            "option",
            "value",
            "exit",
            "secs"
        );
    }
}

#[test]
fn every_option_exits_0_or_2_within_a_second() {
    let cases = cases();
    // Every subcommand and every value-taking argument is there.
    let mut cmd = cli::Cli::command();
    cmd.build();
    for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
        for arg in sub.get_arguments().filter(|a| {
            !matches!(
                a.get_action(),
                ArgAction::Help | ArgAction::HelpShort | ArgAction::HelpLong | ArgAction::Version
            )
        }) {
            assert!(
                cases
                    .iter()
                    .any(|c| c.sub == sub.get_name() && c.option == arg.get_id().as_str()),
                "{} {} not covered",
                sub.get_name(),
                arg.get_id()
            );
        }
    }
    let (rows, seconds) = run_all(&cases, "all", |c| if c.path { &[0, 1, 2] } else { &[0, 2] });
    report(
        "options",
        "exit 0 or 2, also 1 for paths",
        cases.len(),
        seconds,
        &rows,
    );
}

/// The documented conflicts are usage errors (exit 2), found before any work.
#[test]
fn documented_conflicts_exit_2() {
    let conflicts: [&[&str]; 3] = [
        &["--vat", "--format=glb", "-o", "x.glb"],
        &["--no-refine", "--remove=5", "-o", "x.glb"],
        &["--format=exr", "-o", "x.glb"],
    ];
    let cases: Vec<Case> = conflicts
        .iter()
        .map(|extra| {
            let mut argv: Vec<String> = ["convert", "seq", "-r", "16", "-n", "8"]
                .iter()
                .map(|s| s.to_string())
                .collect();
            argv.extend(extra.iter().map(|s| s.to_string()));
            Case {
                sub: "convert".into(),
                option: "(conflict)".into(),
                value: extra.join(" "),
                argv,
                path: false,
            }
        })
        .collect();
    let (rows, seconds) = run_all(&cases, "conflicts", |_| &[2]);
    report("conflicts", "exit 2", cases.len(), seconds, &rows);
}

/// The `(range: ...)` notes are read as the help texts will write them.
#[test]
fn range_notes_are_parsed() {
    let values = |help: &'static str, fractional: bool| -> Vec<f64> {
        range_values(&Arg::new("x").help(help), fractional)
            .iter()
            .map(|v| v.parse().unwrap())
            .collect()
    };
    let same = |got: Vec<f64>, want: &[f64]| {
        assert!(
            got.len() == want.len()
                && got
                    .iter()
                    .zip(want)
                    .all(|(a, b)| (a - b).abs() <= 1e-12 * b.abs().max(1e-300)),
            "{got:?} != {want:?}"
        )
    };
    same(
        values("Weight (range: 0.0..1.0)", true),
        &[0.0, -1e-6, 1e-6, 1.0, 1.0 - 1e-6, 1.0 + 1e-6],
    );
    same(
        values("Voxels along the longest side (range: 1..=100000)", false),
        &[1.0, 0.0, 2.0, 1e5, 1e5 - 1.0, 1e5 + 1.0],
    );
    same(
        values("Frames per second (range: 0.001..=1000)", true),
        &[1e-3, 1e-3 - 1e-9, 1e-3 + 1e-9, 1e3, 1e3 - 1e-3, 1e3 + 1e-3],
    );
    same(
        values("Threshold (range: 1e-9..=0.5; default 1e-3)", true),
        &[
            1e-9,
            1e-9 - 1e-15,
            1e-9 + 1e-15,
            0.5,
            0.5 - 5e-7,
            0.5 + 5e-7,
            1e-3,
            1e-3 - 1e-9,
            1e-3 + 1e-9,
        ],
    );
    same(
        values("Offset (range: -2..2) of x2 (not a range: 7)", false),
        &[-2.0, -3.0, -1.0, 2.0, 1.0, 3.0],
    );
    assert!(values("ρ_gp: largest distance at which ω_max is 0.5", true).is_empty());
    // Whole-number and fractional options are told apart by their own parsers.
    let cmd = cli::Cli::command();
    let convert = cmd.find_subcommand("convert").unwrap();
    let arg = |id: &str| convert.get_arguments().find(|a| a.get_id() == id).unwrap();
    assert!(takes_fractions(arg("beta")) && takes_fractions(arg("fps")));
    assert!(!takes_fractions(arg("centers")) && !takes_fractions(arg("seed")));
}
