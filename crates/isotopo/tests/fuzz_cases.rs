//! Every case the fuzzers kept (`fuzz/regressions/<target>/`: the crashes they found, fixed
//! since, and a few inputs that reach far) through the fuzz targets' own checks.

mod fuzz_checks;

use std::path::PathBuf;

fn cases(target: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../fuzz/regressions")
        .join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no cases in {}", dir.display());
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
    for (path, bytes) in cases("read_volume") {
        eprintln!("{}", path.display());
        fuzz_checks::read_volume(&bytes, dir.path());
    }
}

#[test]
fn simplify_volume_cases() {
    for (path, bytes) in cases("simplify_volume") {
        eprintln!("{}", path.display());
        fuzz_checks::simplify_volume(&bytes);
    }
}
