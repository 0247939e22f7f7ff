#![allow(dead_code)] // each includer (a fuzz target, tests/fuzz_cases.rs) uses a part
//! The checks of the fuzz targets (`fuzz/fuzz_targets`, which include this file), shared with
//! `tests/fuzz_cases.rs`, which runs them on every case the fuzzers found (`fuzz/regressions`).

use isotopo::progress::NoProgress;
use isotopo::simplify::{KeepReason, Mode};
use isotopo::topology::cases::Connectivity;
use isotopo::volume::{self, InMemoryVolume, ReadOptions};
use isotopo::{SimplifyOptions, Source};
use std::io::Write;
use std::path::Path;

/// The formats `read_volume` picks from by its first byte.
pub const EXTENSIONS: [&str; 10] = [
    "nii", "nii.gz", "nrrd", "nhdr", "mgh", "mgz", "mha", "npy", "tif", "raw",
];

/// Each format's reader, for the per-format targets (`read_nifti`, …): its name and the
/// extensions its first byte picks from (in [`EXTENSIONS`]' order, so the seeds of
/// `read_volume` serve unchanged). The detached headers' data files (`.nhdr`, `.mhd`) are
/// named by the header, so a mutated one mostly points nowhere: a clear error too.
pub const FORMATS: [(&str, &[&str]); 7] = [
    ("nifti", &["nii", "nii.gz"]),
    ("nrrd", &["nrrd", "nhdr"]),
    ("mgh", &["mgh", "mgz"]),
    ("metaimage", &["mha", "mhd"]),
    ("npy", &["npy"]),
    ("tiff", &["tif"]),
    ("raw", &["raw"]),
];

/// Every reader on arbitrary bytes: a clear error or a volume, never a panic, never an
/// allocation the file cannot back. The first byte picks the format (by the file's extension);
/// for the gzip formats the rest is compressed first, so mutations reach the header inside.
/// The file is written in `dir`.
pub fn read_volume(data: &[u8], dir: &Path) {
    read_as(&EXTENSIONS, data, dir);
}

/// [`read_volume`] for one format of [`FORMATS`].
pub fn read_format(format: &str, data: &[u8], dir: &Path) {
    let (_, extensions) = FORMATS
        .iter()
        .find(|(name, _)| *name == format)
        .unwrap_or_else(|| panic!("no format {format}"));
    read_as(extensions, data, dir);
}

/// A folder of this process's own for the files a read target writes.
pub fn scratch_dir() -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("isotopo-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn read_as(extensions: &[&str], data: &[u8], dir: &Path) {
    let Some((&pick, bytes)) = data.split_first() else {
        return;
    };
    let ext = extensions[pick as usize % extensions.len()];
    let path = dir.join(format!("v.{ext}"));
    let content = if ext.ends_with("gz") {
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        e.write_all(bytes).unwrap();
        e.finish().unwrap()
    } else {
        bytes.to_vec()
    };
    std::fs::write(&path, content).unwrap();
    // A headerless file: dims from the first three bytes.
    let options = if ext == "raw" {
        let d = |b: Option<&u8>| 1 + b.copied().unwrap_or(0) as usize % 8;
        ReadOptions {
            raw_dims: Some([d(bytes.first()), d(bytes.get(1)), d(bytes.get(2))]),
            raw_type: Some(volume::DType::I16),
            ..ReadOptions::default()
        }
    } else {
        ReadOptions::default()
    };
    if let Ok(mut reader) = volume::open(&path, &options) {
        let mut slice = volume::Samples::F32(Vec::new());
        for _ in 0..reader.info().dims[2] {
            if reader.read_slice(&mut slice).is_err() {
                break;
            }
        }
        let _ = reader.rewind();
    }
    let _ = volume::read_all(&path, &options);
}

/// The options and volume `simplify_volume` makes of its bytes: three for the grid (2 to 13
/// samples an axis), one for the options, then the samples (inside above 127, repeated to fill
/// the grid). `None` if too short.
pub fn simplify_case(data: &[u8]) -> Option<(InMemoryVolume, SimplifyOptions)> {
    if data.len() < 5 {
        return None;
    }
    let (head, samples) = data.split_at(4);
    let dims = [0, 1, 2].map(|i| 2 + head[i] as usize % 12);
    let bits = head[3];
    let value =
        |x: usize, y: usize, z: usize| samples[(x + dims[0] * (y + dims[1] * z)) % samples.len()];
    let volume = InMemoryVolume::from_mask(dims, |x, y, z| value(x, y, z) > 127);
    let mut opts = SimplifyOptions {
        tau: [0.0, 4.0, 6.0, 10.0, f64::INFINITY][(bits & 7) as usize % 5],
        mode: [Mode::Both, Mode::Both, Mode::FillOnly, Mode::CutOnly][(bits >> 3) as usize & 3],
        max_slices: (bits & 0x20 != 0).then_some(3),
        ..SimplifyOptions::default()
    };
    opts.surface.iso = 0.5;
    opts.surface.connectivity = if bits & 0x40 != 0 {
        Connectivity::TwentySix
    } else {
        Connectivity::Six
    };
    if bits & 0x80 != 0 {
        opts = opts.spherical();
    }
    Some((volume, opts))
}

/// The whole pipeline on a small arbitrary volume, checking its guarantees: simplify succeeds
/// on any valid volume (its own check of the whole result turns a broken guarantee into an
/// error, which fails here), `--tau inf` with both operations leaves genus 0, a handle is kept
/// only for a reason the options allow, and simplify run again on its output changes nothing
/// unless the first run kept a component or cavity.
pub fn simplify_volume(data: &[u8]) {
    let Some((volume, opts)) = simplify_case(data) else {
        return;
    };
    let mut done = match isotopo::simplify(Source::from(volume), &opts, &NoProgress) {
        Ok(done) => done,
        Err(e) => panic!("simplify failed on a valid volume: {e}"),
    };
    for k in &done.outcome.kept {
        let allowed = match k.reason {
            KeepReason::Size => true,
            KeepReason::Mode | KeepReason::ClosureFailed => opts.mode != Mode::Both,
            _ => false,
        };
        assert!(allowed, "a handle kept for {:?} ({opts:?})", k.reason);
    }
    if opts.tau.is_infinite() && opts.mode == Mode::Both {
        assert_eq!(done.after.b1, 0, "genus left at tau inf ({opts:?})");
    }
    // Run again on its output, simplify has nothing left to do (its rounds of opening handles
    // end where they begin), unless the first run kept a component or cavity: the walls and
    // flips since may have made room to remove it.
    if !done.outcome.parts.kept.is_empty() {
        return;
    }
    let edited = done.edited().expect("the edited volume");
    let again =
        isotopo::simplify(Source::from(edited), &opts, &NoProgress).expect("simplify again");
    assert!(
        again.outcome.edits.is_empty(),
        "a second run changed {} samples: {:?} ({opts:?}; the first changed {:?})",
        again.outcome.edits.len(),
        again.outcome.edits,
        done.outcome.edits,
    );
}
