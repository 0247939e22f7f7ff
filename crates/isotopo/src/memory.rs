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

/// The memory this process can have: the machine's (`MemTotal`), or its control group's limit
/// when lower. `None` where neither can be read.
pub fn machine() -> Option<u64> {
    let total = std::fs::read_to_string("/proc/meminfo").ok().and_then(|s| {
        let line = s.lines().find(|l| l.starts_with("MemTotal:"))?;
        let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kb * 1024)
    });
    // cgroup v2, then v1 ("max", or a huge number, when unlimited).
    let group = [
        "/sys/fs/cgroup/memory.max",
        "/sys/fs/cgroup/memory/memory.limit_in_bytes",
    ]
    .iter()
    .find_map(|p| std::fs::read_to_string(p).ok()?.trim().parse::<u64>().ok());
    match (total, group) {
        (Some(t), Some(g)) => Some(t.min(g)),
        (t, g) => t.or(g),
    }
}

/// The process's resident memory now, in bytes (`None` without `/proc`).
pub fn resident() -> Option<u64> {
    let statm = std::fs::read_to_string("/proc/self/statm").ok()?;
    let pages: u64 = statm.split_whitespace().nth(1)?.parse().ok()?;
    Some(pages * page_size())
}

fn page_size() -> u64 {
    static PAGE: OnceLock<u64> = OnceLock::new();
    *PAGE.get_or_init(|| rustix::param::page_size() as u64)
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
    static LAST: AtomicU64 = AtomicU64::new(0);
    let now = START.get_or_init(Instant::now).elapsed().as_millis() as u64 + CHECK_EVERY_MS;
    let last = LAST.load(Ordering::Relaxed);
    if now < last + CHECK_EVERY_MS || LAST.swap(now, Ordering::Relaxed) != last {
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
    if let Some(p) = t.strip_suffix('%') {
        let p: f64 = p.trim().parse().map_err(|_| bad())?;
        let m = machine().ok_or("the machine's memory is unknown here: give a size")?;
        if !(p > 0.0 && p <= 100.0) {
            return Err(format!("{text:?}: a percentage between 0 and 100"));
        }
        return Ok((m as f64 * p / 100.0) as u64);
    }
    let digits = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(digits);
    let number: f64 = number.parse().map_err(|_| bad())?;
    let unit = unit.trim().to_ascii_uppercase();
    let shift = match unit.trim_end_matches('B').trim_end_matches('I') {
        "" if unit.is_empty() || unit == "B" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(bad()),
    };
    let bytes = number * (1u64 << shift) as f64;
    if !(bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("{text:?}: a size of at least one byte"));
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
        for bad in ["", "G", "2X", "-1G", "0", "1e9", "2GG", "inf"] {
            assert!(parse_size(bad).is_err(), "{bad:?} was accepted");
        }
        if let Some(m) = machine() {
            assert_eq!(parse_size("50%"), Ok(m / 2));
            assert!(parse_size("0%").is_err() && parse_size("101%").is_err());
        }
    }

    #[test]
    fn the_resident_size_is_read() {
        if std::path::Path::new("/proc/self/statm").exists() {
            let r = resident().unwrap();
            assert!(r > 1 << 20 && r < limit(), "{r}");
        }
    }
}
