//! The entry point `isotopo::simplify` end to end: from samples in memory and from a file, the
//! edited volume returned or written, checked with the cell-counting oracle; and the options a
//! caller can get wrong refused.

mod common;

use common::oracle::betti;
use common::{Rng, BOTH};
use isotopo::progress::NoProgress;
use isotopo::simplify::Mode;
use isotopo::topology::SurfaceOptions;
use isotopo::volume::{self, InMemoryVolume, ReadOptions};
use isotopo::{SimplifyOptions, Source};

fn noise(seed: u64) -> (InMemoryVolume, f64) {
    let mut rng = Rng(seed);
    let dims = [22, 19, 17];
    let v = common::smoothed_noise(dims, 2, &mut rng);
    let iso = common::quantile(&v, 0.45);
    (common::volume_from(dims, &v), iso)
}

/// From memory: the edited volume's topology (by the oracle) is what the result says, the
/// samples changed are exactly the edits, and tau inf leaves genus 0.
#[test]
fn simplify_in_memory_returns_the_edited_volume() {
    for seed in [3u64, 11, 29] {
        let (vol, iso) = noise(seed);
        for conn in BOTH {
            for tau in [8.0, f64::INFINITY] {
                let opts = SimplifyOptions {
                    surface: SurfaceOptions {
                        iso,
                        connectivity: conn,
                        ..SurfaceOptions::default()
                    },
                    tau,
                    ..SimplifyOptions::default()
                };
                let what = format!("seed {seed}, conn {}, tau {tau}", conn.number());
                let mut done = isotopo::simplify(Source::from(vol.clone()), &opts, &NoProgress)
                    .unwrap_or_else(|e| panic!("{what}: {e}"));
                let edited = done.edited().unwrap();
                let before = betti(&common::mask_of(&vol, iso), vol.dims(), conn);
                let after = betti(&common::mask_of(&edited, iso), vol.dims(), conn);
                assert!(before.1 > 0, "{what}: no handle to remove");
                assert_eq!(
                    (before.0, before.1, before.2),
                    (
                        done.before.b0 as i64,
                        done.before.b1 as i64,
                        done.before.b2 as i64
                    ),
                    "{what}"
                );
                assert_eq!(
                    (after.0, after.1, after.2),
                    (
                        done.after.b0 as i64,
                        done.after.b1 as i64,
                        done.after.b2 as i64
                    ),
                    "{what}"
                );
                assert_eq!((after.0, after.2), (before.0, before.2), "{what}");
                if tau.is_infinite() {
                    assert_eq!(after.1, 0, "{what}");
                }
                let [nx, ny, nz] = vol.dims();
                let mut changed = Vec::new();
                for z in 0..nz {
                    for y in 0..ny {
                        for x in 0..nx {
                            if edited.get(x, y, z) != vol.get(x, y, z) {
                                changed.push([x as i64, y as i64, z as i64]);
                            }
                        }
                    }
                }
                let mut edits: Vec<[i64; 3]> = done.outcome.edits.iter().map(|e| e.0).collect();
                edits.sort_by_key(|q| (q[2], q[1], q[0]));
                assert_eq!(changed, edits, "{what}");
            }
        }
    }
}

