//! The guarantees of `simplify`, on synthetic shapes and random volumes, checked against the
//! independent cell-counting oracle (tests/common/oracle.rs) rather than isotopo's own genus:
//!
//! 1. the genus after equals the number of handles kept, and analysing the result finds no
//!    handle smaller than tau (except those kept on purpose: `--max-ratio`, fill/cut only);
//! 2. tau = inf leaves genus 0;
//! 3. b0 and b2 of the solid never change;
//! 4. every changed sample lies near a closed loop (within the wall's thickness of the loop's
//!    spanning fan, hence within a quarter of the loop's length plus that thickness);
//! 5. simplifying the result again changes nothing;
//! 6. fill-only only sets samples inside, cut-only only sets them outside.

mod common;

use common::oracle::betti;
use common::systole::systole;
use common::{shapes, Rng, BOTH};
use isotopo::grid::{Axis, MaskVolume};
use isotopo::loops::Metric;
use isotopo::progress::NoProgress;
use isotopo::simplify::{simplify, KeepReason, Mode, Operation, Outcome, SimplifyOptions};
use isotopo::topology::{Connectivity, Inside, SurfaceOptions};
use isotopo::volume::{Affine, InMemoryVolume};

/// Inside samples of a volume, x fastest.
fn bits(vol: &InMemoryVolume, iso: f64) -> Vec<bool> {
    common::mask_of(vol, iso)
}

/// The mask as a volume of ±1 (inside above 0), so it can be swept again.
fn volume_of(dims: [usize; 3], inside: &[bool]) -> InMemoryVolume {
    let [nx, ny, _] = dims;
    InMemoryVolume::from_fn(dims, |x, y, z| {
        if inside[(z * ny + y) * nx + x] {
            1.0
        } else {
            -1.0
        }
    })
}

/// The loops of every handle of the volume, each measured exactly up to `tau` (edges).
fn handle_loops(
    vol: &InMemoryVolume,
    conn: Connectivity,
    axis: Axis,
    tau: Option<f64>,
) -> Vec<isotopo::loops::HandleLoops> {
    let opts = isotopo::AnalyzeOptions {
        surface: common::opts(0.0, conn),
        axis,
        tau,
        ..isotopo::AnalyzeOptions::default()
    };
    isotopo::analyze(vol.clone().into(), &opts, &NoProgress)
        .unwrap()
        .loops
}

fn options(tau: f64, mode: Mode, conn: Connectivity) -> SimplifyOptions {
    SimplifyOptions {
        tau,
        mode,
        surface: SurfaceOptions {
            connectivity: conn,
            ..SurfaceOptions::default()
        },
        ..SimplifyOptions::default()
    }
}

