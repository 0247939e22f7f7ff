//! Components and cavities (`--min-component`, `--largest`, `--min-cavity`, `--fill-cavities`,
//! `--spherical`), checked against the independent cell-counting oracle and the tests' own flood
//! fill: b0, b1 and b2 of the result are what the options ask for, each part goes by the cheaper
//! of its two operations the mode allows, and nothing else changes.

mod common;

use common::oracle::betti;
use common::{Rng, BOTH};
use isotopo::progress::NoProgress;
use isotopo::simplify::{KeepReason, Mode, PartKind, PartOperation, SimplifyOptions};
use isotopo::topology::Connectivity;
use isotopo::volume::InMemoryVolume;

/// The sizes of the parts of one side, by flood fill over the grid padded with outside (the
/// outside part touching the padding, the exterior, is left out).
fn part_sizes(inside: &[bool], dims: [usize; 3], side: bool, six: bool) -> Vec<usize> {
    let p = dims.map(|d| d as i64 + 2);
    let at = |q: [i64; 3]| -> bool {
        let r = q.map(|x| x - 1);
        if (0..3).any(|a| r[a] < 0 || r[a] >= dims[a] as i64) {
            return false;
        }
        inside[((r[2] as usize * dims[1]) + r[1] as usize) * dims[0] + r[0] as usize]
    };
    let idx = |q: [i64; 3]| ((q[2] * p[1] + q[1]) * p[0] + q[0]) as usize;
    let mut seen = vec![false; (p[0] * p[1] * p[2]) as usize];
    let mut sizes = Vec::new();
    for z in 0..p[2] {
        for y in 0..p[1] {
            for x in 0..p[0] {
                let s = [x, y, z];
                if seen[idx(s)] || at(s) != side {
                    continue;
                }
                seen[idx(s)] = true;
                let (mut size, mut exterior, mut stack) = (0, false, vec![s]);
                while let Some(q) = stack.pop() {
                    let border = (0..3).any(|a| q[a] == 0 || q[a] == p[a] - 1);
                    if border {
                        exterior = true;
                    } else {
                        size += 1;
                    }
                    for d in neighbours(six) {
                        let n = [q[0] + d[0], q[1] + d[1], q[2] + d[2]];
                        if (0..3).any(|a| n[a] < 0 || n[a] >= p[a]) {
                            continue;
                        }
                        if !seen[idx(n)] && at(n) == side {
                            seen[idx(n)] = true;
                            stack.push(n);
                        }
                    }
                }
                if !exterior {
                    sizes.push(size);
                }
            }
        }
    }
    sizes
}

fn neighbours(six: bool) -> Vec<[i64; 3]> {
    let mut out = Vec::new();
    for z in -1i64..=1 {
        for y in -1i64..=1 {
            for x in -1i64..=1 {
                let m = x.abs() + y.abs() + z.abs();
                if m > 0 && (!six || m == 1) {
                    out.push([x, y, z]);
                }
            }
        }
    }
    out
}

/// Component sizes and cavity sizes of a mask.
fn parts_of(inside: &[bool], dims: [usize; 3], conn: Connectivity) -> (Vec<usize>, Vec<usize>) {
    let six = conn == Connectivity::Six;
    (
        part_sizes(inside, dims, true, six),
        part_sizes(inside, dims, false, !six),
    )
}

/// The options at `tau`, without the well-composed step (its flips would blur the counts
/// these tests check; the random volumes run with it).
fn options(conn: Connectivity, tau: f64) -> SimplifyOptions {
    SimplifyOptions {
        tau,
        well_composed: false,
        surface: common::opts(0.0, conn),
        ..SimplifyOptions::default()
    }
}