/// From a file to a file: what is written is what `edited` returns, and the input is untouched.
#[test]
fn simplify_a_file_writes_the_edited_volume() {
    let dir = std::env::temp_dir().join(format!("isotopo-jobs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (vol, iso) = noise(5);
    let input = dir.join("in.nii.gz");
    let output = dir.join("out.nii.gz");
    let mut w = volume::create(&input, &vol.info).unwrap();
    for slice in &vol.slices {
        w.write_slice(slice).unwrap();
    }
    w.finish(&vol.info).unwrap();
    let original = std::fs::read(&input).unwrap();
    let opts = SimplifyOptions {
        surface: SurfaceOptions {
            iso,
            ..SurfaceOptions::default()
        },
        tau: f64::INFINITY,
        mode: Mode::FillOnly,
        ..SimplifyOptions::default()
    };
    let mut done = isotopo::simplify(Source::file(&input), &opts, &NoProgress).unwrap();
    assert!(!done.outcome.edits.is_empty());
    assert!(
        done.outcome.edits.iter().all(|e| e.1),
        "fill only sets samples inside"
    );
    done.write(&output, &NoProgress).unwrap();
    let mut back = volume::open(&output, &ReadOptions::default()).unwrap();
    let written = InMemoryVolume::from_reader(back.as_mut()).unwrap();
    let edited = done.edited().unwrap();
    let [nx, ny, nz] = vol.dims();
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                assert_eq!(written.get(x, y, z), edited.get(x, y, z), "({x}, {y}, {z})");
            }
        }
    }
    assert_eq!(
        std::fs::read(&input).unwrap(),
        original,
        "the input was changed"
    );
    // Writing over the input is refused.
    assert!(done.write(&input, &NoProgress).is_err());
    assert_eq!(
        std::fs::read(&input).unwrap(),
        original,
        "the input was changed"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn options_no_simplification_can_follow_are_refused() {
    let (vol, iso) = noise(7);
    let good = SimplifyOptions {
        surface: SurfaceOptions {
            iso,
            ..SurfaceOptions::default()
        },
        ..SimplifyOptions::default()
    };
    assert!(good.validate().is_ok());
    // tau 0 removes no handle: the output is only made well-composed.
    assert!(SimplifyOptions { tau: 0.0, ..good }.validate().is_ok());
    let bad = [
        SimplifyOptions { tau: -1.0, ..good },
        SimplifyOptions {
            tau: f64::NAN,
            ..good
        },
        SimplifyOptions {
            max_ratio: Some(0.5),
            ..good
        },
        SimplifyOptions {
            max_ratio: Some(f64::NAN),
            ..good
        },
        SimplifyOptions {
            surface: SurfaceOptions {
                iso: f64::NAN,
                ..good.surface
            },
            ..good
        },
    ];
    for opts in bad {
        assert!(opts.validate().is_err(), "{opts:?}");
        let r = isotopo::simplify(Source::from(vol.clone()), &opts, &NoProgress);
        assert!(r.is_err(), "{opts:?}");
    }
}

/// Asks to stop once `after` steps are done.
struct StopAfter {
    after: u64,
    done: std::sync::atomic::AtomicU64,
}

impl StopAfter {
    fn new(after: u64) -> StopAfter {
        StopAfter {
            after,
            done: 0.into(),
        }
    }
}

impl isotopo::progress::Progress for StopAfter {
    fn start(&self, _stage: &str, _total: u64) {}
    fn advance(&self, n: u64) {
        self.done.fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    }
    fn cancelled(&self) -> bool {
        self.done.load(std::sync::atomic::Ordering::Relaxed) >= self.after
    }
}

/// The default surface and analyze options at isovalue `iso`.
fn default_options(iso: f64) -> (SurfaceOptions, isotopo::AnalyzeOptions) {
    let surface = SurfaceOptions {
        iso,
        ..SurfaceOptions::default()
    };
    let analyze = isotopo::AnalyzeOptions {
        surface,
        ..isotopo::AnalyzeOptions::default()
    };
    (surface, analyze)
}

fn is_cancelled<T>(r: isotopo::Result<T>) -> bool {
    matches!(r, Err(isotopo::Error::Cancelled))
}

/// Every job stops with `Error::Cancelled` when the caller asks, at any point: while reading,
/// sweeping, measuring, simplifying or writing (nothing is written then); and runs to the end
/// when the caller never asks.
#[test]
fn a_caller_can_cancel_every_job() {
    let (vol, iso) = noise(7);
    let (surface, analyze) = default_options(iso);
    let simplify = SimplifyOptions {
        surface,
        tau: f64::INFINITY,
        ..SimplifyOptions::default()
    };
    let src = || Source::from(vol.clone());
    let nz = vol.dims()[2] as u64;
    // genus: a step per slice. The others: planes read (nz), then slices swept (nz + 1), then
    // handles measured.
    for after in [0, 1, nz / 2] {
        let stop = StopAfter::new(after);
        assert!(
            is_cancelled(isotopo::genus(src(), &surface, &stop)),
            "genus, {after}"
        );
    }
    for after in [0, 1, nz / 2, nz + 3, 2 * nz + 2, 2 * nz + 4] {
        let stop = StopAfter::new(after);
        assert!(
            is_cancelled(isotopo::analyze(src(), &analyze, &stop)),
            "analyze, {after}"
        );
        let stop = StopAfter::new(after);
        assert!(
            is_cancelled(isotopo::simplify(src(), &simplify, &stop)),
            "simplify, {after}"
        );
    }
    let never = StopAfter::new(u64::MAX);
    isotopo::genus(src(), &surface, &never).unwrap();
    isotopo::analyze(src(), &analyze, &never).unwrap();
    let mut done = isotopo::simplify(src(), &simplify, &never).unwrap();
    assert!(!done.outcome.removed.is_empty());

    let dir = std::env::temp_dir().join(format!("isotopo-cancel-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let output = dir.join("out.nii.gz");
    assert!(is_cancelled(done.write(&output, &StopAfter::new(nz / 2))));
    assert!(!output.exists(), "a cancelled write left a file");
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "a temp file was left"
    );
    done.write(&output, &never).unwrap();
    assert!(output.exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// tau is a strict bound, as documented: a handle whose size (its shorter loop, in edges) is
/// exactly tau is kept, and one edge more removes it. The crate doc's ball with a one-voxel ring
/// fused to its side.
#[test]
fn a_handle_of_size_tau_is_kept() {
    let shape = |x: usize, y: usize, z: usize| {
        let d = |a: usize, c: f64| a as f64 - c;
        let ball = d(x, 8.0).hypot(d(y, 8.0)).hypot(d(z, 8.0)) < 5.0;
        let ring = z == 8 && d(x, 13.0).abs().max(d(y, 8.0).abs()) == 1.0;
        ball || ring
    };
    let volume = InMemoryVolume::from_mask([18, 17, 17], shape);
    let surface = SurfaceOptions {
        iso: 0.5,
        ..SurfaceOptions::default()
    };
    let analyze = isotopo::AnalyzeOptions {
        surface,
        ..isotopo::AnalyzeOptions::default()
    };
    let analysis = isotopo::analyze(Source::from(volume.clone()), &analyze, &NoProgress).unwrap();
    assert_eq!(analysis.loops.len(), 1);
    let size = analysis.loops[0].size().expect("the handle is measured") as f64;
    for (tau, b1) in [(size, 1), (size + 1.0, 0)] {
        let opts = SimplifyOptions {
            surface,
            tau,
            ..SimplifyOptions::default()
        };
        let done = isotopo::simplify(Source::from(volume.clone()), &opts, &NoProgress).unwrap();
        assert_eq!(done.after.b1, b1, "tau {tau}, handle size {size}");
    }
}

/// Options removing every handle of the isosurface at `iso`.
fn every_handle(iso: f64) -> SimplifyOptions {
    SimplifyOptions {
        surface: SurfaceOptions {
            iso,
            ..SurfaceOptions::default()
        },
        tau: f64::INFINITY,
        ..SimplifyOptions::default()
    }
}

/// Each removal's `max_distance` is what it says: the farthest sample the wall changed from the
/// polyline of the loop it closed, in voxels and, with voxels 2 × 1 × 0.5 mm, in millimetres.
/// Recomputed here from the samples and points the report lists.
#[test]
fn removal_reports_how_far_its_wall_reaches() {
    let (mut vol, iso) = noise(5);
    let spacing = [2.0, 1.0, 0.5];
    let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    vol.info.affine = isotopo::volume::Affine::from_parts(identity, spacing, [3.0, -2.0, 1.0]);
    let opts = every_handle(iso);
    let done = isotopo::simplify(Source::from(vol), &opts, &NoProgress).unwrap();
    assert!(!done.outcome.removed.is_empty());
    let farthest = |r: &isotopo::simplify::Removed, scale: [f64; 3]| {
        let near = |q: &[i64; 3]| {
            r.points
                .iter()
                .map(|p| {
                    (0..3)
                        .map(|i| ((q[i] as f64 - p[i]) * scale[i]).powi(2))
                        .sum::<f64>()
                })
                .fold(f64::INFINITY, f64::min)
                .sqrt()
        };
        r.samples.iter().map(near).fold(0.0, f64::max)
    };
    for r in &done.outcome.removed {
        assert!(r.max_distance > 0.0, "a wall lies off its loop's polyline");
        assert!((r.max_distance - farthest(r, [1.0; 3])).abs() < 1e-9);
        assert!((r.max_distance_mm - farthest(r, spacing)).abs() < 1e-9);
    }
    let (vox, mm) = done.outcome.max_distance();
    let worst = |f: fn(&isotopo::simplify::Removed) -> f64| {
        done.outcome.removed.iter().map(f).fold(0.0, f64::max)
    };
    assert_eq!(
        (vox, mm),
        (worst(|r| r.max_distance), worst(|r| r.max_distance_mm))
    );
}

/// What writing reports besides the edits is what it did, recomputed from the input and the
/// output: the samples left exactly at the isovalue (counted, and moved just outside for
/// floating-point samples) and the largest change of any sample.
#[test]
fn writing_reports_the_samples_at_the_isovalue_and_the_largest_move() {
    let (mut vol, iso) = noise(7);
    let iso = iso as f32 as f64;
    let [nx, ny, nz] = vol.dims();
    for k in 0..60 {
        let i = (k * 7919) % (nx * ny * nz);
        vol.set(i % nx, (i / nx) % ny, i / (nx * ny), iso);
    }
    let opts = every_handle(iso);
    let mut done = isotopo::simplify(Source::from(vol.clone()), &opts, &NoProgress).unwrap();
    let out = done.edited().unwrap();
    let written = done.written.expect("edited() records what it wrote");
    let edited: std::collections::HashSet<[i64; 3]> =
        done.outcome.edits.iter().map(|e| e.0).collect();
    let (mut at_iso, mut largest) = (0u64, 0.0f64);
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let (a, b) = (vol.get(x, y, z), out.get(x, y, z));
                assert_ne!(b, iso, "a sample left at the isovalue");
                largest = largest.max((a - b).abs());
                let q = [x as i64, y as i64, z as i64];
                if a == iso && !edited.contains(&q) {
                    at_iso += 1;
                    assert!(b < iso, "a sample at the isovalue not moved outside");
                }
            }
        }
    }
    assert!(at_iso > 0);
    assert!(written.at_iso_moved);
    assert_eq!(written.samples_at_iso, at_iso);
    assert_eq!(written.largest_move, largest);
}

/// `analyze_streamed` (memory flat in the handles: measured as the sweep goes, kept in a scratch
/// file) reports exactly what `analyze` does, handle by handle and in the same order: random
/// volumes with hundreds of handles, both connectivities, lengths in edges, millimetres and
/// both, a limit, and out of core (batches of 64 measured while the sweep goes on); the last
/// volume has more handles than a batch in memory (1,024), so some are measured mid-sweep there
/// too.
#[test]
fn the_streamed_analysis_is_the_analysis() {
    use isotopo::jobs::Lengths;
    let mut handles = 0;
    let mut most = 0;
    for (round, seed) in [5u64, 17, 23, 41, 7].into_iter().enumerate() {
        let mut rng = Rng(seed);
        let dims = [
            [26, 22, 19],
            [17, 31, 12],
            [26, 22, 19],
            [17, 31, 12],
            [44, 40, 36],
        ][round];
        let v = common::smoothed_noise(dims, 1, &mut rng);
        let vol = common::volume_from(dims, &v);
        let iso = common::quantile(&v, 0.5);
        for conn in BOTH {
            let opts = isotopo::AnalyzeOptions {
                surface: common::opts(iso, conn),
                lengths: [Lengths::Edges, Lengths::Both, Lengths::Millimetres][round % 3],
                tau: (round == 3).then_some(9.0),
                max_slices: (round == 1).then_some(3),
                ..isotopo::AnalyzeOptions::default()
            };
            let what = format!("seed {seed}, conn {}", conn.number());
            let whole = isotopo::analyze(Source::from(vol.clone()), &opts, &NoProgress).unwrap();
            let whole = whole.to_json(&opts);
            let mut streamed =
                isotopo::analyze_streamed(Source::from(vol.clone()), &opts, &NoProgress).unwrap();
            let listed = whole["handles"].as_array().unwrap();
            assert_eq!(streamed.len(), listed.len(), "{what}");
            for (i, expected) in listed.iter().enumerate() {
                let h = streamed.next_handle().unwrap().expect("as many handles");
                assert_eq!(&h, expected, "{what}: handle {i}");
            }
            assert!(streamed.next_handle().unwrap().is_none(), "{what}");
            let summary = streamed.to_json(&opts);
            for key in ["genus", "surfaces", "dims", "iso", "tau"] {
                assert_eq!(summary[key], whole[key], "{what}: {key}");
            }
            handles += listed.len();
            most = most.max(listed.len());
        }
    }
    assert!(handles > 400, "{handles} handles compared");
    assert!(
        most > 1024,
        "no volume with more handles than a batch ({most})"
    );
}

/// Every stage a job announces, with the total it announced and the steps it then reported.
#[derive(Default)]
struct Stages(std::sync::Mutex<Vec<(String, u64, u64)>>);

impl isotopo::progress::Progress for Stages {
    fn start(&self, stage: &str, total: u64) {
        self.0.lock().unwrap().push((stage.to_string(), total, 0));
    }
    fn advance(&self, n: u64) {
        let mut stages = self.0.lock().unwrap();
        let last = stages.last_mut().expect("a step before any stage started");
        last.2 += n;
    }
}

/// A progress bar fills exactly once per stage: each job announces its stages once each, in
/// pipeline order, and reports as many steps in a stage as the total it announced (the sweep:
/// one a slice and one to close; the mini-volumes swept for intra-ribbon handles announce
/// nothing of their own).
#[test]
fn each_stage_reports_the_steps_it_announced() {
    let (vol, iso) = noise(7);
    let (_, analyze) = default_options(iso);
    let src = || Source::from(vol.clone());
    let nz = vol.dims()[2] as u64;
    let stages = Stages::default();
    let handles = isotopo::analyze(src(), &analyze, &stages)
        .unwrap()
        .report
        .handles;
    let seen = stages.0.into_inner().unwrap();
    let names: Vec<&str> = seen.iter().map(|s| s.0.as_str()).collect();
    assert_eq!(names, ["classify", "sweep", "loops"], "{seen:?}");
    assert_eq!(seen[1].1, nz + 1, "{seen:?}");
    assert!(handles.len() > 5, "{} handles", handles.len());
    assert_eq!(seen[2].1, handles.len() as u64, "{seen:?}");
    for (stage, total, done) in &seen {
        assert_eq!(done, total, "{stage}");
    }
    // The streamed analysis (the sweep handing over each step's handles) too.
    let stages = Stages::default();
    isotopo::analyze_streamed(src(), &analyze, &stages).unwrap();
    let seen = stages.0.into_inner().unwrap();
    let names: Vec<&str> = seen.iter().map(|s| s.0.as_str()).collect();
    assert_eq!(names, ["classify", "sweep", "loops"], "{seen:?}");
    assert_eq!(seen[1].1, nz + 1, "{seen:?}");
    for (stage, total, done) in &seen {
        assert_eq!(done, total, "streamed: {stage}");
    }
}
