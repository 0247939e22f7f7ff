//! The Gauss linking number of two closed polygons, by counting crossings.
//!
//! Seen along a direction `d`, two disjoint closed curves cross each other in the picture some
//! number of times; at each crossing one passes over the other. The linking number is the sum,
//! over the crossings where `a` passes over `b`, of each crossing's sign (+1 when `b` runs right
//! to left under `a` running up, seen from the tip of `d`; the sign of the solid angle formula):
//!
//! ```text
//!        a                a
//!        ^                ^
//!   <----|---- b     b ---|---->
//!        |                |
//!       +1               -1
//! ```
//!
//! This is exact for every direction in which no vertex of one polygon projects onto the
//! other's edges. The loops here have their vertices at half and quarter voxels (edge midpoints,
//! pushed a quarter voxel), so `d` is taken with irrational slopes: no such coincidence happens,
//! and each pair of edges costs a few multiplications, where the solid angle formula (Klenin and
//! Langowski) took eight arc sines and was a tenth of `simplify`'s time on a sponge.

/// The projection's direction is `(ALPHA, BETA, 1)`: slopes no small-integer combination of
/// quarter-voxel coordinates cancels (1/π and Euler's γ).
const ALPHA: f64 = std::f64::consts::FRAC_1_PI;
const BETA: f64 = 0.577_215_664_901_532_9;

/// A point seen along the direction: its place in the picture, and its height along the
/// direction (the `z` it has: moving along the direction by `s` adds `s` to `z`).
#[derive(Clone, Copy)]
struct Seen {
    x: f64,
    y: f64,
    z: f64,
}

fn seen(p: [f64; 3]) -> Seen {
    Seen {
        x: p[0] - ALPHA * p[2],
        y: p[1] - BETA * p[2],
        z: p[2],
    }
}

/// Twice the signed area of the triangle `o, p, q` in the picture.
fn turn(o: Seen, p: Seen, q: Seen) -> f64 {
    (p.x - o.x) * (q.y - o.y) - (p.y - o.y) * (q.x - o.x)
}

/// Gauss linking number of two closed polygons that do not meet (the last vertex of each joins
/// its first). Its sign follows the polygons' orientations; callers use its magnitude.
pub fn linking_number(a: &[[f64; 3]], b: &[[f64; 3]]) -> i64 {
    let (a, b): (Vec<Seen>, Vec<Seen>) = (
        a.iter().copied().map(seen).collect(),
        b.iter().copied().map(seen).collect(),
    );
    let edges = |p: &[Seen]| -> Vec<(Seen, Seen)> {
        (0..p.len()).map(|i| (p[i], p[(i + 1) % p.len()])).collect()
    };
    let eb = edges(&b);
    let picture = PictureBox::of(&b);
    let mut total = 0;
    for (a1, a2) in edges(&a) {
        // a's edges whose box misses b's cross nothing: most of a long loop's.
        if picture.misses(a1, a2) {
            continue;
        }
        for &(b1, b2) in &eb {
            total += over_crossing(a1, a2, b1, b2);
        }
    }
    total
}

/// The bounding box of a polygon in the picture.
struct PictureBox {
    lo: [f64; 2],
    hi: [f64; 2],
}

impl PictureBox {
    fn of(p: &[Seen]) -> PictureBox {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for q in p {
            lo = [lo[0].min(q.x), lo[1].min(q.y)];
            hi = [hi[0].max(q.x), hi[1].max(q.y)];
        }
        PictureBox { lo, hi }
    }

    /// Whether the edge `a1 a2` lies wholly beside the box, on one side of it.
    fn misses(&self, a1: Seen, a2: Seen) -> bool {
        a1.x.max(a2.x) < self.lo[0]
            || a1.x.min(a2.x) > self.hi[0]
            || a1.y.max(a2.y) < self.lo[1]
            || a1.y.min(a2.y) > self.hi[1]
    }
}

