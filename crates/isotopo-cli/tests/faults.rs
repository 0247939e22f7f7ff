//! Interrupts and bugs: Ctrl-C or SIGTERM stops a run with exit code 130, leaves no temporary
//! file and the earlier output as it was; a panic is one line and exit code 3.

mod common;

use common::{convert, listing};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Uniform noise, uint8, in `dir` under a name that gives its dims and type (xorshift from
/// `seed`).
fn noise_file(dir: &Path, [nx, ny, nz]: [usize; 3], seed: u64) -> std::path::PathBuf {
    let mut state = seed;
    let bytes: Vec<u8> = (0..nx * ny * nz)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 32) as u8
        })
        .collect();
    let path = dir.join(format!("noise_{nx}x{ny}x{nz}_uint8.raw"));
    std::fs::write(&path, bytes).unwrap();
    path
}

/// 64³ of noise: at 127.5 its tens of thousands of handles keep `simplify --tau inf` busy for
/// seconds.
fn noise(dir: &Path) -> std::path::PathBuf {
    noise_file(dir, [64, 64, 64], 0x2545_f491_4f6c_dd1d)
}

fn interrupted_by(signal: &str) {
    let dir = tempfile::tempdir().unwrap();
    let input = noise(dir.path());
    let output = dir.path().join("out.nii");
    std::fs::write(&output, b"the earlier output").unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_isotopo"))
        .args([
            "simplify",
            input.to_str().unwrap(),
            "--iso",
            "127.5",
            "--tau",
            "inf",
        ])
        .args(["-o", output.to_str().unwrap(), "-q"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(700));
    let sent = Instant::now();
    let kill = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{signal}: {stderr}");
    assert!(
        stderr.contains("interrupted; nothing was written"),
        "{stderr}"
    );
    assert!(
        sent.elapsed() < Duration::from_secs(10),
        "{signal}: stopped {:?} after the signal",
        sent.elapsed()
    );
    assert_eq!(std::fs::read(&output).unwrap(), b"the earlier output");
    assert_eq!(
        listing(dir.path()),
        ["noise_64x64x64_uint8.raw", "out.nii"],
        "{signal}: a temporary file left"
    );
}

#[test]
fn ctrl_c_stops_and_leaves_the_earlier_output() {
    interrupted_by("-INT");
}

#[test]
fn sigterm_stops_and_leaves_the_earlier_output() {
    interrupted_by("-TERM");
}

#[test]
fn a_bug_is_one_line_and_exit_code_3() {
    let dir = tempfile::tempdir().unwrap();
    let input = noise(dir.path());
    let out = Command::new(env!("CARGO_BIN_EXE_isotopo"))
        .args(["genus", input.to_str().unwrap(), "--iso", "127.5"])
        .env("ISOTOPO_PANIC_FOR_TESTS", "1")
        .env_remove("RUST_BACKTRACE")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("isotopo: internal error (please report): a deliberate panic at "),
        "{stderr}"
    );
    assert!(stderr.contains("; to reproduce: "), "{stderr}");
    assert!(
        stderr.contains(" genus ") && stderr.trim_end().ends_with("--iso 127.5"),
        "{stderr}"
    );
}

/// Whether `dir`'s filesystem makes unnamed files (Linux `O_TMPFILE`), where isotopo stages its
/// outputs when it can.
fn has_unnamed_files(dir: &Path) -> bool {
    use std::os::unix::fs::OpenOptionsExt;
    const O_TMPFILE: i32 = 0o20_000_000 | 0o200_000; // __O_TMPFILE | O_DIRECTORY
    std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(O_TMPFILE)
        .open(dir)
        .is_ok()
}

/// 32 MiB of noise (256×256×512 uint8): converting it to `.nii.gz` takes about a second, and
/// writes from the first slice read.
fn big_noise(dir: &Path) -> std::path::PathBuf {
    noise_file(dir, [256, 256, 512], 0x9e37_79b9_7f4a_7c15)
}

