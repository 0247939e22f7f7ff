//! Progress and Ctrl-C for calls that run with the GIL released.
//!
//! The library asks [`Progress::cancelled`] between slices, planes and handles. Here that
//! briefly takes the GIL to let Python run its signal handlers (a Ctrl-C becomes
//! `KeyboardInterrupt`), at most every [`SIGNAL_EVERY`]; the user's `progress(stage, done,
//! total)` callback is called at most every [`CALL_EVERY`], and at each stage's start and end.
//! An exception from either stops the job, and the call raises it.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use isotopo::progress::Progress;
use pyo3::prelude::*;

/// How often signals are checked while a job runs.
const SIGNAL_EVERY: Duration = Duration::from_millis(50);
/// How often the progress callback is called within a stage.
const CALL_EVERY: Duration = Duration::from_millis(100);

/// Reports to a Python callable (or nowhere) and turns Ctrl-C into a cancellation.
pub struct PyProgress {
    callback: Option<Py<PyAny>>,
    state: Mutex<State>,
    stop: AtomicBool,
    error: Mutex<Option<PyErr>>,
}

struct State {
    stage: String,
    done: u64,
    total: u64,
    last_call: Instant,
    last_signals: Instant,
}

impl PyProgress {
    /// Progress for `callback` (`None`: only Ctrl-C is watched).
    pub fn new(callback: Option<Py<PyAny>>) -> PyProgress {
        let now = Instant::now();
        PyProgress {
            callback,
            state: Mutex::new(State {
                stage: String::new(),
                done: 0,
                total: 0,
                last_call: now,
                last_signals: now,
            }),
            stop: AtomicBool::new(false),
            error: Mutex::new(None),
        }
    }

    /// The exception that stopped the job (a `KeyboardInterrupt`, or the callback's own).
    pub fn take_error(&self) -> Option<PyErr> {
        self.error.lock().ok()?.take()
    }

    fn fail(&self, e: PyErr) {
        if let Ok(mut slot) = self.error.lock() {
            slot.get_or_insert(e);
        }
        self.stop.store(true, Ordering::SeqCst);
    }

    /// Calls the callback with the current stage, if due (or `force`d).
    fn report(&self, force: bool) {
        let Some(cb) = &self.callback else { return };
        if self.stop.load(Ordering::SeqCst) {
            return;
        }
        let (stage, done, total) = {
            let Ok(mut s) = self.state.lock() else { return };
            if !force && s.last_call.elapsed() < CALL_EVERY {
                return;
            }
            s.last_call = Instant::now();
            (s.stage.clone(), s.done.min(s.total), s.total)
        };
        let result = Python::attach(|py| cb.call1(py, (stage, done, total)).map(|_| ()));
        if let Err(e) = result {
            self.fail(e);
        }
    }
}

impl Progress for PyProgress {
    fn start(&self, stage: &str, total: u64) {
        if let Ok(mut s) = self.state.lock() {
            s.stage = stage.to_string();
            s.done = 0;
            s.total = total;
        }
        self.report(true);
    }

    fn advance(&self, n: u64) {
        if let Ok(mut s) = self.state.lock() {
            s.done += n;
        }
        self.report(false);
    }

    fn finish(&self) {
        if let Ok(mut s) = self.state.lock() {
            s.done = s.total;
        }
        self.report(true);
    }

    fn cancelled(&self) -> bool {
        if self.stop.load(Ordering::SeqCst) {
            return true;
        }
        let due = match self.state.lock() {
            Ok(mut s) if s.last_signals.elapsed() >= SIGNAL_EVERY => {
                s.last_signals = Instant::now();
                true
            }
            _ => false,
        };
        if due {
            // Python runs signal handlers only on its main thread; elsewhere this is a no-op.
            if let Err(e) = Python::attach(|py| py.check_signals()) {
                self.fail(e);
            }
        }
        self.stop.load(Ordering::SeqCst)
    }
}
