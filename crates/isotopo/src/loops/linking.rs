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

/// A polygon `b` ready to be crossed by many short segments (a search that tracks, step by
/// step, how its path links `b`): [`Overpass::over`] counts the crossings where a segment passes
/// over `b`, signed as in [`linking_number`], so its sum over the edges of a closed polygon is
/// their linking number. Mod 2 it says whether a step passes through the curtain that hangs from
/// `b` along the direction, a surface `b` bounds:
///
/// ```text
///        step p -> r      the curtain: every point of b moved up along the direction;
///     p ---+--- r         a closed path through it an odd number of times links b once
///     :::::|:::::         (mod 2), whatever the path
///     ~~~~~b~~~~~
/// ```
///
/// `b`'s edges are filed by the cells of a grid over the picture, each under every cell it comes
/// within [`Overpass::REACH`] of, so a segment no longer than that on either axis is checked
/// against the edges filed under its first end's cell only.
pub struct Overpass {
    edges: Vec<(Seen, Seen)>,
    picture: PictureBox,
    /// The grid: its corner, cell side, cells along x and y; per cell (x fastest), the range
    /// of `filed` holding its edges.
    corner: [f64; 2],
    side: f64,
    size: [usize; 2],
    first: Vec<u32>,
    filed: Vec<u32>,
}

impl Overpass {
    /// Picture extent, on each axis, of the segments looked up in one cell: a step to one of
    /// the 26 neighbours moves at most 1 + |ALPHA| or 1 + |BETA| in the picture.
    pub const REACH: f64 = 2.0;

    /// Cells along each axis of the grid at most (the cell side grows beyond).
    const MOST_CELLS: f64 = 256.0;

    /// Files the edges of the closed polygon `b`.
    pub fn new(b: &[[f64; 3]]) -> Overpass {
        let pts: Vec<Seen> = b.iter().copied().map(seen).collect();
        let edges: Vec<(Seen, Seen)> = (0..pts.len())
            .map(|i| (pts[i], pts[(i + 1) % pts.len()]))
            .collect();
        let picture = PictureBox::of(&pts);
        let margin = Self::REACH + 1.0;
        let corner = [picture.lo[0] - margin, picture.lo[1] - margin];
        let extent = [0, 1].map(|k| (picture.hi[k] - picture.lo[k]).max(0.0) + 2.0 * margin);
        let side = (extent[0].max(extent[1]) / Self::MOST_CELLS).max(1.0);
        // (An empty `b` has an inverted picture box: every lookup misses it.)
        let size = extent.map(|e| (e / side).ceil() as usize + 1);
        let mut lists: Vec<Vec<u32>> = vec![Vec::new(); size[0] * size[1]];
        for (e, (b1, b2)) in edges.iter().enumerate() {
            let range = |lo: f64, hi: f64, k: usize| {
                let cell = |v: f64| ((v - corner[k]) / side).floor().max(0.0) as usize;
                cell(lo - Self::REACH).saturating_sub(1)..=cell(hi + Self::REACH).min(size[k] - 1)
            };
            for j in range(b1.y.min(b2.y), b1.y.max(b2.y), 1) {
                for i in range(b1.x.min(b2.x), b1.x.max(b2.x), 0) {
                    lists[j * size[0] + i].push(e as u32);
                }
            }
        }
        let mut first = Vec::with_capacity(lists.len() + 1);
        first.push(0);
        let mut filed = Vec::new();
        for list in lists {
            filed.extend(list);
            first.push(filed.len() as u32);
        }
        Overpass {
            edges,
            picture,
            corner,
            side,
            size,
            first,
            filed,
        }
    }

    /// The signed count of crossings where the segment `p q` passes over the polygon.
    pub fn over(&self, p: [f64; 3], q: [f64; 3]) -> i64 {
        self.from(p).to(q)
    }

