//! The genus pass against the independent oracle: synthetic shapes of known topology, the small
//! configurations that tell the conventions apart, and hundreds of random smoothed-noise volumes.

mod common;

use common::{oracle, shapes, Rng, BOTH};
use isotopo::topology::Connectivity;

#[test]
fn shapes_match_known_topology_and_oracle() {
    let mut failures = Vec::new();
    for s in shapes::all() {
        let mask = common::mask_of(&s.volume, 0.0);
        for conn in BOTH {
            let r = common::run_genus(&s.volume, 0.0, conn);
            let got = (r.b0 as i64, r.b1 as i64, r.b2 as i64);
            let (o0, o1, o2, ochi) = oracle::betti(&mask, s.volume.dims(), conn);
            if got != (o0, o1, o2) || r.chi != ochi {
                failures.push(format!(
                    "{} ({}): isotopo {:?} chi {}, oracle {:?} chi {}",
                    s.name,
                    conn.number(),
                    got,
                    r.chi,
                    (o0, o1, o2),
                    ochi
                ));
            }
            let expect = if conn == Connectivity::Six {
                s.expect6
            } else {
                s.expect26
            };
            if let Some(e) = expect {
                if got != e {
                    failures.push(format!(
                        "{} ({}): isotopo {:?}, known {:?}",
                        s.name,
                        conn.number(),
                        got,
                        e
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "\n{}", failures.join("\n"));
}

#[test]
fn random_smoothed_noise_matches_oracle() {
    let mut rng = Rng(20261122);
    let mut failures = Vec::new();
    let mut cases = 0;
    let sizes = [
        [6, 6, 6],
        [9, 7, 8],
        [12, 12, 12],
        [16, 11, 13],
        [20, 20, 20],
    ];
    for round in 0..60 {
        let dims = sizes[round % sizes.len()];
        let passes = 1 + round % 3;
        let v = common::smoothed_noise(dims, passes, &mut rng);
        let vol = common::volume_from(dims, &v);
        for q in [0.35, 0.5, 0.65] {
            let iso = common::quantile(&v, q + 0.1 * (rng.f64() - 0.5));
            let mask = common::mask_of(&vol, iso);
            for conn in BOTH {
                cases += 1;
                let r = common::run_genus(&vol, iso, conn);
                let (o0, o1, o2, ochi) = oracle::betti(&mask, dims, conn);
                if (r.b0 as i64, r.b1 as i64, r.b2 as i64, r.chi) != (o0, o1, o2, ochi) {
                    failures.push(format!(
                        "round {round} dims {dims:?} passes {passes} iso {iso} conn {}: isotopo ({}, {}, {}) chi {}, oracle ({o0}, {o1}, {o2}) chi {ochi}",
                        conn.number(),
                        r.b0,
                        r.b1,
                        r.b2,
                        r.chi
                    ));
                }
            }
        }
    }
    assert!(cases >= 300, "{cases} cases");
    assert!(
        failures.is_empty(),
        "{} of {cases} cases differ:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// The genus pass's survey of where meshers disagree (`Agreement`), on random smoothed noise
/// with some samples exactly at the isovalue: the other connectivity's Betti numbers as the
/// oracle gives them, the critical faces and cubes as a sample-by-sample count gives them, and
/// the samples at the isovalue counted. Smooth blobs leave most slices without a critical cell
/// (their surfels are copied from the chosen connectivity's), noise few.
#[test]
fn the_meshers_survey_matches_the_oracle() {
    let mut rng = Rng(20261204);
    let mut failures = Vec::new();
    let (mut cases, mut ties_seen) = (0, 0);
    for round in 0..40 {
        let dims = [[9, 7, 8], [16, 11, 13], [20, 20, 20], [24, 10, 18]][round % 4];
        let passes = 1 + round % 4;
        let v = common::smoothed_noise(dims, passes, &mut rng);
        let mut vol = common::volume_from(dims, &v);
        // A stored value (the samples are f32), so that samples set to it tie.
        let iso = common::quantile(&v, 0.3 + 0.4 * rng.f64()) as f32 as f64;
        let mut ties = 0;
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    if rng.below(25) == 0 {
                        vol.set(x, y, z, iso);
                    }
                    ties += u64::from(vol.get(x, y, z) == iso);
                }
            }
        }
        ties_seen += ties;
        let mask = common::mask_of(&vol, iso);
        let critical = common::critical_cells(&mask, dims);
        for conn in BOTH {
            cases += 1;
            let mut input = vol.clone();
            let (_, survey) = isotopo::topology::genus(
                &mut input,
                &common::opts(iso, conn),
                &isotopo::progress::NoProgress,
            )
            .expect("genus pass");
            let (o0, o1, o2, _) = oracle::betti(&mask, dims, conn.other());
            let got = (
                (survey.b0 as i64, survey.b1 as i64, survey.b2 as i64),
                (
                    survey.critical.faces as usize,
                    survey.critical.cubes as usize,
                ),
                survey.samples_at_iso,
            );
            if got != ((o0, o1, o2), critical, ties) {
                failures.push(format!(
                    "round {round} dims {dims:?} conn {}: {got:?}, expected {:?}",
                    conn.number(),
                    ((o0, o1, o2), critical, ties)
                ));
            }
        }
    }
    assert!(ties_seen > 1000, "{ties_seen} ties");
    assert!(
        cases == 80 && failures.is_empty(),
        "{}",
        failures.join("\n")
    );
}
