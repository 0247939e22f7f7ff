//! Every handle is found: for every surface, handles located by the sweep == genus from the
//! Euler characteristic, on synthetic shapes and random volumes, along all three axes, under both
//! connectivities; and the known counts of Reeb cycles and intra-ribbon handles.

mod common;

use common::{shapes, Rng, BOTH};
use isotopo::grid::{Axis, MaskVolume};
use isotopo::progress::NoProgress;
use isotopo::sweep::{find_handles, HandleKind, HandleReport};
use isotopo::topology::Connectivity;
use isotopo::volume::InMemoryVolume;

const AXES: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

fn sweep(vol: &InMemoryVolume, iso: f64, conn: Connectivity, axis: Axis) -> HandleReport {
    let opts = isotopo::AnalyzeOptions {
        surface: common::opts(iso, conn),
        axis,
        ..isotopo::AnalyzeOptions::default()
    };
    isotopo::handles(vol.clone().into(), &opts, &NoProgress)
        .unwrap_or_else(|e| panic!("sweep along {}: {e}", axis.name()))
        .report
}

/// Checks handles == genus per surface and in total (against the genus pass). Returns an error
/// naming the volume, axis and surface.
fn check(
    vol: &InMemoryVolume,
    iso: f64,
    conn: Connectivity,
    axis: Axis,
    name: &str,
) -> Result<HandleReport, String> {
    let r = sweep(vol, iso, conn, axis);
    let g = common::run_genus(vol, iso, conn);
    for s in &r.surfaces {
        if s.handles as i64 != s.genus {
            return Err(format!(
                "{name}, axis {}, conn {}: surface {} has genus {} but {} handles located",
                axis.name(),
                conn.number(),
                s.id,
                s.genus,
                s.handles
            ));
        }
    }
    if r.handles.len() as u64 != g.b1 || r.surfaces.len() != g.surfaces.len() {
        return Err(format!(
            "{name}, axis {}, conn {}: {} handles on {} surfaces, genus pass b1 {} on {} surfaces",
            axis.name(),
            conn.number(),
            r.handles.len(),
            r.surfaces.len(),
            g.b1,
            g.surfaces.len()
        ));
    }
    // Each handle on the surface of its number in the genus pass: its cycle's cubes (lower
    // corners) within that surface's samples' box, one sample wider below.
    for h in &r.handles {
        let b = &h.located.bbox;
        let sb = &g
            .surfaces
            .iter()
            .find(|s| s.id == h.surface)
            .ok_or("no such surface")?
            .bbox;
        if (0..3).any(|k| b.min[k] < sb.min[k] - 1 || b.max[k] > sb.max[k]) {
            return Err(format!(
                "{name}, axis {}: handle {} in {b:?}, its surface {} in {sb:?}",
                axis.name(),
                h.id,
                h.surface
            ));
        }
    }
    // Same surface numbering and genus as the genus pass.
    for s in &g.surfaces {
        if r.surfaces[s.id].genus != s.genus as i64 {
            return Err(format!(
                "{name}, axis {}: surface {} genus {} in the sweep, {} in the genus pass",
                axis.name(),
                s.id,
                r.surfaces[s.id].genus,
                s.genus
            ));
        }
    }
    Ok(r)
}

fn count(r: &HandleReport, kind: HandleKind) -> usize {
    r.handles.iter().filter(|h| h.located.kind == kind).count()
}