/// +1 or -1 when the edge `a1 a2` passes over `b1 b2` in the picture (its sign), else 0.
fn over_crossing(a1: Seen, a2: Seen, b1: Seen, b2: Seen) -> i64 {
    let (t1, t2) = (turn(a1, a2, b1), turn(a1, a2, b2));
    if (t1 > 0.0) == (t2 > 0.0) {
        return 0;
    }
    let (t3, t4) = (turn(b1, b2, a1), turn(b1, b2, a2));
    if (t3 > 0.0) == (t4 > 0.0) {
        return 0;
    }
    // Where they cross: a fraction u along a, w along b.
    let u = t3 / (t3 - t4);
    let w = t1 / (t1 - t2);
    let za = a1.z + u * (a2.z - a1.z);
    let zb = b1.z + w * (b2.z - b1.z);
    if za <= zb {
        return 0;
    }
    // b starts on the right of a (t1 < 0): it runs right to left under a.
    if t1 < 0.0 {
        1
    } else {
        -1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The solid angle formula (Klenin and Langowski): an oracle independent of projections.
    fn solid_angle_linking(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
        let sub = |p: [f64; 3], q: [f64; 3]| [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
        let cross = |p: [f64; 3], q: [f64; 3]| {
            [
                p[1] * q[2] - p[2] * q[1],
                p[2] * q[0] - p[0] * q[2],
                p[0] * q[1] - p[1] * q[0],
            ]
        };
        let dot = |p: [f64; 3], q: [f64; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
        let unit = |p: [f64; 3]| {
            let l = dot(p, p).sqrt();
            if l > 1e-15 {
                [p[0] / l, p[1] / l, p[2] / l]
            } else {
                [0.0; 3]
            }
        };
        let mut total = 0.0;
        for i in 0..a.len() {
            let (p1, p2) = (a[i], a[(i + 1) % a.len()]);
            for j in 0..b.len() {
                let (p3, p4) = (b[j], b[(j + 1) % b.len()]);
                let (r13, r14, r23, r24) = (sub(p3, p1), sub(p4, p1), sub(p3, p2), sub(p4, p2));
                let n = [
                    unit(cross(r13, r14)),
                    unit(cross(r14, r24)),
                    unit(cross(r24, r23)),
                    unit(cross(r23, r13)),
                ];
                let s: f64 = (0..4)
                    .map(|k| dot(n[k], n[(k + 1) % 4]).clamp(-1.0, 1.0).asin())
                    .sum();
                let sign = dot(cross(sub(p4, p3), sub(p2, p1)), r13);
                total += s * sign.signum() * (sign != 0.0) as i32 as f64;
            }
        }
        total / (4.0 * std::f64::consts::PI)
    }

    fn ring(c: [f64; 3], axis: usize, r: f64, n: usize) -> Vec<[f64; 3]> {
        (0..n)
            .map(|k| {
                let t = k as f64 / n as f64 * std::f64::consts::TAU;
                let (a, b) = (r * t.cos(), r * t.sin());
                match axis {
                    0 => [c[0], c[1] + a, c[2] + b],
                    1 => [c[0] + a, c[1], c[2] + b],
                    _ => [c[0] + a, c[1] + b, c[2]],
                }
            })
            .collect()
    }

    #[test]
    fn linked_and_unlinked_rings() {
        let a = ring([0.0; 3], 2, 2.0, 40);
        let b = ring([2.0, 0.0, 0.0], 1, 2.0, 40);
        assert_eq!(linking_number(&a, &b).abs(), 1);
        // Reversing either ring flips the sign; swapping them keeps it.
        let rev: Vec<_> = b.iter().rev().copied().collect();
        assert_eq!(linking_number(&a, &rev), -linking_number(&a, &b));
        assert_eq!(linking_number(&b, &a), linking_number(&a, &b));
        let far = ring([10.0, 0.0, 0.0], 1, 2.0, 40);
        assert_eq!(linking_number(&a, &far), 0);
        // Side by side, overlapping in the picture along z but not linked.
        let beside = ring([1.0, 0.5, 3.0], 2, 2.0, 40);
        assert_eq!(linking_number(&a, &beside), 0);
    }

    /// The cull: an edge misses a polygon's picture box exactly when the two boxes share no
    /// point (intervals on both axes, compared the other way round), and an edge that misses
    /// crosses none of the polygon's edges. Random edges round a random polygon.
    #[test]
    fn an_edge_misses_the_box_exactly_when_the_boxes_are_apart() {
        let mut rng = crate::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        let mut next = || rng.unit() * 20.0 - 10.0;
        let b: Vec<Seen> = (0..7).map(|_| seen([next(), next(), next()])).collect();
        let picture = PictureBox::of(&b);
        let (mut missed, mut met) = (0, 0);
        for _ in 0..20_000 {
            let (a1, a2) = (
                seen([next(), next(), next()]),
                seen([next(), next(), next()]),
            );
            let overlap = |lo: f64, hi: f64, u: f64, v: f64| u.max(v) >= lo && u.min(v) <= hi;
            let bx = b
                .iter()
                .map(|q| q.x)
                .fold([f64::INFINITY, f64::NEG_INFINITY], |m, x| {
                    [m[0].min(x), m[1].max(x)]
                });
            let by = b
                .iter()
                .map(|q| q.y)
                .fold([f64::INFINITY, f64::NEG_INFINITY], |m, y| {
                    [m[0].min(y), m[1].max(y)]
                });
            let apart = !(overlap(bx[0], bx[1], a1.x, a2.x) && overlap(by[0], by[1], a1.y, a2.y));
            assert_eq!(picture.misses(a1, a2), apart);
            if apart {
                missed += 1;
                for i in 0..b.len() {
                    assert_eq!(over_crossing(a1, a2, b[i], b[(i + 1) % b.len()]), 0);
                }
            } else {
                met += 1;
            }
        }
        assert!(missed > 2_000 && met > 2_000, "{missed} missed, {met} met");
    }

    /// A (2, 2k) torus link: two curves on a torus, each winding k times round the other.
    #[test]
    fn torus_links_of_every_linking_number() {
        for k in 1..=4 {
            let curve = |phase: f64| -> Vec<[f64; 3]> {
                (0..400)
                    .map(|i| {
                        let t = i as f64 / 400.0 * std::f64::consts::TAU;
                        let (big, small) = (5.0, 1.5);
                        let (u, v) = (t, k as f64 * t + phase);
                        let r = big + small * v.cos();
                        [r * u.cos(), r * u.sin(), small * v.sin()]
                    })
                    .collect()
            };
            let (a, b) = (curve(0.0), curve(std::f64::consts::PI));
            assert_eq!(linking_number(&a, &b).abs(), k as i64, "k = {k}");
            let oracle = solid_angle_linking(&a, &b);
            assert!(
                (oracle - linking_number(&a, &b) as f64).abs() < 1e-6,
                "k = {k}: {oracle}"
            );
        }
    }

    /// Random lattice polygons, one on the half-voxel lattice and one shifted a quarter voxel
    /// along every axis, against the solid angle formula: equal, sign included. Their edges run
    /// along the axes (each walk goes back to its start that way too), so every point of one has
    /// two coordinates a multiple of a half and every point of the other two coordinates a
    /// quarter off it: they never meet, and they line up in every way the picture could stumble
    /// on.
    #[test]
    fn agrees_with_the_solid_angle_formula_on_lattice_polygons() {
        let mut rng = crate::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let mut next = |m: u64| rng.below(m);
        let (mut linked, mut checked) = (0, 0);
        for _ in 0..3000 {
            let mut walk = |offset: f64| -> Vec<[f64; 3]> {
                let mut p = [0i64; 3];
                let mut pts = vec![p];
                for _ in 0..2 + next(12) {
                    p[next(3) as usize] += next(5) as i64 - 2;
                    pts.push(p);
                }
                for k in 0..3 {
                    p[k] = 0;
                    pts.push(p);
                }
                pts.dedup();
                pts.pop(); // the start again
                pts.iter()
                    .map(|p| p.map(|x| x as f64 * 0.5 + offset))
                    .collect()
            };
            let (a, b) = (walk(0.25), walk(0.0));
            if a.len() < 3 || b.len() < 3 {
                continue;
            }
            let oracle = solid_angle_linking(&a, &b);
            assert!(
                (oracle - oracle.round()).abs() < 1e-6,
                "{a:?} {b:?}: {oracle}"
            );
            checked += 1;
            linked += (oracle.round() != 0.0) as usize;
            assert_eq!(linking_number(&a, &b), oracle.round() as i64, "{a:?} {b:?}");
        }
        assert!(
            checked > 1000 && linked > 50,
            "{checked} checked, {linked} linked"
        );
    }
}
