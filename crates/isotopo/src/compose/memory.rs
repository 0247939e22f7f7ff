//! What the well-composed step learnt of the cells it left, kept from one look and one step to
//! the next.
//!
//! Each kind of change reads the volume only near the cell it mends (see [`READS`]: a rewrite
//! within 6 samples, a speck's new place within 13 (a single sample's, last, 18), a swap's
//! path within 42); only an opening reads far (whether its two corners are one component).
//! So a kind that found nothing for a cell finds nothing again while no sample within its
//! reach changes, and a kind whose flips were refused (they would move a held handle) is
//! refused again. A step on a volume a pass changed in a few places, or a look after a few
//! flips, then tries again only what those changes may alter; the cells left far from them,
//! most of a noisy scan's, cost a lookup instead of thousands of rewrites each. The answers
//! are those of trying every kind again: the same flips, in the same order.
//!
//! ```text
//!   . . . . . . . . .      x: a cell left, last tried at clock 5
//!   . . . x . . . . .      o: a sample flipped at clock 9, beyond a rewrite's reach of x but
//!   . . . . . . . o .         within a swap's: x's rewrites are known to find nothing, its
//!   . . . . . . . . .         swap is looked for again
//! ```

use super::{Cell, Change};
use crate::surface::search::FastMap;
use crate::topology::cases::Connectivity;

/// How far from a cell's cube (in samples, along any axis) trying a kind of change reads the
/// volume, a sample more than counted for safety: the cell's corners and their neighbours for
/// one flip (1), two or three within one sample of the cube (2), a dent of up to 8 samples (8),
/// a rewrite's box round the samples within two of the cube (5), a speck put down up to
/// `TELEPORT_REACH` (7) from its corner with the box its region search spans round the place
/// (5 more: 12), or up to `FAR_TELEPORT_REACH` (12, so 17); a swap's path within
/// `FAR_SWAP_REACH` (40) and a cut sample's neighbours (41).
pub(super) const READS: [(Change, i64); 8] = [
    (Change::Single, 2),
    (Change::Pair, 3),
    (Change::Move, 13),
    (Change::FarMove, super::FAR_TELEPORT_REACH + 6),
    (Change::Triple, 3),
    (Change::Dent, 9),
    (Change::Swap, super::FAR_SWAP_REACH + 2),
    (Change::Rewrite, 6),
];

/// The farthest of [`READS`]: changes beyond it are not looked at.
const FARTHEST_READ: i64 = super::FAR_SWAP_REACH + 2;

/// Side of the cubes of samples changes are kept by.
const BUCKET: i64 = 16;

/// The changes in one cube of [`BUCKET`] samples: the latest one's clock, and each sample's
/// latest.
type Changes = (u64, Vec<([i64; 3], u64)>);

/// What trying `cell` found, and when.
#[derive(Clone, Copy, Debug)]
struct Tried {
    /// The clock when it was tried.
    at: u64,
    /// The kinds (bits by their place in [`Change::ALL`]) that found nothing.
    none: u16,
    /// The kind whose flips were refused, if one was (the kinds after it were not tried).
    refused: Option<Change>,
}

/// See the module notes. `simplify` keeps one for its run; [`super::compose`] starts afresh.
#[derive(Debug, Default)]
pub struct Memory {
    /// Counts the changes: each flip a step makes, each sample changed between steps.
    clock: u64,
    /// The samples changed, by cube of [`BUCKET`] samples: the latest change's clock in the
    /// cube, and each sample's.
    changes: FastMap<[i64; 3], Changes>,
    /// Where each sample changed is in its cube's list.
    place: FastMap<[i64; 3], usize>,
    /// The cells tried and left.
    left: FastMap<Cell, Tried>,
    /// The connectivity and the side flips were restricted to, when the cells were tried.
    rules: Option<(Connectivity, Option<bool>)>,
    /// The samples held (see [`super::compose_holding`]) when the last step ended, sorted.
    held: Vec<[i64; 3]>,
    /// How many tries of a kind of change were answered from memory.
    pub(super) recalled: u64,
    /// Never answers (tests compare steps with and without memory).
    #[cfg(test)]
    pub(super) forget: bool,
}

