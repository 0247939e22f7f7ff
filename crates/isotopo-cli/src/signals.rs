//! Interrupts and panics, so that neither leaves a user with half a file or a stack dump.
//!
//! - A closed pipe (`| head`) ends the command quietly.
//! - Ctrl-C (SIGINT) or SIGTERM sets a flag the library polls between steps (a slice, a
//!   handle, a plane written): the command stops with "interrupted", exit code 130, and the
//!   temporary output file is removed as the error unwinds. A second signal stops at once.
//! - A panic (a bug) prints one line naming it and the command that reproduces it, and the
//!   process exits with code 3 (`RUST_BACKTRACE=1` adds the backtrace).

use std::sync::atomic::{AtomicBool, Ordering};

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Whether SIGINT or SIGTERM arrived.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::Relaxed)
}

#[cfg(unix)]
mod sys {
    extern "C" {
        pub fn signal(signum: i32, handler: usize) -> usize;
        pub fn raise(signum: i32) -> i32;
    }
    pub const SIGINT: i32 = 2;
    pub const SIGPIPE: i32 = 13;
    pub const SIGTERM: i32 = 15;
    pub const SIG_DFL: usize = 0;
}

/// The handler: the first signal asks to stop; a second (the flag already set) takes the
/// default action. Only async-signal-safe calls: an atomic swap, `signal`, `raise`.
#[cfg(unix)]
extern "C" fn on_signal(signum: i32) {
    if INTERRUPTED.swap(true, Ordering::SeqCst) {
        // SAFETY: both are async-signal-safe.
        unsafe {
            sys::signal(signum, sys::SIG_DFL);
            sys::raise(signum);
        }
    }
}

/// Installs the handlers for SIGINT and SIGTERM, before any thread starts.
pub fn catch_interrupts() {
    #[cfg(unix)]
    // SAFETY: installs a handler that only touches an atomic (see `on_signal`).
    unsafe {
        let handler = on_signal as extern "C" fn(i32) as usize;
        sys::signal(sys::SIGINT, handler);
        sys::signal(sys::SIGTERM, handler);
    }
}

/// `isotopo info scan.nii | head` should end quietly when `head` does, as other command-line
/// tools do, not panic on the closed pipe: restore the default action of SIGPIPE (Rust ignores
/// it).
pub fn quiet_on_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: sets a signal disposition to the default, before any thread starts.
    unsafe {
        sys::signal(sys::SIGPIPE, sys::SIG_DFL);
    }
}

/// A panic prints one line: what and where, and the command to run again.
pub fn report_panics() {
    std::panic::set_hook(Box::new(|info| {
        let what = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".to_string());
        let place = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        let command: Vec<String> = std::env::args().map(|a| quoted(&a)).collect();
        eprintln!(
            "isotopo: internal error (please report): {what}{place}; to reproduce: {}",
            command.join(" ")
        );
        if std::env::var_os("RUST_BACKTRACE").is_some_and(|v| v != "0") {
            eprintln!("{}", std::backtrace::Backtrace::force_capture());
        }
    }));
}

/// An argument as a shell reads it back.
fn quoted(arg: &str) -> String {
    let plain = |c: char| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c);
    if !arg.is_empty() && arg.chars().all(plain) {
        arg.to_string()
    } else {
        format!("'{}'", arg.replace('\'', r"'\''"))
    }
}