/// Waits (up to 5 s) until the process `pid` holds an unnamed file in `folder`: the output it
/// is writing. False if it ended or never opened one.
fn writing_unnamed(pid: u32, folder: &Path) -> bool {
    let prefix = format!("{}/#", folder.display());
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline {
        let Ok(fds) = std::fs::read_dir(format!("/proc/{pid}/fd")) else {
            return false;
        };
        let open = fds.filter_map(|e| std::fs::read_link(e.ok()?.path()).ok());
        if open
            .map(|t| t.to_string_lossy().to_string())
            .any(|t| t.starts_with(&prefix) && t.ends_with("(deleted)"))
        {
            return true;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    false
}

/// A signal while the output is written: SIGINT and SIGTERM stop the run (exit 130), and
/// SIGKILL, which nothing can catch, leaves no file either: the output is written to an unnamed
/// file that gets its name only when complete. The earlier output stays as it was.
#[test]
fn a_signal_while_writing_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    if !has_unnamed_files(dir.path()) {
        eprintln!("skipped: this filesystem has no unnamed files (O_TMPFILE)");
        return;
    }
    let input = big_noise(dir.path());
    let output = dir.path().join("out.nii.gz");
    std::fs::write(&output, b"the earlier output").unwrap();
    for (signal, after_ms) in [
        ("-KILL", 0),
        ("-KILL", 100),
        ("-KILL", 250),
        ("-INT", 100),
        ("-TERM", 100),
    ] {
        let child = convert(&input, &output)
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        assert!(
            writing_unnamed(child.id(), dir.path()),
            "the run never held an unnamed output"
        );
        std::thread::sleep(Duration::from_millis(after_ms));
        let kill = Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        // The run is about a second long: every signal lands while it writes.
        assert!(!out.status.success(), "{signal}: the run ended first");
        if signal != "-KILL" {
            assert_eq!(out.status.code(), Some(130), "{signal}: {stderr}");
        }
        assert_eq!(std::fs::read(&output).unwrap(), b"the earlier output");
        assert_eq!(
            listing(dir.path()),
            ["noise_256x256x512_uint8.raw", "out.nii.gz"],
            "{signal} after {after_ms} ms of writing: a file left behind"
        );
    }
}

/// The output's folder removed while the output is written: exit code 2 saying so, nothing
/// recreated.
#[test]
fn the_output_folder_vanishing_while_writing_is_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let input = big_noise(dir.path());
    let folder = dir.path().join("results");
    std::fs::create_dir(&folder).unwrap();
    let child = convert(&input, &folder.join("out.nii.gz"))
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    if has_unnamed_files(&folder) {
        assert!(writing_unnamed(child.id(), &folder));
    } else {
        std::thread::sleep(Duration::from_millis(300));
    }
    // With the output still unnamed the folder looks empty, so it can go at once.
    std::fs::remove_dir_all(&folder).unwrap();
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("out.nii.gz: error"), "{stderr}");
    assert!(stderr.contains("No such file or directory"), "{stderr}");
    assert_eq!(listing(dir.path()), ["noise_256x256x512_uint8.raw"]);
}

/// A small tmpfs, unmounted when dropped; `None` where mounting is not allowed (not root).
struct SmallDisk(tempfile::TempDir);

impl SmallDisk {
    fn mount(options: &str) -> Option<SmallDisk> {
        let dir = tempfile::tempdir().unwrap();
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", options, "tmpfs"])
            .arg(dir.path())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        ok.then_some(SmallDisk(dir))
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.0.path()).status();
    }
}

