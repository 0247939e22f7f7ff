//! Progress reporting, decoupled from any terminal: the library reports stages and steps, the
//! command line draws bars (or nothing, under `--quiet` or when stderr is not a terminal).

use crate::error::{Error, Result};

/// Receives progress from long operations. All methods take `&self` so one reporter can be shared.
pub trait Progress: Sync {
    /// A new stage begins with `total` steps (slices, handles…).
    fn start(&self, stage: &str, total: u64);
    /// `n` more steps are done.
    fn advance(&self, n: u64);
    /// A short status for the current stage ("12 handles found").
    fn message(&self, _msg: &str) {}
    /// The current stage is complete.
    fn finish(&self) {}
    /// A line for whoever debugs a run (what was measured, how a pass ended); the command line
    /// prints these when `ISOTOPO_DEBUG` is set. Ignored by default.
    fn trace(&self, _line: std::fmt::Arguments<'_>) {}
    /// Whether the caller asked to stop (a Ctrl-C in Python, a cancel button). Long operations
    /// ask between steps (a slice, a handle, a plane written) and return [`Error::Cancelled`];
    /// nothing is written. By default, never.
    fn cancelled(&self) -> bool {
        false
    }
    /// `Err(Error::Cancelled)` once [`Progress::cancelled`] says so.
    fn check(&self) -> Result<()> {
        match self.cancelled() {
            true => Err(Error::Cancelled),
            false => Ok(()),
        }
    }
}

/// Between two steps of a stage: stops if the caller asked to ([`Progress::check`]) or if the
/// process has grown past its memory limit during `stage` ([`crate::memory::check`]).
pub fn between_steps(progress: &dyn Progress, stage: &str) -> Result<()> {
    progress.check()?;
    crate::memory::check(stage)
}

/// Reports nothing.
pub struct NoProgress;

impl Progress for NoProgress {
    fn start(&self, _stage: &str, _total: u64) {}
    fn advance(&self, _n: u64) {}
}

/// Passes on cancellation and traces only: for work done inside another stage's steps (the
/// loops measured while the sweep goes on), whose own counts would confuse its bar.
pub struct StepsOnly<'a>(pub &'a dyn Progress);

impl Progress for StepsOnly<'_> {
    fn start(&self, _stage: &str, _total: u64) {}
    fn advance(&self, _n: u64) {}
    fn trace(&self, line: std::fmt::Arguments<'_>) {
        self.0.trace(line)
    }
    fn cancelled(&self) -> bool {
        self.0.cancelled()
    }
}
