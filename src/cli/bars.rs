//! Progress bars on a terminal, nothing when stderr is piped.

use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;
use voltrack::progress::ProgressSink;
use voltrack::{Progress, Stage};

pub struct Bars {
    multi: Option<MultiProgress>,
    current: Mutex<Option<(Stage, ProgressBar)>>,
}

impl Bars {
    pub fn new() -> Self {
        let multi = std::io::stderr().is_terminal().then(|| MultiProgress::with_draw_target(ProgressDrawTarget::stderr()));
        Bars { multi, current: Mutex::new(None) }
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
    fn report(&self, stage: Stage, done: usize, total: usize) {
        let Some(multi) = &self.multi else { return };
        let mut cur = self.current.lock().unwrap();
        if cur.as_ref().map(|(s, _)| *s) != Some(stage) {
            if let Some((_, bar)) = cur.take() {
                bar.finish();
            }
            let bar = multi.add(ProgressBar::new(total as u64));
            bar.set_style(
                ProgressStyle::with_template("{prefix:>9} [{bar:32}] {pos}/{len} {elapsed_precise} eta {eta}")
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