/// A full disk and a read-only folder: exit code 2 naming the problem, the earlier file at the
/// output path as it was, no temporary file left. (Needs `mount`, so root: CI's machine.)
#[test]
fn full_disk_and_read_only_folder_keep_the_earlier_output() {
    let Some(disk) = SmallDisk::mount("size=64k") else {
        eprintln!("skipped: cannot mount a tmpfs here (not root)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let input = noise(dir.path());
    let output = disk.0.path().join("out.nii");
    std::fs::write(&output, b"the earlier output").unwrap();
    // 256 KiB of samples on a 64 KiB disk; then the same folder read-only.
    for (remount, reason) in [
        (None, "No space left on device"),
        (Some("remount,ro"), "Read-only file system"),
    ] {
        if let Some(options) = remount {
            let status = Command::new("mount")
                .args(["-o", options])
                .arg(disk.0.path())
                .status();
            assert!(status.unwrap().success());
        }
        let out = convert(&input, &output).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{stderr}");
        assert!(stderr.contains(reason), "{stderr}");
        assert_eq!(std::fs::read(&output).unwrap(), b"the earlier output");
        assert_eq!(listing(disk.0.path()), ["out.nii"]);
    }
}

/// Two runs writing the same output at once never interleave: each writes its own temporary
/// file and renames it into place, so the output is one run's whole file or the other's.
#[test]
fn two_runs_writing_one_output_do_not_interleave() {
    let dir = tempfile::tempdir().unwrap();
    let a = noise(dir.path());
    // A second input of another type (so another length): the first one's samples as int16.
    let b = dir.path().join("noise_64x64x64_int16.raw");
    let wide: Vec<u8> = std::fs::read(&a)
        .unwrap()
        .iter()
        .flat_map(|&v| (v as i16 * 3).to_le_bytes())
        .collect();
    std::fs::write(&b, wide).unwrap();
    let convert = |input: &Path, output: &Path| {
        convert(input, output)
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let done = |child: std::process::Child| {
        let out = child.wait_with_output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let refs = tempfile::tempdir().unwrap();
    let (ra, rb) = (refs.path().join("a.nrrd"), refs.path().join("b.nrrd"));
    done(convert(&a, &ra));
    done(convert(&b, &rb));
    let (ra, rb) = (std::fs::read(ra).unwrap(), std::fs::read(rb).unwrap());
    assert_ne!(ra.len(), rb.len());
    let output = dir.path().join("out.nrrd");
    for _ in 0..5 {
        let (x, y) = (convert(&a, &output), convert(&b, &output));
        done(x);
        done(y);
        let got = std::fs::read(&output).unwrap();
        assert!(got == ra || got == rb, "the output mixes the two runs");
        assert_eq!(
            listing(dir.path()),
            [
                "noise_64x64x64_int16.raw",
                "noise_64x64x64_uint8.raw",
                "out.nrrd"
            ]
        );
    }
}

/// A memory limit too small for a run stops it before it is killed: exit code 2, a message
/// naming what did not fit, the earlier output as it was. Each case meets the limit at another
/// place: a reader's slices, the planes of inside bits (the whole volume with `--max-slices 0`),
/// the growth of the loop searches between two handles.
#[test]
fn a_memory_limit_too_small_for_the_volume_is_exit_2_naming_what() {
    let dir = tempfile::tempdir().unwrap();
    let input = noise(dir.path());
    let input = input.to_str().unwrap();
    // 512 MiB of zeros that take no room on disk: refused before a byte of it is read.
    let sparse = dir.path().join("zeros_2048x2048x128_uint8.raw");
    std::fs::File::create(&sparse)
        .unwrap()
        .set_len(2048 * 2048 * 128)
        .unwrap();
    let sparse = sparse.to_str().unwrap();
    let output = dir.path().join("out.nii");
    std::fs::write(&output, b"the earlier output").unwrap();
    let out = output.to_str().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (
            &["genus", input, "--iso", "127.5", "--max-memory", "1M"],
            "not enough memory for 2 slices of 64×64 uint8 samples (reading)",
        ),
        (
            &[
                "simplify",
                sparse,
                "--iso",
                "0.5",
                "--tau",
                "5",
                "--max-slices",
                "0",
            ],
            "not enough memory for 128 planes of 2048×2048 inside bits",
        ),
        (
            &[
                "simplify",
                sparse,
                "--iso",
                "0.5",
                "--tau",
                "5",
                "--max-slices",
                "100",
            ],
            "not enough memory for 100 planes of 2048×2048 inside bits",
        ),
        (
            // The sweep peaks near 9 MiB, the loop searches near 30 MiB: a limit half-way is
            // met by the searches wherever the allocator's overhead lands.
            &["analyze", input, "--iso", "127.5", "--max-memory", "16M"],
            // Seen between two handles' searches ("grew to ... during the loop searches"),
            // or by the allocation after them.
            "",
        ),
    ];
    for (args, words) in cases {
        let mut args = args.to_vec();
        if args[0] == "simplify" {
            args.extend(["--max-memory", "20M", "-o", out]);
        }
        let (code, _, stderr) = common::isotopo(&args);
        assert_eq!(code, 2, "{args:?}: {stderr}");
        assert!(stderr.contains(words), "{args:?}: {stderr}");
        assert!(stderr.contains("over the memory limit of "), "{stderr}");
        assert!(
            stderr.contains("not enough memory for ") || stderr.contains("the process grew to "),
            "{stderr}"
        );
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert_eq!(std::fs::read(&output).unwrap(), b"the earlier output");
    }
    assert!(listing(dir.path()).len() == 3, "{:?}", listing(dir.path()));
    // The labels of the components-and-cavities phase, 4 bytes a sample (64 MiB here): refused
    // under a limit of 40 MiB that the volume's planes and one byte a sample would fit in.
    let other = tempfile::tempdir().unwrap();
    let zeros = other.path().join("zeros_256x256x256_uint8.raw");
    std::fs::File::create(&zeros)
        .unwrap()
        .set_len(256 * 256 * 256)
        .unwrap();
    let out = other.path().join("out.nii");
    let (code, _, stderr) = common::isotopo(&[
        "simplify",
        zeros.to_str().unwrap(),
        "--iso",
        "0.5",
        "--tau",
        "5",
        "--min-cavity",
        "10",
        "--max-memory",
        "40M",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("not enough memory for the labels of the components-and-cavities phase"),
        "{stderr}"
    );
    assert!(!out.exists());
    // A size that is not one is refused as such.
    let (code, _, stderr) =
        common::isotopo(&["genus", input, "--iso", "1", "--max-memory", "lots"]);
    assert_eq!(code, 2);
    assert!(stderr.contains("\"lots\" is not a size"), "{stderr}");
}

/// Where unnamed files cannot be made (or with `ISOTOPO_NAMED_STAGING` set), outputs are
/// staged under a hidden name instead: every format's output is the same bytes either way, and
/// nothing is left beside it.
#[test]
fn outputs_staged_under_a_name_are_the_same_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let input = noise(dir.path());
    let (unnamed, named) = (dir.path().join("unnamed"), dir.path().join("named"));
    for folder in [&unnamed, &named] {
        std::fs::create_dir(folder).unwrap();
    }
    let formats = [
        "nii", "nii.gz", "nrrd", "nhdr", "mha", "mhd", "mgh", "mgz", "npy", "tif",
    ];
    for ext in formats {
        for folder in [&unnamed, &named] {
            let mut c = convert(&input, &folder.join(format!("v.{ext}")));
            if folder == &named {
                c.env("ISOTOPO_NAMED_STAGING", "1");
            }
            let out = c.output().unwrap();
            assert!(
                out.status.success(),
                "{ext}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }
    let files = listing(&unnamed);
    assert_eq!(files, listing(&named));
    assert!(files.iter().all(|f| !f.starts_with('.')), "{files:?}");
    for f in &files {
        let read = |folder: &Path| std::fs::read(folder.join(f)).unwrap();
        // NRRD and MetaImage detached headers name their data files: the same names here.
        assert!(read(&unnamed) == read(&named), "{f} differs");
    }
    // And the plots, drawn in memory then staged.
    let plots = Command::new(env!("CARGO_BIN_EXE_isotopo"))
        .args(["analyze", input.to_str().unwrap(), "--iso", "200", "-q"])
        .arg("--plots")
        .arg(named.join("plots"))
        .env("ISOTOPO_NAMED_STAGING", "1")
        .output()
        .unwrap();
    assert!(
        plots.status.success(),
        "{}",
        String::from_utf8_lossy(&plots.stderr)
    );
    assert_eq!(
        listing(&named.join("plots")),
        [
            "histogram.png",
            "histogram.svg",
            "scatter.png",
            "scatter.svg"
        ]
    );
}