impl Memory {
    /// Notes that sample `p` changed (its side, or whether it is held).
    pub fn changed(&mut self, p: [i64; 3]) {
        self.clock += 1;
        let (latest, list) = self
            .changes
            .entry(p.map(|c| c.div_euclid(BUCKET)))
            .or_default();
        *latest = self.clock;
        match self.place.get(&p) {
            Some(&i) => list[i].1 = self.clock,
            None => {
                self.place.insert(p, list.len());
                list.push((p, self.clock));
            }
        }
    }

    /// Notes the samples on another side in `now` than in `before`: two lists of the samples
    /// that differ from a volume's original, with their sides (a sample in one list only
    /// changed; in both, it is on the same side, not its original).
    pub fn changed_between(&mut self, before: &[([i64; 3], bool)], now: &[([i64; 3], bool)]) {
        let sorted = |list: &[([i64; 3], bool)]| {
            let mut keys: Vec<[i64; 3]> = list.iter().map(|&(q, _)| q).collect();
            keys.sort_unstable();
            keys
        };
        for p in symmetric_difference(&sorted(before), &sorted(now)) {
            self.changed(p);
        }
    }

    /// Starts a step with these rules and held samples: forgets everything if the rules
    /// changed, else notes the samples held then or now but not both as changed.
    pub(super) fn begin(&mut self, conn: Connectivity, only: Option<bool>, held: &[[i64; 3]]) {
        if self.rules != Some((conn, only)) {
            *self = Memory {
                rules: Some((conn, only)),
                #[cfg(test)]
                forget: self.forget,
                ..Memory::default()
            };
        }
        let mut now = held.to_vec();
        now.sort_unstable();
        let before = std::mem::take(&mut self.held);
        for p in symmetric_difference(&before, &now) {
            self.changed(p);
        }
        self.held = now;
    }

    /// Ends a step: keeps the held samples, and only the cells still `critical`.
    pub(super) fn end(&mut self, held: &[[i64; 3]], critical: impl Fn(Cell) -> bool) {
        let mut now = held.to_vec();
        now.sort_unstable();
        self.held = now;
        self.left.retain(|&cell, _| critical(cell));
    }

    /// What was found when `cell` was last tried and still holds now, if it was tried.
    pub(super) fn recall(&self, cell: Cell) -> Option<Recall> {
        #[cfg(test)]
        if self.forget {
            return None;
        }
        let t = self.left.get(&cell)?;
        Some(Recall {
            tried: *t,
            clear: self.clear_since(cell, t.at),
        })
    }

    /// Notes that trying `cell` now found nothing for the kinds of `none` and, if given, flips
    /// of kind `refused` that were refused.
    pub(super) fn left(&mut self, cell: Cell, none: u16, refused: Option<Change>) {
        let tried = Tried {
            at: self.clock,
            none,
            refused,
        };
        self.left.insert(cell, tried);
    }

    /// How far from `cell`'s cube (along any axis) the nearest sample changed after clock
    /// `at` lies, up to [`FARTHEST_READ`] + 1.
    fn clear_since(&self, (_, c): Cell, at: u64) -> i64 {
        let far = FARTHEST_READ + 1;
        let lo = c.map(|x| (x - far).div_euclid(BUCKET));
        let hi = c.map(|x| (x + 1 + far).div_euclid(BUCKET));
        let mut clear = far;
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let Some((latest, list)) = self.changes.get(&[x, y, z]) else {
                        continue;
                    };
                    if *latest <= at {
                        continue;
                    }
                    for (q, t) in list {
                        if *t > at {
                            let off = |k: usize| (c[k] - q[k]).max(q[k] - c[k] - 1).max(0);
                            clear = clear.min(off(0).max(off(1)).max(off(2)));
                        }
                    }
                }
            }
        }
        clear
    }
}

/// What [`Memory::recall`] gives: the last try, and how far from the cell nothing changed since.
pub(super) struct Recall {
    tried: Tried,
    clear: i64,
}

impl Recall {
    /// What trying `change` now would find, if known: `Some(true)` nothing, `Some(false)`
    /// flips that are refused; `None` when it must be tried.
    pub(super) fn known(&self, change: Change) -> Option<bool> {
        let (_, reach) = READS.iter().find(|(c, _)| *c == change)?;
        let nothing = self.tried.none & 1 << change as u16 != 0;
        let known = nothing || self.tried.refused == Some(change);
        (known && *reach < self.clear).then_some(nothing)
    }
}