/// Runs simplify on `vol` (inside above 0); returns the job and the result's mask. Checks what
/// holds for every option: b1 by the oracle equals the handles kept, b0 and b2 those the job
/// reports, and every part removed went by its cheaper allowed operation.
fn run(vol: &InMemoryVolume, opts: &SimplifyOptions) -> (isotopo::Simplified, Vec<bool>) {
    let mut done = isotopo::simplify(vol.clone().into(), opts, &NoProgress).expect("simplify");
    let out = done.edited().expect("edited");
    let mask = common::mask_of(&out, 0.0);
    let (b0, b1, b2, _) = betti(&mask, vol.dims(), opts.surface.connectivity);
    assert_eq!(b1 as usize, done.outcome.kept.len(), "genus = handles kept");
    assert_eq!((b0 as u64, b2 as u64), (done.after.b0, done.after.b2));
    if opts.mode == Mode::Both {
        assert!(
            done.outcome.parts.kept.is_empty(),
            "both operations allowed: nothing kept"
        );
    }
    for r in &done.outcome.parts.removed {
        let joined = matches!(r.operation, PartOperation::Bridge | PartOperation::Open);
        if joined {
            assert_eq!(r.samples_changed, r.path.len());
            if opts.mode == Mode::Both {
                assert!(
                    r.samples_changed < r.size,
                    "{r:?}: a join only when cheaper"
                );
            }
        } else {
            assert_eq!(r.samples_changed, r.size);
        }
    }
    (done, mask)
}

/// A solid ball of radius `r` at the centre of an `n`³ grid, with extra samples set inside.
fn ball_with(n: usize, r: f64, extra: &[[usize; 3]], hollow: Option<f64>) -> InMemoryVolume {
    let c = (n as f64 - 1.0) / 2.0;
    InMemoryVolume::from_fn([n; 3], |x, y, z| {
        let d = ((x as f64 - c).powi(2) + (y as f64 - c).powi(2) + (z as f64 - c).powi(2)).sqrt();
        let solid = d <= r && hollow.is_none_or(|h| d > h);
        if solid || extra.contains(&[x, y, z]) {
            1.0
        } else {
            -1.0
        }
    })
}

/// Samples of a 2×2×2 cube with its lowest corner at `at`.
fn cube_at(at: [usize; 3]) -> Vec<[usize; 3]> {
    (0..8)
        .map(|b| [at[0] + (b & 1), at[1] + (b >> 1 & 1), at[2] + (b >> 2)])
        .collect()
}

/// A ball of radius 7 round (11.5, 11.5, 11.5): its lowest samples are at z = 5. Specks of 1, 2
/// and 2 samples far from it (bridging them would cost more than deleting them), and a 2×2×2
/// cube at z = 2..3 right below it: one sample at z = 4 bridges it (deleting: 8).
fn ball_and_specks() -> InMemoryVolume {
    let mut extra = vec![[1, 1, 1], [1, 20, 1], [1, 21, 1], [20, 1, 1], [21, 1, 1]];
    extra.extend(cube_at([11, 11, 2]));
    ball_with(24, 7.0, &extra, None)
}

#[test]
fn far_specks_are_deleted_and_a_near_one_bridged() {
    let vol = ball_and_specks();
    for conn in BOTH {
        let (comps, _) = parts_of(&common::mask_of(&vol, 0.0), vol.dims(), conn);
        assert_eq!(comps.len(), 5, "{conn:?}: {comps:?}");
        let opts = SimplifyOptions {
            min_component: Some(10),
            ..options(conn, 0.0)
        };
        let (done, mask) = run(&vol, &opts);
        let (comps, cavities) = parts_of(&mask, vol.dims(), conn);
        assert_eq!(comps.len(), 1, "{conn:?}: {comps:?}");
        assert!(cavities.is_empty());
        let p = &done.outcome.parts;
        assert!(p.kept.is_empty());
        assert_eq!(p.count(PartOperation::Delete), 3, "{:?}", p.removed);
        assert_eq!(p.count(PartOperation::Bridge), 1, "{:?}", p.removed);
        let bridge = p
            .removed
            .iter()
            .find(|r| r.operation == PartOperation::Bridge);
        assert_eq!(bridge.map(|b| (b.path.len(), b.path[0][2])), Some((1, 4)));
        assert_eq!(done.outcome.edits.len(), 6, "1 + 2 + 2 deleted, 1 bridged");
        // The bridged cube stays whole: its 8 samples, the ball's and the bridge.
        let before = common::mask_of(&vol, 0.0).iter().filter(|&&b| b).count();
        assert_eq!(comps[0], before - 5 + 1);
    }
}