/// Runs simplify and checks every guarantee; returns the outcome and the result's mask.
fn check(
    name: &str,
    vol: &InMemoryVolume,
    iso: f64,
    axis: Axis,
    opts: &SimplifyOptions,
) -> Result<(Outcome, Vec<bool>), String> {
    let conn = opts.surface.connectivity;
    let dims = vol.dims();
    let [nx, ny, _] = dims;
    let what = format!(
        "{name} (conn {}, axis {}, tau {}, {:?}, inside {})",
        conn.number(),
        axis.name(),
        opts.tau,
        opts.mode,
        opts.surface.inside.name()
    );
    let surface = SurfaceOptions {
        iso,
        ..opts.surface
    };
    let before_bits = common::mask_on(vol, iso, surface.inside);
    let before = betti(&before_bits, dims, conn);
    let mut m = common::masks_with(vol, &surface, axis);
    let out = simplify(&mut m, opts, &Affine::IDENTITY, &NoProgress).map_err(|e| e.to_string())?;

    // The edits, applied to the original samples, give the result.
    let mut after_bits = before_bits.clone();
    for &([x, y, z], inside) in &out.edits {
        let i = (z as usize * ny + y as usize) * nx + x as usize;
        if after_bits[i] == inside {
            return Err(format!("{what}: edit at {:?} changes nothing", [x, y, z]));
        }
        after_bits[i] = inside;
    }
    let after = betti(&after_bits, dims, conn);

    // 3. Components and cavities unchanged.
    if (after.0, after.2) != (before.0, before.2) {
        return Err(format!(
            "{what}: b0, b2 went from {:?} to {:?}",
            (before.0, before.2),
            (after.0, after.2)
        ));
    }
    // The genus never rises: a handle the well-composed step opened is closed by a later pass
    // or taken back (the count below holds either way).
    if after.1 > before.1 {
        return Err(format!("{what}: genus {} -> {}", before.1, after.1));
    }
    // 1. Genus after = handles kept.
    if after.1 != out.kept.len() as i64 {
        return Err(format!(
            "{what}: genus {} -> {} but {} kept",
            before.1,
            after.1,
            out.kept.len()
        ));
    }
    // The well-composed step may open a handle through a face it could not mend otherwise
    // (only where a pass follows to close it): those are removed too.
    let removed: usize = out.removed.iter().map(|r| r.handles).sum();
    let opened = out.composition.as_ref().map_or(0, |c| c.opened.len());
    if before.1 - after.1 + opened as i64 != removed as i64 {
        return Err(format!(
            "{what}: genus {} -> {} but {} handles reported removed, {} opened",
            before.1, after.1, removed, opened
        ));
    }
    // The report's counts by operation (JSON `collapse`, `pinch`): every removed handle is
    // one or the other, and fill only collapses, cut only pinches.
    let (collapsed, pinched) = (
        out.handles_removed_by(Operation::Collapse),
        out.handles_removed_by(Operation::Pinch),
    );
    let by_mode = match opts.mode {
        Mode::Both => true,
        Mode::FillOnly => pinched == 0,
        Mode::CutOnly => collapsed == 0,
    };
    if collapsed + pinched != removed || !by_mode {
        return Err(format!(
            "{what}: {removed} handles removed, {collapsed} by collapse, {pinched} by pinch"
        ));
    }
    // With both operations allowed, nothing is kept for want of a closure. With fill or cut
    // only, a handle whose loops can only be closed the other way may be (two linked tori:
    // filling either hole would join them).
    let restricted = |r: KeepReason| {
        r == KeepReason::Mode || (opts.mode != Mode::Both && r == KeepReason::ClosureFailed)
    };
    if let Some(k) = out
        .kept
        .iter()
        .find(|k| k.reason != KeepReason::Size && !restricted(k.reason))
    {
        return Err(format!("{what}: kept {k:?}"));
    }
    // 2. tau = inf removes everything (in both-ways mode).
    if opts.tau.is_infinite() && opts.mode == Mode::Both && after.1 != 0 {
        return Err(format!("{what}: genus {} left with tau inf", after.1));
    }
    // 1. With both operations, the result is certified: no loop below tau is left. An
    // analysis of the result finds no handle below tau. With fill or cut only, every handle an
    // analysis with simplify's limits finds below tau has its small loops of the excluded kind.
    let result = volume_of(dims, &after_bits);
    if opts.mode == Mode::Both && opts.tau.is_finite() {
        if out.certified != Some(true) {
            return Err(format!("{what}: not certified ({:?})", out.certified));
        }
        // The independent oracle: no non-separating cycle of the result is shorter than tau.
        let sys = systole(&result, 0.0, conn);
        if sys.edges.is_some_and(|e| (e as f64) < opts.tau) {
            return Err(format!(
                "{what}: a non-separating cycle of {:?} edges is left: {:?}",
                sys.edges, sys.cycle
            ));
        }
    }
    // Both ways, every loop exactly; one way, up to tau as simplify measures them.
    let exact_up_to = (opts.mode != Mode::Both && opts.tau.is_finite()).then_some(opts.tau);
    let analysed = handle_loops(&result, conn, axis, exact_up_to);
    // With fill or cut only, a handle the mode allows closing may stay when every such wall is
    // refused (filling the hole of one of two linked tori would join them).
    let failed = out
        .kept
        .iter()
        .filter(|k| opts.mode != Mode::Both && k.reason == KeepReason::ClosureFailed)
        .count();
    let mut closable = Vec::new();
    for l in &analysed {
        let small: Vec<&isotopo::loops::Loop> = [&l.reeb, &l.cross]
            .into_iter()
            .flatten()
            .filter(|x| (x.length as f64) < opts.tau)
            .collect();
        let allowed = small.iter().any(|x| {
            let fill = x.encloses == isotopo::loops::Encloses::Void;
            match opts.mode {
                Mode::Both => true,
                Mode::FillOnly => fill,
                Mode::CutOnly => !fill,
            }
        });
        if allowed {
            closable.push(
                small
                    .iter()
                    .map(|x| (x.length, x.encloses))
                    .collect::<Vec<_>>(),
            );
        }
    }
    if closable.len() > failed {
        return Err(format!(
            "{what}: {} handles below tau left that the mode could close ({failed} refused): {closable:?}",
            closable.len()
        ));
    }
    // 4. Every changed sample was flipped by a wall, and lies where that kind of wall reaches
    // from its own loop: a fan wall (or a peeled one, cut from the fan's samples) within its
    // thickness of the fan, whose points are within a quarter of the loop's length of it; a
    // single sample within its reach of the loop's centroid; a wall peeled in a box inside it,
    // or in that box moved along the other loop.
    let mut flipped_by: std::collections::HashMap<[i64; 3], usize> = Default::default();
    for (i, r) in out.removed.iter().enumerate() {
        for &q in &r.samples {
            flipped_by.insert(q, i);
        }
    }
    // The well-composed step's samples (checked by tests/compose.rs) are listed apart.
    let composed: std::collections::HashSet<[i64; 3]> = out
        .composition
        .iter()
        .flat_map(|c| c.flips.iter().map(|f| f.0))
        .collect();
    for &(q, _) in &out.edits {
        if composed.contains(&q) && !flipped_by.contains_key(&q) {
            continue;
        }
        let Some(&i) = flipped_by.get(&q) else {
            return Err(format!("{what}: changed sample {q:?} flipped by no wall"));
        };
        let r = &out.removed[i];
        let p = q.map(|c| c as f64);
        let dist = |a: &[f64; 3]| {
            ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2) + (p[2] - a[2]).powi(2)).sqrt()
        };
        let extent = |k: usize| {
            let lo = r.points.iter().map(|a| a[k]).fold(f64::INFINITY, f64::min);
            let hi = r
                .points
                .iter()
                .map(|a| a[k])
                .fold(f64::NEG_INFINITY, f64::max);
            (lo.floor(), hi.ceil())
        };
        let ok = match r.wall {
            // The box round the loop, with its margin; a `peeled_along` wall's box is that box
            // moved along its partner from the vertex they share, by at most half the partner
            // (its edge midpoints step at most a voxel on each axis): the wall fits in a box
            // that size, within that shift of the loop's box.
            "peeled_box" | "peeled_along" => (0..3).all(|k| {
                let (lo, hi) = extent(k);
                let (lo, hi) = (lo - r.thickness, hi + r.thickness);
                let shift = match r.wall {
                    "peeled_box" => 0.0,
                    _ => r.partner.map_or(f64::NAN, |n| n as f64 / 2.0),
                };
                let spread = r.samples.iter().map(|s| s[k] as f64);
                let (a, b) = (
                    spread.clone().fold(f64::INFINITY, f64::min),
                    spread.fold(f64::NEG_INFINITY, f64::max),
                );
                b - a <= hi - lo && p[k] >= lo - shift && p[k] <= hi + shift
            }),
            _ => {
                let reach = r.thickness + r.length as f64 / 4.0 + 1e-6;
                r.points.iter().any(|a| dist(a) <= reach)
            }
        };
        if !ok {
            return Err(format!(
                "{what}: changed sample {q:?} is beyond the reach of its {} wall (loop of {})",
                r.wall, r.length
            ));
        }
    }
    let reported: usize = out.removed.iter().map(|r| r.samples_changed).sum();
    if out.edits.len() > reported + composed.len() {
        return Err(format!(
            "{what}: {} samples changed, walls flipped {reported}",
            out.edits.len()
        ));
    }
    // 6. Fill only adds, cut only removes.
    for &(q, inside) in &out.edits {
        let bad = match opts.mode {
            Mode::FillOnly => !inside,
            Mode::CutOnly => inside,
            Mode::Both => false,
        };
        if bad {
            return Err(format!(
                "{what}: {q:?} set {}",
                if inside { "inside" } else { "outside" }
            ));
        }
    }
    // 7. Well-composed (by default): where no critical cell is left, the other connectivity
    // sees the same topology.
    if out.composition.as_ref().is_some_and(|c| c.well_composed()) {
        let other = betti(&after_bits, dims, conn.other());
        if (other.0, other.1, other.2) != (after.0, after.1, after.2) {
            return Err(format!(
                "{what}: well-composed, but the other connectivity gives {other:?}, not {after:?}"
            ));
        }
    }
    // 5. Idempotent.
    let mut again = common::masks(&result, 0.0, conn, axis);
    let second =
        simplify(&mut again, opts, &Affine::IDENTITY, &NoProgress).map_err(|e| e.to_string())?;
    if !second.edits.is_empty() {
        return Err(format!(
            "{what}: a second run changed {} samples",
            second.edits.len()
        ));
    }
    Ok((out, after_bits))
}

