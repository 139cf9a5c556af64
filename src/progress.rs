//! Progress reporting: the library never prints; it calls back, and the CLI
//! turns the calls into progress bars (or nothing when piped).

/// A phase of a conversion, for progress reports and timings: the five
/// stages of the crate root's list, with reading the frames (`Read`) and the
/// deformation's conform step (`Conform`) and measuring the result (`Fit`)
/// reported on their own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    /// Reading the input frames.
    Read,
    /// Voxelising every frame on the common grid (stage 1).
    Voxelize,
    /// Tracking the centers through the frames (stage 2).
    Track,
    /// Removing irregular centers and the global optimisation (stage 3).
    Refine,
    /// Moving the reference frame's mesh by the centers (stage 4).
    Deform,
    /// Fitting the deformed mesh to every frame's input (stage 4).
    Conform,
    /// Measuring the result against every input frame.
    Fit,
    /// Writing an output (stage 5).
    Export,
}

impl Stage {
    /// The stage's name in lower case (`"read"`, `"fit"`), as progress and
    /// timings show it.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Read => "read",
            Stage::Voxelize => "voxelize",
            Stage::Track => "track",
            Stage::Refine => "refine",
            Stage::Deform => "deform",
            Stage::Conform => "conform",
            Stage::Fit => "fit",
            Stage::Export => "export",
        }
    }
}

/// Receives `(stage, done, total)` as work advances; `done == total` ends a
/// stage. It can also ask the work to stop (Ctrl-C): long stages poll
/// [`ProgressSink::cancelled`] and return [`crate::Error::Interrupted`].
pub trait ProgressSink: Sync {
    /// `done` of `total` units of `stage`'s work are finished.
    fn report(&self, stage: Stage, done: usize, total: usize);
    /// Whether the work should stop; never, unless overridden.
    fn cancelled(&self) -> bool {
        false
    }
}

impl<F: Fn(Stage, usize, usize) + Sync> ProgressSink for F {
    fn report(&self, stage: Stage, done: usize, total: usize) {
        self(stage, done, total)
    }
}

/// An optional progress callback, cheap to pass around.
#[derive(Clone, Copy, Default)]
pub struct Progress<'a>(pub Option<&'a dyn ProgressSink>);

impl<'a> Progress<'a> {
    /// No callback: reports go nowhere and nothing is ever cancelled.
    pub fn none() -> Self {
        Progress(None)
    }
    /// Passes `(stage, done, total)` to the callback, if there is one.
    pub fn report(&self, stage: Stage, done: usize, total: usize) {
        if let Some(sink) = self.0 {
            sink.report(stage, done, total);
        }
    }
    /// Whether the caller asked the work to stop.
    pub fn cancelled(&self) -> bool {
        self.0.is_some_and(|sink| sink.cancelled())
    }
}

/// Counts completed items across rayon threads and reports each one.
pub(crate) struct Counter<'a> {
    progress: Progress<'a>,
    stage: Stage,
    total: usize,
    done: std::sync::atomic::AtomicUsize,
}

impl<'a> Counter<'a> {
    pub fn new(progress: Progress<'a>, stage: Stage, total: usize) -> Self {
        progress.report(stage, 0, total);
        Counter {
            progress,
            stage,
            total,
            done: 0.into(),
        }
    }
    pub fn tick(&self) {
        let d = self.done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        self.progress.report(self.stage, d, self.total);
    }
}
