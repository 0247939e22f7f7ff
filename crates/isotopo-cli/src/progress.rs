//! Progress bars on stderr, shown only on a terminal and without `--quiet`.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use isotopo::progress::Progress;
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Duration;

pub struct Bars {
    bar: Mutex<Option<ProgressBar>>,
    enabled: bool,
    /// `ISOTOPO_DEBUG` is set: the library's trace lines go to stderr.
    tracing: bool,
}

impl Bars {
    pub fn new(quiet: bool) -> Bars {
        Bars {
            bar: Mutex::new(None),
            enabled: !quiet && std::io::stderr().is_terminal(),
            tracing: std::env::var_os("ISOTOPO_DEBUG").is_some(),
        }
    }
}

impl Progress for Bars {
    fn cancelled(&self) -> bool {
        crate::signals::interrupted()
    }

    fn start(&self, stage: &str, total: u64) {
        if !self.enabled {
            return;
        }
        let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr_with_hz(8));
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix:>12.cyan.bold} [{bar:32}] {pos}/{len} {msg} ({elapsed})",
            )
            .unwrap()
            .progress_chars("=> "),
        );
        bar.set_prefix(stage.to_string());
        bar.enable_steady_tick(Duration::from_millis(250));
        if let Some(old) = self.bar.lock().unwrap().replace(bar) {
            old.finish_and_clear();
        }
    }

    fn advance(&self, n: u64) {
        if let Some(b) = self.bar.lock().unwrap().as_ref() {
            b.inc(n);
        }
    }

    fn message(&self, msg: &str) {
        if let Some(b) = self.bar.lock().unwrap().as_ref() {
            b.set_message(msg.to_string());
        }
    }

    fn finish(&self) {
        if let Some(b) = self.bar.lock().unwrap().take() {
            b.finish_and_clear();
        }
    }

    fn trace(&self, line: std::fmt::Arguments<'_>) {
        if self.tracing {
            eprintln!("{line}");
        }
    }
}
