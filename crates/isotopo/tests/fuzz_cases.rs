//! Every case the fuzzers kept (`fuzz/regressions/<target>/`: the crashes they found, fixed
//! since, and a few inputs that reach far) through the fuzz targets' own checks.

mod fuzz_checks;

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The fuzzers fail any single allocation above 2 GiB (`-rss_limit_mb=2048`): one sized from a
/// header the file cannot back. Here the largest allocation is recorded, so a kept case fails
/// the same way without libFuzzer.
struct Recording;

static LARGEST: AtomicUsize = AtomicUsize::new(0);
const LARGEST_ALLOWED: usize = 2 << 30;

// SAFETY: every call goes to the system allocator unchanged; only the size is recorded.
unsafe impl GlobalAlloc for Recording {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        System.alloc(layout)
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        System.alloc_zeroed(layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        System.realloc(ptr, layout, new_size)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
}

#[global_allocator]
static ALLOCATOR: Recording = Recording;

/// Fails if a case allocated more than the fuzzers allow at once.
fn no_huge_allocation(case: &std::path::Path) {
    let largest = LARGEST.swap(0, Ordering::Relaxed);
    assert!(
        largest <= LARGEST_ALLOWED,
        "{}: an allocation of {largest} bytes",
        case.display()
    );
}

/// The cases kept for `target` (none if it has no folder yet).
fn cases(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fuzz/regressions")
        .join(target);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries.map(|e| e.unwrap().path()).collect();
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let b = std::fs::read(&p).unwrap();
            (p, b)
        })
        .collect()
}

#[test]
fn read_volume_cases() {
    let dir = tempfile::tempdir().unwrap();
    let kept = cases("read_volume");
    assert!(!kept.is_empty(), "the read_volume cases are missing");
    for (path, bytes) in kept {
        eprintln!("{}", path.display());
        fuzz_checks::read_volume(&bytes, dir.path());
        no_huge_allocation(&path);
    }
    for (format, _) in fuzz_checks::FORMATS {
        for (path, bytes) in cases(&format!("read_{format}")) {
            eprintln!("{}", path.display());
            fuzz_checks::read_format(format, &bytes, dir.path());
            no_huge_allocation(&path);
        }
    }
}

#[test]
fn simplify_volume_cases() {
    let kept = cases("simplify_volume");
    assert!(!kept.is_empty(), "the simplify_volume cases are missing");
    for (path, bytes) in kept {
        eprintln!("{}", path.display());
        fuzz_checks::simplify_volume(&bytes);
    }
}
