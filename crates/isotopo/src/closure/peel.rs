//! A wall grown one sample at a time, with the topology watched at each: for the loops no fan
//! wall closes cleanly (round a long twisted loop the fan touches other parts of the surface).
//!
//! Within a region across the loop (the samples near its spanning fan, or a whole box round
//! it), the side a closure changes is thinned by *simple* samples only: flipping a simple sample
//! changes no topology (Bertrand and Malandain's topological numbers, in its 26-neighbourhood,
//! are both 1). What is left of that side in the region is a skeleton. A sample of it with two
//! pieces of its side beside it (and one of the other) is where a single flip cuts a thread of
//! the side. That flip removes one handle and nothing else exactly when the two pieces stay
//! joined elsewhere: the thread is part of a *ring* of the side, and the ring the loop goes
//! round when it links the loop ([`Ring`]: a search through the side, then a linking number).
//! Then every thinned sample whose flip back is simple again is flipped back, so that the wall
//! keeps only what the change needs.
//!
//! ```text
//!    bar across the region     thinned to a thread      cut at one sample, the rest put back
//!     # # # # # # #             # # # . # # #            # # # . # # #
//!     # # # # # # #      ->     . . . # . . .     ->     # # #   # # #
//!     # # # # # # #             # # # . # # #            # # # . # # #
//! ```
//!
//! So every wall returned removes a handle round which the loop goes and changes no component
//! or cavity, whatever the shape: as long as the region holds a cut of that ring, the closure
//! cannot fail. It is still verified by [`super::close`] like any other wall.

use super::Operation;
use crate::grid::simple::{label_pieces, neighbourhood, topological_numbers, FACES};
use crate::grid::{shift, BoxCells, MaskVolume};
use crate::surface::search::FastMap;
use crate::topology::cases::Connectivity;

/// The loop a peeled wall closes, and the box within which the ring it goes round is looked
/// for (a search through the side, then a linking number).
pub struct PeelTarget<'a> {
    /// The loop's points (edge midpoints, volume-local), closed.
    pub loop_points: &'a [[f64; 3]],
    /// Inclusive corners of the box: the loop's and its partner's, with a margin.
    pub lo: [i64; 3],
    pub hi: [i64; 3],
}

/// Walls for closing the loop by `op` within `region` (see the module notes), one per sample of
/// the thinned region whose flip cuts (or fills) the ring the loop goes round, nearest `centre`
/// first, at most `most` of them. The volume is left as it was.
pub fn peel_walls(
    vol: &mut MaskVolume,
    conn: Connectivity,
    region: &[[i64; 3]],
    centre: [f64; 3],
    op: Operation,
    target: &PeelTarget,
    most: usize,
) -> Vec<Vec<[i64; 3]>> {
    let side = !op.target();
    let mut cand: Vec<[i64; 3]> = region
        .iter()
        .copied()
        .filter(|&q| vol.contains(q))
        .filter(|q| vol.get(q[0], q[1], q[2]) == side)
        .collect();
    // Far from the centre first: the side is peeled from the loop inwards.
    let d2 = |q: &[i64; 3]| {
        (0..3)
            .map(|c| (q[c] as f64 - centre[c]).powi(2))
            .sum::<f64>()
    };
    cand.sort_by(|a, b| d2(b).total_cmp(&d2(a)));
    let set = |vol: &mut MaskVolume, q: [i64; 3], inside: bool| {
        vol.set(q[0] as usize, q[1] as usize, q[2] as usize, inside)
    };
    let thinned = thin(vol, conn, &cand, side);
    let is_thinned: FastMap<[i64; 3], ()> = thinned.iter().map(|&q| (q, ())).collect();
    // The single change: a sample whose neighbourhood holds two pieces of the side, joined
    // round the loop (so the flip cuts the ring, and splits nothing).
    let splits = |t: (usize, usize)| match op {
        Operation::Pinch => t == (2, 1),
        Operation::Collapse => t == (1, 2),
    };
    let mut ring = Ring::new(target, side, conn);
    let cuts: Vec<[i64; 3]> = cand
        .iter()
        .rev()
        .copied()
        .filter(|q| !is_thinned.contains_key(q) && splits(topological_numbers(vol, *q, conn)))
        .take(MAX_RING_SEARCHES)
        .filter(|&q| ring.cuts(vol, q))
        .take(most)
        .collect();
    let mut walls = Vec::new();
    for c in cuts {
        set(vol, c, !side);
        let back = put_back(vol, conn, &thinned, side);
        let back_set: FastMap<[i64; 3], ()> = back.iter().map(|&q| (q, ())).collect();
        let mut kept: Vec<[i64; 3]> = thinned
            .iter()
            .copied()
            .filter(|q| !back_set.contains_key(q))
            .collect();
        // Back to the thinned state for the next cut.
        for &q in &back {
            set(vol, q, !side);
        }
        set(vol, c, side);
        kept.push(c);
        walls.push(kept);
    }
    for &q in &thinned {
        set(vol, q, side);
    }
    walls
}

