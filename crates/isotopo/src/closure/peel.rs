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
//! round when every such ring links the loop and no ring avoiding the sample does ([`Ring`]: a
//! search through the side that counts, step by step, how its path links the loop).
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
use crate::grid::simple::{
    is_simple, label_side_pieces, neighbourhood, topological_numbers, FACES,
};
use crate::grid::{shift, BoxCells, MaskVolume};
use crate::loops::{Overpass, SegmentsFrom};
use crate::surface::search::FastMap;
use crate::topology::cases::Connectivity;
use crate::volume::BBox;

/// The loop a peeled wall closes, and the box within which the ring it goes round is looked
/// for.
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

/// Tells whether flipping a sample cuts the rings of its side that the loop goes round, and
/// only those:
///
/// ```text
///        side (e.g. the void of a tunnel)          q has two pieces A, B of its side beside
///      +-------------------------------+           it; a path A ~> B of the side avoiding q,
///      |   A  q  B     loop a round q  |           closed through q, is a ring. If every
///      |   ^      |    (its fan)       |           such ring links the loop, and no ring of
///      |   +------+  path round        |           the side avoiding q does, flipping q cuts
///      +-------------------------------+           what the loop goes round, and since A and
///                                                  B stay joined the side does not fall apart.
/// ```
///
/// Linking is counted mod 2, step by step: a path's parity is how many times it passes through
/// the curtain hanging from the loop ([`Overpass`]), and the search runs through pairs (sample,
/// parity), the side taken twice. The rings through q are then all odd exactly when the pairs
/// reached from A never meet those reached from B, and A reaches B's samples (with the other
/// parity). So the answer is a property of the side and the loop, not of the order in which the
/// search goes: two rings through q that differ in linking the loop (round q's thread and round
/// another) mean that the cut would leave the loop going round something, and q is refused.
///
/// Flipping such a q (in a region thinned by simple samples) removes exactly one handle and
/// changes no component or cavity; the paths are searched within the target's box only.
struct Ring {
    overpass: Overpass,
    side: bool,
    six: bool,
    cells: BoxCells,
    /// Per box cell and parity (`2 * cell + parity`): the search, and the front, that reached it.
    stamp: Vec<u32>,
    generation: u32,
    /// Per box cell, the parities of the steps from it already counted (they depend on the
    /// loop only, so the searches from the region's many candidates share them): bit `k` says
    /// the step to neighbour `k` is known, bit `32 + k` that it passes through the curtain an
    /// odd number of times.
    known: Vec<u64>,
    /// The steps between samples of the side, with their neighbour numbers.
    steps: Vec<(usize, [i64; 3])>,
}

/// Moved by this off the grid (the loop, the other way), no step of a search meets the loop.
const NUDGE: [f64; 3] = [1.1e-3, 2.3e-3, 3.7e-3];

impl Ring {
    fn new(target: &PeelTarget, side: bool, conn: Connectivity) -> Ring {
        let moved: Vec<[f64; 3]> = target
            .loop_points
            .iter()
            .map(|p| std::array::from_fn(|k| p[k] - NUDGE[k]))
            .collect();
        // Inside samples are 6-adjacent with connectivity 6, outside ones with 26.
        let six = side == (conn == Connectivity::Six);
        Ring {
            overpass: Overpass::new(&moved),
            side,
            six,
            cells: BoxCells::new(target.lo, target.hi),
            stamp: Vec::new(),
            generation: 0,
            known: Vec::new(),
            steps: (0..26)
                .map(|k| (k, neighbourhood().offsets[k]))
                .filter(|(_, d)| !six || FACES.contains(d))
                .collect(),
        }
    }

    fn cell(&self, q: [i64; 3]) -> Option<usize> {
        self.cells.index(q)
    }

    /// Does the step from `p` (box cell `c`) to its neighbour `k` pass through the loop's
    /// curtain an odd number of times? (1 if so.) Counted once per step, the edges filed near
    /// `p` looked up once for all its steps (`from`).
    fn parity<'o>(
        (overpass, known): (&'o Overpass, &mut [u64]),
        from: &mut Option<SegmentsFrom<'o>>,
        (p, c): ([i64; 3], usize),
        k: usize,
    ) -> usize {
        if known[c] >> k & 1 == 0 {
            let at = |p: [i64; 3]| p.map(|x| x as f64);
            let from = from.get_or_insert_with(|| overpass.from(at(p)));
            let odd = from.to(at(shift(p, neighbourhood().offsets[k]))) & 1;
            known[c] |= 1 << k | (odd as u64) << (32 + k);
        }
        (known[c] >> (32 + k) & 1) as usize
    }

