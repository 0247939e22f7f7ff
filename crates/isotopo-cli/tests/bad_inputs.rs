//! Bad input gets a clear message and exit code 2, never a panic, and leaves no output behind.

mod common;

use common::{isotopo, listing};
use std::io::Write;
use std::process::Command;

/// A valid little NIfTI-1 volume (4×3×2 int16) as bytes.
fn nifti_bytes(datatype: i16, bitpix: i16, dims: [i16; 3]) -> Vec<u8> {
    let mut h = vec![0u8; 352];
    h[0..4].copy_from_slice(&348i32.to_le_bytes());
    let dim = [3i16, dims[0], dims[1], dims[2], 1, 1, 1, 1];
    for (i, d) in dim.iter().enumerate() {
        h[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
    }
    h[70..72].copy_from_slice(&datatype.to_le_bytes());
    h[72..74].copy_from_slice(&bitpix.to_le_bytes());
    for i in 0..4 {
        h[76 + 4 * i..80 + 4 * i].copy_from_slice(&1f32.to_le_bytes());
    }
    h[108..112].copy_from_slice(&352f32.to_le_bytes());
    h[344..348].copy_from_slice(b"n+1\0");
    h
}

fn good_nifti() -> Vec<u8> {
    let mut b = nifti_bytes(4, 16, [4, 3, 2]);
    for i in 0..24i16 {
        b.extend_from_slice(&(i * 10).to_le_bytes());
    }
    b
}

/// A NumPy .npy (version 1) with the given descr and shape in its header, and 24 int16 samples.
fn npy_bytes(descr: &str, shape: &str) -> Vec<u8> {
    let mut dict = format!("{{'descr': {descr}, 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + dict.len() + 1) % 64 != 0 {
        dict.push(' ');
    }
    dict.push('\n');
    let mut b = b"\x93NUMPY\x01\x00".to_vec();
    b.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    b.extend_from_slice(dict.as_bytes());
    b.extend_from_slice(&[0u8; 48]);
    b
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

struct Case {
    name: &'static str,
    /// Files to create: (name, bytes).
    files: Vec<(&'static str, Vec<u8>)>,
    /// Arguments; `{d}` is replaced by the case's directory.
    args: Vec<&'static str>,
    /// Substrings the error message must contain.
    message: &'static [&'static str],
}

fn cases() -> Vec<Case> {
    let good = good_nifti();
    let mut truncated = good.clone();
    truncated.truncate(352 + 30);
    let big_gz = {
        // Enough data that the cut falls inside the deflate stream.
        let mut b = nifti_bytes(4, 16, [64, 64, 16]);
        for i in 0..64 * 64 * 16u32 {
            b.extend_from_slice(&((i.wrapping_mul(2654435761) >> 20) as i16).to_le_bytes());
        }
        gzip(&b)
    };
    let mut truncated_gz = big_gz.clone();
    truncated_gz.truncate(big_gz.len() / 2);
    let mut corrupt_gz = big_gz.clone();
    let mid = corrupt_gz.len() / 3;
    for b in &mut corrupt_gz[mid..mid + 64] {
        *b ^= 0x5a;
    }
    let mut zero_dims = nifti_bytes(4, 16, [4, 0, 2]);
    zero_dims.extend_from_slice(&[0u8; 48]);
    let absurd = {
        // NIfTI-2 claiming 2^31 samples per axis.
        let mut h = vec![0u8; 544];
        h[0..4].copy_from_slice(&540i32.to_le_bytes());
        h[4..12].copy_from_slice(b"n+2\0\r\n\x1a\n");
        h[12..14].copy_from_slice(&4i16.to_le_bytes());
        h[14..16].copy_from_slice(&16i16.to_le_bytes());
        let dim = [3i64, 1 << 31, 1 << 31, 1 << 31, 1, 1, 1, 1];
        for (i, d) in dim.iter().enumerate() {
            h[16 + 8 * i..24 + 8 * i].copy_from_slice(&d.to_le_bytes());
        }
        h[168..176].copy_from_slice(&544i64.to_le_bytes());
        h.extend_from_slice(&[0u8; 100]);
        h
    };
    let absurd_gz = {
        let mut b = nifti_bytes(2, 8, [4000, 4000, 4000]);
        b.extend_from_slice(&[0u8; 1000]);
        gzip(&b)
    };
    let mut rgb = nifti_bytes(128, 24, [4, 3, 2]);
    rgb.extend_from_slice(&[0u8; 72]);
    let bzip_nrrd =
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 3 2\nencoding: bzip2\n\nxxxxxxxx".to_vec();
    let int64_nrrd =
        b"NRRD0004\ntype: int64\ndimension: 3\nsizes: 4 3 2\nendian: little\nencoding: raw\n\n"
            .to_vec();
    let missing_detached = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 3 2\nencoding: raw\ndata file: nowhere.raw\n\n".to_vec();
    let wrong_size_detached =
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 3 2\nencoding: raw\ndata file: d.raw\n\n"
            .to_vec();
    vec![
        Case {
            name: "truncated data",
            files: vec![("t.nii", truncated.clone())],
            args: vec!["info", "{d}/t.nii"],
            message: &["t.nii", "truncated", "4×3×2 int16"],
        },
        Case {
            name: "truncated gzip",
            files: vec![("t.nii.gz", truncated_gz)],
            args: vec!["info", "{d}/t.nii.gz"],
            message: &["t.nii.gz", "truncated", "z-slice"],
        },
        Case {
            name: "corrupt gzip",
            files: vec![("c.nii.gz", corrupt_gz)],
            args: vec!["convert", "{d}/c.nii.gz", "-o", "{d}/out.nii"],
            message: &["c.nii.gz", "corrupt"],
        },
        Case {
            name: "raw size does not match dims × type",
            files: vec![("v.raw", vec![0u8; 100])],
            args: vec![
                "info",
                "{d}/v.raw",
                "--raw-dims",
                "4,3,2",
                "--raw-type",
                "int16",
            ],
            message: &["v.raw", "52 more", "exactly 48 bytes"],
        },
        Case {
            name: "detached data of the wrong size",
            files: vec![("w.nhdr", wrong_size_detached), ("d.raw", vec![0u8; 25])],
            args: vec!["info", "{d}/w.nhdr"],
            message: &["d.raw", "exactly 24 bytes"],
        },
        Case {
            name: "zero dimension",
            files: vec![("z.nii", zero_dims)],
            args: vec!["info", "{d}/z.nii"],
            message: &["z.nii", "dim[2] = 0"],
        },
        Case {
            name: "absurd dimensions",
            files: vec![("a.nii", absurd)],
            args: vec!["info", "{d}/a.nii"],
            message: &["a.nii", "absurd dimensions"],
        },
        Case {
            name: "dimensions impossible for the compressed size",
            files: vec![("a.nii.gz", absurd_gz)],
            args: vec!["info", "{d}/a.nii.gz"],
            message: &["a.nii.gz", "header is corrupt"],
        },
        Case {
            name: "unsupported NIfTI type",
            files: vec![("rgb.nii", rgb)],
            args: vec!["info", "{d}/rgb.nii"],
            message: &["rgb.nii", "unsupported sample type RGB24"],
        },
        Case {
            name: "unsupported NRRD type",
            files: vec![("i64.nrrd", int64_nrrd)],
            args: vec!["info", "{d}/i64.nrrd"],
            message: &["i64.nrrd", "unsupported sample type \"int64\""],
        },
        Case {
            name: "unsupported encoding",
            files: vec![("b.nrrd", bzip_nrrd)],
            args: vec!["info", "{d}/b.nrrd"],
            message: &["b.nrrd", "unsupported encoding \"bzip2\""],
        },
        Case {
            name: "missing detached file",
            files: vec![("m.nhdr", missing_detached)],
            args: vec!["info", "{d}/m.nhdr"],
            message: &["m.nhdr", "nowhere.raw does not exist"],
        },
        Case {
            name: "not a volume",
            files: vec![(
                "text.nii",
                b"hello, this is not a NIfTI file at all".repeat(20),
            )],
            args: vec!["info", "{d}/text.nii"],
            message: &["text.nii", "header size field"],
        },
        Case {
            name: "raw without dimensions",
            files: vec![("plain.raw", vec![0u8; 24])],
            args: vec!["info", "{d}/plain.raw"],
            message: &["plain.raw", "--raw-dims"],
        },
        Case {
            name: "output equal to input",
            files: vec![("g.nii", good.clone())],
            args: vec!["convert", "{d}/g.nii", "-o", "{d}/./g.nii"],
            message: &["would overwrite the input"],
        },
        Case {
            name: "output directory missing",
            files: vec![("g.nii", good.clone())],
            args: vec!["convert", "{d}/g.nii", "-o", "{d}/no/such/dir/out.nii"],
            message: &["does not exist"],
        },
        Case {
            name: "unwritable output",
            files: vec![("g.nii", good.clone())],
            args: vec!["convert", "{d}/g.nii", "-o", "/proc/isotopo-test.nii"],
            message: &["/proc/isotopo-test.nii", "error creating"],
        },
        Case {
            name: "type the output format cannot store",
            files: vec![("g.nii", {
                let mut b = nifti_bytes(512, 16, [4, 3, 2]);
                b.extend_from_slice(&[0u8; 48]);
                b
            })],
            args: vec!["convert", "{d}/g.nii", "-o", "{d}/out.mgz"],
            message: &["MGH cannot store uint16"],
        },
        Case {
            name: "unknown output extension",
            files: vec![("g.nii", good.clone())],
            args: vec!["convert", "{d}/g.nii", "-o", "{d}/out.xyz"],
            message: &["cannot tell the output format"],
        },
        Case {
            // Found by mutating files (issue 20): the dtype's first byte not ASCII panicked.
            name: "npy dtype not ASCII",
            files: vec![("a.npy", npy_bytes("'\u{2026}i2'", "(4, 3, 2)"))],
            args: vec!["info", "{d}/a.npy"],
            message: &["a.npy", "dtype"],
        },
        Case {
            name: "npy dtype empty",
            files: vec![("a.npy", npy_bytes("''", "(4, 3, 2)"))],
            args: vec!["genus", "{d}/a.npy", "--iso", "1"],
            message: &["a.npy", "dtype"],
        },
        Case {
            name: "missing input",
            files: vec![],
            args: vec!["info", "{d}/nothing.nii"],
            message: &["nothing.nii", "error opening"],
        },
        Case {
            name: "simplify: truncated input",
            files: vec![("t.nii", truncated.clone())],
            args: vec![
                "simplify",
                "{d}/t.nii",
                "--iso",
                "50",
                "--tau",
                "20",
                "-o",
                "{d}/out.nii",
            ],
            message: &["t.nii", "truncated", "4×3×2 int16"],
        },
        Case {
            name: "simplify: tau negative",
            files: vec![("g.nii", good.clone())],
            args: vec![
                "simplify",
                "{d}/g.nii",
                "--iso",
                "50",
                "--tau=-1",
                "-o",
                "{d}/out.nii",
            ],
            message: &["--tau must be 0", "positive or inf"],
        },
        Case {
            name: "simplify: tau not a number",
            files: vec![("g.nii", good.clone())],
            args: vec![
                "simplify",
                "{d}/g.nii",
                "--iso",
                "50",
                "--tau",
                "nan",
                "-o",
                "{d}/out.nii",
            ],
            message: &["--tau must be 0", "positive or inf"],
        },
        Case {
            name: "simplify: max ratio below 1",
            files: vec![("g.nii", good.clone())],
            args: vec![
                "simplify",
                "{d}/g.nii",
                "--iso",
                "50",
                "--tau",
                "20",
                "--max-ratio",
                "0.5",
                "-o",
                "{d}/out.nii",
            ],
            message: &["--max-ratio must be at least 1"],
        },
        Case {
            name: "simplify: fill only and cut only",
            files: vec![("g.nii", good.clone())],
            args: vec![
                "simplify",
                "{d}/g.nii",
                "--iso",
                "50",
                "--tau",
                "20",
                "--fill-only",
                "--cut-only",
                "-o",
                "{d}/out.nii",
            ],
            message: &["--fill-only", "cannot be used with"],
        },
        Case {
            name: "simplify: output equal to input",
            files: vec![("g.nii", good.clone())],
            args: vec![
                "simplify",
                "{d}/g.nii",
                "--iso",
                "50",
                "--tau",
                "20",
                "-o",
                "{d}/g.nii",
            ],
            message: &["would overwrite the input"],
        },
        Case {
            name: "simplify: mesh and volume to the same file",
            files: vec![("g.nii", good.clone())],
            args: vec![
                "simplify",
                "{d}/g.nii",
                "--iso",
                "50",
                "--tau",
                "20",
                "-o",
                "{d}/out.nii",
                "--mesh",
                "{d}/out.nii",
            ],
            message: &["given as two different outputs"],
        },
        Case {
            name: "simplify: report in a missing directory",
            files: vec![("g.nii", good.clone())],
            args: vec![
                "simplify",
                "{d}/g.nii",
                "--iso",
                "50",
                "--tau",
                "20",
                "-o",
                "{d}/out.nii",
                "--report",
                "{d}/no/such/dir/r.json",
            ],
            message: &["does not exist"],
        },
    ]
}

#[test]
fn bad_inputs_get_clear_errors_and_exit_code_2() {
    let mut failures = Vec::new();
    for case in cases() {
        let dir = tempfile::tempdir().unwrap();
        for (name, bytes) in &case.files {
            std::fs::write(dir.path().join(name), bytes).unwrap();
        }
        let before = listing(dir.path());
        let d = dir.path().to_string_lossy().to_string();
        let args: Vec<String> = case.args.iter().map(|a| a.replace("{d}", &d)).collect();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (code, _out, err) = isotopo(&args);
        let mut problems = Vec::new();
        if code != 2 {
            problems.push(format!("exit code {code}, expected 2"));
        }
        if err.contains("panicked") {
            problems.push("panicked".into());
        }
        for m in case.message {
            if !err.contains(m) {
                problems.push(format!("message lacks {m:?}"));
            }
        }
        if listing(dir.path()) != before {
            problems.push(format!("files changed: {:?}", listing(dir.path())));
        }
        if !problems.is_empty() {
            failures.push(format!(
                "{}: {} — stderr: {}",
                case.name,
                problems.join(", "),
                err.trim()
            ));
        }
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

#[test]
fn good_input_still_works() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("g.nii");
    std::fs::write(&p, good_nifti()).unwrap();
    let (code, out, err) = isotopo(&["info", p.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("4 × 3 × 2"), "{out}");
    assert!(out.contains("max 230"), "{out}");
    let o = dir.path().join("o.nrrd");
    let (code, _, err) = isotopo(&["convert", p.to_str().unwrap(), "-o", o.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        listing(dir.path()).len(),
        2,
        "no temporary files left: {:?}",
        listing(dir.path())
    );
}

/// Out of core with nowhere to put the scratch file: a clear message (where, how to fix it),
/// exit code 2, no output left.
#[test]
fn unwritable_scratch_folder_is_a_clear_error() {
    let d = tempfile::tempdir().unwrap();
    // 4×3×2 volume: a window of 8 planes covers it, so this asks for 20 planes along z.
    let mut b = nifti_bytes(4, 16, [4, 3, 20]);
    for i in 0..240i16 {
        b.extend_from_slice(&(i % 7 * 10).to_le_bytes());
    }
    let input = d.path().join("tall.nii");
    std::fs::write(&input, b).unwrap();
    let output = d.path().join("out.nii");
    let out = Command::new(env!("CARGO_BIN_EXE_isotopo"))
        .args([
            "simplify",
            input.to_str().unwrap(),
            "--iso",
            "30",
            "--tau",
            "20",
        ])
        .args(["-o", output.to_str().unwrap(), "--max-slices", "8", "-q"])
        .env("TMPDIR", d.path().join("missing"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    for want in ["scratch file", "missing", "TMPDIR", "--max-slices 0"] {
        assert!(stderr.contains(want), "message lacks {want:?}: {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!output.exists());
}
