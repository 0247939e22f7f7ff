//! The memory limit: how large the process may grow before a job stops with [`Error::Memory`],
//! naming what would not fit, instead of being killed by the system.
//!
//! The limit is on the process's resident memory (what the system's out-of-memory killer looks
//! at), so it is one setting for the process ([`set_limit`]); by default 3/4 of the machine's
//! memory, or of the control group's limit when that is lower (a container). It is checked:
//!
//! - before each allocation sized from the volume ([`reserve`]): slice buffers, the planes of
//!   inside bits kept in memory, the labels of the components-and-cavities phase, a whole volume
//!   of samples in memory. These fail before anything is allocated, with what and how much;
//! - between the steps of every stage ([`check`], at most every few milliseconds), for what grows
//!   as a job runs: contours, loop searches, handle lists, meshes. A single step can pass the limit
//!   by what it allocates before the next check (one handle's loop searches, one slice's
//!   triangles).
//!
//! On systems without `/proc` the resident size is unknown: only [`reserve`]'s sizes count.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;
use std::time::Instant;

use crate::error::{Error, Result};

/// The limit in bytes; 0 until [`set_limit`] (the default then applies).
static LIMIT: AtomicU64 = AtomicU64::new(0);

/// Sets the memory limit of the process, in bytes; `None` restores the default
/// ([`default_limit`]).
pub fn set_limit(bytes: Option<u64>) {
    LIMIT.store(bytes.unwrap_or(0), Ordering::Relaxed);
}

/// The memory limit in force, in bytes.
pub fn limit() -> u64 {
    match LIMIT.load(Ordering::Relaxed) {
        0 => default_limit(),
        n => n,
    }
}

/// 3/4 of [`machine`] (no limit when that is unknown).
pub fn default_limit() -> u64 {
    static DEFAULT: OnceLock<u64> = OnceLock::new();
    *DEFAULT.get_or_init(|| machine().map_or(u64::MAX, |m| m / 4 * 3))
}

/// The memory this process can have: the machine's (`MemTotal`), or the lowest limit of its
/// control group and the groups above it when lower (a container, a batch job's allocation,
/// `systemd-run -p MemoryMax=`). `None` where neither can be read.
pub fn machine() -> Option<u64> {
    let total = std::fs::read_to_string("/proc/meminfo").ok().and_then(|s| {
        let line = s.lines().find(|l| l.starts_with("MemTotal:"))?;
        let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kb * 1024)
    });
    let group = std::fs::read_to_string("/proc/self/cgroup")
        .ok()
        .and_then(|groups| cgroup_limit(&groups, Path::new("/sys/fs/cgroup")));
    match (total, group) {
        (Some(t), Some(g)) => Some(t.min(g)),
        (t, g) => t.or(g),
    }
}

/// The lowest memory limit of the control groups in `/proc/self/cgroup` (`groups`) and their
/// parents, under the cgroup file system mounted at `root`: v2 (`0::/path`, `memory.max` and
/// `memory.high`) or v1 (`N:memory:/path`, `memory.limit_in_bytes`). Inside a cgroup
/// namespace the paths are `/` and the files at the root are the group's own. "max" (v2) or a
/// huge number (v1) means no limit.
fn cgroup_limit(groups: &str, root: &Path) -> Option<u64> {
    let mut lowest: Option<u64> = None;
    for line in groups.lines() {
        let mut fields = line.splitn(3, ':');
        let (_, controllers, path) = (fields.next()?, fields.next()?, fields.next()?);
        let (dir, files): (PathBuf, &[&str]) = match controllers {
            "" => (root.to_path_buf(), &["memory.max", "memory.high"]),
            c if c.split(',').any(|c| c == "memory") => {
                (root.join("memory"), &["memory.limit_in_bytes"])
            }
            _ => continue,
        };
        let mut at = Some(Path::new(path.trim()));
        while let Some(p) = at {
            let group = dir.join(p.strip_prefix("/").unwrap_or(p));
            for f in files {
                let limit = std::fs::read_to_string(group.join(f))
                    .ok()
                    .and_then(|v| v.trim().parse::<u64>().ok())
                    .filter(|&v| v < 1 << 60);
                if let Some(v) = limit {
                    lowest = Some(lowest.map_or(v, |l| l.min(v)));
                }
            }
            at = p.parent();
        }
    }
    lowest
}

/// The process's resident memory now, in bytes (`None` without `/proc`).
pub fn resident() -> Option<u64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * page_size()?)
}

#[cfg(unix)]
fn page_size() -> Option<u64> {
    static PAGE: OnceLock<u64> = OnceLock::new();
    Some(*PAGE.get_or_init(|| rustix::param::page_size() as u64))
}

#[cfg(not(unix))]
fn page_size() -> Option<u64> {
    None
}

/// Fails with [`Error::Memory`] if allocating `bytes` for `what` would take the process past the
/// limit. Call it before the allocation; `what` says what it is for ("the labels of the
/// components-and-cavities phase, 4 bytes a sample").
pub fn reserve(what: &str, bytes: u64) -> Result<()> {
    let limit = limit();
    let in_use = resident().unwrap_or(0);
    if in_use.saturating_add(bytes) > limit {
        return Err(Error::Memory {
            what: what.to_string(),
            needed: Some(bytes),
            in_use,
            limit,
        });
    }
    Ok(())
}