#[test]
fn every_handle_of_every_shape_is_found_along_every_axis() {
    let mut failures = Vec::new();
    for s in shapes::all() {
        for conn in BOTH {
            for axis in AXES {
                if let Err(e) = check(&s.volume, 0.0, conn, axis, &s.name) {
                    failures.push(e);
                }
            }
        }
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

/// The paper's figure 7: a torus made of two C-shaped contours in consecutive planes has no Reeb
/// cycle along z, only an intra-ribbon handle.
fn two_c_torus() -> InMemoryVolume {
    InMemoryVolume::from_fn([16, 16, 8], |x, y, z| {
        let (dx, dy) = (x as f64 - 7.6, y as f64 - 7.4);
        let r = dx.hypot(dy);
        let a = dy.atan2(dx).to_degrees();
        let ring = (2.5..5.5).contains(&r);
        let c = match z {
            3 => ring && !(-35.0..35.0).contains(&a),
            4 => ring && a.abs() < 145.0,
            _ => false,
        };
        if c {
            1.0
        } else {
            -1.0
        }
    })
}

#[test]
fn the_two_c_torus_is_an_intra_ribbon_handle_along_z() {
    let vol = two_c_torus();
    for conn in BOTH {
        let r = check(&vol, 0.0, conn, Axis::Z, "two-C torus").unwrap();
        assert_eq!(count(&r, HandleKind::ReebCycle), 0);
        assert_eq!(count(&r, HandleKind::IntraRibbon), 1);
        for axis in [Axis::X, Axis::Y] {
            check(&vol, 0.0, conn, axis, "two-C torus").unwrap();
        }
    }
}

#[test]
fn known_counts() {
    use std::f64::consts::FRAC_PI_2;
    let cases: Vec<(&str, InMemoryVolume, usize)> = vec![
        (
            "upright torus",
            shapes::torus(26, 8.0, 3.0, 0.0, 0.0, 0.0),
            1,
        ),
        (
            "torus on its side",
            shapes::torus(26, 8.0, 3.0, FRAC_PI_2, 0.0, 0.0),
            1,
        ),
        ("ball", shapes::ball(20, 7.3), 0),
        (
            "bowl",
            shapes::field(24, |p| {
                let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                (9.0 - d).min(d - 6.0).min(-p[2])
            }),
            0,
        ),
    ];
    for (name, vol, n) in cases {
        for conn in BOTH {
            let r = check(&vol, 0.0, conn, Axis::Z, name).unwrap();
            assert_eq!(r.handles.len(), n, "{name}");
            assert_eq!(count(&r, HandleKind::ReebCycle), n, "{name}: Reeb cycles");
        }
    }
    for holes in 1..=4 {
        let vol = shapes::holed_slab(holes);
        for axis in AXES {
            let r = check(&vol, 0.0, Connectivity::Six, axis, "slab").unwrap();
            assert_eq!(
                r.handles.len(),
                holes,
                "{holes}-holed slab along {}",
                axis.name()
            );
        }
    }
}

#[test]
fn random_volumes_all_axes_both_connectivities() {
    let mut rng = Rng(4242);
    let mut failures = Vec::new();
    let mut n = 0;
    let mut intra = 0;
    for round in 0..50 {
        let dims = [
            [8, 9, 7],
            [12, 12, 12],
            [16, 10, 14],
            [20, 18, 16],
            [10, 22, 12],
        ][round % 5];
        let v = common::smoothed_noise(dims, 1 + round % 3, &mut rng);
        let vol = common::volume_from(dims, &v);
        let iso = common::quantile(&v, 0.35 + 0.3 * rng.f64());
        for conn in BOTH {
            for axis in AXES {
                n += 1;
                match check(&vol, iso, conn, axis, &format!("noise round {round}")) {
                    Ok(r) => intra += count(&r, HandleKind::IntraRibbon),
                    Err(e) => failures.push(e),
                }
            }
        }
    }
    assert!(n >= 300);
    assert!(
        failures.is_empty(),
        "{} of {n}:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(
        intra > 0,
        "random volumes should exercise intra-ribbon handles"
    );
}

/// Stepping back and sweeping again gives exactly the same handles, also after letting go of
/// the handles found so far.
#[test]
fn rewinding_reproduces_the_sweep() {
    use isotopo::sweep::Sweeper;
    let mut rng = Rng(7);
    for round in 0..12 {
        let dims = [14, 12, 16];
        let v = common::smoothed_noise(dims, 1 + round % 2, &mut rng);
        let vol = common::volume_from(dims, &v);
        let iso = common::quantile(&v, 0.5);
        for conn in BOTH {
            let mut src = vol.clone();
            let masks = MaskVolume::from_reader(
                &mut src,
                &common::opts(iso, conn),
                Axis::Z,
                None,
                &NoProgress,
            )
            .unwrap();
            let describe = |s: &Sweeper| {
                s.handles()
                    .iter()
                    .map(|(z, h)| (*z, h.kind, h.cut.clone(), h.bbox))
                    .collect::<Vec<_>>()
            };
            let mut a = Sweeper::new(conn);
            while !a.done(&masks) {
                a.step(&masks).unwrap();
            }
            let mut b = Sweeper::new(conn);
            let stops = [5 + round as i64 % 7, 9, 13];
            for &stop in &stops {
                while b.next <= stop && !b.done(&masks) {
                    b.step(&masks).unwrap();
                }
                b.rewind(&masks, stop - 3 - round as i64 % 3).unwrap();
            }
            while !b.done(&masks) {
                b.step(&masks).unwrap();
            }
            assert_eq!(describe(&a), describe(&b), "round {round}");
            // Handles let go of before each rewind (as simplify does) stay counted: the same
            // handles, in the same places; once let go of, none holds its cut.
            let mut c = Sweeper::new(conn);
            for &stop in &stops {
                while c.next <= stop && !c.done(&masks) {
                    c.step(&masks).unwrap();
                }
                c.release_handles();
                let held = c.handles().iter().filter(|(_, h)| !h.cut.is_empty());
                assert_eq!(held.count(), 0, "round {round}: handles not let go of");
                c.rewind(&masks, stop - 3 - round as i64 % 3).unwrap();
            }
            while !c.done(&masks) {
                c.step(&masks).unwrap();
            }
            let placed = |s: &Sweeper| {
                s.handles()
                    .iter()
                    .map(|(z, h)| (*z, h.kind, h.bbox))
                    .collect::<Vec<_>>()
            };
            assert_eq!(placed(&a), placed(&c), "round {round}");
        }
    }
}

/// Out of core (a window of a few planes, the rest in a scratch file), the sweep finds the same
/// handles, in the same places, along every axis; the window stays bounded.
#[test]
fn out_of_core_sweep_finds_the_same_handles() {
    use isotopo::grid::MIN_WINDOW;
    for s in shapes::all()
        .into_iter()
        .filter(|s| s.volume.dims()[2] > MIN_WINDOW)
    {
        for (k, axis) in AXES.into_iter().enumerate() {
            let conn = BOTH[k % 2];
            let run = |max_slices| {
                let mut v = s.volume.clone();
                let mut m = MaskVolume::from_reader(
                    &mut v,
                    &common::opts(0.0, conn),
                    axis,
                    max_slices,
                    &NoProgress,
                )
                .unwrap();
                let r = find_handles(&mut m, axis, conn, &NoProgress).unwrap();
                (r, m)
            };
            let (whole, _) = run(Some(0));
            let (window, m) = run(Some(MIN_WINDOW));
            let what = format!("{}, axis {}", s.name, axis.name());
            assert!(
                m.out_of_core() && m.planes_in_memory() <= MIN_WINDOW,
                "{what}"
            );
            assert_eq!(whole.genus, window.genus, "{what}");
            assert_eq!(whole.handles.len(), window.handles.len(), "{what}");
            for (a, b) in whole.handles.iter().zip(&window.handles) {
                assert_eq!(a.located.cut, b.located.cut, "{what}");
                assert_eq!(a.located.bbox, b.located.bbox, "{what}");
            }
        }
    }
}

/// A sweep made without rewind keeps no union log: it finds the same handles, and refuses to
/// be rewound (an error, not a wrong graph).
#[test]
fn a_sweep_without_rewind_finds_the_same_and_refuses_to_rewind() {
    use isotopo::sweep::Sweeper;
    let mut rng = Rng(11);
    let dims = [20, 18, 16];
    let v = common::smoothed_noise(dims, 1, &mut rng);
    let vol = common::volume_from(dims, &v);
    let iso = common::quantile(&v, 0.5);
    for conn in BOTH {
        let mut src = vol.clone();
        let opts = common::opts(iso, conn);
        let masks = MaskVolume::from_reader(&mut src, &opts, Axis::Z, None, &NoProgress).unwrap();
        let sweep = |mut s: Sweeper| {
            while !s.done(&masks) {
                s.step(&masks).unwrap();
            }
            let found: Vec<_> = s
                .handles()
                .iter()
                .map(|(z, h)| (*z, h.cut.clone()))
                .collect();
            (found, s)
        };
        let (a, _) = sweep(Sweeper::new(conn));
        let (b, mut without) = sweep(Sweeper::new(conn).without_rewind());
        assert!(!a.is_empty());
        assert_eq!(a, b);
        assert!(without.rewind(&masks, 3).is_err());
    }
}

/// A handle's box is the box of the cubes its cycle passes through (lower corners, original
/// coordinates): a square ring standing across the sweep, its tube w × w samples (x and z in
/// 2 ..= 11, y in 2 .. 2 + w), has one Reeb cycle through both arms, so its box spans the
/// cubes 1 ..= 11 across the ring and 1 ..= 1 + w through it, along every axis that crosses
/// the ring's plane.
#[test]
fn a_ring_handles_box_is_the_box_of_its_cubes() {
    for w in 1..=3usize {
        let vol = InMemoryVolume::from_fn([14, 8, 14], |x, y, z| {
            let outer = (2..12).contains(&x) && (2..12).contains(&z);
            let hole = (2 + w..12 - w).contains(&x) && (2 + w..12 - w).contains(&z);
            if outer && !hole && (2..2 + w).contains(&y) {
                1.0
            } else {
                -1.0
            }
        });
        for conn in BOTH {
            for axis in [Axis::X, Axis::Z] {
                let r = check(&vol, 0.0, conn, axis, "standing ring").unwrap();
                assert_eq!(r.handles.len(), 1);
                let h = &r.handles[0].located;
                assert_eq!(h.kind, HandleKind::ReebCycle);
                let across = if axis == Axis::X { 0 } else { 2 };
                let at = format!("tube {w}, {conn:?}, along {}", axis.name());
                // The arms reach across the ring; the cycle runs from the one to the other.
                assert_eq!(h.bbox.min[2 - across], 1, "{at}: {:?}", h.bbox);
                assert_eq!(h.bbox.max[2 - across], 11, "{at}: {:?}", h.bbox);
                assert_eq!(h.bbox.min[1], 1, "{at}: {:?}", h.bbox);
                assert_eq!(h.bbox.max[1], 1 + w as i64, "{at}: {:?}", h.bbox);
                assert!(h.bbox.min[across] >= 1 && h.bbox.max[across] <= 11, "{at}");
            }
        }
    }
}
