//! Every case the fuzzers kept (`fuzz/regressions/<target>/`: the crashes they found, fixed
//! since, and a few inputs that reach far) through the fuzz targets' own checks.

mod fuzz_checks;

use std::path::PathBuf;

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
    }
    for (format, _) in fuzz_checks::FORMATS {
        for (path, bytes) in cases(&format!("read_{format}")) {
            eprintln!("{}", path.display());
            fuzz_checks::read_format(format, &bytes, dir.path());
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
