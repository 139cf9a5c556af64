//! Progress bars on a terminal, a line per stage (and every 10 s) when
//! stderr is a log; and Ctrl-C,
//! which the library sees through the same progress callback.

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};
use voltrack::progress::ProgressSink;
use voltrack::{Progress, Stage};

/// Set by the first SIGINT/SIGTERM; a second one exits at once with 130.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Makes Ctrl-C (and SIGTERM) ask the library to stop at its next safe point,
/// where it saves a checkpoint if it keeps one; the second press quits.
pub fn handle_interrupts() -> std::io::Result<()> {
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // The shutdown goes first so that it only fires once the flag is set.
        signal_hook::flag::register_conditional_shutdown(signal, 130, &INTERRUPTED)?;
        signal_hook::flag::register(signal, &INTERRUPTED)?;
    }
    Ok(())
}

pub struct Bars {
    multi: Option<MultiProgress>,
    current: Mutex<Option<(Stage, ProgressBar)>>,
    announced: AtomicBool,
    /// Without a terminal (a log, CI): the stage last shown, when it began
    /// and when its last line was printed.
    plain: Mutex<Option<(Stage, Instant, Instant)>>,
}

/// Without a terminal, a line per stage and one this often within a stage,
/// so a log shows the run is alive.
const PLAIN_EVERY: Duration = Duration::from_secs(10);

impl Bars {
    pub fn new() -> Self {
        let multi = std::io::stderr()
            .is_terminal()
            .then(|| MultiProgress::with_draw_target(ProgressDrawTarget::stderr()));
        Bars {
            multi,
            current: Mutex::new(None),
            announced: AtomicBool::new(false),
            plain: Mutex::new(None),
        }
    }

    /// A line when a stage begins, and every [`PLAIN_EVERY`] within it.
    fn plain_report(&self, stage: Stage, done: usize, total: usize) {
        let now = Instant::now();
        let mut plain = self.plain.lock().unwrap();
        match &mut *plain {
            Some((shown, began, printed)) if *shown == stage => {
                if now.duration_since(*printed) >= PLAIN_EVERY {
                    eprintln!(
                        "voltrack: {} {done}/{total} ({:.0} s)",
                        stage.name(),
                        now.duration_since(*began).as_secs_f64()
                    );
                    *printed = now;
                }
            }
            _ => {
                eprintln!("voltrack: {} ...", stage.name());
                *plain = Some((stage, now, now));
            }
        }
    }

    pub fn progress(&self) -> Progress<'_> {
        Progress(Some(self))
    }

    pub fn finish(&self) {
        if let Some((_, bar)) = self.current.lock().unwrap().take() {
            bar.finish();
        }
    }
}

impl ProgressSink for Bars {
    fn cancelled(&self) -> bool {
        let stop = INTERRUPTED.load(Ordering::Relaxed);
        if stop && !self.announced.swap(true, Ordering::Relaxed) {
            let say = || {
                eprintln!("voltrack: stopping at the next safe point (Ctrl-C again quits at once)")
            };
            match &self.multi {
                Some(multi) => multi.suspend(say),
                None => say(),
            }
        }
        stop
    }

    fn report(&self, stage: Stage, done: usize, total: usize) {
        let Some(multi) = &self.multi else {
            return self.plain_report(stage, done, total);
        };
        let mut cur = self.current.lock().unwrap();
        if cur.as_ref().map(|(s, _)| *s) != Some(stage) {
            if let Some((_, bar)) = cur.take() {
                bar.finish();
            }
            let bar = multi.add(ProgressBar::new(total as u64));
            bar.set_style(
                ProgressStyle::with_template(
                    "{prefix:>9} [{bar:32}] {pos}/{len} {elapsed_precise} eta {eta}",
                )
                .unwrap()
                .progress_chars("=> "),
            );
            bar.set_prefix(stage.name());
            *cur = Some((stage, bar));
        }
        let (_, bar) = cur.as_ref().unwrap();
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    }
}