    /// Does flipping `q` cut the rings of the side that the loop goes round, and only those (see
    /// the type)? Searched from both pieces at once, the smaller front first: a piece closed off
    /// within the box (the flip would split the side), or the rings all odd, are known when one
    /// front has run out, at the cost of that front.
    fn cuts(&mut self, vol: &MaskVolume, q: [i64; 3]) -> bool {
        let cells = self.cells.len();
        let Some(qc) = self.cell(q) else {
            return false;
        };
        if cells > MAX_RING_BOX {
            return false;
        }
        if self.stamp.len() < 2 * cells {
            self.stamp = vec![0; 2 * cells];
            self.known = vec![0; cells];
        }
        // Two stamps per search: reached from piece 0, from piece 1.
        self.generation += 2;
        let stamps = [self.generation, self.generation + 1];
        let nb = neighbourhood();
        let mut piece = [usize::MAX; 26];
        if label_side_pieces(vol, q, self.side, self.six, |p, k| piece[k] = p) != 2 {
            return false;
        }
        let mut fronts = [
            std::collections::VecDeque::new(),
            std::collections::VecDeque::new(),
        ];
        let mut starts: [Vec<usize>; 2] = [Vec::new(), Vec::new()];
        let Ring {
            overpass,
            known,
            stamp,
            cells,
            steps,
            side,
            ..
        } = self;
        let mut from = None;
        for k in 0..26 {
            let r = shift(q, nb.offsets[k]);
            if let (p @ (0 | 1), Some(c)) = (piece[k], cells.index(r)) {
                let state = 2 * c + Self::parity((overpass, known), &mut from, (q, qc), k);
                stamp[state] = stamps[p];
                fronts[p].push_back(state);
                starts[p].push(c);
            }
        }
        loop {
            let i = usize::from(fronts[1].len() < fronts[0].len());
            let Some(state) = fronts[i].pop_front() else {
                // All reached from piece i: the other piece, with the other parity, or not.
                return starts[1 - i]
                    .iter()
                    .any(|&c| stamp[2 * c] == stamps[i] || stamp[2 * c + 1] == stamps[i]);
            };
            let (pc, mut from) = (state / 2, None);
            let p = cells.sample(pc);
            for &(k, d) in steps.iter() {
                let r = shift(p, d);
                let Some(rc) = cells.index(r).filter(|&rc| rc != qc) else {
                    continue;
                };
                if vol.get(r[0], r[1], r[2]) != *side {
                    continue;
                }
                let odd = Self::parity((overpass, known), &mut from, (p, pc), k);
                let next = 2 * rc + ((state & 1) ^ odd);
                if stamp[next] == stamps[1 - i] {
                    // A ring through q with as many crossings from both ends: even.
                    return false;
                }
                if stamp[next] != stamps[i] {
                    stamp[next] = stamps[i];
                    fronts[i].push_back(next);
                }
            }
        }
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
/// at again (a neighbour later in the list in the same pass, one earlier in the next). They are
/// found by the bits of a mask, 64 at a time: scanning a flag per sample, pass after pass, was
/// half of this function's time.
pub(crate) fn flip_simple(
    vol: &mut MaskVolume,
    conn: Connectivity,
    cand: &[[i64; 3]],
    to: bool,
) -> Vec<[i64; 3]> {
    let index = Places::new(cand);
    let mut flipped: Vec<[i64; 3]> = Vec::new();
    let mut done = vec![false; cand.len()];
    let mut dirty = Bits::all(cand.len());
    loop {
        let mut any = false;
        let mut next = dirty.first_from(0);
        while let Some(i) = next {
            dirty.clear(i);
            let q = cand[i];
            if is_simple(vol, q, conn) {
                vol.set(q[0] as usize, q[1] as usize, q[2] as usize, to);
                flipped.push(q);
                done[i] = true;
                any = true;
                for d in neighbourhood().offsets {
                    match index.get(shift(q, d)) {
                        Some(j) if !done[j] => dirty.set(j),
                        _ => {}
                    }
                }
            }
            next = dirty.first_from(i + 1);
        }
        if !any {
            return flipped;
        }
    }
}

/// A set of small numbers, as bits.
struct Bits(Vec<u64>);

impl Bits {
    /// `0 .. n`.
    fn all(n: usize) -> Bits {
        let mut words = vec![u64::MAX; n.div_ceil(64)];
        if !n.is_multiple_of(64) {
            words[n / 64] = (1 << (n % 64)) - 1;
        }
        Bits(words)
    }

    fn set(&mut self, i: usize) {
        self.0[i / 64] |= 1 << (i % 64);
    }

    fn clear(&mut self, i: usize) {
        self.0[i / 64] &= !(1 << (i % 64));
    }

    /// The smallest member at least `i`.
    fn first_from(&self, i: usize) -> Option<usize> {
        let w = i / 64;
        let first = self.0.get(w)? & (u64::MAX << (i % 64));
        if first != 0 {
            return Some(w * 64 + first.trailing_zeros() as usize);
        }
        let rest = self.0[w + 1..].iter().position(|&x| x != 0)?;
        let k = w + 1 + rest;
        Some(k * 64 + self.0[k].trailing_zeros() as usize)
    }
}

/// Where each sample of a list is in it: by an array over the list's box where the box is not
/// much larger than the list (a hash map, looked up 26 times a flip, cost as much as the
/// flips' tests), else by a hash map (the walls of a whole volume, trimmed at once).
enum Places {
    Array { cells: BoxCells, at: Vec<u32> },
    Map(FastMap<[i64; 3], usize>),
}

/// Box samples per listed sample (beyond a first 64 Ki) an array of places may spend.
const PLACES_PER_SAMPLE: usize = 32;

impl Places {
    fn new(list: &[[i64; 3]]) -> Places {
        if list.is_empty() {
            return Places::Map(FastMap::default());
        }
        let mut b = BBox::EMPTY;
        for &q in list {
            b.include(q);
        }
        let (lo, hi) = (b.min, b.max);
        let span: [u64; 3] = std::array::from_fn(|k| hi[k].abs_diff(lo[k]) + 1);
        let most = (PLACES_PER_SAMPLE * list.len() + (1 << 16)) as u64;
        if span[0].saturating_mul(span[1]).saturating_mul(span[2]) > most {
            return Places::Map(list.iter().enumerate().map(|(i, &q)| (q, i)).collect());
        }
        let cells = BoxCells::new(lo, hi);
        let mut at = vec![u32::MAX; cells.len()];
        for (i, &q) in list.iter().enumerate() {
            if let Some(c) = cells.index(q) {
                at[c] = i as u32;
            }
        }
        Places::Array { cells, at }
    }

    /// The place of `q` in the list (its last, if it is there more than once).
    fn get(&self, q: [i64; 3]) -> Option<usize> {
        match self {
            Places::Array { cells, at } => {
                let c = cells.index(q)?;
                (at[c] != u32::MAX).then_some(at[c] as usize)
            }
            Places::Map(map) => map.get(&q).copied(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::simple::label_pieces;
    use crate::grid::Frame;
    use crate::loops::linking_number;

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

    /// The bits hold what a list of flags holds, and the next member from any place is the
    /// next flag set (sets of every length round a word's, random sets and clears, dense and
    /// sparse).
    #[test]
    fn bits_find_the_next_member_as_flags_do() {
        let mut rng = crate::test_rng::Rng(0xa54f_f53a_5f1d_36f1);
        for n in [0, 1, 63, 64, 65, 127, 128, 129, 500, 1001] {
            let mut bits = Bits::all(n);
            let mut flags = vec![true; n];
            let sparse = n % 2 == 1;
            if sparse {
                (0..n).for_each(|i| bits.clear(i));
                flags.fill(false);
            }
            for _ in 0..4 * n + 10 {
                let next = |flags: &[bool], i: usize| (i..n).find(|&j| flags[j]);
                for i in 0..=n + 1 {
                    assert_eq!(bits.first_from(i), next(&flags, i), "n {n}, from {i}");
                }
                if n == 0 {
                    break;
                }
                // Dense or sparse (whole words empty, skipped), by the size.
                let i = rng.below(n as u64) as usize;
                match rng.below(if sparse { 200 } else { 3 }) {
                    0 => (bits.set(i), flags[i] = true),
                    _ => (bits.clear(i), flags[i] = false),
                };
            }
        }
    }

    /// A list's places, by array (a compact list) or by hash map (a list spread far), are
    /// those of the list: for every sample in and round its box, the last place it has in it,
    /// or none. Random lists with repeats.
    #[test]
    fn places_are_where_the_list_has_them() {
        let mut rng = crate::test_rng::Rng(0x3c6e_f372_fe94_f82b);
        let mut arrays = 0;
        for round in 0..60 {
            let reach = if round % 3 == 0 { 200_000 } else { 6 };
            let list: Vec<[i64; 3]> = (0..rng.below(40))
                .map(|_| [0; 3].map(|_| rng.below(2 * reach) as i64 - reach as i64))
                .collect();
            let list: Vec<[i64; 3]> = list
                .iter()
                .chain(&list[..list.len() / 4])
                .copied()
                .collect();
            let places = Places::new(&list);
            arrays += usize::from(matches!(places, Places::Array { .. }));
            let last = |q: [i64; 3]| list.iter().rposition(|&p| p == q);
            let near = list
                .iter()
                .flat_map(|&p| neighbourhood().offsets.map(|d| shift(p, d)));
            for q in list.iter().copied().chain(near) {
                assert_eq!(places.get(q), last(q), "{q:?} in {list:?}");
            }
        }
        assert!((20..60).contains(&arrays), "{arrays} by array");
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

    /// [`Ring::cuts`]'s answer, found another way: a spanning tree of the side within the box
    /// (q left out) from a sample of one of q's pieces, every cycle closed by a step off the
    /// tree, and every ring through q (out to a sample of one piece, along the tree to a sample
    /// of the other, back to q), each linked with the loop by [`linking_number`] whole (no
    /// parity carried step by step, no [`Overpass`]). [`Ring::cuts`] should be true for `Odd`
    /// only.
    fn rings_by_cycles(
        vol: &MaskVolume,
        side: bool,
        six: bool,
        q: [i64; 3],
        (lo, hi): ([i64; 3], [i64; 3]),
        loop_points: &[[f64; 3]],
    ) -> Rings {
        let nb = neighbourhood();
        let cells = BoxCells::new(lo, hi);
        let is_side =
            |r: [i64; 3]| cells.index(r).is_some() && r != q && vol.get(r[0], r[1], r[2]) == side;
        let member: [bool; 26] = std::array::from_fn(|k| {
            let r = shift(q, nb.offsets[k]);
            vol.get(r[0], r[1], r[2]) == side
        });
        let mut piece = [usize::MAX; 26];
        if label_pieces(&member, six, |p, k| piece[k] = p) != 2 {
            return Rings::Apart;
        }
        let ends: [Vec<[i64; 3]>; 2] = [0, 1].map(|p| {
            (0..26)
                .filter(|&k| piece[k] == p)
                .map(|k| shift(q, nb.offsets[k]))
                .filter(|&r| is_side(r))
                .collect()
        });
        let Some(&root) = ends[0].first() else {
            return Rings::Apart;
        };
        let steps: &[[i64; 3]] = if six { &FACES } else { &nb.offsets };
        let parent = spanning_tree(root, steps, is_side);
        if !ends[1].iter().any(|b| parent.contains_key(b)) {
            return Rings::Apart;
        }
        let tree_path = |u, v| tree_path(&parent, u, v);
        let odd = |cycle: &[[i64; 3]]| {
            let nudged: Vec<[f64; 3]> = cycle
                .iter()
                .map(|p| std::array::from_fn(|k| p[k] as f64 + NUDGE[k]))
                .collect();
            linking_number(&nudged, loop_points) % 2 != 0
        };
        for (&u, &pu) in &parent {
            for d in steps {
                let v = shift(u, *d);
                if parent
                    .get(&v)
                    .is_some_and(|&pv| u < v && pv != u && pu != v)
                    && odd(&tree_path(u, v))
                {
                    return Rings::Both;
                }
            }
        }
        let rings = ends[0].iter().flat_map(|&a| {
            ends[1]
                .iter()
                .filter(|b| parent.contains_key(*b))
                .map(move |&b| (a, b))
        });
        let parities: Vec<bool> = rings
            .map(|(a, b)| {
                let mut ring = tree_path(a, b);
                ring.push(q);
                odd(&ring)
            })
            .collect();
        match (parities.contains(&false), parities.contains(&true)) {
            (true, true) => Rings::Both,
            (false, _) => Rings::Odd,
            (true, false) => Rings::Even,
        }
    }

    /// The samples `is_side` reached from `root` by `steps`, each with the one it was reached
    /// from (the root with itself).
    fn spanning_tree(
        root: [i64; 3],
        steps: &[[i64; 3]],
        is_side: impl Fn([i64; 3]) -> bool,
    ) -> FastMap<[i64; 3], [i64; 3]> {
        let mut parent: FastMap<[i64; 3], [i64; 3]> = FastMap::default();
        parent.insert(root, root);
        let mut queue = std::collections::VecDeque::from([root]);
        while let Some(u) = queue.pop_front() {
            for d in steps {
                let v = shift(u, *d);
                if is_side(v) && !parent.contains_key(&v) {
                    parent.insert(v, u);
                    queue.push_back(v);
                }
            }
        }
        parent
    }

    /// The tree path from u to v: up from u to where the two paths up to the root meet, then
    /// down to v.
    fn tree_path(parent: &FastMap<[i64; 3], [i64; 3]>, u: [i64; 3], v: [i64; 3]) -> Vec<[i64; 3]> {
        let up = |mut u: [i64; 3]| {
            let mut path = vec![u];
            while parent[&u] != u {
                u = parent[&u];
                path.push(u);
            }
            path
        };
        let (mut pu, mut pv) = (up(u), up(v));
        while pu.len() > 1 && pv.len() > 1 && pu[pu.len() - 2] == pv[pv.len() - 2] {
            pu.pop();
            pv.pop();
        }
        pv.pop();
        pu.extend(pv.into_iter().rev());
        pu
    }

    /// How the rings through a sample link a loop: the pieces beside it are apart (no ring), or
    /// the rings all link it evenly, all oddly, or both kinds are there.
    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Rings {
        Apart,
        Even,
        Odd,
        Both,
    }

    /// A rectangle in a plane between samples across `axis` (between samples `at` and
    /// `at + 1`), its sides between samples too (round samples `u0 + 1 ..= u1` and
    /// `v0 + 1 ..= v1` of the other two axes), a vertex every half sample.
    struct Rectangle {
        axis: usize,
        at: i64,
        u: (i64, i64),
        v: (i64, i64),
    }

    impl Rectangle {
        fn random(rng: &mut crate::test_rng::Rng, n: u64) -> Rectangle {
            let mut span = || {
                let a = rng.below(n - 2) as i64;
                (a, a + 1 + rng.below(n - 1 - a as u64) as i64)
            };
            let (u, v) = (span(), span());
            Rectangle {
                axis: rng.below(3) as usize,
                at: rng.below(n - 1) as i64,
                u,
                v,
            }
        }

        fn points(&self) -> Vec<[f64; 3]> {
            let half = |x: i64| x as f64 + 0.5;
            let ((u0, u1), (v0, v1)) = (self.u, self.v);
            let mut flat = Vec::new();
            flat.extend((0..2 * (u1 - u0)).map(|i| (half(u0) + 0.5 * i as f64, half(v0))));
            flat.extend((0..2 * (v1 - v0)).map(|i| (half(u1), half(v0) + 0.5 * i as f64)));
            flat.extend((0..2 * (u1 - u0)).map(|i| (half(u1) - 0.5 * i as f64, half(v1))));
            flat.extend((0..2 * (v1 - v0)).map(|i| (half(u0), half(v1) - 0.5 * i as f64)));
            flat.iter()
                .map(|&(a, b)| self.place(half(self.at), a, b))
                .collect()
        }

        /// The point with these coordinates across the plane, along u and along v.
        fn place<T: Copy + Default>(&self, across: T, along_u: T, along_v: T) -> [T; 3] {
            let mut p = [T::default(); 3];
            p[self.axis] = across;
            p[(self.axis + 1) % 3] = along_u;
            p[(self.axis + 2) % 3] = along_v;
            p
        }
    }

    /// Threads of the side in a cube of the other side with specks of the side: closed walks of
    /// face steps, the first out through the rectangle.
    fn threads(
        rng: &mut crate::test_rng::Rng,
        n: usize,
        side: bool,
        rect: &Rectangle,
    ) -> MaskVolume {
        let mut vol = MaskVolume::new([n; 3], Frame::identity());
        for k in 0..n * n * n {
            vol.set(k % n, k / n % n, k / (n * n), (rng.below(100) < 5) == side);
        }
        for walk in 0..1 + rng.below(3) {
            let mut start = [0; 3].map(|_| rng.below(n as u64) as i64);
            if walk == 0 {
                let inside = |(a, b): (i64, i64), rng: &mut crate::test_rng::Rng| {
                    a + 1 + rng.below((b - a) as u64) as i64
                };
                start = rect.place(rect.at, inside(rect.u, rng), inside(rect.v, rng));
            }
            let mut p = start;
            let mut put = |p: [i64; 3]| {
                let [x, y, z] = p.map(|c| c as usize);
                vol.set(x, y, z, side);
            };
            put(p);
            for step in 0..1 + rng.below(8) {
                let a = if step == 0 {
                    rect.axis
                } else {
                    rng.below(3) as usize
                };
                let to = rng.below(n as u64) as i64;
                while p[a] != to {
                    p[a] += (to - p[a]).signum();
                    put(p);
                }
            }
            for a in 0..3 {
                while p[a] != start[a] {
                    p[a] += (start[a] - p[a]).signum();
                    put(p);
                }
            }
        }
        vol
    }

    /// The ring search against [`rings_by_cycles`] on random volumes: every sample of one side
    /// of 7-sample cubes, random (30% to 70% inside) or threads of that side, the box one
    /// sample wider, with a random rectangle between the samples as the loop, both sides and
    /// both connectivities. Samples whose pieces are apart, whose rings all link the loop
    /// evenly, all oddly, and both ways (where a search that took the first ring it met would
    /// answer by its order) all come up many times.
    #[test]
    fn the_ring_search_answers_as_the_cycles_do() {
        let mut rng = crate::test_rng::Rng(0x6a09_e667_f3bc_c908);
        let n = 7usize;
        let mut seen: std::collections::BTreeMap<String, usize> = Default::default();
        for round in 0..400 {
            let side = rng.below(2) == 0;
            let conn = [Connectivity::Six, Connectivity::TwentySix][rng.below(2) as usize];
            let six = side == (conn == Connectivity::Six);
            let rect = Rectangle::random(&mut rng, n as u64);
            let loop_points = rect.points();
            let vol = if round % 2 == 0 {
                let mut vol = MaskVolume::new([n; 3], Frame::identity());
                let dense = 30 + rng.below(41);
                for k in 0..n * n * n {
                    vol.set(k % n, k / n % n, k / (n * n), rng.below(100) < dense);
                }
                vol
            } else {
                threads(&mut rng, n, side, &rect)
            };
            let target = PeelTarget {
                loop_points: &loop_points,
                lo: [-1; 3],
                hi: [n as i64; 3],
            };
            let mut ring = Ring::new(&target, side, conn);
            for k in 0..n * n * n {
                let q = [k % n, k / n % n, k / (n * n)].map(|x| x as i64);
                if vol.get(q[0], q[1], q[2]) != side {
                    continue;
                }
                let rings =
                    rings_by_cycles(&vol, side, six, q, (target.lo, target.hi), &loop_points);
                assert_eq!(
                    ring.cuts(&vol, q),
                    rings == Rings::Odd,
                    "round {round}, {q:?}: {rings:?}"
                );
                *seen.entry(format!("{rings:?}")).or_insert(0) += 1;
            }
        }
        assert!(
            ["Apart", "Even", "Odd", "Both"]
                .iter()
                .all(|k| seen.get(*k).is_some_and(|&n| n > 150)),
            "{seen:?}"
        );
    }

    /// A ring search labels at most [`MAX_RING_BOX`] samples: a thread ring, one sample thick,
    /// cut at a sample of its bar that the loop goes round, in a box of exactly that many
    /// samples, and in one a plane longer (then the sample is not searched, and not cut).
    #[test]
    fn the_ring_search_stops_at_its_box_limit() {
        let mut vol = MaskVolume::new([10, 10, 6], Frame::identity());
        for (x, y) in (1..=8).flat_map(|x| (1..=8).map(move |y| (x, y))) {
            if x == 1 || x == 8 || y == 1 || y == 8 {
                vol.set(x, y, 3, true);
            }
        }
        let pts = [
            [4.0, 0.5, 3.0],
            [4.0, 1.0, 3.5],
            [4.0, 1.5, 3.0],
            [4.0, 1.0, 2.5],
        ];
        let (lo, size) = ([-1i64; 3], [256, 128, 128]);
        assert_eq!(size.iter().product::<i64>(), MAX_RING_BOX as i64);
        for more in [0, 1] {
            let target = PeelTarget {
                loop_points: &pts,
                lo,
                hi: [
                    lo[0] + size[0] - 1 + more,
                    lo[1] + size[1] - 1,
                    lo[2] + size[2] - 1,
                ],
            };
            let mut ring = Ring::new(&target, true, Connectivity::Six);
            assert_eq!(ring.cuts(&vol, [4, 1, 3]), more == 0, "{more} plane more");
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