/// Cut samples looked at (each with a search in the box) per peeled region.
const MAX_RING_SEARCHES: usize = 64;

/// Samples a ring search may label (the box is skipped beyond: 16 MiB of labels).
const MAX_RING_BOX: usize = 1 << 22;

/// Tells whether flipping a sample cuts a ring of its side that the loop goes round:
///
/// ```text
///        side (e.g. the void of a tunnel)          q has two pieces A, B of its side beside
///      +-------------------------------+           it; a path A ~> B of the side avoiding q,
///      |   A  q  B     loop a round q  |           closed through q, is a ring. If it links
///      |   ^      |    (its fan)       |           the loop, flipping q cuts the ring the
///      |   +------+  path round        |           loop goes round, and since A and B stay
///      +-------------------------------+           joined the side does not fall apart.
/// ```
///
/// Flipping such a q (in a region thinned by simple samples) removes exactly one handle and
/// changes no component or cavity; the path is searched within the target's box only.
struct Ring<'a> {
    target: &'a PeelTarget<'a>,
    side: bool,
    six: bool,
    cells: BoxCells,
    /// Per box cell: generation it was reached in, and the cell it was reached from.
    stamp: Vec<u32>,
    from: Vec<u32>,
    generation: u32,
}

impl<'a> Ring<'a> {
    fn new(target: &'a PeelTarget<'a>, side: bool, conn: Connectivity) -> Ring<'a> {
        Ring {
            target,
            side,
            // Inside samples are 6-adjacent with connectivity 6, outside ones with 26.
            six: side == (conn == Connectivity::Six),
            cells: BoxCells::new(target.lo, target.hi),
            stamp: Vec::new(),
            from: Vec::new(),
            generation: 0,
        }
    }

    fn cell(&self, q: [i64; 3]) -> Option<usize> {
        self.cells.index(q)
    }

    fn sample(&self, c: usize) -> [i64; 3] {
        self.cells.sample(c)
    }

    /// Does flipping `q` cut a ring of the side that the loop goes round (see the type)?
    /// Searched from both pieces at once, the smaller front first: a piece closed off within
    /// the box (the flip would split the side) is done with at the cost of that piece.
    fn cuts(&mut self, vol: &MaskVolume, q: [i64; 3]) -> bool {
        let cells = self.cells.len();
        let Some(qc) = self.cell(q) else {
            return false;
        };
        if cells > MAX_RING_BOX {
            return false;
        }
        if self.stamp.len() < cells {
            self.stamp = vec![0; cells];
            self.from = vec![0; cells];
        }
        // Two stamps per search: reached from piece 0, from piece 1.
        self.generation += 2;
        let stamps = [self.generation, self.generation + 1];
        let nb = neighbourhood();
        let member: [bool; 26] = std::array::from_fn(|k| {
            let r = shift(q, nb.offsets[k]);
            vol.get(r[0], r[1], r[2]) == self.side
        });
        let mut piece = [usize::MAX; 26];
        if label_pieces(&member, self.six, |p, k| piece[k] = p) != 2 {
            return false;
        }
        let mut fronts = [
            std::collections::VecDeque::new(),
            std::collections::VecDeque::new(),
        ];
        for k in 0..26 {
            if let (p @ (0 | 1), Some(c)) = (piece[k], self.cell(shift(q, nb.offsets[k]))) {
                self.stamp[c] = stamps[p];
                self.from[c] = qc as u32;
                fronts[p].push_back(c);
            }
        }
        let steps: &[[i64; 3]] = if self.six { &FACES } else { &nb.offsets };
        loop {
            let i = usize::from(fronts[1].len() < fronts[0].len());
            let Some(c) = fronts[i].pop_front() else {
                return false;
            };
            let p = self.sample(c);
            for d in steps {
                let r = shift(p, *d);
                let Some(rc) = self.cell(r).filter(|&rc| rc != qc) else {
                    continue;
                };
                if self.stamp[rc] == stamps[1 - i] {
                    return self.links(qc, c, rc);
                }
                if self.stamp[rc] != stamps[i] && vol.get(r[0], r[1], r[2]) == self.side {
                    self.stamp[rc] = stamps[i];
                    self.from[rc] = c as u32;
                    fronts[i].push_back(rc);
                }
            }
        }
    }

    /// The samples from `c` back to q (excluded) along the search's steps.
    fn trace(&self, qc: usize, mut c: usize) -> Vec<[i64; 3]> {
        let mut out = Vec::new();
        while c != qc {
            out.push(self.sample(c));
            c = self.from[c] as usize;
        }
        out
    }

    /// Does the ring q ~> a, b ~> q (the two fronts met across the step a -> b) link the loop?
    fn links(&self, qc: usize, a: usize, b: usize) -> bool {
        let mut ring = self.trace(qc, a);
        ring.reverse();
        ring.extend(self.trace(qc, b));
        ring.push(self.sample(qc));
        // Off the grid a little, so that no segment of the ring meets one of the loop.
        let nudge = [1.1e-3, 2.3e-3, 3.7e-3];
        let ring: Vec<[f64; 3]> = ring
            .iter()
            .map(|p| std::array::from_fn(|k| p[k] as f64 + nudge[k]))
            .collect();
        crate::loops::linking_number(&ring, self.target.loop_points) != 0
    }
}