/// A bridge touches no other part that goes: under the ball of `ball_and_specks` (its lowest
/// samples at z = 5), a 2×2×2 cube at z = 0..1 (bridged: 3 samples, deleting it 8) and, beside
/// the first straight way up from it, a 3×3 plate at z = 3 (9 samples: parts go smallest
/// first, so the plate goes after the cube). A bridge touching the plate would join it too,
/// before its own turn; the cube's bridge goes up a column out of the plate's reach (found
/// first, not after ways the local check refuses), and the plate is bridged by one sample of
/// its own.
///
/// ```text
///   z = 5  ball ball ball ball          x = 8 ..= 12 at y = 11
///   z = 3  [plate ] .  (11) (12)        (11), (12): columns a bridge may take
///   z = 0..1        .  cube cube        the cube's way up (11) touches the plate
/// ```
#[test]
fn a_bridge_touches_no_other_part_that_goes() {
    let plate: Vec<[usize; 3]> = (0..9).map(|i| [8 + i % 3, 9 + i / 3, 3]).collect();
    let mut extra = cube_at([11, 11, 0]);
    extra.extend(&plate);
    let vol = ball_with(24, 7.0, &extra, None);
    for conn in BOTH {
        let (comps, _) = parts_of(&common::mask_of(&vol, 0.0), vol.dims(), conn);
        assert_eq!(comps.len(), 3, "{conn:?}: {comps:?}");
        let opts = SimplifyOptions {
            min_component: Some(10),
            ..options(conn, 0.0)
        };
        let (done, mask) = run(&vol, &opts);
        assert_eq!(parts_of(&mask, vol.dims(), conn).0.len(), 1, "{conn:?}");
        let removed = &done.outcome.parts.removed;
        let bridges: Vec<_> = removed.iter().map(|r| (r.size, r.path.len())).collect();
        assert_eq!(bridges, [(8, 3), (9, 1)], "{conn:?}: {removed:?}");
        // Next to the plate under the connectivity's adjacency.
        let touches = |q: &[i64; 3]| {
            plate.iter().any(|b| {
                let d = (0..3).map(|k| (q[k] - b[k] as i64).abs());
                match conn {
                    Connectivity::Six => d.sum::<i64>() <= 1,
                    Connectivity::TwentySix => d.max() <= Some(1),
                }
            })
        };
        let cube_bridge = &removed[0].path;
        assert!(
            !cube_bridge.iter().any(touches),
            "{conn:?}: the cube's bridge {cube_bridge:?} touches the plate"
        );
        // Nor was one offered: the local check refuses a way that joins the plate too (a
        // search that let it through offered one at 6, two at 26).
        assert_eq!(done.outcome.parts.refused, 0, "{conn:?}");
    }
}

/// The phase runs only when asked: with no option of it, the specks and the cube stay and the
/// report has no count after it; with one, it does.
#[test]
fn the_phase_runs_only_when_asked() {
    let vol = ball_and_specks();
    let (done, mask) = run(&vol, &options(Connectivity::Six, 0.0));
    assert_eq!(done.outcome.parts.after, None);
    assert_eq!(mask, common::mask_of(&vol, 0.0));
    let opts = SimplifyOptions {
        min_cavity: Some(1),
        ..options(Connectivity::Six, 0.0)
    };
    let (done, _) = run(&vol, &opts);
    assert_eq!(done.outcome.parts.after, Some((5, 0)));
}