/// Fails with [`Error::Memory`] if the process has grown past the limit while `stage` ran.
/// Reads the resident size at most once every [`CHECK_EVERY_MS`] milliseconds, so it can be
/// called at every step.
pub fn check(stage: &str) -> Result<()> {
    static START: OnceLock<Instant> = OnceLock::new();
    // Milliseconds since START of the last reading, plus one (0: none yet).
    static LAST: AtomicU64 = AtomicU64::new(0);
    let now = START.get_or_init(Instant::now).elapsed().as_millis() as u64 + 1;
    let last = LAST.load(Ordering::Relaxed);
    let due = last == 0 || now >= last + CHECK_EVERY_MS;
    // One thread reads per period: the others go on.
    if !due
        || LAST
            .compare_exchange(last, now, Ordering::Relaxed, Ordering::Relaxed)
            .is_err()
    {
        return Ok(());
    }
    let (limit, in_use) = (limit(), resident().unwrap_or(0));
    if in_use > limit {
        return Err(Error::Memory {
            what: stage.to_string(),
            needed: None,
            in_use,
            limit,
        });
    }
    Ok(())
}

/// How often [`check`] reads the resident size.
pub const CHECK_EVERY_MS: u64 = 5;

/// Parses a size as a user writes it: bytes (`1000000`), with a binary unit (`512K`, `300M`,
/// `2G`, `1T`; `MiB`, `GB` and lower case too, all powers of 1024), or a percentage of
/// [`machine`] (`50%`).
pub fn parse_size(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    let bad = || {
        format!("{text:?} is not a size: write bytes, or a number with K, M, G or T (powers of 1024), or a percentage of the machine's memory")
    };
    let number_end = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(number_end);
    let number: f64 = number.parse().map_err(|_| bad())?;
    let bytes = match unit.trim().to_ascii_uppercase().as_str() {
        "%" => {
            let m = machine().ok_or("the machine's memory is unknown here: give a size")?;
            if !(number > 0.0 && number <= 100.0) {
                return Err(format!("{text:?}: a percentage above 0 and at most 100"));
            }
            m as f64 * number / 100.0
        }
        "" | "B" => number,
        "K" | "KB" | "KIB" => number * (1u64 << 10) as f64,
        "M" | "MB" | "MIB" => number * (1u64 << 20) as f64,
        "G" | "GB" | "GIB" => number * (1u64 << 30) as f64,
        "T" | "TB" | "TIB" => number * (1u64 << 40) as f64,
        _ => return Err(bad()),
    };
    if bytes < 1.0 {
        return Err(format!("{text:?}: a size of at least one byte"));
    }
    if bytes >= (1u64 << 60) as f64 {
        return Err(format!("{text:?}: a size below 1024 PiB"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_as_users_write_them() {
        assert_eq!(parse_size("1000000"), Ok(1_000_000));
        assert_eq!(parse_size("512K"), Ok(512 << 10));
        assert_eq!(parse_size("300M"), Ok(300 << 20));
        assert_eq!(parse_size("300MiB"), Ok(300 << 20));
        assert_eq!(parse_size("2g"), Ok(2 << 30));
        assert_eq!(parse_size("2 GB"), Ok(2 << 30));
        assert_eq!(parse_size("1.5G"), Ok(3 << 29));
        assert_eq!(parse_size("1T"), Ok(1 << 40));
        for bad in [
            "",
            "G",
            "2X",
            "-1G",
            "0",
            "1e9",
            "2GG",
            "2MBB",
            "2MII",
            "inf",
            "1e2%",
            "0.5",
            "1%%",
            "99999999999T",
        ] {
            assert!(parse_size(bad).is_err(), "{bad:?} was accepted");
        }
        if let Some(m) = machine() {
            assert_eq!(parse_size("50%"), Ok(m / 2));
            assert!(parse_size("0%").is_err() && parse_size("101%").is_err());
            assert!(parse_size("0.0000000000001%").is_err());
        }
    }

    /// A job's group inside a parent with a lower limit: the parent's counts.
    #[test]
    fn the_lowest_limit_of_the_group_and_its_parents() {
        let root = tempfile::tempdir().unwrap();
        let write = |dir: &str, file: &str, value: &str| {
            let d = root.path().join(dir);
            std::fs::create_dir_all(&d).unwrap();
            std::fs::write(d.join(file), value).unwrap();
        };
        write("batch", "memory.max", "4294967296\n");
        write("batch/job7", "memory.max", "max\n");
        write("batch/job7", "memory.high", "8589934592\n");
        assert_eq!(cgroup_limit("0::/batch/job7\n", root.path()), Some(4 << 30));
        write("memory/slurm/job3", "memory.limit_in_bytes", "2147483648\n");
        write("memory", "memory.limit_in_bytes", "9223372036854771712\n");
        let v1 = "9:pids:/\n4:memory:/slurm/job3\n1:cpu:/\n";
        assert_eq!(cgroup_limit(v1, root.path()), Some(2 << 30));
        // No limit anywhere (the root's "max" or v1's huge number), or no memory controller.
        assert_eq!(cgroup_limit("0::/\n", root.path()), None);
        assert_eq!(cgroup_limit("4:memory:/\n", root.path()), None);
        assert_eq!(cgroup_limit("3:cpuset:/\n", root.path()), None);
    }

    #[test]
    fn the_resident_size_is_read() {
        if std::path::Path::new("/proc/self/statm").exists() {
            let r = resident().unwrap();
            assert!(r > 1 << 20 && r < limit(), "{r}");
        }
    }
}