/// Flips the samples of `cand` (all of state `side`) that are simple, in their order, until none
/// is left; returns those flipped.
fn thin(vol: &mut MaskVolume, conn: Connectivity, cand: &[[i64; 3]], side: bool) -> Vec<[i64; 3]> {
    flip_simple(vol, conn, cand, !side)
}

/// With the cut made: flips back, in turn, every thinned sample whose flip back is simple,
/// until none is; returns those flipped back (the volume keeps them flipped back).
fn put_back(
    vol: &mut MaskVolume,
    conn: Connectivity,
    thinned: &[[i64; 3]],
    side: bool,
) -> Vec<[i64; 3]> {
    flip_simple(vol, conn, thinned, side)
}

/// Sets to `to`, in their order and pass after pass, the samples of `cand` whose flip is simple
/// at the time, until none is; returns those set. A sample's simplicity changes only when a
/// neighbour flips, so after the first pass only the neighbours of flipped samples are looked
/// at again.
pub(crate) fn flip_simple(
    vol: &mut MaskVolume,
    conn: Connectivity,
    cand: &[[i64; 3]],
    to: bool,
) -> Vec<[i64; 3]> {
    let index: FastMap<[i64; 3], usize> = cand.iter().enumerate().map(|(i, &q)| (q, i)).collect();
    let mut flipped: Vec<[i64; 3]> = Vec::new();
    let mut done = vec![false; cand.len()];
    let mut dirty = vec![true; cand.len()];
    loop {
        let mut any = false;
        for (i, &q) in cand.iter().enumerate() {
            if done[i] || !dirty[i] {
                continue;
            }
            dirty[i] = false;
            if topological_numbers(vol, q, conn) == (1, 1) {
                vol.set(q[0] as usize, q[1] as usize, q[2] as usize, to);
                flipped.push(q);
                done[i] = true;
                any = true;
                mark_neighbours(&index, q, &mut dirty);
            }
        }
        if !any {
            return flipped;
        }
    }
}