fn expect_ok(r: Result<(Outcome, Vec<bool>), String>) -> Outcome {
    match r {
        Ok((o, _)) => o,
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn tau_inf_removes_every_handle_of_every_shape() {
    let mut failures = Vec::new();
    for s in shapes::all() {
        for conn in BOTH {
            for axis in [Axis::Z, Axis::X] {
                if let Err(e) = check(
                    &s.name,
                    &s.volume,
                    0.0,
                    axis,
                    &options(f64::INFINITY, Mode::Both, conn),
                ) {
                    failures.push(e);
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A torus whose tube is thick (cross loop about 2π·3.5 ≈ 22 edges) with a one-sample bridge
/// across its hole (a handle of size 4): tau 10 takes the bridge and keeps the torus.
/// Fill only and cut only, tau inf: every handle is a tunnel to fill and a bar to cut, so
/// either way removes it, except filling the holes of two linked tori (which would join them).
#[test]
fn fill_only_and_cut_only_on_every_shape() {
    let mut failures = Vec::new();
    for s in shapes::all() {
        for conn in BOTH {
            for mode in [Mode::FillOnly, Mode::CutOnly] {
                if let Err(e) = check(
                    &s.name,
                    &s.volume,
                    0.0,
                    Axis::Z,
                    &options(f64::INFINITY, mode, conn),
                ) {
                    failures.push(e);
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn linked_tori_cannot_be_unlinked_by_filling() {
    let s = shapes::all()
        .into_iter()
        .find(|s| s.name == "two linked tori")
        .unwrap();
    for conn in BOTH {
        let out = expect_ok(check(
            &s.name,
            &s.volume,
            0.0,
            Axis::Z,
            &options(f64::INFINITY, Mode::FillOnly, conn),
        ));
        assert_eq!(out.kept.len(), 2, "{:?}", out.kept);
        assert!(out
            .kept
            .iter()
            .all(|k| k.reason == KeepReason::ClosureFailed));
        let out = expect_ok(check(
            &s.name,
            &s.volume,
            0.0,
            Axis::Z,
            &options(f64::INFINITY, Mode::CutOnly, conn),
        ));
        assert!(out.kept.is_empty());
    }
}

/// Sizes in millimetres, as reported: with tau in millimetres, the torus's handle is kept at
/// a size no shorter than tau and than its loop round the tube, 2πr (the interpolated
/// surface's chords cut the circle by 0.2% at most, `tests/loops.rs`; beyond tau the loops
/// need not be the shortest), and the bar through its hole is removed at a size below tau, no
/// longer than the loop that closed it (one of its two loops).
#[test]
fn sizes_in_millimetres_are_the_loops_lengths() {
    let (n, big, small) = (32, 10.0, 3.5);
    let c = (n as f64 - 1.0) / 2.0;
    let vol = InMemoryVolume::from_fn([n, n, 16], |x, y, z| {
        let p = [x as f64 - c, y as f64 - c, z as f64 - 7.5];
        let bar = y == 16 && (z == 7 || z == 8) && (x as f64 - c).abs() < 8.0;
        if bar {
            1.0
        } else {
            shapes::torus_field(p, big, small) as f32
        }
    });
    let tube = std::f64::consts::TAU * small;
    for conn in BOTH {
        let opts = SimplifyOptions {
            metric: Metric::Millimetres,
            ..options(12.0, Mode::Both, conn)
        };
        let out = expect_ok(check(
            "torus with a bar, tau in mm",
            &vol,
            0.0,
            Axis::Z,
            &opts,
        ));
        let what = format!("conn {}", conn.number());
        assert_eq!(out.kept.len(), 1, "{what}: {:?}", out.kept);
        let kept = out.kept[0].size_mm.expect("the kept handle's size");
        assert!(
            kept >= 12.0 && kept >= 0.998 * tube,
            "{what}: kept at {kept:.2} mm, 2πr {tube:.2}"
        );
        assert!(!out.removed.is_empty(), "{what}");
        for r in &out.removed {
            assert!(
                r.size_mm < 12.0 && r.size_mm <= r.length_mm + 1e-9,
                "{what}: removed at {} mm, its closed loop {} mm",
                r.size_mm,
                r.length_mm
            );
        }
    }
}

#[test]
fn tau_keeps_the_large_handle_and_removes_the_small_one() {
    let n = 32;
    let c = (n as f64 - 1.0) / 2.0;
    let vol = InMemoryVolume::from_fn([n, n, 16], |x, y, z| {
        let p = [x as f64 - c, y as f64 - c, z as f64 - 7.5];
        let t = shapes::torus_field(p, 10.0, 3.5);
        // A bar of single samples along x through the hole, in the torus's mid-plane.
        let bar = y == 16 && (z == 7 || z == 8) && (x as f64 - c).abs() < 8.0;
        if bar {
            1.0
        } else {
            t as f32
        }
    });
    for conn in BOTH {
        let before = betti(&bits(&vol, 0.0), vol.dims(), conn);
        assert_eq!(before.1, 2, "conn {}: torus + bar", conn.number());
        let out = expect_ok(check(
            "torus with a bar",
            &vol,
            0.0,
            Axis::Z,
            &options(10.0, Mode::Both, conn),
        ));
        assert_eq!(out.kept.len(), 1, "conn {}: {:?}", conn.number(), out.kept);
        assert!(out.kept[0].size.unwrap() >= 10);
        assert!(out.removed.iter().all(|r| r.size < 10));
        // The bar is pinched (cut) — filling the torus's hole would take far more.
        assert!(out
            .removed
            .iter()
            .all(|r| r.operation == isotopo::simplify::Operation::Pinch));
        // Fill only: the bar's handles can only be removed by filling round them.
        let fill = expect_ok(check(
            "torus with a bar",
            &vol,
            0.0,
            Axis::Z,
            &options(10.0, Mode::FillOnly, conn),
        ));
        assert!(fill.edits.iter().all(|e| e.1));
    }
}

/// Case `case` of the random volumes: smoothed noise of side 10 to 20 thresholded at a
/// quantile between 0.3 and 0.7 (the volume, its isovalue, and the case's generator for what
/// else it draws).
fn random_case(case: u64) -> (InMemoryVolume, f64, Rng) {
    let mut rng = Rng(0xfeed ^ (case * 7919));
    let n = 10 + rng.below(11) as usize;
    let dims = [n, n + rng.below(4) as usize, n - 1 - rng.below(3) as usize];
    let v = common::smoothed_noise(dims, 1 + rng.below(3) as usize, &mut rng);
    let vol = common::volume_from(dims, &v);
    let iso = common::quantile(&v, 0.3 + 0.4 * rng.f64());
    (vol, iso, rng)
}

/// The property test: random smoothed noise (hundreds of handles, nested ones, tiny components
/// and cavities), every combination of connectivity, sweep axis, tau (finite and infinite) and
/// mode drawn independently; every guarantee of `check`, the independent oracles deciding.
#[test]
fn random_volumes_keep_every_guarantee() {
    let cases: u64 = std::env::var("ISOTOPO_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(216);
    let mut failures = Vec::new();
    let mut removed = 0;
    let mut seen = std::collections::HashSet::new();
    for case in 0..cases {
        let (vol, iso, mut rng) = random_case(case);
        // Every combination of connectivity, axis, finite or infinite tau and mode in turn.
        let combo = case as usize % 36;
        let conn = BOTH[combo % 2];
        let axis = [Axis::Z, Axis::Y, Axis::X][combo / 2 % 3];
        let tau = if (combo / 6).is_multiple_of(2) {
            [5.0, 8.0, 12.0, 20.0][rng.below(4) as usize]
        } else {
            f64::INFINITY
        };
        let mode = [Mode::Both, Mode::FillOnly, Mode::CutOnly][combo / 12];
        seen.insert((
            conn.number(),
            axis.name(),
            tau.is_finite(),
            format!("{mode:?}"),
        ));
        match check(
            &format!("case {case}"),
            &vol,
            iso,
            axis,
            &options(tau, mode, conn),
        ) {
            Ok((o, _)) => removed += o.removed.len(),
            Err(e) => failures.push(e),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // Every combination drawn (2 connectivities x 3 axes x finite or not x 3 modes), and the
    // cases exercised something.
    assert!(
        cases < 160 || seen.len() == 36,
        "{} combinations",
        seen.len()
    );
    assert!(
        removed > 50 * cases as usize / 10,
        "only {removed} handles removed"
    );
}

/// `--max-ratio`: a long thin handle (a ring of thin tube, cross loop small, Reeb loop long) is
/// kept when its ratio exceeds the limit, removed otherwise.
#[test]
fn max_ratio_keeps_long_skinny_handles() {
    let vol = shapes::torus(40, 14.0, 1.6, 0.0, 0.0, 0.0);
    for conn in BOTH {
        let mut opts = options(f64::INFINITY, Mode::Both, conn);
        let out = expect_ok(check("thin ring", &vol, 0.0, Axis::Z, &opts));
        assert_eq!(out.removed.len(), 1);
        // A handle exactly at the ratio is not "more than" it: removed.
        let r = &out.removed[0];
        let (a, b) = (r.reeb.unwrap() as f64, r.cross.unwrap() as f64);
        let ratio = a.max(b) / a.min(b);
        assert!(ratio > 2.0, "the ring is skinny: {a} vs {b}");
        opts.max_ratio = Some(ratio);
        let mut m = common::masks(&vol, 0.0, conn, Axis::Z);
        let out = simplify(&mut m, &opts, &Affine::IDENTITY, &NoProgress).unwrap();
        assert_eq!(out.removed.len(), 1, "ratio {ratio}: {:?}", out.kept);
        // At a finite tau just above the short loop, the searches go up to tau × the ratio:
        // far enough for the long loop, so the ratio is known and the handle goes.
        let finite = SimplifyOptions {
            tau: a.min(b) + 1.0,
            ..opts
        };
        let mut m = common::masks(&vol, 0.0, conn, Axis::Z);
        let out = simplify(&mut m, &finite, &Affine::IDENTITY, &NoProgress).unwrap();
        assert_eq!(out.removed.len(), 1, "tau {}: {:?}", finite.tau, out.kept);
        opts.max_ratio = Some(2.0);
        let mut m = common::masks(&vol, 0.0, conn, Axis::Z);
        let out = simplify(&mut m, &opts, &Affine::IDENTITY, &NoProgress).unwrap();
        assert!(out.removed.is_empty());
        // What changed is the well-composed step's.
        let composed = out.composition.as_ref().map_or(0, |c| c.flips.len());
        assert_eq!(out.edits.len(), composed);
        assert_eq!(out.kept.len(), 1);
        assert_eq!(out.kept[0].reason, KeepReason::Ratio);
    }
}

/// Out of core — a window of a few planes in memory, the rest in a scratch file, read back when
/// a loop reaches far below the sweep — simplify gives exactly the in-memory result (the same
/// edits, so the same output bytes), along z and along x (rows gathered into sweep planes).
#[test]
fn out_of_core_gives_the_same_result() {
    use isotopo::grid::MIN_WINDOW;
    let mut rng = Rng(0x00c0);
    let mut cases: Vec<(String, InMemoryVolume, f64)> = vec![
        ("menger 2".into(), shapes::menger(2), 0.0),
        ("trefoil".into(), shapes::trefoil(), 0.0),
        ("gyroid".into(), shapes::gyroid(), 0.0),
    ];
    for k in 0..4 {
        let dims = [14, 12, 30 + 4 * k];
        let v = common::smoothed_noise(dims, 2, &mut rng);
        let iso = common::quantile(&v, 0.45);
        cases.push((format!("noise {k}"), common::volume_from(dims, &v), iso));
    }
    let mut compared = 0;
    for (i, (name, vol, iso)) in cases.iter().enumerate() {
        let conn = BOTH[i % 2];
        for axis in [Axis::Z, Axis::X] {
            let opts = options(12.0, Mode::Both, conn);
            let run = |max_slices: Option<usize>| {
                let mut v = vol.clone();
                let mut m = MaskVolume::from_reader(
                    &mut v,
                    &common::opts(*iso, conn),
                    axis,
                    max_slices,
                    &NoProgress,
                )
                .unwrap();
                let out = simplify(&mut m, &opts, &Affine::IDENTITY, &NoProgress).unwrap();
                (out, m)
            };
            let (whole, m_whole) = run(Some(0));
            let (window, m_window) = run(Some(MIN_WINDOW));
            let what = format!("{name}, axis {}", axis.name());
            assert!(!m_whole.out_of_core(), "{what}");
            assert!(m_window.out_of_core(), "{what}: not out of core");
            assert!(m_window.planes_in_memory() <= MIN_WINDOW, "{what}");
            assert_eq!(whole.edits, window.edits, "{what}: edits differ");
            assert_eq!(whole.removed.len(), window.removed.len(), "{what}");
            assert_eq!(whole.kept.len(), window.kept.len(), "{what}");
            assert_eq!(
                m_whole.genus(conn).unwrap().b1,
                m_window.genus(conn).unwrap().b1
            );
            compared += usize::from(!whole.edits.is_empty());
        }
    }
    assert!(compared >= 8, "only {compared} runs edited anything");
}

/// Loops below tau that no handle's own measurement shows: in these two noise volumes the code
/// that measured each handle on its own (its Reeb loop confined to its cycle, or chained round
/// it, and the cross loop of that) kept handles it had measured at 8 edges or more, and left a
/// non-separating cycle of 5 (seed 2) and 4 (seed 4) edges, found by the oracle. Now each kept
/// handle's curves are certified and together span every loop.
#[test]
fn no_loop_below_tau_hides_between_handles() {
    for name in ["noise24-seed2.txt", "noise24-seed4.txt"] {
        let vol = common::fixture(name);
        for conn in BOTH {
            for axis in [Axis::Z, Axis::X] {
                let (out, _) = check(name, &vol, 0.0, axis, &options(8.0, Mode::Both, conn))
                    .unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(out.certified, Some(true));
                assert!(!out.kept.is_empty(), "{name}: the test needs kept handles");
            }
        }
    }
}

/// Walls the fan cannot close: in these random volumes every fan wall across the loops of one
/// handle is refused (it cuts off a spur or touches another part of the surface); the code that
/// stopped at fan walls kept each as `closure_failed`. Peeled walls close them.
#[test]
fn walls_the_fan_cannot_close_are_closed_otherwise() {
    // (case of the generator below, connectivity, axis, tau): the closure failures of the code
    // before peeled walls.
    let failing = [
        (46u64, Connectivity::Six, Axis::Y, 20.0),
        (180, Connectivity::TwentySix, Axis::X, 20.0),
        (256, Connectivity::TwentySix, Axis::Y, 20.0),
        (258, Connectivity::Six, Axis::Y, 20.0),
        (292, Connectivity::Six, Axis::X, 12.0),
    ];
    let (mut other_walls, mut refused) = (0, 0);
    for (seed, conn, axis, tau) in failing {
        let mut rng = Rng(0xfeed ^ (seed * 7919));
        let n = 10 + rng.below(12) as usize;
        let dims = [n, n + rng.below(4) as usize, n - 1 - rng.below(3) as usize];
        let v = common::smoothed_noise(dims, 1 + rng.below(3) as usize, &mut rng);
        let vol = common::volume_from(dims, &v);
        let iso = common::quantile(&v, 0.3 + 0.4 * rng.f64());
        let (out, _) = check(
            &format!("seed {seed}"),
            &vol,
            iso,
            axis,
            &options(tau, Mode::Both, conn),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        assert!(
            out.kept.iter().all(|k| k.reason == KeepReason::Size),
            "{:?}",
            out.kept
        );
        other_walls += out.removed.iter().filter(|r| r.wall != "fan").count();
        // The refusals reported add up, reason by reason.
        let by_reason: usize = out.refused_by.values().sum();
        assert_eq!(out.refused, by_reason, "seed {seed}: {:?}", out.refused_by);
        refused += out.refused;
    }
    assert!(other_walls >= 3, "only {other_walls} walls other than fans");
    // A wall other than a fan is tried only after the three fans across its loop were refused.
    assert!(
        refused >= 3 * other_walls,
        "{refused} refused, {other_walls} other walls"
    );
}

/// A torus whose tube is hollow where it is thinnest:
///
/// ```text
///    seen from above                 the tube's section at θ = 0
///      . - ~ - .                        # # # # #
///    /           \                    # # . . . # #     . : a cavity running along the
///   |      o      |  θ = 0 -> [.]     # # . . . # #         core for |θ| < 50°
///    \           /                    # # # # # # #
///      ' - ~ - '
/// ```
///
/// The shortest loop round the tube is where the cavity is, and any cut there opens the
/// cavity (b2 would change). Cutting only, the code that peeled walls in boxes round the loop
/// kept it as `closure_failed`; boxes moved along the loop round the hole find the tube solid.
/// The same shape turned inside out is a box of material holding a toroidal cavity with a rod
/// floating in part of it: filling only, the tunnel is filled where the rod is not (filling
/// across the rod would join it to the box).
#[test]
fn a_hollow_bar_is_cut_where_it_is_solid() {
    let dims = [34usize, 34, 16];
    let (c, big_r) = ([16.5, 16.5, 7.5], 9.0);
    let inside: Vec<bool> = (0..dims[2])
        .flat_map(|z| (0..dims[1]).flat_map(move |y| (0..dims[0]).map(move |x| (x, y, z))))
        .map(|(x, y, z)| {
            let (dx, dy, dz) = (x as f64 - c[0], y as f64 - c[1], z as f64 - c[2]);
            let theta = dy.atan2(dx);
            let rho = ((dx.hypot(dy) - big_r).powi(2) + dz * dz).sqrt();
            let tube = 3.6 - 0.9 * theta.cos();
            let hollow = theta.abs() < 50f64.to_radians() && rho < 1.1;
            rho < tube && !hollow
        })
        .collect();
    let vol = volume_of(dims, &inside);
    for conn in BOTH {
        let (b0, b1, b2, _) = betti(&inside, dims, conn);
        assert_eq!(
            (b0, b1, b2),
            (1, 1, 1),
            "the shape itself (conn {})",
            conn.number()
        );
        for axis in [Axis::Z, Axis::X] {
            let opts = options(f64::INFINITY, Mode::CutOnly, conn);
            let (out, _) =
                check("hollow torus", &vol, 0.0, axis, &opts).unwrap_or_else(|e| panic!("{e}"));
            assert!(
                out.kept.is_empty(),
                "conn {}, axis {}: {:?}",
                conn.number(),
                axis.name(),
                out.kept
            );
            assert!(
                out.edits.iter().all(|e| !e.1),
                "cut only sets samples outside"
            );
        }
    }
    let turned: Vec<bool> = inside.iter().map(|&b| !b).collect();
    let vol = volume_of(dims, &turned);
    for conn in BOTH {
        let (b0, b1, b2, _) = betti(&turned, dims, conn);
        assert_eq!((b0, b1, b2), (2, 1, 1), "turned (conn {})", conn.number());
        for axis in [Axis::Z, Axis::X] {
            let opts = options(f64::INFINITY, Mode::FillOnly, conn);
            let (out, _) = check("turned hollow torus", &vol, 0.0, axis, &opts)
                .unwrap_or_else(|e| panic!("{e}"));
            let at = format!("turned, conn {}, axis {}", conn.number(), axis.name());
            assert!(out.kept.is_empty(), "{at}: {:?}", out.kept);
            assert!(
                out.edits.iter().all(|e| e.1),
                "fill only sets samples inside"
            );
        }
    }
}

/// A short loop whose fans are all refused is closed by flipping one sample next to it (a
/// single-sample wall), where that sample is not already on the closure's side: on these
/// random volumes (cases of the generator of `random_volumes_keep_every_guarantee`, at tau
/// inf) such walls close handles, each changing exactly one sample.
#[test]
fn single_sample_walls_close_what_fans_cannot() {
    let cases = [
        (13u64, Connectivity::TwentySix),
        (23, Connectivity::Six),
        (72, Connectivity::TwentySix),
        (175, Connectivity::TwentySix),
        (221, Connectivity::Six),
    ];
    let mut singles = 0;
    for (case, conn) in cases {
        let (vol, iso, _) = random_case(case);
        let opts = options(f64::INFINITY, Mode::Both, conn);
        let (out, _) = check(&format!("case {case}"), &vol, iso, Axis::Z, &opts)
            .unwrap_or_else(|e| panic!("{e}"));
        for r in out.removed.iter().filter(|r| r.wall == "single_sample") {
            assert_eq!(r.samples_changed, 1, "case {case}: {r:?}");
            assert!(r.length <= 8, "case {case}: a loop of {} edges", r.length);
            singles += 1;
        }
    }
    assert!(singles >= cases.len(), "{singles} single-sample walls");
}

/// The report counts each intra-ribbon handle once, as the first pass first meets it: a wide
/// torus of two C-shaped contours in consecutive planes (the paper's figure 7: an intra-ribbon
/// handle; its loops, round its 6-sample-wide strip and round its hole, are longer than tau:
/// kept) under a small ring standing up (a Reeb-cycle handle round a one-sample hole: closed).
/// The pass that checks the result meets the wide torus again. The ring alone counts none.
///
/// ```text
///   z = 9..11   small ring in x-z, 3 deep in y      #.#  (# material, . the hole)
///   z = 3, 4    two C's, radii 2.5 to 8.5, open on opposite sides
/// ```
///
/// At a tau that closes both, the second pass meets neither: the count is still one.
#[test]
fn intra_ribbon_handles_are_counted_once() {
    let dims = [26, 26, 16];
    let shape = |with_cs: bool| {
        InMemoryVolume::from_fn(dims, move |x, y, z| {
            let (dx, dy) = (x as f64 - 12.6, y as f64 - 12.4);
            let (r, a) = (dx.hypot(dy), dy.atan2(dx).to_degrees());
            let ring = (2.5..8.5).contains(&r);
            let two_c = match z {
                3 => ring && !(-35.0..35.0).contains(&a),
                4 => ring && a.abs() < 145.0,
                _ => false,
            };
            let (x, y, z) = (x as i64, y as i64, z as i64);
            let standing = (11..=13).contains(&y) && (x - 12).abs().max((z - 10).abs()) == 1;
            if (two_c && with_cs) || standing {
                1.0
            } else {
                -1.0
            }
        })
    };
    let vol = shape(true);
    let conn = Connectivity::Six;
    let mut m = common::masks(&vol, 0.0, conn, Axis::Z);
    let found = isotopo::sweep::find_handles(&mut m, Axis::Z, conn, &NoProgress).unwrap();
    let kinds: Vec<_> = found.handles.iter().map(|h| h.located.kind).collect();
    use isotopo::sweep::HandleKind::{IntraRibbon, ReebCycle};
    assert_eq!(kinds.len(), 2, "{kinds:?}");
    assert!(
        kinds.contains(&IntraRibbon) && kinds.contains(&ReebCycle),
        "{kinds:?}"
    );

    let opts = options(8.0, Mode::Both, conn);
    let mut m = common::masks(&vol, 0.0, conn, Axis::Z);
    let out = simplify(&mut m, &opts, &Affine::IDENTITY, &NoProgress).unwrap();
    assert_eq!((out.removed.len(), out.kept.len()), (1, 1));
    assert!(out.passes >= 2, "{} passes", out.passes);
    assert_eq!(out.intra_ribbon, 1);
    // Both closed in the first pass: the second finds neither, and the count stays.
    let mut m = common::masks(&vol, 0.0, conn, Axis::Z);
    let all = options(1000.0, Mode::Both, conn);
    let out = simplify(&mut m, &all, &Affine::IDENTITY, &NoProgress).unwrap();
    assert_eq!((out.removed.len(), out.kept.len()), (2, 0));
    assert_eq!(out.intra_ribbon, 1);
    // The ring alone: its Reeb cycle is not counted as intra-ribbon.
    let mut m = common::masks(&shape(false), 0.0, conn, Axis::Z);
    let out = simplify(&mut m, &opts, &Affine::IDENTITY, &NoProgress).unwrap();
    assert_eq!((out.removed.len(), out.kept.len()), (1, 0));
    assert_eq!(out.intra_ribbon, 0);
}

/// `simplify --tau inf` along z in memory, with or without the well-composed step.
fn simplify_inf(
    vol: &InMemoryVolume,
    iso: f64,
    conn: Connectivity,
    well_composed: bool,
) -> Outcome {
    let opts = SimplifyOptions {
        surface: common::opts(iso, conn),
        tau: f64::INFINITY,
        well_composed,
        ..SimplifyOptions::default()
    };
    let mut m = common::masks(vol, iso, conn, Axis::Z);
    simplify(&mut m, &opts, &Affine::IDENTITY, &NoProgress).unwrap()
}

/// Walls are trimmed to what holds the handles closed: after `simplify --tau inf` without the
/// well-composed step, on random smoothed noise, every sample the walls changed is needed:
/// flipping it back alone changes the Betti numbers (by the oracle) of the chosen
/// connectivity, so a simple flip back was left for none. Samples of an earlier pass's walls
/// that a later wall made simple again are not trimmed again (few: measured 0 of 355).
#[test]
fn every_sample_a_wall_keeps_changed_is_needed() {
    let mut rng = Rng(0x7a11_5eed);
    let dims = [18, 16, 14];
    let (mut edits, mut loose) = (0, 0);
    for (vol, iso) in common::noise_rounds(&mut rng, dims, 2, 6) {
        for conn in BOTH {
            let out = simplify_inf(&vol, iso, conn, false);
            let mut mask = bits(&vol, iso);
            let at =
                |q: [i64; 3]| (q[0] as usize) + dims[0] * (q[1] as usize + dims[1] * q[2] as usize);
            for &(q, inside) in &out.edits {
                mask[at(q)] = inside;
            }
            let after = betti(&mask, dims, conn);
            for &(q, inside) in &out.edits {
                mask[at(q)] = !inside;
                loose += usize::from(betti(&mask, dims, conn) == after);
                mask[at(q)] = inside;
                edits += 1;
            }
        }
    }
    eprintln!("{loose} of {edits} wall samples could flip back");
    assert!(edits > 100, "{edits} samples changed");
    assert!(loose * 100 <= edits, "{loose} of {edits} could flip back");
}

/// What the report says of the run is about the run: a refused closure is refused for its
/// topology, never because its wall would change nothing (a single-sample wall already on the
/// operation's side is not tried), and the stages' seconds are times, none negative, together
/// within the call's. Random smoothed noise at tau inf, both connectivities.
#[test]
fn the_report_counts_real_refusals_and_real_times() {
    let mut rng = Rng(0x005e_ed0f_7e57);
    let dims = [32, 32, 24];
    let mut refused = 0;
    for (vol, iso) in common::noise_rounds(&mut rng, dims, 1, 3) {
        for conn in BOTH {
            let start = std::time::Instant::now();
            let out = simplify_inf(&vol, iso, conn, true);
            let elapsed = start.elapsed().as_secs_f64();
            assert_eq!(out.refused, out.refused_by.values().sum::<usize>());
            assert_eq!(
                out.refused_by.get("nothing_to_change"),
                None,
                "{:?}",
                out.refused_by
            );
            refused += out.refused;
            let s = &out.seconds;
            let stages = [s.parts, s.sweep, s.loops, s.closures];
            assert!(stages.iter().all(|&t| t >= 0.0), "{stages:?}");
            assert!(
                stages.iter().sum::<f64>() <= elapsed,
                "{stages:?} in {elapsed} s"
            );
            if !out.removed.is_empty() {
                assert!(
                    s.sweep > 0.0 && s.loops > 0.0 && s.closures > 0.0,
                    "{stages:?}"
                );
            }
        }
    }
    assert!(refused > 60, "{refused} closures refused"); // measured 135
}

/// Case `case` of the larger random volumes: smoothed noise of side `side` to `side` + 7,
/// with its isovalue, connectivity, sweep axis, finite tau and mode all drawn from the case.
fn larger_random_case(case: u64, side: usize) -> (InMemoryVolume, f64, Axis, SimplifyOptions) {
    let mut rng = Rng(0xabc ^ (case * 7919));
    let n = side + rng.below(8) as usize;
    let dims = [n, n + rng.below(4) as usize, n - 1 - rng.below(3) as usize];
    let v = common::smoothed_noise(dims, 1 + rng.below(2) as usize, &mut rng);
    let vol = common::volume_from(dims, &v);
    let iso = common::quantile(&v, 0.3 + 0.4 * rng.f64());
    let conn = BOTH[rng.below(2) as usize];
    let axis = [Axis::Z, Axis::Y, Axis::X][rng.below(3) as usize];
    let tau = [5.0, 8.0, 12.0, 20.0][rng.below(4) as usize];
    let mode = [Mode::Both, Mode::FillOnly, Mode::CutOnly][rng.below(3) as usize];
    (vol, iso, axis, options(tau, mode, conn))
}

/// [`larger_random_case`] with two more draws, from a generator of their own so that the
/// cases above keep theirs: tau inf in one case of five, the inside below the isovalue in one of
/// two.
fn wider_random_case(case: u64, side: usize) -> (InMemoryVolume, f64, Axis, SimplifyOptions) {
    let (vol, iso, axis, mut opts) = larger_random_case(case, side);
    let mut rng = Rng(0xdef ^ (case * 7919));
    if rng.below(5) == 0 {
        opts.tau = f64::INFINITY;
    }
    if rng.below(2) == 0 {
        opts.surface.inside = Inside::Below;
    }
    (vol, iso, axis, opts)
}

/// A handle the well-composed step opened but no pass could close is taken back; the faces
/// left then are not those the first openings met, and one may now be mended by opening a
/// handle that a wall closes. Simplify opens again, round after round, until a round ends
/// where it began; before, it stopped opening after the first take-back, and a second run
/// (which opens from the start) changed samples: 1 on the first volume here (fill only), 5 on
/// the second (cut only), 15 on the cranium CT filled only along x at tau 20. Every guarantee
/// of `check`, the second run's included.
#[test]
fn a_face_left_once_openings_are_taken_back_is_mended_in_a_later_round() {
    let mut failures = Vec::new();
    let mut repeats = 0;
    for (case, side) in [(39, 24), (197, 24)] {
        let (vol, iso, axis, opts) = larger_random_case(case, side);
        if let Err(e) = check(&format!("case {case}"), &vol, iso, axis, &opts) {
            failures.push(e);
        }
        // The last round, which would open and take back what the one before did, is cut
        // short (its step undone): checked above to change nothing the second run would.
        let traces = Traces::default();
        let mut m = common::masks(&vol, iso, opts.surface.connectivity, axis);
        simplify(&mut m, &opts, &Affine::IDENTITY, &traces).expect("simplified");
        repeats += traces.count("would repeat the last");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert!(repeats > 0, "no round cut short");
}

/// A block against the volume's three high faces, with a tunnel along each axis through it to
/// those faces (each a handle): the loops round a tunnel's mouth run along the face, and the
/// samples beyond it are padding, never written. Every mode, connectivity and axis, at tau inf
/// and 20: every guarantee of `check`.
#[test]
fn tunnels_opening_on_the_volumes_high_faces_are_closed_within_it() {
    let n = 14;
    let inside = |x: usize, y: usize, z: usize| {
        let block = x >= 3 && y >= 3 && z >= 3;
        let tunnel = (y, z) == (7, 7) || (x, z) == (10, 5) || (x, y) == (5, 10);
        block && !tunnel
    };
    let vol = InMemoryVolume::from_fn([n; 3], |x, y, z| if inside(x, y, z) { 1.0 } else { -1.0 });
    let mut failures = Vec::new();
    for mode in [Mode::FillOnly, Mode::CutOnly, Mode::Both] {
        for conn in BOTH {
            for axis in [Axis::Z, Axis::X] {
                for tau in [20.0, f64::INFINITY] {
                    if let Err(e) = check("block", &vol, 0.0, axis, &options(tau, mode, conn)) {
                        failures.push(e);
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The well-composed step is not run again on a volume it last ended on with the same options
/// (it would flip nothing: a pass that closes nothing and the round after a take-back met it
/// each time, a full look over every face left, most of a fill-only run on a noisy scan); the
/// result keeps every guarantee of `check`.
#[test]
fn the_step_is_not_run_again_on_the_volume_it_ended_on() {
    let (vol, iso, axis, opts) = larger_random_case(39, 24);
    if let Err(e) = check("case 39", &vol, iso, axis, &opts) {
        panic!("{e}");
    }
    let traces = Traces::default();
    let mut m = common::masks(&vol, iso, opts.surface.connectivity, axis);
    simplify(&mut m, &opts, &Affine::IDENTITY, &traces).expect("simplified");
    let ran = traces.count("critical cells before");
    let skipped = traces.count("nothing changed since the step last ended");
    assert!(ran > 0 && skipped > 0, "{ran} steps run, {skipped} skipped");
}

/// A 9³ crop of the cranium (`tests/data/cranium-moved-opening.txt`) where fill-only at tau 2
/// took the genus from 0 to 1: the well-composed step filled a sample to open a handle through
/// a face, then mended the faces round it, and the handle moved beside the sample (the sample
/// became simple); no pass closed it (its loops are longer than 2), and flipping the sample
/// back no longer removed it. Every mode, connectivity and axis, and taus on both sides of the
/// handle's loops.
#[test]
fn a_handle_the_step_opened_is_taken_back_after_later_mends() {
    let vol = common::fixture("cranium-moved-opening.txt");
    let mut failures = Vec::new();
    for mode in [Mode::FillOnly, Mode::CutOnly, Mode::Both] {
        for conn in BOTH {
            for axis in [Axis::Z, Axis::X] {
                for tau in [1.0, 2.0, 4.0, 8.0, f64::INFINITY] {
                    let opts = options(tau, mode, conn);
                    if let Err(e) = check("cranium crop", &vol, 0.0, axis, &opts) {
                        failures.push(e);
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// At tau 0 no pass closes a handle, so the well-composed step opens none: a handle opened
/// there would have to be taken back. On the cranium crop above, where filling opens one at
/// tau 2, every step at tau 0 reports none opened, in every mode, connectivity and axis.
#[test]
fn at_tau_0_the_step_opens_no_handle() {
    let vol = common::fixture("cranium-moved-opening.txt");
    for mode in [Mode::FillOnly, Mode::CutOnly, Mode::Both] {
        for conn in BOTH {
            for axis in [Axis::Z, Axis::X] {
                let traces = Traces::default();
                let mut m = common::masks(&vol, 0.0, conn, axis);
                let opts = options(0.0, mode, conn);
                simplify(&mut m, &opts, &Affine::IDENTITY, &traces).expect("simplified");
                let opened = traces.numbers_before(" opened");
                assert!(!opened.is_empty(), "no step ran");
                assert!(
                    opened.iter().all(|&n| n == 0),
                    "{mode:?}, conn {}, axis {axis:?}: opened {opened:?}",
                    conn.number()
                );
            }
        }
    }
}

/// A progress reporter that keeps the trace lines.
#[derive(Default)]
struct Traces(std::sync::Mutex<Vec<String>>);

impl Traces {
    fn count(&self, what: &str) -> usize {
        let lines = self.0.lock().expect("trace lines");
        lines.iter().filter(|l| l.contains(what)).count()
    }

    /// The number just before `what` on each line that has it ("3 opened" gives 3).
    fn numbers_before(&self, what: &str) -> Vec<usize> {
        let lines = self.0.lock().expect("trace lines");
        lines
            .iter()
            .filter_map(|l| l.split_once(what))
            .map(|(before, _)| {
                let n = before.rsplit(' ').next().unwrap_or_default();
                n.parse()
                    .unwrap_or_else(|_| panic!("no number before {what:?}: {before}"))
            })
            .collect()
    }
}

impl isotopo::progress::Progress for Traces {
    fn start(&self, _: &str, _: u64) {}
    fn advance(&self, _: u64) {}
    fn trace(&self, line: std::fmt::Arguments<'_>) {
        self.0.lock().expect("trace lines").push(line.to_string());
    }
}

/// Two handles found at one step whose cuts lie side by side can find one loop, through both
/// cuts, as their Reeb loop: their four curves then span only two dimensions, and the
/// certificate that no loop below tau is left failed (random 18³ noise, tau 5: loops of 13
/// and 14 edges through two contours of one plane). The second handle's certificate now takes
/// the walk round its own cycle as well. Every guarantee of `check`, the certificate's included.
#[test]
fn two_handles_of_a_step_with_one_loop_are_certified() {
    let (vol, iso, axis, opts) = larger_random_case(58, 14);
    if let Err(e) = check("case 58", &vol, iso, axis, &opts) {
        panic!("{e}");
    }
}

/// The property test below, on a few of its smaller cases, in every run: every option drawn
/// (tau inf and the inside below the isovalue included), every guarantee of `check`.
#[test]
fn random_volumes_with_every_option_drawn_keep_every_guarantee() {
    let mut failures = Vec::new();
    let mut drawn = std::collections::HashSet::new();
    for case in 0..40 {
        let (vol, iso, axis, opts) = wider_random_case(case, 14);
        drawn.insert((opts.tau.is_finite(), opts.surface.inside == Inside::Below));
        if let Err(e) = check(&format!("case {case}"), &vol, iso, axis, &opts) {
            failures.push(e);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert_eq!(
        drawn.len(),
        4,
        "finite and infinite tau, inside above and below"
    );
}

/// The guarantees of `check` on larger random volumes (side 24 to 31, tau finite or inf, the
/// inside above or below), where rarer sequences of openings, take-backs and walls happen;
/// slow (minutes), so run on demand:
/// `ISOTOPO_CASES=200 cargo test --release --test simplify larger -- --ignored` (cases from
/// `ISOTOPO_FIRST`, 0 by default; sides from `ISOTOPO_SIDE`, 24 by default).
#[test]
#[ignore]
fn larger_random_volumes_keep_every_guarantee() {
    let number = |name: &str, default: u64| {
        std::env::var(name)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(default)
    };
    let first = number("ISOTOPO_FIRST", 0);
    let cases = number("ISOTOPO_CASES", 100);
    let side = number("ISOTOPO_SIDE", 24) as usize;
    let mut failures = Vec::new();
    for case in first..first + cases {
        let (vol, iso, axis, opts) = wider_random_case(case, side);
        if let Err(e) = check(&format!("case {case}"), &vol, iso, axis, &opts) {
            failures.push(e);
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