#[test]
fn a_cavity_behind_a_thin_wall_is_opened_and_a_small_one_filled() {
    // A box shell [3, 19]³ two samples thick round a cavity of 13³ samples, its outer layer
    // dented at the top's centre: cutting one sample opens the cavity (filling: 2,197). Below
    // it, a solid 7³ cube with its centre sample empty: filled (opening it cuts through 3).
    let solid = |x: usize, y: usize, z: usize| {
        let within = |lo: usize, hi: usize, q: [usize; 3]| q.iter().all(|&c| c >= lo && c <= hi);
        let q = [x, y, z];
        let shell = within(3, 19, q) && !within(5, 17, q) && q != [11, 11, 19];
        let cube = (3..=9).contains(&x) && (3..=9).contains(&y) && (24..=30).contains(&z);
        shell || (cube && q != [6, 6, 27])
    };
    let vol = InMemoryVolume::from_fn(
        [23, 23, 34],
        |x, y, z| if solid(x, y, z) { 1.0 } else { -1.0 },
    );
    for conn in BOTH {
        let mask0 = common::mask_of(&vol, 0.0);
        let (_, cavities) = parts_of(&mask0, vol.dims(), conn);
        assert_eq!(cavities.len(), 2, "{conn:?}: {cavities:?}");
        let opts = SimplifyOptions {
            fill_cavities: true,
            ..options(conn, 0.0)
        };
        let (done, mask) = run(&vol, &opts);
        let (comps, cavities) = parts_of(&mask, vol.dims(), conn);
        assert!(cavities.is_empty(), "{conn:?}: {cavities:?}");
        assert_eq!(comps.len(), 2);
        let p = &done.outcome.parts;
        assert_eq!(p.count(PartOperation::Open), 1, "{conn:?}: {:?}", p.removed);
        assert_eq!(p.count(PartOperation::Fill), 1, "{conn:?}: {:?}", p.removed);
        let open = p
            .removed
            .iter()
            .find(|r| r.operation == PartOperation::Open);
        let one_cut = |o: &&isotopo::simplify::PartRemoved| o.path.len() == 1 && o.path[0][2] == 18;
        assert!(
            open.is_some_and(|o| o.size == 2197 && one_cut(&o)),
            "{open:?}"
        );
        assert_eq!(done.outcome.edits.len(), 2);
    }
}

#[test]
fn the_modes_choose_the_only_operation_they_allow() {
    let specks = ball_and_specks();
    for conn in BOTH {
        for (mode, op) in [
            (Mode::CutOnly, PartOperation::Delete),
            (Mode::FillOnly, PartOperation::Bridge),
        ] {
            let opts = SimplifyOptions {
                min_component: Some(10),
                mode,
                ..options(conn, 0.0)
            };
            let (done, mask) = run(&specks, &opts);
            assert_eq!(parts_of(&mask, specks.dims(), conn).0.len(), 1);
            assert_eq!(done.outcome.parts.count(op), 4, "{conn:?} {mode:?}");
            // Every edit counted, all of the one kind the mode allows.
            let (filled, cut) = done.outcome.samples_filled_cut();
            assert_eq!(filled + cut, done.outcome.edits.len(), "{conn:?} {mode:?}");
            let (allowed, other) = match mode {
                Mode::CutOnly => (cut, filled),
                _ => (filled, cut),
            };
            assert!(
                allowed > 0 && other == 0,
                "{conn:?} {mode:?}: {filled} filled, {cut} cut"
            );
        }
    }
}

/// Random smoothed noise at several isovalues: every option set gives exactly the topology it
/// asks for, by the oracle and the tests' own flood fill, with the well-composed step on.
#[test]
fn random_volumes_get_the_components_and_cavities_asked_for() {
    let mut rng = Rng(0x9a7e_5eed);
    let dims = [20, 18, 16];
    let (mut checked, mut kept_by_mode, mut removed) = (0, 0, 0);
    for _ in 0..6 {
        let values = common::smoothed_noise(dims, 2, &mut rng);
        for q in [0.3, 0.5, 0.7] {
            let iso = common::quantile(&values, q);
            let shifted: Vec<f32> = values.iter().map(|v| v - iso as f32).collect();
            let vol = common::volume_from(dims, &shifted);
            for conn in BOTH {
                let base = SimplifyOptions {
                    well_composed: true,
                    ..options(conn, 8.0)
                };
                let sets = [
                    SimplifyOptions {
                        min_component: Some(20),
                        ..base
                    },
                    SimplifyOptions {
                        min_cavity: Some(20),
                        ..base
                    },
                    SimplifyOptions {
                        largest: true,
                        fill_cavities: true,
                        ..base
                    },
                    base.spherical(),
                    SimplifyOptions {
                        min_component: Some(20),
                        min_cavity: Some(20),
                        mode: Mode::FillOnly,
                        ..base
                    },
                    SimplifyOptions {
                        largest: true,
                        min_cavity: Some(20),
                        mode: Mode::CutOnly,
                        ..base
                    },
                ];
                for opts in sets {
                    let (done, mask) = run(&vol, &opts);
                    let (comps, cavities) = parts_of(&mask, dims, conn);
                    let kept = |k: PartKind| {
                        done.outcome
                            .parts
                            .kept
                            .iter()
                            .filter(|p| p.part == k)
                            .count()
                    };
                    let small_comps = comps
                        .iter()
                        .filter(|&&s| (s as u64) < opts.min_component.unwrap_or(0))
                        .count();
                    let small_cavities = cavities
                        .iter()
                        .filter(|&&s| {
                            opts.fill_cavities || (s as u64) < opts.min_cavity.unwrap_or(0)
                        })
                        .count();
                    let what = format!(
                        "{conn:?} q {q} {:?}",
                        (
                            opts.min_component,
                            opts.largest,
                            opts.min_cavity,
                            opts.fill_cavities,
                            opts.mode
                        )
                    );
                    assert!(
                        small_comps <= kept(PartKind::Component),
                        "{what}: {comps:?}"
                    );
                    assert!(
                        small_cavities <= kept(PartKind::Cavity),
                        "{what}: {cavities:?}"
                    );
                    if opts.largest {
                        assert!(
                            comps.len() <= 1 + kept(PartKind::Component),
                            "{what}: {comps:?}"
                        );
                    }
                    if opts.tau.is_infinite() {
                        assert_eq!(done.after.b1, 0, "{what}");
                    }
                    checked += 1;
                    kept_by_mode += done.outcome.parts.kept.len();
                    removed += done.outcome.parts.removed.len();
                }
            }
        }
    }
    assert_eq!(checked, 6 * 3 * 2 * 6);
    // The volumes are an adversary only if they have parts to remove; the modes rarely block.
    assert!(
        removed > 500 && kept_by_mode * 20 < removed,
        "{removed} removed, {kept_by_mode} kept"
    );
}