/// The samples in one of two sorted lists but not the other.
fn symmetric_difference(a: &[[i64; 3]], b: &[[i64; 3]]) -> Vec<[i64; 3]> {
    let (mut i, mut j, mut out) = (0, 0, Vec::new());
    while i < a.len() || j < b.len() {
        match (a.get(i), b.get(j)) {
            (Some(x), Some(y)) if x == y => (i, j) = (i + 1, j + 1),
            (Some(x), Some(y)) if x < y => (out.push(*x), i += 1).1,
            (Some(_), Some(y)) => (out.push(*y), j += 1).1,
            (Some(x), None) => (out.push(*x), i += 1).1,
            (None, Some(y)) => (out.push(*y), j += 1).1,
            (None, None) => break,
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::critical::CellKind;

    fn known(m: &Memory, cell: Cell, change: Change) -> Option<bool> {
        m.recall(cell)?.known(change)
    }

    fn reach(change: Change) -> i64 {
        READS.iter().find(|(c, _)| *c == change).unwrap().1
    }

    #[test]
    fn a_known_answer_lasts_until_a_change_within_its_reach() {
        let mut m = Memory::default();
        m.begin(Connectivity::Six, None, &[]);
        let cell = (CellKind::FaceZ, [20, 20, 20]);
        m.left(
            cell,
            1 << Change::Rewrite as u16 | 1 << Change::Swap as u16,
            None,
        );
        assert_eq!(known(&m, cell, Change::Rewrite), Some(true));
        assert_eq!(known(&m, cell, Change::Single), None, "never tried");
        assert_eq!(
            known(&m, cell, Change::Opening),
            None,
            "reads the whole volume"
        );
        // Just beyond a rewrite's reach of the cube [20, 21]³: rewrites still known, not swaps.
        let r = reach(Change::Rewrite);
        m.changed([21 + r + 1, 20, 20]);
        assert_eq!(known(&m, cell, Change::Rewrite), Some(true));
        assert_eq!(known(&m, cell, Change::Swap), None);
        // Within it, on either side, diagonally.
        m.left(cell, 1 << Change::Rewrite as u16, None);
        m.changed([20 - r, 21 + r, 20]);
        assert_eq!(known(&m, cell, Change::Rewrite), None);
        // A refusal is known like an answer.
        m.left(cell, 0, Some(Change::Pair));
        assert_eq!(known(&m, cell, Change::Pair), Some(false));
        // A swap reads farthest: a change just beyond it, in another cube of changes, is not
        // seen; one at its reach is.
        let s = reach(Change::Swap);
        m.left(cell, 1 << Change::Swap as u16, None);
        m.changed([20, 20 - s - 1, 21 + s + 1]);
        assert_eq!(known(&m, cell, Change::Swap), Some(true));
        m.changed([20, 21 + s, 20]);
        assert_eq!(known(&m, cell, Change::Swap), None);
    }

    #[test]
    fn held_samples_that_come_or_go_count_as_changes() {
        let mut m = Memory::default();
        m.begin(Connectivity::Six, Some(true), &[[5, 5, 5]]);
        let cell = (CellKind::Cube, [5, 5, 6]);
        m.left(cell, 1 << Change::Single as u16, None);
        m.end(&[[5, 5, 5]], |_| true);
        m.begin(Connectivity::Six, Some(true), &[[5, 5, 5]]);
        assert_eq!(known(&m, cell, Change::Single), Some(true));
        m.begin(Connectivity::Six, Some(true), &[]);
        assert_eq!(known(&m, cell, Change::Single), None);
        // Other rules: nothing is known.
        m.left(cell, 1 << Change::Single as u16, None);
        m.begin(Connectivity::TwentySix, Some(true), &[]);
        assert_eq!(known(&m, cell, Change::Single), None);
        // Cells no longer critical are let go at a step's end.
        m.left(cell, 1 << Change::Single as u16, None);
        m.end(&[], |_| false);
        assert!(m.recall(cell).is_none());
    }

    #[test]
    fn symmetric_difference_of_sorted_lists() {
        let a = [[0, 0, 0], [1, 0, 0], [3, 0, 0]];
        let b = [[1, 0, 0], [2, 0, 0]];
        assert_eq!(
            symmetric_difference(&a, &b),
            vec![[0, 0, 0], [2, 0, 0], [3, 0, 0]]
        );
        assert!(symmetric_difference(&a, &a).is_empty());
    }
}