/// Marks the samples of `index` next to `q` as to be looked at again.
fn mark_neighbours(index: &FastMap<[i64; 3], usize>, q: [i64; 3], dirty: &mut [bool]) {
    for d in neighbourhood().offsets {
        if let Some(&j) = index.get(&shift(q, d)) {
            dirty[j] = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Frame;

    /// Looking again only at the neighbours of flipped samples loses nothing: `flip_simple`
    /// flips the same samples in the same order as passes over every candidate until a pass
    /// flips none, and leaves no candidate whose flip is simple. Random volumes (30% to 70%
    /// inside), the candidates every sample of one side in a random box, both connectivities
    /// and both sides.
    #[test]
    fn flipping_simple_samples_looks_again_where_it_must() {
        let mut rng = crate::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let mut next = |m: u64| rng.below(m);
        let n = 10;
        let mut flipped = 0;
        for round in 0..40 {
            let dense = 30 + next(41);
            let bits: Vec<bool> = (0..n * n * n).map(|_| next(100) < dense).collect();
            let build = || {
                let mut vol = MaskVolume::new([n; 3], Frame::identity());
                for (k, &b) in bits.iter().enumerate() {
                    vol.set(k % n, (k / n) % n, k / (n * n), b);
                }
                vol
            };
            let mut vol = build();
            let conn = [Connectivity::Six, Connectivity::TwentySix][round % 2];
            let to = round % 4 < 2;
            let lo = [next(4), next(4), next(4)].map(|x| x as i64);
            let cand: Vec<[i64; 3]> = (0..6 * 6 * 6)
                .map(|k| [k % 6, (k / 6) % 6, k / 36].map(|x| x as i64))
                .map(|d| [lo[0] + d[0], lo[1] + d[1], lo[2] + d[2]])
                .filter(|q| vol.get(q[0], q[1], q[2]) != to)
                .collect();
            let mut naive_vol = build();
            let mut naive = Vec::new();
            loop {
                let before = naive.len();
                for &q in &cand {
                    if naive_vol.get(q[0], q[1], q[2]) != to
                        && topological_numbers(&naive_vol, q, conn) == (1, 1)
                    {
                        naive_vol.set(q[0] as usize, q[1] as usize, q[2] as usize, to);
                        naive.push(q);
                    }
                }
                if naive.len() == before {
                    break;
                }
            }
            let got = flip_simple(&mut vol, conn, &cand, to);
            assert_eq!(got, naive, "round {round}");
            for &q in &cand {
                let left = vol.get(q[0], q[1], q[2]) != to;
                assert!(!left || topological_numbers(&vol, q, conn) != (1, 1));
            }
            flipped += got.len();
        }
        assert!(flipped > 500, "{flipped} flipped");
    }

    #[test]
    fn simple_samples_of_a_bar() {
        let mut vol = MaskVolume::new([7, 5, 5], Frame::identity());
        for x in 0..7 {
            vol.set(x, 2, 2, true);
        }
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            // The end of the bar is simple; a sample in its middle splits it in two.
            assert_eq!(topological_numbers(&vol, [0, 2, 2], conn), (1, 1));
            assert_eq!(topological_numbers(&vol, [3, 2, 2], conn), (2, 1));
            // An outside sample beside the bar: adding it changes nothing.
            assert_eq!(topological_numbers(&vol, [3, 1, 2], conn), (1, 1));
        }
    }

    /// A square ring of 3×3 section in 14×14×7 (a solid torus), and the loop round its bar at
    /// x = 6 (edge midpoints round the section y 1..=3, z 2..=4).
    fn ring_and_loop(closed: bool) -> (MaskVolume, Vec<[f64; 3]>) {
        let mut vol = MaskVolume::new([14, 14, 7], Frame::identity());
        for x in 1..13 {
            for y in 1..13 {
                let in_hole = (4..10).contains(&x) && (4..10).contains(&y);
                // Open: the bar opposite the loop is missing, so the ring is a U.
                let opened = !closed && y >= 10 && (4..10).contains(&x);
                if !in_hole && !opened {
                    for z in 2..5 {
                        vol.set(x, y, z, true);
                    }
                }
            }
        }
        (vol, loop_round_bar(6.0))
    }

    /// The loop round a bar of section y 1..=3, z 2..=4 at `x` (edge midpoints).
    fn loop_round_bar(x: f64) -> Vec<[f64; 3]> {
        let mut pts = Vec::new();
        pts.extend((2..5).map(|z| [x, 0.5, z as f64]));
        pts.extend((1..4).map(|y| [x, y as f64, 4.5]));
        pts.extend((2..5).rev().map(|z| [x, 3.5, z as f64]));
        pts.extend((1..4).rev().map(|y| [x, y as f64, 1.5]));
        pts
    }

    /// Peels the slab x = 6 across the ring's bar towards its centre, for the loop `pts`,
    /// searching rings in the whole volume; the volume must be left as it was.
    fn peel_bar(vol: &mut MaskVolume, pts: &[[f64; 3]]) -> Vec<Vec<[i64; 3]>> {
        peel_slab(vol, pts, 6..=6)
    }

    /// [`peel_bar`] with the slab `xs` thick.
    fn peel_slab(
        vol: &mut MaskVolume,
        pts: &[[f64; 3]],
        xs: std::ops::RangeInclusive<i64>,
    ) -> Vec<Vec<[i64; 3]>> {
        let all = |vol: &MaskVolume| -> Vec<bool> {
            (0..14 * 14 * 7)
                .map(|i| vol.get(i % 14, i / 14 % 14, i / 196))
                .collect()
        };
        let before = all(vol);
        let region: Vec<[i64; 3]> = xs
            .flat_map(|x| (0..6).flat_map(move |y| (1..6).map(move |z| [x, y, z])))
            .collect();
        let target = PeelTarget {
            loop_points: pts,
            lo: [-1, -1, -1],
            hi: [14, 14, 7],
        };
        let walls = peel_walls(
            vol,
            Connectivity::Six,
            &region,
            [6.0, 2.0, 3.0],
            Operation::Pinch,
            &target,
            4,
        );
        assert_eq!(before, all(vol), "the volume is left as it was");
        walls
    }

    /// The ring's bar, peeled within the slab x = 6 down to its centre and cut there: none of
    /// the peeled samples can go back without joining the two sides again, so the wall is the
    /// whole section (a 6-connected bar is only cut by all 9). Once the ring is open (a U), the
    /// same cut would split the solid in two: no wall.
    #[test]
    fn peeling_a_thick_bar_cuts_its_ring_and_never_splits() {
        let (mut vol, pts) = ring_and_loop(true);
        let walls = peel_bar(&mut vol, &pts);
        let wall = walls.first().expect("a cut");
        assert_eq!(wall.len(), 9, "{wall:?}");
        assert!(wall.iter().all(|q| q[0] == 6), "{wall:?}");
        let (mut open, pts) = ring_and_loop(false);
        let walls = peel_bar(&mut open, &pts);
        assert!(walls.is_empty(), "{walls:?}");
    }

    /// Peeled three samples thick, the bar is thinned to a thread and cut at its centre; every
    /// peeled sample that can go back without joining the two sides goes back: the wall is
    /// one section of the bar, the middle one (9 samples, not the 27 of the slab). Each later
    /// cut of the thread starts from the thinned slab again, and its wall too is 9 samples that
    /// cut the ring and nothing else.
    #[test]
    fn a_peeled_wall_keeps_only_what_the_cut_needs() {
        let (mut vol, pts) = ring_and_loop(true);
        let walls = peel_slab(&mut vol, &pts, 5..=7);
        let wall = walls.first().expect("a cut");
        assert_eq!(wall.len(), 9, "{wall:?}");
        assert!(wall.iter().all(|q| q[0] == 6), "{wall:?}");
        assert!(walls.len() >= 2, "{walls:?}");
        for w in &walls {
            assert_eq!(w.len(), 9, "{w:?}");
            let set = |vol: &mut MaskVolume, inside: bool| {
                for q in w {
                    assert!(vol.get(q[0], q[1], q[2]) != inside, "{q:?} of {w:?}");
                    vol.set(q[0] as usize, q[1] as usize, q[2] as usize, inside);
                }
            };
            set(&mut vol, false);
            let g = vol.genus(Connectivity::Six).unwrap();
            assert_eq!((g.b0, g.b1), (1, 0), "{w:?}");
            set(&mut vol, true);
        }
    }

    /// Only samples of the thinned region that could cut a thread are searched for a ring
    /// (each search may cross the whole box, and a region has 64 of them): beside the ring's
    /// bar lies a hollow cube (a cavity's shell, 152 samples that no thinning removes and that
    /// split nothing), nearer the given centre than the bar. The bar is still cut, by a wall
    /// that removes the ring's handle and leaves the cube and its cavity.
    ///
    /// ```text
    ///   z = 3    +--------------------+
    ///            |  +--------------+  |    ring: 3 wide, z 2..=4
    ///            |  |   +------+   |  |    cube: x, y 6..=11, z 1..=6, one thick
    ///            |  |   | cav. |   |  |
    ///            |  |   +------+   |  |
    ///            |  +--------------+  |
    ///            +--------------------+
    ///               ^ bar at x 7..=9 peeled, loop round it at x = 8
    /// ```
    #[test]
    fn a_shell_beside_the_bar_does_not_use_up_the_ring_searches() {
        let mut vol = MaskVolume::new([20, 20, 9], Frame::identity());
        for (x, y, z) in (0..20 * 20 * 9).map(|k| (k % 20, (k / 20) % 20, k / 400)) {
            let within = |w: usize, lo: usize, hi: usize| (lo..=hi).contains(&w);
            let ring = within(x, 1, 18)
                && within(y, 1, 18)
                && !(within(x, 4, 15) && within(y, 4, 15))
                && within(z, 2, 4);
            let cube = within(x, 6, 11) && within(y, 6, 11) && within(z, 1, 6);
            let cavity = within(x, 7, 10) && within(y, 7, 10) && within(z, 2, 5);
            vol.set(x, y, z, ring || (cube && !cavity));
        }
        let conn = Connectivity::Six;
        let g = vol.genus(conn).unwrap();
        assert_eq!((g.b0, g.b1, g.b2), (2, 1, 1));
        let pts = loop_round_bar(8.0);
        let bar = (7..=9).flat_map(|x| (0..5).flat_map(move |y| (1..6).map(move |z| [x, y, z])));
        let around_cube =
            (5..=12).flat_map(|x| (5..=12).flat_map(move |y| (0..=7).map(move |z| [x, y, z])));
        let region: Vec<[i64; 3]> = bar.chain(around_cube).collect();
        let target = PeelTarget {
            loop_points: &pts,
            lo: [-1, -1, -1],
            hi: [20, 20, 9],
        };
        let centre = [8.5, 8.5, 3.5];
        let walls = peel_walls(
            &mut vol,
            conn,
            &region,
            centre,
            Operation::Pinch,
            &target,
            4,
        );
        assert!(!walls.is_empty(), "no wall");
        for w in &walls {
            for q in w {
                assert!(vol.get(q[0], q[1], q[2]), "{q:?} of {w:?}");
                vol.set(q[0] as usize, q[1] as usize, q[2] as usize, false);
            }
            let g = vol.genus(conn).unwrap();
            assert_eq!((g.b0, g.b1, g.b2), (2, 0, 1), "{w:?}");
            for q in w {
                vol.set(q[0] as usize, q[1] as usize, q[2] as usize, true);
            }
        }
    }

    /// A loop that does not go round the bar (beside it) links no ring: no wall.
    #[test]
    fn a_cut_must_link_the_loop() {
        let (mut vol, pts) = ring_and_loop(true);
        let away: Vec<[f64; 3]> = pts.iter().map(|p| [p[0], p[1] + 20.0, p[2]]).collect();
        let walls = peel_bar(&mut vol, &away);
        assert!(walls.is_empty(), "{walls:?}");
    }
}