/// `keep_handles`: the genus of the result is exactly k (or what there was), by the oracle;
/// components and cavities stay. (Which handles stay is decided by their sizes as measured at
/// the time: a wall can shorten the loops of a handle beside it, so a handle kept may measure
/// less in the result than one removed earlier.)
#[test]
fn keep_handles_leaves_exactly_that_many() {
    let mut rng = Rng(0x0006_e1e5);
    let dims = [18, 18, 16];
    let mut cases = 0;
    for _ in 0..4 {
        let values = common::smoothed_noise(dims, 2, &mut rng);
        let iso = common::quantile(&values, 0.5);
        let shifted: Vec<f32> = values.iter().map(|v| v - iso as f32).collect();
        let vol = common::volume_from(dims, &shifted);
        for conn in BOTH {
            let before = betti(&common::mask_of(&vol, 0.0), dims, conn);
            assert!(before.1 >= 4, "the test needs handles: {before:?}");
            for k in [0, 1, 3, before.1 as usize + 2] {
                let opts = SimplifyOptions {
                    keep_handles: Some(k),
                    well_composed: true,
                    ..options(conn, 0.0)
                };
                let (done, mask) = run(&vol, &opts);
                let after = betti(&mask, dims, conn);
                assert_eq!(after.1, before.1.min(k as i64), "{conn:?} k {k}");
                assert_eq!((after.0, after.2), (before.0, before.2));
                // Kept for their size (at or above the last threshold) or by the count only.
                let reasons = done.outcome.kept.iter().map(|h| h.reason);
                assert!(reasons
                    .clone()
                    .all(|r| matches!(r, KeepReason::KeepHandles | KeepReason::Size)));
                cases += 1;
            }
        }
    }
    assert_eq!(cases, 4 * 2 * 4);
}

/// `keep_handles` keeps the largest: three tori of different tubes, the largest met first by
/// the sweep (lowest in z) and the smallest last; keeping 1 keeps the largest, keeping 2 the
/// two largest, whatever order the sweep meets them in.
#[test]
fn keep_handles_keeps_the_largest() {
    // (centre z, ring radius, tube radius), largest first along the sweep.
    let tori = [(8.0, 9.0, 3.2), (20.0, 7.0, 2.4), (31.0, 5.0, 1.6)];
    let vol = InMemoryVolume::from_fn([28, 28, 38], |x, y, z| {
        let (dx, dy) = (x as f32 - 13.5, y as f32 - 13.5);
        let ring = (dx * dx + dy * dy).sqrt();
        tori.iter()
            .map(|&(cz, big, small)| small - (ring - big).hypot(z as f32 - cz))
            .fold(f32::MIN, f32::max)
    });
    for conn in BOTH {
        for k in [1, 2] {
            let opts = SimplifyOptions {
                keep_handles: Some(k),
                ..options(conn, 0.0)
            };
            let (done, _) = run(&vol, &opts);
            // Which torus each kept handle is: the one its loops' box is centred on in z.
            let mut which: Vec<usize> = done
                .outcome
                .kept
                .iter()
                .map(|h| {
                    let z = (h.bbox.min[2] + h.bbox.max[2]) as f32 / 2.0;
                    (0..3)
                        .min_by(|&a, &b| (tori[a].0 - z).abs().total_cmp(&(tori[b].0 - z).abs()))
                        .unwrap()
                })
                .collect();
            which.sort_unstable();
            let want: Vec<usize> = (0..k).collect();
            assert_eq!(which, want, "{conn:?} keep {k}: {:?}", done.outcome.kept);
        }
    }
}

