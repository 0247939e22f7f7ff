//! One error type for the whole library.
//!
//! Every error a user can cause carries the file it is about, what was found there and what was
//! expected, so the message alone tells them what to fix:
//!
//! ```text
//! scan.nii.gz: data ends after 12 of 361 slices (truncated file?); expected 512×512×361 int16 samples
//! ```

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

/// What went wrong, with enough context to act on it.
#[derive(Debug)]
pub enum Error {
    /// A file's content is not what it should be (bad header, truncated data, unsupported type…).
    Input {
        /// The file.
        path: PathBuf,
        /// What was found.
        found: String,
        /// What was expected instead.
        expected: String,
    },
    /// The operating system refused an operation on a file.
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done ("reading", "creating"…).
        action: &'static str,
        /// The operating system's error.
        source: io::Error,
    },
    /// A scratch file a job keeps out of memory (in `TMPDIR`) could not be made, written or read
    /// back: most often a full disk.
    Scratch {
        /// What was being done: "write the scratch file of the loops in /tmp".
        what: String,
        /// The operating system's error.
        source: io::Error,
        /// What to do about it.
        advice: &'static str,
    },
    /// The options do not make sense together (missing `--raw-dims`, output equal to input…).
    Usage(String),
    /// A bug: an internal invariant failed. Reported rather than panicking.
    Internal(String),
    /// The process would grow past its memory limit ([`crate::memory`]); nothing was written.
    Memory {
        /// What needed the memory: an allocation ("the labels of ..."), or the stage running when
        /// the process grew past the limit ("loops").
        what: String,
        /// The allocation's size, or `None` when the process grew past the limit during `what`.
        needed: Option<u64>,
        /// The process's resident memory when this was found, in bytes.
        in_use: u64,
        /// The limit, in bytes.
        limit: u64,
    },
    /// The caller asked to stop ([`crate::progress::Progress::cancelled`]); nothing was written.
    Cancelled,
}

/// The library's result: [`Error`] by default.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// A problem with the content of `path`.
    pub fn input(
        path: impl AsRef<Path>,
        found: impl Into<String>,
        expected: impl Into<String>,
    ) -> Self {
        Error::Input {
            path: path.as_ref().to_path_buf(),
            found: found.into(),
            expected: expected.into(),
        }
    }

    /// An operating-system error while doing `action` ("reading", "creating", …) on `path`.
    pub fn io(path: impl AsRef<Path>, action: &'static str, source: io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            action,
            source,
        }
    }

    /// A scratch file in `TMPDIR` failed: `action` ("write") on the scratch file of `of` ("the
    /// loops").
    pub(crate) fn scratch(action: &str, of: &str, source: io::Error, advice: &'static str) -> Self {
        Error::Scratch {
            what: format!(
                "cannot {action} the scratch file of {of} in {}",
                std::env::temp_dir().display()
            ),
            source,
            advice,
        }
    }

    /// Options that do not make sense together, with what to do instead.
    pub fn usage(msg: impl Into<String>) -> Self {
        Error::Usage(msg.into())
    }

    /// True for errors caused by the user's files or options (exit code 2), false for bugs.
    pub fn is_user_error(&self) -> bool {
        !matches!(self, Error::Internal(_))
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Input {
                path,
                found,
                expected,
            } => write!(f, "{}: {}; expected {}", path.display(), found, expected),
            Error::Io {
                path,
                action,
                source,
            } => write!(
                f,
                "{}: error {} the file: {}",
                path.display(),
                action,
                source
            ),
            Error::Scratch {
                what,
                source,
                advice,
            } => write!(f, "{what}: {source}; {advice}"),
            Error::Usage(msg) => write!(f, "{msg}"),
            Error::Internal(msg) => write!(f, "internal error (please report): {msg}"),
            Error::Memory {
                what,
                needed,
                in_use,
                limit,
            } => {
                match needed {
                    Some(n) => write!(
                        f,
                        "not enough memory for {what}: {} more, with {} in use",
                        human(*n),
                        human(*in_use)
                    )?,
                    None => write!(
                        f,
                        "the process grew to {} during the {what}",
                        human(*in_use)
                    )?,
                }
                write!(
                    f,
                    ", over the memory limit of {} (--max-memory, or isotopo.set_memory_limit in \
                     Python; by default 3/4 of the memory this process can have)",
                    human(*limit)
                )
            }
            Error::Cancelled => write!(f, "cancelled"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } | Error::Scratch { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// `bytes` as a person reads it: "12.0 MiB", "3.25 GiB".
fn human(bytes: u64) -> String {
    let b = bytes as f64;
    match bytes {
        _ if bytes >= 1 << 30 => format!("{:.2} GiB", b / (1u64 << 30) as f64),
        _ if bytes >= 1 << 20 => format!("{:.1} MiB", b / (1u64 << 20) as f64),
        _ if bytes >= 1 << 10 => format!("{:.1} KiB", b / 1024.0),
        _ => format!("{bytes} bytes"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn human_sizes() {
        assert_eq!(human(1000), "1000 bytes");
        assert_eq!(human(3 << 20), "3.0 MiB");
        assert_eq!(human(13 << 29), "6.50 GiB");
    }
}