    /// The segments from `p`, for many of them: the edges filed under its cell, looked up once.
    pub fn from(&self, p: [f64; 3]) -> SegmentsFrom<'_> {
        let a1 = seen(p);
        let cell = |v: f64, k: usize| {
            let c = ((v - self.corner[k]) / self.side).floor();
            (c >= 0.0 && c < self.size[k] as f64).then_some(c as usize)
        };
        // Outside the grid (it cannot be, and a short segment from it still meet the box):
        // every edge.
        let filed = cell(a1.x, 0).zip(cell(a1.y, 1)).map(|(i, j)| {
            let c = j * self.size[0] + i;
            &self.filed[self.first[c] as usize..self.first[c + 1] as usize]
        });
        SegmentsFrom {
            overpass: self,
            a1,
            filed,
        }
    }
}

/// Segments from one point across an [`Overpass`] (see [`Overpass::from`]).
pub struct SegmentsFrom<'a> {
    overpass: &'a Overpass,
    a1: Seen,
    filed: Option<&'a [u32]>,
}

impl SegmentsFrom<'_> {
    /// The signed count of crossings where the segment from the point to `q` passes over the
    /// polygon.
    pub fn to(&self, q: [f64; 3]) -> i64 {
        let (o, a1, a2) = (self.overpass, self.a1, seen(q));
        if o.picture.misses(a1, a2) {
            return 0;
        }
        let short =
            (a2.x - a1.x).abs() <= Overpass::REACH && (a2.y - a1.y).abs() <= Overpass::REACH;
        match self.filed {
            Some(filed) if short => filed
                .iter()
                .map(|&e| {
                    let (b1, b2) = o.edges[e as usize];
                    over_crossing(a1, a2, b1, b2)
                })
                .sum(),
            // Long, or from outside the grid: every edge.
            _ => o
                .edges
                .iter()
                .map(|&(b1, b2)| over_crossing(a1, a2, b1, b2))
                .sum(),
        }
    }
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

    /// A closed polygon of moves along the axes from the origin, of up to four samples each,
    /// back to the origin along the axes (its vertices; the origin once).
    fn axis_polygon(rng: &mut crate::test_rng::Rng) -> Vec<[i64; 3]> {
        let mut p = [0i64; 3];
        let mut b = vec![p];
        for _ in 0..3 + rng.below(20) {
            p[rng.below(3) as usize] += rng.below(9) as i64 - 4;
            b.push(p);
        }
        for k in 0..3 {
            p[k] = 0;
            b.push(p);
        }
        b.dedup();
        b.pop();
        b
    }

    /// A square of integer samples round the middle of edge `i` of an axis polygon, one
    /// sample clear of it on either side (its samples in order, the first once).
    fn square_round_edge(b: &[[f64; 3]], i: usize) -> Vec<[i64; 3]> {
        let (e1, e2) = (b[i], b[(i + 1) % b.len()]);
        let axis = (0..3).find(|&k| e1[k] != e2[k]).unwrap();
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut c = [0i64; 3];
        c[axis] = ((e1[axis] + e2[axis]) / 2.0).round() as i64;
        let (u0, v0) = (e1[u].floor() as i64 - 1, e1[v].floor() as i64 - 1);
        let (u1, v1) = (e1[u].ceil() as i64 + 1, e1[v].ceil() as i64 + 1);
        let corners = [(u0, v0), (u1, v0), (u1, v1), (u0, v1), (u0, v0)];
        let mut square = Vec::new();
        for w in corners.windows(2) {
            let ((su, sv), (tu, tv)) = (w[0], w[1]);
            let mut at = c;
            (at[u], at[v]) = (su, sv);
            while (at[u], at[v]) != (tu, tv) {
                square.push(at);
                at[u] += (tu - at[u]).signum();
                at[v] += (tv - at[v]).signum();
            }
        }
        square
    }

    /// An [`Overpass`] loses no crossing to its filing: each segment counts what every edge of
    /// the polygon counts, and the counts over a closed walk's steps add up to its linking
    /// number. Polygons on the half-voxel lattice, small (cells of side 1) and stretched to
    /// hundreds of voxels (cells of side > 1); segments that are steps to one of the 26
    /// neighbours from integer samples moved a little off the grid (the ring searches'), and
    /// longer ones (which go past the filing); closed walks of such steps round the polygon.
    #[test]
    fn an_overpass_counts_what_every_edge_counts() {
        let mut rng = crate::test_rng::Rng(0x1405_7b7e_f767_814f);
        let nudge = [1.1e-3, 2.3e-3, 3.7e-3];
        let (mut crossed, mut walks_linked, mut long_cells) = (0, 0, 0);
        for round in 0..300 {
            let scale = if round % 3 == 0 { 60.0 } else { 0.5 };
            let b = axis_polygon(&mut rng);
            if b.len() < 3 {
                continue;
            }
            let b: Vec<[f64; 3]> = b.iter().map(|p| p.map(|x| x as f64 * scale)).collect();
            let over = Overpass::new(&b);
            long_cells += usize::from(over.side > 1.0);
            let reach = if scale > 1.0 { 150 } else { 5 };
            let point = |rng: &mut crate::test_rng::Rng| -> [i64; 3] {
                std::array::from_fn(|_| rng.below(2 * reach + 1) as i64 - reach as i64)
            };
            let off = |p: [i64; 3]| -> [f64; 3] { std::array::from_fn(|k| p[k] as f64 + nudge[k]) };
            let every = |a1: [f64; 3], a2: [f64; 3]| -> i64 {
                (0..b.len())
                    .map(|i| {
                        over_crossing(seen(a1), seen(a2), seen(b[i]), seen(b[(i + 1) % b.len()]))
                    })
                    .sum()
            };
            for _ in 0..400 {
                let p = point(&mut rng);
                let d: [i64; 3] = std::array::from_fn(|_| rng.below(3) as i64 - 1);
                let long = rng.below(4) == 0;
                let r: [i64; 3] = std::array::from_fn(|k| {
                    p[k] + d[k] * if long { 1 + rng.below(12) as i64 } else { 1 }
                });
                let (a1, a2) = (off(p), off(r));
                let n = over.over(a1, a2);
                assert_eq!(n, every(a1, a2), "{a1:?} {a2:?} over {b:?}");
                crossed += usize::from(n != 0);
            }
            // A closed walk of steps: out along a random path, back along the axes; half of
            // them start round an edge of the polygon (a square about its middle, then
            // on at random from a corner of it).
            let mut walk = if round % 2 == 0 {
                square_round_edge(&b, rng.below(b.len() as u64) as usize)
            } else {
                Vec::new()
            };
            let start = walk.first().copied().unwrap_or_else(|| point(&mut rng));
            walk.push(start);
            let mut at = start;
            for _ in 0..rng.below(3 * reach) {
                let d: [i64; 3] = std::array::from_fn(|_| rng.below(3) as i64 - 1);
                at = std::array::from_fn(|k| at[k] + d[k]);
                walk.push(at);
            }
            for k in 0..3 {
                while at[k] != start[k] {
                    at[k] += (start[k] - at[k]).signum();
                    walk.push(at);
                }
            }
            walk.dedup();
            walk.pop();
            if walk.len() < 3 {
                continue;
            }
            let walk: Vec<[f64; 3]> = walk.into_iter().map(off).collect();
            let steps: i64 = (0..walk.len())
                .map(|i| over.over(walk[i], walk[(i + 1) % walk.len()]))
                .sum();
            let lk = linking_number(&walk, &b);
            assert_eq!(steps, lk, "{walk:?} round {b:?}");
            walks_linked += usize::from(lk != 0);
        }
        assert!(
            crossed > 1500 && walks_linked > 40 && long_cells > 60,
            "{crossed} crossed, {walks_linked} linked, {long_cells} with long cells"
        );
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