/// Out of core (a window of 8 planes, the rest in a scratch file) the parts and the handles go
/// exactly as in memory.
#[test]
fn out_of_core_is_the_same_as_in_memory() {
    let mut rng = Rng(0x000c_c00e);
    let dims = [16, 14, 30];
    let values = common::smoothed_noise(dims, 1, &mut rng);
    let iso = common::quantile(&values, 0.6);
    let shifted: Vec<f32> = values.iter().map(|v| v - iso as f32).collect();
    let vol = common::volume_from(dims, &shifted);
    for conn in BOTH {
        for base in [
            options(conn, 0.0).spherical(),
            SimplifyOptions {
                min_component: Some(20),
                min_cavity: Some(20),
                keep_handles: Some(2),
                ..options(conn, 0.0)
            },
        ] {
            let whole = SimplifyOptions {
                max_slices: Some(0),
                ..base
            };
            let window = SimplifyOptions {
                max_slices: Some(8),
                ..base
            };
            let (a, _) = run(&vol, &whole);
            let (b, _) = run(&vol, &window);
            let parts = a.outcome.parts.removed.len();
            assert!(parts > 3, "{conn:?}: the test needs parts, has {parts}");
            assert_eq!(a.outcome.edits, b.outcome.edits, "{conn:?}");
        }
    }
}

/// `--min-cavity N` and `--min-component N` remove the parts of fewer than N samples and keep
/// those of exactly N: a block with cavities of 1, 2 and 8 samples, beside specks of 1, 2 and
/// 8 samples, at every threshold round those sizes.
#[test]
fn parts_of_exactly_the_minimum_size_stay() {
    let hollow = |q: [usize; 3]| {
        q == [4, 4, 4]
            || (q[1] == 4 && q[2] == 9 && (4..=5).contains(&q[0]))
            || cube_at([9, 9, 9]).contains(&q)
    };
    let speck = |q: [usize; 3]| {
        q == [1, 1, 16]
            || (q[1] == 8 && q[2] == 16 && (1..=2).contains(&q[0]))
            || cube_at([12, 1, 16]).contains(&q)
    };
    let vol = InMemoryVolume::from_fn([16, 16, 19], |x, y, z| {
        let q = [x, y, z];
        let block = q.iter().take(2).all(|&c| (2..=13).contains(&c)) && (2..=13).contains(&z);
        if (block && !hollow(q)) || speck(q) {
            1.0
        } else {
            -1.0
        }
    });
    for conn in BOTH {
        let (comps, cavities) = parts_of(&common::mask_of(&vol, 0.0), vol.dims(), conn);
        assert_eq!((comps.len(), cavities.len()), (4, 3), "{conn:?}");
        for (min, left) in [
            (1, vec![1, 2, 8]),
            (2, vec![2, 8]),
            (3, vec![8]),
            (8, vec![8]),
            (9, vec![]),
        ] {
            let opts = SimplifyOptions {
                min_cavity: Some(min),
                min_component: Some(min),
                ..options(conn, 0.0)
            };
            let (_, mask) = run(&vol, &opts);
            let (mut comps, mut cavities) = parts_of(&mask, vol.dims(), conn);
            comps.sort();
            cavities.sort();
            assert_eq!(cavities, left, "{conn:?}, at least {min}: cavities");
            // The block's size depends on how its cavities went (filled or opened): leave it out.
            comps.pop();
            assert_eq!(comps, left, "{conn:?}, at least {min}: specks");
        }
    }
}
