//! Well-composed output: the same isosurface topology under every mesher.
//!
//! Where a unit face shows one diagonal, or a unit cube two opposite corners alone
//! ([`crate::topology::critical`]), connectivity 6 and 26, VTK and scikit-image each pass the
//! surface their own way. This step removes those patterns by flipping *simple* samples (a
//! flip that changes no component, handle or cavity of the chosen connectivity;
//! `grid::simple`) or, where none helps, small sets of flips that keep the number of each
//! together, so the topology the user chose is kept and every mesher sees it.
//!
//! ```text
//!   # .        # #        a diagonal face: flip one of its corners, the one whose flip is
//!   . #   ->   . #        simple and leaves the fewest critical cells around it
//! ```
//!
//! A critical cell is mended only by flipping one of its corners. The step takes, among the
//! corners whose flip is simple, the one that lowers the number of critical cells around it the
//! most; when none lowers it, in turn:
//!
//! - a pair of simple flips within one sample of the cell (a neighbour steps aside, then the
//!   corner goes);
//! - a *speck* at a corner (a piece of the 6-connected side of at most [`MAX_SPECK`] samples: a
//!   ball) moved up to [`MAX_STEPS`] unit steps, each step simple flips, or put down whole
//!   elsewhere within that reach ([`TELEPORT_REACH`] for a single sample) where nothing of its
//!   side touches it and the same piece of the other side surrounds it (its surface, a sphere,
//!   stays in the same region); where no such place lowers the count (a grain in a small
//!   bubble, a cloud of grains), the samples of its side that touch it diagonally let go by
//!   simple flips, round the best few places or where it is (`Mender::clear_room`);
//! - a detour of three simple flips (two beside the cell, then the corner);
//! - a *dent* of the other side at a corner of a cube, joined to the rest of its side only
//!   across the cube's diagonal, filled in by simple flips (`Mender::fill_dent`);
//! - a handle moved off a face whose two corners are joined elsewhere (see
//!   `Mender::swap_handle`): one flip adds the handle through the face, one cuts the path. The
//!   path is looked for near the face, then up to [`FAR_SWAP_REACH`] away: a thread of one
//!   sample that passes itself diagonally closes its loop far from there (the MNI map's last
//!   two critical faces);
//! - two flips within two samples of the cell or three within one, not simple one at a
//!   time but keeping the topology together, checked in a box round them (`Mender::best_rewrite`,
//!   `grid::simple::SetTest`): a crack between two sheets that crosses a face diagonally goes round it;
//! - a single-sample speck put down farther ([`FAR_TELEPORT_REACH`]): in a cloud of grains
//!   on dense noise the nearest room may lie beyond the usual reach;
//! - last, and only when asked ([`ComposeOptions::open_handles`], which `simplify` sets when it
//!   closes handles afterwards): a face whose two corners are one component but no swap mends
//!   (joined only far away, or through material no single sample cuts) gets the handle the
//!   other connectivity sees through it (`Mender::open_handle`), followed, where that alone
//!   makes another cell critical, by one simple flip beside it. Simplify's next pass closes
//!   that handle elsewhere, with the sample kept ([`Composition::opened`]). Until then no
//!   change may move the handle off that sample (mending the faces round it could: see
//!   `compose_holding`), so that one no pass closes is taken back by flipping the sample back.
//!
//! Every other change keeps the components, handles and cavities of the chosen connectivity (a
//! swap or a rewrite may move a handle, never add or remove one); every change lowers the number
//! of critical cells of the volume, so the step ends; cells no such change mends are left and
//! counted: specks packed among other pieces with nowhere to go, threads tangled with
//! themselves. The step looks over the volume plane by plane, then again near what it flipped
//! until a look flips nothing (a cell left may become mendable once its neighbours change), so
//! run again on its own output it flips nothing. What each kind of change found for a cell left
//! is remembered ([`Memory`]): it is not looked for again while nothing within that kind's
//! reach changes, in later looks and, in `simplify`, in later steps (the same flips come out). (A checkerboard of single samples has more separate pieces than a
//! well-composed set of its size can hold: no step can mend all of it.)

use crate::error::Result;
use crate::grid::simple::{is_simple, same_piece, topological_numbers, SetTest};
use crate::grid::{shift, BoxCells, MaskVolume};
use crate::progress::Progress;
use crate::surface::search::FastMap;
use crate::topology::cases::Connectivity;
use crate::topology::critical::{
    count_critical, critical, cube_bits, each_critical, CellKind, CriticalCounts,
};

mod memory;
pub use memory::Memory;

/// A unit face or cube, by its kind and lowest corner (volume-local, -1 ..= n - 1).
type Cell = (CellKind, [i64; 3]);

/// What [`compose`] did.
#[derive(Clone, Debug, Default)]
pub struct Composition {
    /// Critical faces and cubes before.
    pub before: CriticalCounts,
    /// Critical faces and cubes left (none: the result is well-composed).
    pub left: CriticalCounts,
    /// The samples flipped, in volume-local coordinates, with the side each ends on (a sample
    /// flipped and flipped back is not listed).
    pub flips: Vec<([i64; 3], bool)>,
    /// Changes that took two or three simple flips (a sample stepping aside first, or a detour).
    pub pairs: u64,
    /// Specks moved aside whole (see [`MAX_SPECK`]) or cleared round, dents filled.
    pub moves: u64,
    /// Handles moved off a critical face (see `Mender::swap_handle`).
    pub swaps: u64,
    /// Sets of two or three flips, not simple one at a time, that keep the topology together
    /// (see `Mender::best_rewrite`).
    pub rewrites: u64,
    /// Samples flipped to the 6-connected side that each added one handle (see
    /// [`ComposeOptions::open_handles`]); a wall that closes such a handle must keep them.
    /// Volume-local coordinates from [`compose`]; `simplify`'s outcome gives them in the
    /// volume's own, like `flips`, and only those whose handle a pass closed.
    pub opened: Vec<[i64; 3]>,
}

/// What [`compose`] may do beyond flips that keep the topology.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ComposeOptions {
    /// The only side samples may be flipped to, if any (inside: material is only added).
    /// Default: either.
    pub only: Option<bool>,
    /// Where nothing that keeps the topology mends a critical face whose two corners of the
    /// 6-connected side are one component, flip one of its other corners to that side: one
    /// handle more, the one the other connectivity already sees through the face. For callers
    /// that close handles afterwards (simplify with `tau > 0`). Default: off.
    pub open_handles: bool,
}

impl Composition {
    /// Whether no critical configuration is left.
    pub fn well_composed(&self) -> bool {
        self.left.total() == 0
    }
}

/// Critical faces and cubes of the whole volume (plane by plane, out of core).
pub fn count_volume(vol: &MaskVolume) -> CriticalCounts {
    let mut counts = CriticalCounts::default();
    for w in -1..vol.dims[2] as i64 {
        counts.add(count_critical(&vol.plane_once(w), &vol.plane_once(w + 1)));
    }
    counts
}

/// Makes the volume well-composed by flipping simple samples, or sets of samples that keep the
/// topology together (see the module notes), and, if `opts` allow, samples that open a handle.
pub fn compose(
    vol: &mut MaskVolume,
    conn: Connectivity,
    opts: ComposeOptions,
    progress: &dyn Progress,
) -> Result<Composition> {
    compose_holding(vol, conn, opts, &[], &mut Memory::default(), progress)
}

/// [`compose`], holding the handles opened before (`held`: samples an earlier step flipped to
/// open one, see [`Composition::opened`]) where they are, as it holds those it opens: no change
/// alters the topological numbers of such a sample, so flipping it back still removes exactly
/// its handle (`take_back`). `memory` is what earlier steps on this volume found (see
/// [`Memory`]: the caller notes the samples changed since the last step ended); the step adds
/// to it.
///
/// ```text
///   a b .        a b #        b opened a handle between a and d; filling c to mend a face
///   . d .   ->   . d .        beside it would let the handle pass round b (b simple): then
///                             taking b back would leave the handle. Such a change is refused.
/// ```
pub(crate) fn compose_holding(
    vol: &mut MaskVolume,
    conn: Connectivity,
    opts: ComposeOptions,
    held: &[[i64; 3]],
    memory: &mut Memory,
    progress: &dyn Progress,
) -> Result<Composition> {
    let before = count_volume(vol);
    memory.begin(conn, opts.only, held);
    let mut mender = Mender {
        conn,
        only: opts.only,
        open_handles: opts.open_handles,
        held: held.iter().map(|&b| (b, ())).collect(),
        original: FastMap::default(),
        pairs: 0,
        moves: 0,
        swaps: 0,
        rewrites: 0,
        opened: Vec::new(),
        touched: Vec::new(),
        memory: std::mem::take(memory),
    };
    // A cell left may become mendable once later mends change what lies round it: look again
    // near the last look's flips until a look flips nothing (each mend lowers the count, so
    // this ends). The step is then its own fixed point: run again, it flips nothing.
    let mut near: Option<Near> = None;
    for look in 1.. {
        let stage = match look {
            1 => "well-composed".to_string(),
            n => format!("well-composed, look {n}"),
        };
        mender.look(vol, progress, &stage, near.as_ref())?;
        if mender.touched.is_empty() {
            break;
        }
        near = Some(Near::of(&mender.touched));
    }
    *memory = std::mem::take(&mut mender.memory);
    let held: Vec<[i64; 3]> = mender.held.keys().copied().collect();
    memory.end(&held, |cell| is_critical(vol, cell));
    let mut flips: Vec<([i64; 3], bool)> = mender
        .original
        .into_iter()
        .filter(|&(q, was)| vol.get(q[0], q[1], q[2]) != was)
        .map(|(q, was)| (q, !was))
        .collect();
    flips.sort_unstable_by_key(|(q, _)| [q[2], q[1], q[0]]);
    Ok(Composition {
        before,
        left: count_volume(vol),
        flips,
        pairs: mender.pairs,
        moves: mender.moves,
        swaps: mender.swaps,
        rewrites: mender.rewrites,
        opened: mender.opened,
    })
}

/// Where a look after the first tries cells again: blocks of [`NEAR_BLOCK`]³ samples within
/// [`NEAR_REACH`] of a sample the last look flipped (a cell left is mended later only if
/// something a mend of it reads changed; the farthest read is a swap's path).
struct Near {
    blocks: FastMap<[i64; 3], ()>,
    planes: FastMap<i64, ()>,
}

/// Side of the blocks [`Near`] marks.
const NEAR_BLOCK: i64 = 16;
/// How far from a flip a cell it may let be mended lies: a swap's far path, and the cell's cube.
const NEAR_REACH: i64 = FAR_SWAP_REACH + 2;

impl Near {
    fn of(flips: &[[i64; 3]]) -> Near {
        let block = |p: [i64; 3]| p.map(|c| c.div_euclid(NEAR_BLOCK));
        let r = (NEAR_REACH + NEAR_BLOCK - 1) / NEAR_BLOCK;
        let mut near = Near {
            blocks: FastMap::default(),
            planes: FastMap::default(),
        };
        let centres: FastMap<[i64; 3], ()> = flips.iter().map(|&p| (block(p), ())).collect();
        for b in centres.keys() {
            for z in -r..=r {
                near.planes.insert(b[2] + z, ());
                for y in -r..=r {
                    for x in -r..=r {
                        near.blocks.insert([b[0] + x, b[1] + y, b[2] + z], ());
                    }
                }
            }
        }
        near
    }

    /// Whether plane `w` holds cells near.
    fn plane(&self, w: i64) -> bool {
        self.planes.contains_key(&w.div_euclid(NEAR_BLOCK))
    }

    /// Whether a cell whose lowest corner is `c` lies near.
    fn holds(&self, c: [i64; 3]) -> bool {
        self.blocks
            .contains_key(&c.map(|x| x.div_euclid(NEAR_BLOCK)))
    }
}

/// The kinds of change that mend a critical cell, in the order they are tried (see the module
/// notes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Change {
    /// One simple flip (`Mender::best_single`).
    Single,
    /// Two simple flips within one sample (`Mender::best_pair`).
    Pair,
    /// A speck moved or put down elsewhere (`Mender::relocate`).
    Move,
    /// A detour of three simple flips (`Mender::best_triple`).
    Triple,
    /// A dent filled (`Mender::fill_dent`).
    Dent,
    /// A handle moved off the face (`Mender::swap_handle`).
    Swap,
    /// Flips that keep the topology together (`Mender::best_rewrite`).
    Rewrite,
    /// A single-sample speck put down farther (`Mender::relocate_far`).
    FarMove,
    /// A handle opened through the face (`Mender::open_handle`).
    Opening,
}

impl Change {
    const ALL: [Change; 9] = [
        Change::Single,
        Change::Pair,
        Change::Move,
        Change::Triple,
        Change::Dent,
        Change::Swap,
        Change::Rewrite,
        Change::FarMove,
        Change::Opening,
    ];
}

struct Mender {
    conn: Connectivity,
    /// The only side samples may be flipped to, if any.
    only: Option<bool>,
    /// Whether a face may be mended by opening a handle (see [`ComposeOptions`]).
    open_handles: bool,
    /// Samples that opened a handle, before or in this step: held where they are (see
    /// [`compose_holding`]).
    held: FastMap<[i64; 3], ()>,
    /// Each flipped sample's first side.
    original: FastMap<[i64; 3], bool>,
    pairs: u64,
    moves: u64,
    swaps: u64,
    rewrites: u64,
    opened: Vec<[i64; 3]>,
    /// Samples flipped in the current look.
    touched: Vec<[i64; 3]>,
    /// What was found for the cells left (see [`Memory`]).
    memory: Memory,
}

impl Mender {
    /// One look over the volume, plane by plane, mending each critical cell met (only those
    /// `near` the last look's flips, if given).
    fn look(
        &mut self,
        vol: &mut MaskVolume,
        progress: &dyn Progress,
        stage: &str,
        near: Option<&Near>,
    ) -> Result<()> {
        self.touched.clear();
        let nw = vol.dims[2] as i64;
        progress.start(stage, nw as u64 + 1);
        for w in -1..nw {
            if near.is_some_and(|n| !n.plane(w)) {
                progress.advance(1);
                continue;
            }
            // Out of core: keep the window of planes up to a few above this slab (a speck
            // moves at most three samples); planes further below are read back when a mend
            // reaches them.
            vol.follow_sweep(w + 4)?;
            let mut cells: Vec<Cell> = Vec::new();
            each_critical(&vol.plane_once(w), &vol.plane_once(w + 1), |i, j, kind| {
                cells.push((kind, [i as i64 - 1, j as i64 - 1, w]))
            });
            for cell in cells {
                if near.is_none_or(|n| n.holds(cell.1)) {
                    self.mend(vol, cell);
                }
            }
            progress.advance(1);
            crate::progress::between_steps(progress, "well-composed step")?;
        }
        progress.finish();
        vol.follow_sweep(nw)
    }

    /// Mends `start` and every cell its changes make critical, while a change lowers the count.
    fn mend(&mut self, vol: &mut MaskVolume, start: Cell) {
        let mut todo = vec![start];
        while let Some(cell) = todo.pop() {
            if !is_critical(vol, cell) {
                continue;
            }
            let Some((change, flipped)) = self.first_change(vol, cell) else {
                continue;
            };
            match change {
                Change::Single => {}
                Change::Pair | Change::Triple => self.pairs += 1,
                Change::Move | Change::Dent | Change::FarMove => self.moves += 1,
                Change::Swap => self.swaps += 1,
                Change::Rewrite => self.rewrites += 1,
                Change::Opening => {
                    self.opened.push(flipped[0]);
                    self.held.insert(flipped[0], ());
                }
            }
            for p in flipped {
                self.flip(vol, p);
                todo.extend(cells_at(p).into_iter().filter(|&c| is_critical(vol, c)));
            }
        }
    }

    /// The first kind of change, in [`Change::ALL`]'s order, that mends `cell`, and its flips;
    /// none if that change would move an opened handle (see [`compose_holding`]). Kinds whose
    /// answer is known (nothing changed near enough since they were tried, see [`Memory`]) are
    /// not tried again.
    fn first_change(
        &mut self,
        vol: &mut MaskVolume,
        cell: Cell,
    ) -> Option<(Change, Vec<[i64; 3]>)> {
        let recall = self.memory.recall(cell);
        let mut none = 0u16;
        for change in Change::ALL {
            let known = recall.as_ref().and_then(|r| r.known(change));
            self.memory.recalled += known.is_some() as u64;
            let flips = match known {
                Some(true) => None,
                Some(false) => {
                    self.memory.left(cell, none, Some(change));
                    return None;
                }
                None => self.try_change(vol, cell, change),
            };
            let Some(flips) = flips else {
                none |= 1 << change as u16;
                continue;
            };
            // The cell is left while the handle stands (the kinds after would cost the most
            // and seldom do better).
            if self.holds_the_opened(vol, &flips) {
                return Some((change, flips));
            }
            self.memory.left(cell, none, Some(change));
            return None;
        }
        self.memory.left(cell, none, None);
        None
    }

    /// The flips of one kind of change that mend `cell`, if any.
    fn try_change(
        &mut self,
        vol: &mut MaskVolume,
        cell: Cell,
        change: Change,
    ) -> Option<Vec<[i64; 3]>> {
        match change {
            Change::Single => self.best_single(vol, cell).map(|p| vec![p]),
            Change::Pair => self.best_pair(vol, cell).map(|(p, q)| vec![p, q]),
            Change::Move => self.relocate(vol, cell),
            Change::Triple => self.best_triple(vol, cell),
            Change::Dent => self.fill_dent(vol, cell),
            Change::Swap => self.swap_handle(vol, cell),
            Change::Rewrite => self.best_rewrite(vol, cell),
            Change::FarMove => self.relocate_far(vol, cell),
            Change::Opening => self.open_handle(vol, cell),
        }
    }

    /// Whether every held sample (see [`compose_holding`]) keeps its handle's passage with
    /// `flips` made: still two pieces of the 6-connected side round it and one of the other,
    /// so that flipping it back removes exactly one handle. A held sample is never flipped.
    fn holds_the_opened(&self, vol: &mut MaskVolume, flips: &[[i64; 3]]) -> bool {
        if self.held.is_empty() {
            return true;
        }
        // (A sample that opens a handle is held once flipped.)
        if flips.iter().any(|p| self.held.contains_key(p)) {
            return false;
        }
        // A sample's numbers read its 26 neighbours: only held samples next to a flip change.
        let offsets = &crate::grid::simple::neighbourhood().offsets;
        let mut near = Vec::new();
        for p in flips {
            for d in offsets {
                let q = shift(*p, *d);
                if self.held.contains_key(&q) {
                    near.push(q);
                }
            }
        }
        if near.is_empty() {
            return true;
        }
        after(vol, flips, |vol| {
            near.iter().all(|&b| self.numbers(vol, b) == (2, 1))
        })
    }

    fn flip(&mut self, vol: &mut MaskVolume, p: [i64; 3]) {
        self.touched.push(p);
        self.memory.changed(p);
        let now = vol.get(p[0], p[1], p[2]);
        self.original.entry(p).or_insert(now);
        set(vol, p, !now);
    }

    /// Whether `p` may flip: towards the allowed side, and simple.
    fn simple(&self, vol: &MaskVolume, p: [i64; 3]) -> bool {
        self.only
            .is_none_or(|side| vol.get(p[0], p[1], p[2]) != side)
            && is_simple(vol, p, self.conn)
    }

    /// The corner of `cell` whose flip is simple and lowers the critical cells around it the
    /// most (ties: the first corner).
    fn best_single(&self, vol: &mut MaskVolume, cell: Cell) -> Option<[i64; 3]> {
        let mut best: Option<([i64; 3], i64)> = None;
        for p in corners(vol, cell) {
            if !self.simple(vol, p) {
                continue;
            }
            let d = change(vol, &[p]);
            if d < 0 && best.is_none_or(|(_, b)| d < b) {
                best = Some((p, d));
            }
        }
        best.map(|(p, _)| p)
    }

    /// Two flips, each simple in turn, one of them a corner of `cell` and the other within one
    /// sample of it, that lower the critical cells around them the most.
    fn best_pair(&self, vol: &mut MaskVolume, cell: Cell) -> Option<([i64; 3], [i64; 3])> {
        let near = near(vol, cell);
        let (mut count, flips) = LocalCount::of_near(vol, cell, &near);
        let corners = corners(vol, cell);
        let corners = corners
            .iter()
            .filter_map(|c| near.iter().position(|n| n == c));
        let orders = corners.flat_map(|c| (0..near.len()).flat_map(move |n| [(c, n), (n, c)]));
        // The count first (a table look-up); each sample's test alone once, when needed.
        let mut alone: Vec<Option<bool>> = vec![None; near.len()];
        let mut best: Option<((usize, usize), i64)> = None;
        for (i, j) in orders {
            if i == j {
                continue;
            }
            let d = count.change(&near, &flips, &[i, j]);
            if d >= 0 || best.is_some_and(|(_, b)| d >= b) {
                continue;
            }
            let (p, q) = (near[i], near[j]);
            if *alone[i].get_or_insert_with(|| self.simple(vol, p))
                && self.simple_after(vol, &[p], q)
            {
                best = Some(((i, j), d));
            }
        }
        best.map(|((i, j), _)| (near[i], near[j]))
    }
}

/// Largest piece of the 6-connected side moved aside whole: specks that touch another piece
/// only at an edge or a corner (a diagonal chain of single samples) cannot be mended by one or
/// two flips without joining or deleting them.
pub const MAX_SPECK: usize = 4;

/// Farthest a single-sample speck is put down elsewhere, along each axis (a speck in a cloud of
/// others may find room only a few samples away).
pub const TELEPORT_REACH: i64 = 7;

/// Farthest a single-sample speck is put down when no place within [`TELEPORT_REACH`] and no
/// room cleared where it is lowers the critical cells (a cloud of grains on dense noise, each
/// touching the next diagonally).
pub const FAR_TELEPORT_REACH: i64 = 12;

/// How many places a speck is tried at with a room cleared round it (the best places first).
const ROOMS_TRIED: usize = 8;

/// Farthest a speck is moved, in unit steps along the axes.
pub const MAX_STEPS: usize = 3;

/// Unit steps along the axes, in the order paths are tried (the results depend on it).
const STEPS: [[i64; 3]; 6] = [
    [1, 0, 0],
    [-1, 0, 0],
    [0, 1, 0],
    [0, -1, 0],
    [0, 0, 1],
    [0, 0, -1],
];

impl Mender {
    /// The side whose pieces are 6-connected: inside under connectivity 6, outside under 26.
    fn six_side(&self) -> bool {
        self.conn == Connectivity::Six
    }

    /// Moves a speck at a corner of `cell` (a piece of the 6-connected side of at most
    /// [`MAX_SPECK`] samples) by up to [`MAX_STEPS`] unit steps, each step a sequence of simple
    /// flips (grow one sample ahead, then let go behind), when that lowers the critical cells
    /// around it; returns the samples to flip, in order.
    fn relocate(&mut self, vol: &mut MaskVolume, cell: Cell) -> Option<Vec<[i64; 3]>> {
        if self.only.is_some() {
            return None; // a move both adds and removes
        }
        let side = self.six_side();
        for p in corners(vol, cell) {
            if vol.get(p[0], p[1], p[2]) != side {
                continue;
            }
            let Some(speck) = small_piece(vol, p, side, MAX_SPECK) else {
                continue;
            };
            for path in paths() {
                if let Some(flips) = self.try_move(vol, &speck, path, side) {
                    return Some(flips);
                }
            }
            if let Some(moved) = self.teleport(vol, &speck, side, TELEPORT_REACH) {
                return Some(moved);
            }
            if let Some(room) = self.clear_room(vol, &speck, side) {
                return Some(room);
            }
        }
        None
    }

    /// A single-sample speck at a corner of `cell` put down up to [`FAR_TELEPORT_REACH`] away
    /// (see `Mender::teleport`), when every other kind of change that keeps the topology
    /// found nothing: in a cloud of grains on dense noise the nearest room may lie farther
    /// than [`TELEPORT_REACH`].
    fn relocate_far(&self, vol: &mut MaskVolume, cell: Cell) -> Option<Vec<[i64; 3]>> {
        if self.only.is_some() {
            return None;
        }
        let side = self.six_side();
        for p in corners(vol, cell) {
            if state(vol, p) != side {
                continue;
            }
            let Some(speck) = small_piece(vol, p, side, 1) else {
                continue;
            };
            if let Some(moved) = self.teleport(vol, &speck, side, FAR_TELEPORT_REACH) {
                return Some(moved);
            }
        }
        None
    }

    /// A speck hemmed in (every step aside touches another piece): where it can be put instead,
    /// moved by up to [`MAX_STEPS`] samples along each axis (a single sample: up to `reach`; a
    /// reach beyond [`TELEPORT_REACH`] tries only the places beyond it), with no sample of its
    /// side beside the new place and the two places in one piece of the other side. A speck
    /// of at most [`MAX_SPECK`] 6-adjacent samples is a ball, so its surface is a sphere in
    /// the same region as before: nothing but its place changes. Returns the new place that
    /// lowers the critical cells around the two the most.
    fn teleport(
        &self,
        vol: &mut MaskVolume,
        speck: &[[i64; 3]],
        side: bool,
        reach: i64,
    ) -> Option<Vec<[i64; 3]>> {
        let r = if speck.len() == 1 {
            reach
        } else {
            MAX_STEPS as i64
        };
        let mut places: Vec<(i64, Vec<[i64; 3]>)> = Vec::new();
        // Farther than the usual reach, only the places beyond it are new.
        let tried_before = |d: i64| reach > TELEPORT_REACH && d.abs() <= TELEPORT_REACH;
        for dz in -r..=r {
            for dy in -r..=r {
                for dx in -r..=r {
                    if tried_before(dx) && tried_before(dy) && tried_before(dz) {
                        continue;
                    }
                    let to: Vec<[i64; 3]> = speck
                        .iter()
                        .map(|q| [q[0] + dx, q[1] + dy, q[2] + dz])
                        .collect();
                    if self.free_for(vol, speck, &to, side) {
                        let flips: Vec<[i64; 3]> = speck.iter().chain(&to).copied().collect();
                        places.push((change(vol, &flips), to));
                    }
                }
            }
        }
        // Stable: among places as good, the first met.
        places.sort_by_key(|(d, _)| *d);
        // The region search last: it is the costly test.
        let mut tried = 0;
        for (d, to) in places {
            if d >= 0 && tried == ROOMS_TRIED {
                break;
            }
            if !same_region(vol, speck, to[0], side) {
                continue;
            }
            let moved: Vec<[i64; 3]> = speck.iter().chain(&to).copied().collect();
            if d < 0 {
                return Some(moved);
            }
            // No place lowers the critical cells alone: clear a room round the best few.
            tried += 1;
            for &q in &moved {
                toggle(vol, q);
            }
            let room = self.clear_room(vol, &to, side);
            for &q in moved.iter().rev() {
                toggle(vol, q);
            }
            if let Some(room) = room {
                let all: Vec<[i64; 3]> = moved.into_iter().chain(room).collect();
                if change(vol, &all) < 0 {
                    return Some(all);
                }
            }
        }
        None
    }

    /// Whether the speck can be put at `to`: inside the volume, apart from where it is (not
    /// even beside it), of the other side now, and with no sample of `side` beside it.
    fn free_for(&self, vol: &MaskVolume, speck: &[[i64; 3]], to: &[[i64; 3]], side: bool) -> bool {
        let apart = to.iter().all(|t| {
            speck
                .iter()
                .all(|q| (0..3).map(|c| (t[c] - q[c]).abs()).sum::<i64>() > 1)
        });
        apart
            && to.iter().all(|&t| {
                vol.contains(t)
                    && vol.get(t[0], t[1], t[2]) != side
                    && STEPS.iter().all(|e| {
                        let q = [t[0] + e[0], t[1] + e[1], t[2] + e[2]];
                        to.contains(&q) || state(vol, q) != side
                    })
            })
    }

    /// A speck with nowhere to go (a grain in a small bubble): the samples of its side that
    /// touch it at an edge or a corner let go instead, each a simple flip in turn (the one
    /// that lowers the critical cells most first), until the speck is alone in the middle of
    /// its 3 × 3 × 3 neighbourhood; when that lowers the critical cells, returns the flips.
    ///
    /// ```text
    ///   # # # #      # . . #
    ///   # . # #      # . . #      (the bubble round the grain s grows by simple flips of
    ///   # s . #  ->  # s . #       its wall, until nothing of s's side touches s)
    ///   # # . #      # . . #
    /// ```
    fn clear_room(
        &self,
        vol: &mut MaskVolume,
        speck: &[[i64; 3]],
        side: bool,
    ) -> Option<Vec<[i64; 3]>> {
        let offsets = &crate::grid::simple::neighbourhood().offsets;
        let mut around: Vec<[i64; 3]> = speck
            .iter()
            .flat_map(|q| offsets.iter().map(|&d| shift(*q, d)))
            .filter(|q| !speck.contains(q))
            .collect();
        around.sort_unstable();
        around.dedup();
        self.flip_all(vol, &around, side).map(|(flips, _)| flips)
    }

    /// Flips every sample of `samples` now on `side`, each a simple flip in turn (the one that
    /// lowers the critical cells most first); the flips and the change in critical cells, when
    /// all could be made and together they lower the count (the volume is left as it was).
    fn flip_all(
        &self,
        vol: &mut MaskVolume,
        samples: &[[i64; 3]],
        side: bool,
    ) -> Option<(Vec<[i64; 3]>, i64)> {
        let mut flips: Vec<[i64; 3]> = Vec::new();
        let all = loop {
            let mut best: Option<(i64, [i64; 3])> = None;
            let mut left = false;
            for &q in samples {
                if state(vol, q) != side {
                    continue;
                }
                left = true;
                if vol.contains(q) && self.simple(vol, q) {
                    let d = (change(vol, &[q]), q);
                    best = Some(best.map_or(d, |b| b.min(d)));
                }
            }
            if !left {
                break true;
            }
            let Some((_, q)) = best else { break false };
            toggle(vol, q);
            flips.push(q);
        };
        for &q in flips.iter().rev() {
            toggle(vol, q);
        }
        if !all || flips.is_empty() {
            return None;
        }
        let d = change(vol, &flips);
        (d < 0).then_some((flips, d))
    }

    /// A cube whose only two samples of the side that is not 6-connected are opposite corners
    /// (joined by the chosen connectivity, apart under the other): a small piece of that side
    /// (6-adjacent samples, at most [`MAX_SPECK`] + 4) at one corner, a dent joined to the rest
    /// of its side only across the cube, is filled in, each flip simple in turn.
    ///
    /// ```text
    ///   # # #        # # #
    ///   # . #   ->   # # #        (the dent at the corner of the cube, joined to the rest of
    ///   # # .        # # .         its side only through the cube's diagonal, filled in)
    /// ```
    fn fill_dent(&self, vol: &mut MaskVolume, cell: Cell) -> Option<Vec<[i64; 3]>> {
        let side = !self.six_side();
        if cell.0 != CellKind::Cube {
            return None;
        }
        let mut best: Option<(Vec<[i64; 3]>, i64)> = None;
        for p in corners(vol, cell) {
            if state(vol, p) != side {
                continue;
            }
            let Some(dent) = small_piece(vol, p, side, MAX_SPECK + 4) else {
                continue;
            };
            if let Some((flips, d)) = self.flip_all(vol, &dent, side) {
                if best.as_ref().is_none_or(|(_, b)| d < *b) {
                    best = Some((flips, d));
                }
            }
        }
        best.map(|(flips, _)| flips)
    }

    /// The flips moving `speck` along `path`, if each is simple in turn and the move lowers the
    /// critical cells around them (the volume is left as it was).
    fn try_move(
        &self,
        vol: &mut MaskVolume,
        speck: &[[i64; 3]],
        path: &[[i64; 3]],
        side: bool,
    ) -> Option<Vec<[i64; 3]>> {
        let mut at: Vec<[i64; 3]> = speck.to_vec();
        let mut flips: Vec<[i64; 3]> = Vec::new();
        let mut ok = true;
        'steps: for e in path {
            let next: Vec<[i64; 3]> = at
                .iter()
                .map(|q| [q[0] + e[0], q[1] + e[1], q[2] + e[2]])
                .collect();
            let grow = next.iter().filter(|q| !at.contains(q));
            let shrink = at.iter().filter(|q| !next.contains(q));
            for &q in grow.chain(shrink) {
                let growing = !at.contains(&q);
                if !vol.contains(q)
                    || (vol.get(q[0], q[1], q[2]) == side) == growing
                    || !self.simple(vol, q)
                {
                    ok = false;
                    break 'steps;
                }
                set(vol, q, !vol.get(q[0], q[1], q[2]));
                flips.push(q);
            }
            at = next;
        }
        for &q in flips.iter().rev() {
            set(vol, q, !vol.get(q[0], q[1], q[2]));
        }
        (ok && change(vol, &flips) < 0).then_some(flips)
    }
}

/// Whether `t` and the speck (samples of `side`, to be let go) lie in one piece of the other
/// side (26-adjacent samples) within a box round them.
fn same_region(vol: &MaskVolume, speck: &[[i64; 3]], t: [i64; 3], side: bool) -> bool {
    let p = speck[0];
    let lo: [i64; 3] = std::array::from_fn(|c| p[c].min(t[c]) - MAX_SPECK as i64 - 1);
    let hi: [i64; 3] = std::array::from_fn(|c| p[c].max(t[c]) + MAX_SPECK as i64 + 1);
    let other = |q: [i64; 3]| speck.contains(&q) || state(vol, q) != side;
    // The samples reached, one flag per sample of the box (a few thousand): this test runs for
    // every place a speck might go, and a hash set of positions was most of its time.
    let cells = BoxCells::new(lo, hi);
    let mut seen = vec![false; cells.len()];
    if let Some(c) = cells.index(t) {
        seen[c] = true;
    }
    // Breadth first: when the two places are in one piece (the answer looked for), the search
    // reaches `p` within a ball round `t` instead of wandering through the box first.
    let mut queue = std::collections::VecDeque::from([t]);
    while let Some(q) = queue.pop_front() {
        if q == p {
            return true;
        }
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let n = [q[0] + dx, q[1] + dy, q[2] + dz];
                    let Some(c) = cells.index(n) else { continue };
                    if !seen[c] && other(n) {
                        seen[c] = true;
                        queue.push_back(n);
                    }
                }
            }
        }
    }
    false
}

/// The piece of `side` (6-adjacent samples) through `p`, if it has at most `max` samples and
/// stays inside the volume.
fn small_piece(vol: &MaskVolume, p: [i64; 3], side: bool, max: usize) -> Option<Vec<[i64; 3]>> {
    let mut piece = vec![p];
    let mut k = 0;
    while k < piece.len() {
        let q = piece[k];
        k += 1;
        for e in STEPS {
            let r = [q[0] + e[0], q[1] + e[1], q[2] + e[2]];
            if state(vol, r) == side && !piece.contains(&r) {
                if !vol.contains(r) || piece.len() == max {
                    return None;
                }
                piece.push(r);
            }
        }
    }
    Some(piece)
}

/// Paths of one to [`MAX_STEPS`] unit steps, shortest first, never stepping straight back.
fn paths() -> &'static [Vec<[i64; 3]>] {
    static PATHS: std::sync::OnceLock<Vec<Vec<[i64; 3]>>> = std::sync::OnceLock::new();
    PATHS.get_or_init(|| {
        let mut all: Vec<Vec<[i64; 3]>> = vec![vec![]];
        let mut out = Vec::new();
        for _ in 0..MAX_STEPS {
            let mut longer = Vec::new();
            for p in &all {
                for e in STEPS {
                    if p.last()
                        .is_some_and(|l| l.iter().zip(e).all(|(a, b)| a + b == 0))
                    {
                        continue;
                    }
                    let mut q = p.clone();
                    q.push(e);
                    longer.push(q);
                }
            }
            out.extend(longer.iter().cloned());
            all = longer;
        }
        out
    })
}

impl Mender {
    /// Three flips, each simple in turn: two samples within one sample of `cell`, the second
    /// next to the first, then a corner of `cell`; the first such that lowers the critical cells
    /// around them. A thread that steps diagonally past another part of its own piece is
    /// mended so: a detour grows beside the corner, then the corner goes.
    ///
    /// ```text
    ///   # . .      # # .      # # .
    ///   # . .  ->  # # .  ->  . # .     (the corner left of the diagonal moves aside)
    ///   . # #      . # #      . # #
    /// ```
    fn best_triple(&self, vol: &mut MaskVolume, cell: Cell) -> Option<Vec<[i64; 3]>> {
        let near = near(vol, cell);
        let (mut count, flips) = LocalCount::of_near(vol, cell, &near);
        let corners: Vec<usize> = corners(vol, cell)
            .iter()
            .filter_map(|c| near.iter().position(|n| n == c))
            .collect();
        let next_to = |a: [i64; 3], b: [i64; 3]| a != b && (0..3).all(|c| (a[c] - b[c]).abs() <= 1);
        // The first triple in order that lowers the count and whose flips are simple in turn:
        // the count first (a table look-up), each flip's test once, when a triple needs it.
        for (i, &p) in near.iter().enumerate() {
            let mut p_simple = None;
            for (j, &q) in near.iter().enumerate().filter(|&(_, &q)| next_to(p, q)) {
                let mut q_simple = None;
                for &k in corners.iter().filter(|&&k| k != i && k != j) {
                    if count.change(&near, &flips, &[i, j, k]) >= 0 {
                        continue;
                    }
                    if !*p_simple.get_or_insert_with(|| self.simple(vol, p)) {
                        break;
                    }
                    if !*q_simple.get_or_insert_with(|| self.simple_after(vol, &[p], q)) {
                        break;
                    }
                    let r = near[k];
                    if self.simple_after(vol, &[p, q], r) {
                        return Some(vec![p, q, r]);
                    }
                }
                if p_simple == Some(false) {
                    break;
                }
            }
        }
        None
    }

    /// Whether `r` may flip once `before` are flipped, in turn.
    fn simple_after(&self, vol: &mut MaskVolume, before: &[[i64; 3]], r: [i64; 3]) -> bool {
        after(vol, before, |vol| self.simple(vol, r))
    }
}

/// How far from a critical face the path joining its two corners is looked for.
const SWAP_REACH: i64 = 6;
/// How far it is looked for when it is not found near (a box of 81³ samples).
pub const FAR_SWAP_REACH: i64 = 40;

impl Mender {
    /// A face whose two corners of the 6-connected side are joined elsewhere by a path of that
    /// side (so the other connectivity sees a handle through the face that this one does not):
    /// flip one of the other two corners to that side, which makes the handle this
    /// connectivity's too, and cut the path at a sample whose flip cuts that handle and nothing
    /// else. Components, cavities and the number of handles stay; the handle now goes round
    /// the face instead of through it.
    ///
    /// ```text
    ///   a .        a b        the path a ~~ d elsewhere; b joins a and d (a handle of the
    ///   . d   ->   . d        piece), then a sample e of the path is cut: its two pieces are
    ///                         still joined, through b
    /// ```
    fn swap_handle(&self, vol: &mut MaskVolume, cell: Cell) -> Option<Vec<[i64; 3]>> {
        let side = self.six_side();
        if self.only.is_some() {
            return None;
        }
        let (joined, others) = face_corners(vol, cell, side)?;
        // Near first (most such faces are mended so, and the search is cheap), then far: a
        // thread of one sample that passes itself diagonally closes its loop far away.
        let path = [SWAP_REACH, FAR_SWAP_REACH]
            .into_iter()
            .find_map(|r| side_path(vol, joined[0], joined[1], side, cell.1, r))?;
        let mut best: Option<(Vec<[i64; 3]>, i64)> = None;
        for &b in &others {
            // b's two pieces must be a's and d's (joined elsewhere by the path): then b makes a
            // handle, and joins no two components.
            if !self.joins_the_two(vol, b, joined) {
                continue;
            }
            toggle(vol, b);
            for i in 0..path.len() {
                let e = path[i];
                // Cut only where the path's two sides at e are e's only two pieces.
                let ends = (i.checked_sub(1).map(|j| path[j]), path.get(i + 1).copied());
                let cuts = match ends {
                    (Some(p), Some(n)) => !same_piece(vol, e, side, p, n),
                    // At a or d: the other side is b.
                    (None, Some(n)) | (Some(n), None) => !same_piece(vol, e, side, b, n),
                    (None, None) => false,
                };
                if !cuts || self.numbers(vol, e) != (2, 1) {
                    continue;
                }
                toggle(vol, b);
                let d = change(vol, &[b, e]);
                toggle(vol, b);
                if d < 0 && best.as_ref().is_none_or(|(_, x)| d < *x) {
                    best = Some((vec![b, e], d));
                }
            }
            toggle(vol, b);
        }
        best.map(|(flips, _)| flips)
    }

    /// Where simplify closes handles afterwards ([`ComposeOptions::open_handles`]): a face whose
    /// two corners `a`, `d` of the 6-connected side are one component, but no swap moved the
    /// handle through it aside (the path joining them runs far away, or through material no
    /// single sample cuts): the other corner `b` whose flip to that side joins exactly `a`'s
    /// and `d`'s pieces round it, which adds one handle (the one the other connectivity sees
    /// through the face) and changes no component or cavity. Where `b` alone makes another
    /// cell critical, a simple flip next to `b` that mends it may follow (`b` kept the passage
    /// of the handle: `Mender::then_simple`); the flips are `b` first.
    ///
    /// ```text
    ///   a .        a b        a ~~~ d joined far away: one handle more, through b; simplify
    ///   . d   ->   . d        closes it elsewhere and keeps b
    /// ```
    fn open_handle(&self, vol: &mut MaskVolume, cell: Cell) -> Option<Vec<[i64; 3]>> {
        let side = self.six_side();
        if !self.open_handles || self.only.is_some_and(|s| s != side) {
            return None;
        }
        let (joined, others) = face_corners(vol, cell, side)?;
        let mut best: Option<(Vec<[i64; 3]>, i64)> = None;
        for &b in &others {
            if !self.joins_the_two(vol, b, joined) {
                continue;
            }
            let alone = change(vol, &[b]);
            let found = match alone < 0 {
                true => Some((vec![b], alone)),
                false => self.then_simple(vol, b),
            };
            if let Some((flips, d)) = found {
                if best.as_ref().is_none_or(|(_, x)| d < *x) {
                    best = Some((flips, d));
                }
            }
        }
        let (flips, _) = best?;
        // Last, as it may visit a whole component: joined elsewhere, else b would join two.
        (one_component(vol, joined[0], joined[1], side, Reach::Near) == Some(true)).then_some(flips)
    }

    /// After `b` (of the other side) opens a handle, the sample next to it whose flip is then
    /// simple, keeps `b` the handle's passage (two pieces of the 6-connected side round it and
    /// one of the other, so that taking `b` back still removes exactly that handle) and lowers
    /// the critical cells round the two flips the most, with that change, if it lowers them.
    ///
    /// ```text
    ///   z = 1    z = 2        b opened: the face (b, e) of the plane x = const shows a
    ///   a b      . e          diagonal; e (simple once b is flipped) lets go, and no face
    ///   . d      . .          round the two is critical (a thread passing itself diagonally
    ///                         at a turn of a 48^3 noise, left by every single change)
    /// ```
    fn then_simple(&self, vol: &mut MaskVolume, b: [i64; 3]) -> Option<(Vec<[i64; 3]>, i64)> {
        let offsets = &crate::grid::simple::neighbourhood().offsets;
        let mut best: Option<([i64; 3], i64)> = None;
        for &o in offsets {
            let e = shift(b, o);
            if !vol.contains(e) || self.held.contains_key(&e) {
                continue;
            }
            let d = change(vol, &[b, e]);
            if d >= 0 || best.is_some_and(|(_, x)| d >= x) || !self.simple_after(vol, &[b], e) {
                continue;
            }
            if self.numbers_after(vol, &[b, e], b) == (2, 1) {
                best = Some((e, d));
            }
        }
        best.map(|(e, d)| (vec![b, e], d))
    }

    /// The numbers of `p` once `flips` are made (the volume is left as it was).
    fn numbers_after(
        &self,
        vol: &mut MaskVolume,
        flips: &[[i64; 3]],
        p: [i64; 3],
    ) -> (usize, usize) {
        after(vol, flips, |vol| self.numbers(vol, p))
    }

    /// The topological numbers of `p` as (6-connected side, other side).
    fn numbers(&self, vol: &MaskVolume, p: [i64; 3]) -> (usize, usize) {
        side_numbers(vol, p, self.conn)
    }

    /// Whether flipping `b` (of the other side) to the 6-connected side would join exactly the
    /// two pieces of `ends` round it, and leave the other side one piece there.
    fn joins_the_two(&self, vol: &MaskVolume, b: [i64; 3], ends: [[i64; 3]; 2]) -> bool {
        self.numbers(vol, b) == (2, 1) && !same_piece(vol, b, self.six_side(), ends[0], ends[1])
    }
}

/// The topological numbers of `p` as (6-connected side, other side).
fn side_numbers(vol: &MaskVolume, p: [i64; 3], conn: Connectivity) -> (usize, usize) {
    let (inside, outside) = topological_numbers(vol, p, conn);
    if conn == Connectivity::Six {
        (inside, outside)
    } else {
        (outside, inside)
    }
}

/// A face's two corners of one side and its two of the other: its two diagonals.
type Diagonals = ([[i64; 3]; 2], [[i64; 3]; 2]);

/// A face's [`Diagonals`], those of `side` first, if it shows one diagonal; `None` for a cube.
fn face_corners(vol: &MaskVolume, cell: Cell, side: bool) -> Option<Diagonals> {
    if cell.0 == CellKind::Cube {
        return None;
    }
    let (on, off): (Vec<[i64; 3]>, Vec<[i64; 3]>) = corners(vol, cell)
        .into_iter()
        .partition(|p| vol.get(p[0], p[1], p[2]) == side);
    Some((on.try_into().ok()?, off.try_into().ok()?))
}

/// The rewrites tried, in turn (see `Mender::best_rewrite`): how many flips, and how far from
/// the cell's cube they may be. Sets hold a corner of the cell: pairs within two samples are
/// about 900 (a face) to 1,700 (a cube) to try, and reach a grain three samples from the
/// face, let go there and put down at the corner; triples within one sample are 7,400 to
/// 13,900, within two they would be about twelve times as many.
const REWRITES: [(usize, i64); 2] = [(2, 2), (3, 1)];

impl Mender {
    /// The last resort: two flips within two samples of `cell`, or three within one, one of
    /// them a corner, that need not be simple one at a time but together keep the topology
    /// ([`SetTest`]; a handle may move); the fewest flips, then the lowest count. Two sheets one sample thick
    /// that meet along an edge, with a crack of the other side between them, make faces whose
    /// every corner punches or seals a sheet; a corner let go and a sample of the crack filled
    /// beside it punch and seal at once.
    ///
    /// ```text
    ///   . . # .        . . . .      a plane of the chest CT between two sheets: the crack (.)
    ///   # . # #   ->   # # # #      crossed a face diagonally; one flip seals it there, one
    ///   # # . #        # # . #      opens it beside, and it goes round
    /// ```
    fn best_rewrite(&self, vol: &MaskVolume, cell: Cell) -> Option<Vec<[i64; 3]>> {
        let corners = corners(vol, cell);
        // Every set lies in the widest reach's box; one copy of it serves them all.
        let reach = REWRITES.iter().map(|r| r.1).max().unwrap_or(1);
        let (lo, hi) = (cell.1.map(|c| c - reach), cell.1.map(|c| c + 1 + reach));
        let (mut test, mut count) = (None, None);
        for (k, r) in REWRITES {
            let near: Vec<[i64; 3]> = around(vol, cell, r)
                .into_iter()
                .filter(|p| {
                    self.only
                        .is_none_or(|side| vol.get(p[0], p[1], p[2]) != side)
                })
                .collect();
            let is_corner: Vec<bool> = near.iter().map(|p| corners.contains(p)).collect();
            let count = count.get_or_insert_with(|| LocalCount::new(vol, lo, hi));
            let flips: Vec<Flip> = near.iter().map(|&p| count.flip(p)).collect();
            // Sets as indices into `near` (thousands are tried: no allocation for each).
            let mut lowering: Vec<(i64, [usize; 3])> = Vec::new();
            each_marked_subset(&is_corner, k, &mut |set| {
                let d = count.change(&near, &flips, set);
                if d < 0 {
                    let mut at = [0; 3];
                    at[..k].copy_from_slice(set);
                    lowering.push((d, at));
                }
            });
            if lowering.is_empty() {
                continue;
            }
            // Lowest count first, ties in the order met; the topology test is the costly part.
            lowering.sort_by_key(|(d, _)| *d);
            let flips_of = |set: &[usize; 3]| set[..k].iter().map(|&i| near[i]).collect::<Vec<_>>();
            let test = test.get_or_insert_with(|| SetTest::new(vol, lo, hi, self.conn));
            if let Some(flips) = lowering
                .iter()
                .map(|(_, set)| flips_of(set))
                .find(|flips| test.keeps(flips))
            {
                return Some(flips);
            }
        }
        None
    }
}

/// The critical cells round a region, counted on a copy of its cubes' corners: a rewrite tries
/// thousands of sets of flips, and reading each cell's corners from the volume's planes (with
/// the cells of a set sorted to count each once) was most of the step's time on noise.
struct LocalCount {
    /// The cubes that have a sample of the region as a corner, by their lowest corner.
    cubes: BoxCells,
    /// Each one's corners, as `cube_bits` orders them.
    bits: Vec<u8>,
    /// Room for the corners a set flips in each cube (all zero between sets).
    flipped: Vec<u8>,
}

impl LocalCount {
    /// For flips within `lo ..= hi`.
    fn new(vol: &MaskVolume, lo: [i64; 3], hi: [i64; 3]) -> Self {
        let cubes = BoxCells::new(lo.map(|c| c - 1), hi);
        let bits: Vec<u8> = (0..cubes.len())
            .map(|i| {
                let c = cubes.sample(i);
                (0..8).fold(0u8, |bits, k| {
                    let d = corner_offset(k);
                    let q = [c[0] + d[0], c[1] + d[1], c[2] + d[2]];
                    bits | u8::from(state(vol, q)) << k
                })
            })
            .collect();
        let flipped = vec![0; bits.len()];
        LocalCount {
            cubes,
            bits,
            flipped,
        }
    }

    /// The count round a cell for flips among `near` (its samples within one sample), and
    /// their parts.
    fn of_near(vol: &MaskVolume, (_, c): Cell, near: &[[i64; 3]]) -> (LocalCount, Vec<Flip>) {
        let count = LocalCount::new(vol, c.map(|v| v - 1), c.map(|v| v + 2));
        let flips = near.iter().map(|&p| count.flip(p)).collect();
        (count, flips)
    }

    /// Sample `p`'s part in the count (it must lie in the region the count was made for).
    fn flip(&self, p: [i64; 3]) -> Flip {
        let cubes: [u32; 8] = std::array::from_fn(|k| {
            let d = corner_offset(k as u8);
            let c = [p[0] - d[0], p[1] - d[1], p[2] - d[2]];
            let i = self.cubes.index(c);
            i.expect("flips lie in the region the count was made for") as u32
        });
        let alone = (0..8)
            .map(|k| {
                let bits = self.bits[cubes[k] as usize];
                owned_critical(bits ^ 1 << k) - owned_critical(bits)
            })
            .sum();
        Flip { cubes, alone }
    }

    /// The change in critical cells if the samples `set` (indices into `samples`, whose parts
    /// are `flips`) are flipped (see [`change`]): only the cubes with a flip as a corner, and
    /// the cells they own (the cube and its three faces at its lowest corner), can change. Flips
    /// more than a sample apart on some axis share no cube: their changes add up.
    fn change(&mut self, samples: &[[i64; 3]], flips: &[Flip], set: &[usize]) -> i64 {
        // A rewrite's three flips at most, thousands of sets a cell: no allocation.
        assert!(set.len() <= 3, "a rewrite flips at most three samples");
        let apart = |a: usize, b: usize| (0..3).any(|c| (samples[a][c] - samples[b][c]).abs() > 1);
        let all_apart = (0..set.len()).all(|i| (i + 1..set.len()).all(|j| apart(set[i], set[j])));
        if all_apart {
            return set.iter().map(|&i| flips[i].alone).sum();
        }
        // The corners flipped in each cube, gathered in `flipped` (distinct samples are
        // distinct corners of a cube they share: no bit is flipped twice).
        let (mut touched, mut n) = ([0u32; 24], 0);
        for &i in set {
            for (k, &cube) in flips[i].cubes.iter().enumerate() {
                let mask = &mut self.flipped[cube as usize];
                if *mask == 0 {
                    touched[n] = cube;
                    n += 1;
                }
                *mask |= 1 << k;
            }
        }
        touched[..n]
            .iter()
            .map(|&cube| {
                let (bits, mask) = (self.bits[cube as usize], self.flipped[cube as usize]);
                self.flipped[cube as usize] = 0;
                owned_critical(bits ^ mask) - owned_critical(bits)
            })
            .sum()
    }
}

/// A sample's part in a [`LocalCount`]: the cubes it is a corner of (corner `k` of the `k`-th,
/// as numbers in the count's box) and the change in critical cells its flip alone makes.
struct Flip {
    cubes: [u32; 8],
    alone: i64,
}

/// How many of the cells a cube owns (itself and its three faces at its lowest corner) are
/// critical, by its corners.
fn owned_critical(bits: u8) -> i64 {
    static TABLE: std::sync::OnceLock<[u8; 256]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let kinds = [
            CellKind::Cube,
            CellKind::FaceX,
            CellKind::FaceY,
            CellKind::FaceZ,
        ];
        std::array::from_fn(|b| kinds.iter().filter(|&&k| critical(k, b as u8)).count() as u8)
    });
    i64::from(table[bits as usize])
}

/// Corner `k` of a cube from its lowest corner, as `cube_bits` numbers them: bit 0 of `k` is
/// the step along x, bit 1 along y, bit 2 along z.
fn corner_offset(k: u8) -> [i64; 3] {
    [k & 1, (k >> 1) & 1, (k >> 2) & 1].map(i64::from)
}

/// Calls `f` with each `k`-element subset of `0..marked.len()` that holds a marked index, each
/// in increasing order and the subsets in lexicographic order, skipping without a look the
/// runs that cannot hold one (most: a cell has at most 8 corners among hundreds of samples).
fn each_marked_subset(marked: &[bool], k: usize, f: &mut dyn FnMut(&[usize])) {
    let n = marked.len();
    // The first marked index at or after each place (`n`: none).
    let mut next = vec![n; n + 1];
    for i in (0..n).rev() {
        next[i] = if marked[i] { i } else { next[i + 1] };
    }
    pick(&next, marked, k, 0, false, &mut Vec::with_capacity(k), f);
}

/// [`each_marked_subset`] from index `from` on, `set` chosen so far (`has`: it holds a mark).
fn pick(
    next: &[usize],
    marked: &[bool],
    k: usize,
    from: usize,
    has: bool,
    set: &mut Vec<usize>,
    f: &mut dyn FnMut(&[usize]),
) {
    if set.len() == k {
        f(set);
        return;
    }
    let n = marked.len();
    let mut i = from;
    while i + (k - set.len()) <= n {
        if !has {
            if next[i] == n {
                return;
            }
            // Without a mark so far, the last index chosen must be one.
            if set.len() + 1 == k {
                i = next[i];
            }
        }
        set.push(i);
        pick(next, marked, k, i + 1, has || marked[i], set, f);
        set.pop();
        i += 1;
    }
}

/// A shortest path of 6-adjacent samples of `side` from `a` to `d` within `reach` of `near`
/// along each axis, both ends included.
fn side_path(
    vol: &MaskVolume,
    a: [i64; 3],
    d: [i64; 3],
    side: bool,
    near: [i64; 3],
    reach: i64,
) -> Option<Vec<[i64; 3]>> {
    let cells = BoxCells::new(near.map(|c| c - reach), near.map(|c| c + reach));
    // Each sample reached, by the step it was reached from (one byte per sample of the box:
    // the far reach is a box of a few hundred thousand samples).
    let mut from = vec![u8::MAX; cells.len()];
    // Any value but MAX marks `a` reached; the walk back stops at `a` before reading it.
    from[cells.index(a)?] = 0;
    let mut queue = std::collections::VecDeque::from([a]);
    while let Some(q) = queue.pop_front() {
        if q == d {
            let mut path = vec![d];
            let mut at = d;
            while at != a {
                let e = STEPS[from[cells.index(at)?] as usize];
                at = [at[0] - e[0], at[1] - e[1], at[2] - e[2]];
                path.push(at);
            }
            path.reverse();
            return Some(path);
        }
        for (k, e) in STEPS.iter().enumerate() {
            let r = [q[0] + e[0], q[1] + e[1], q[2] + e[2]];
            let Some(c) = cells.index(r) else { continue };
            if from[c] == u8::MAX && vol.contains(r) && vol.get(r[0], r[1], r[2]) == side {
                from[c] = k as u8;
                queue.push_back(r);
            }
        }
    }
    None
}

/// Takes back a handle [`Mender::open_handle`] opened with sample `b` if it is still there:
/// flips `b` back when its two pieces of the 6-connected side round it are one component
/// without it (so the flip removes exactly one handle, and changes no component or cavity);
/// says whether it did.
pub(crate) fn take_back(vol: &mut MaskVolume, conn: Connectivity, b: [i64; 3]) -> bool {
    if !may_hold_a_handle(vol, conn, b) {
        return false;
    }
    let side = conn == Connectivity::Six;
    toggle(vol, b);
    let faces = STEPS.map(|e| [b[0] + e[0], b[1] + e[1], b[2] + e[2]]);
    let ends = faces
        .iter()
        .filter(|&&q| state(vol, q) == side)
        .find_map(|&a| {
            let d = faces
                .iter()
                .find(|&&q| state(vol, q) == side && !same_piece(vol, b, side, a, q))?;
            Some((a, *d))
        });
    let joined = ends.is_some_and(|(a, d)| joined_for_sure(vol, a, d, side));
    if !joined {
        toggle(vol, b);
    }
    joined
}

/// Whether `a` and `d` are one component of `side`: near first, then, when that does not tell
/// and the volume is in core, the whole volume (the handle's other way round may be longer
/// than a near search reaches; a handle left for that raised the genus of a chest CT).
fn joined_for_sure(vol: &MaskVolume, a: [i64; 3], d: [i64; 3], side: bool) -> bool {
    let near = one_component(vol, a, d, side, Reach::Near);
    let known = near.or_else(|| {
        (!vol.out_of_core())
            .then(|| one_component(vol, a, d, side, Reach::Whole))
            .flatten()
    });
    known == Some(true)
}

/// Whether sample `b`, flipped to open a handle, may still be its passage (to hold, see
/// [`compose_holding`]; the first test of [`take_back`]): on the 6-connected side, with two
/// pieces of that side round it and one of the other (its numbers do not read `b` itself).
/// Local, so cheap: a handle a wall closed beside `b` (joining the two pieces there) is let go;
/// one closed far away is held no matter, which only leaves a face or two round `b` unmended.
pub(crate) fn may_hold_a_handle(vol: &MaskVolume, conn: Connectivity, b: [i64; 3]) -> bool {
    let side = conn == Connectivity::Six;
    vol.contains(b) && state(vol, b) == side && side_numbers(vol, b, conn) == (2, 1)
}

/// How far [`one_component`] may search.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Reach {
    /// Within [`COMPONENT_PLANES`] planes of the first end and [`COMPONENT_BUDGET`] samples,
    /// kept in hash maps: cheap, for the many searches of the step, and may not know.
    Near,
    /// The whole volume, a bit a padded sample for each end: always knows. For the few searches
    /// that decide the topology (taking a handle back), in core only (each plane it reads
    /// stays loaded).
    Whole,
}

/// The samples one end of [`one_component`] has reached.
enum Seen {
    /// By coordinates packed into one word (21 bits each).
    Keys(FastMap<u64, ()>),
    /// A bit for each sample of the padded grid.
    Bits(Vec<u64>),
}

impl Seen {
    fn new(reach: Reach, padded: usize) -> Seen {
        match reach {
            Reach::Near => Seen::Keys(FastMap::default()),
            Reach::Whole => Seen::Bits(vec![0; padded.div_ceil(64)]),
        }
    }

    fn contains(&self, k: u64) -> bool {
        match self {
            Seen::Keys(m) => m.contains_key(&k),
            Seen::Bits(b) => b[(k / 64) as usize] >> (k % 64) & 1 == 1,
        }
    }

    fn insert(&mut self, k: u64) {
        match self {
            Seen::Keys(m) => {
                m.insert(k, ());
            }
            Seen::Bits(b) => b[(k / 64) as usize] |= 1 << (k % 64),
        }
    }
}

/// Whether `a` and `d` lie in one component of `side` (6-adjacent samples; the padding beyond
/// the volume is outside and joins everything on the border): searched from both ends, the
/// smaller side a whole level at a time, as far as `reach` lets. `None` (only within
/// [`Reach::Near`]) when the search would visit more than [`COMPONENT_BUDGET`] samples, or a
/// side ends having reached [`COMPONENT_PLANES`] planes from `a` (a component of a large scan:
/// the face is left).
fn one_component(
    vol: &MaskVolume,
    a: [i64; 3],
    d: [i64; 3],
    side: bool,
    reach: Reach,
) -> Option<bool> {
    if reach == Reach::Near && vol.dims.iter().any(|&n| n + 2 >= 1 << 21) {
        return None;
    }
    // The volume and its padding; a sample's place in it is its key for the whole volume.
    let grid = BoxCells::new([-1; 3], vol.dims.map(|n| n as i64));
    let key = |q: [i64; 3]| match reach {
        Reach::Near => q.iter().fold(0u64, |k, &c| (k << 21) | (c + 1) as u64),
        Reach::Whole => grid.index(q).map_or(u64::MAX, |c| c as u64),
    };
    let (budget, planes) = match reach {
        Reach::Near => (COMPONENT_BUDGET, COMPONENT_PLANES),
        Reach::Whole => (usize::MAX, i64::MAX),
    };
    let inside = |q: [i64; 3]| grid.index(q).is_some();
    let near = |q: [i64; 3]| (q[2] - a[2]).abs() <= planes;
    // Whether each side's search met the plane limit: then its end proves nothing.
    let mut limited = [false; 2];
    let mut seen = [Seen::new(reach, grid.len()), Seen::new(reach, grid.len())];
    let mut count = 2;
    let mut levels = [vec![a], vec![d]];
    seen[0].insert(key(a));
    seen[1].insert(key(d));
    while !levels[0].is_empty() && !levels[1].is_empty() {
        let k = usize::from(levels[1].len() < levels[0].len());
        let mut next = Vec::new();
        for q in std::mem::take(&mut levels[k]) {
            for e in STEPS {
                let r = [q[0] + e[0], q[1] + e[1], q[2] + e[2]];
                if !inside(r) || seen[k].contains(key(r)) {
                    continue;
                }
                if !near(r) {
                    limited[k] = true;
                    continue;
                }
                if state(vol, r) != side {
                    continue;
                }
                if seen[1 - k].contains(key(r)) {
                    return Some(true);
                }
                seen[k].insert(key(r));
                next.push(r);
            }
        }
        count += next.len();
        if count > budget {
            return None;
        }
        levels[k] = next;
    }
    // One side's component was searched whole without meeting the other end (unless the plane
    // limit cut it).
    let ended = if levels[0].is_empty() { 0 } else { 1 };
    (!limited[ended]).then_some(false)
}

/// Most samples [`one_component`] visits within [`Reach::Near`] (about 40 MB of maps).
const COMPONENT_BUDGET: usize = 1 << 20;

/// How far from the face, in planes, [`one_component`] searches within [`Reach::Near`].
const COMPONENT_PLANES: i64 = 64;

/// What `read` finds once the samples `flips` are flipped in turn (the volume is left as it
/// was).
fn after<T>(vol: &mut MaskVolume, flips: &[[i64; 3]], read: impl FnOnce(&MaskVolume) -> T) -> T {
    flips.iter().for_each(|&p| toggle(vol, p));
    let found = read(vol);
    flips.iter().rev().for_each(|&p| toggle(vol, p));
    found
}

fn toggle(vol: &mut MaskVolume, p: [i64; 3]) {
    set(vol, p, !vol.get(p[0], p[1], p[2]));
}

fn set(vol: &mut MaskVolume, p: [i64; 3], inside: bool) {
    vol.set(p[0] as usize, p[1] as usize, p[2] as usize, inside)
}

/// The change in critical cells if the samples `flips` are flipped in turn: among the cells
/// that have one of them as a corner, the only ones a flip can change (the volume is left as it
/// was).
fn change(vol: &mut MaskVolume, flips: &[[i64; 3]]) -> i64 {
    let mut cells: Vec<Cell> = flips.iter().flat_map(|&q| cells_at(q)).collect();
    cells.sort_unstable();
    cells.dedup();
    let count = |vol: &MaskVolume| cells.iter().filter(|&&c| is_critical(vol, c)).count() as i64;
    let before = count(vol);
    after(vol, flips, count) - before
}

fn is_critical(vol: &MaskVolume, (kind, c): Cell) -> bool {
    // Corners -1 ..= n - 1 are padded columns and rows 0 ..= n.
    let bits = cube_bits(
        vol.plane(c[2]),
        vol.plane(c[2] + 1),
        (c[0] + 1) as usize,
        (c[1] + 1) as usize,
    );
    critical(kind, bits)
}

/// Which side sample `q` is on: inside, or outside (the padding beyond the volume too).
fn state(vol: &MaskVolume, q: [i64; 3]) -> bool {
    vol.get(q[0], q[1], q[2])
}

/// The in-volume corners of a cell.
fn corners(vol: &MaskVolume, (kind, c): Cell) -> Vec<[i64; 3]> {
    let fixed = match kind {
        CellKind::FaceX => Some(0),
        CellKind::FaceY => Some(1),
        CellKind::FaceZ => Some(2),
        CellKind::Cube => None,
    };
    (0..8u8)
        .map(corner_offset)
        .filter(|d| fixed.is_none_or(|a| d[a] == 0))
        .map(|d| [c[0] + d[0], c[1] + d[1], c[2] + d[2]])
        .filter(|&p| vol.contains(p))
        .collect()
}

/// The in-volume samples within one sample of a cell's cube (4 × 4 × 4).
fn near(vol: &MaskVolume, cell: Cell) -> Vec<[i64; 3]> {
    around(vol, cell, 1)
}

/// The in-volume samples within `r` samples of a cell's cube.
fn around(vol: &MaskVolume, (_, c): Cell, r: i64) -> Vec<[i64; 3]> {
    let mut out = Vec::with_capacity((2 * r as usize + 2).pow(3));
    for z in -r..=1 + r {
        for y in -r..=1 + r {
            for x in -r..=1 + r {
                let p = [c[0] + x, c[1] + y, c[2] + z];
                if vol.contains(p) {
                    out.push(p);
                }
            }
        }
    }
    out
}

/// The twenty cells that have sample `p` as a corner: eight cubes and twelve faces.
fn cells_at(p: [i64; 3]) -> [Cell; 20] {
    let mut out = [(CellKind::Cube, p); 20];
    let mut n = 0;
    for k in 0..8u8 {
        let d = corner_offset(k);
        let c = [p[0] - d[0], p[1] - d[1], p[2] - d[2]];
        out[n] = (CellKind::Cube, c);
        n += 1;
        // A face through p normal to axis a: its corner lies in p's plane along a.
        for (a, kind) in [CellKind::FaceX, CellKind::FaceY, CellKind::FaceZ]
            .into_iter()
            .enumerate()
        {
            if d[a] == 0 {
                out[n] = (kind, c);
                n += 1;
            }
        }
    }
    debug_assert_eq!(n, 20);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Frame;

    fn mender() -> Mender {
        Mender {
            conn: Connectivity::Six,
            only: None,
            open_handles: false,
            held: FastMap::default(),
            original: FastMap::default(),
            pairs: 0,
            moves: 0,
            swaps: 0,
            rewrites: 0,
            opened: Vec::new(),
            touched: Vec::new(),
            memory: Memory::default(),
        }
    }

    /// The step at connectivity 6, either side allowed, opening handles or not.
    fn compose_six(vol: &mut MaskVolume, open_handles: bool) -> Composition {
        let opts = ComposeOptions {
            only: None,
            open_handles,
        };
        compose(vol, Connectivity::Six, opts, &crate::progress::NoProgress).unwrap()
    }

    fn betti(vol: &MaskVolume) -> (u64, u64, u64) {
        let g = vol.genus(Connectivity::Six).unwrap();
        (g.b0, g.b1, g.b2)
    }

    /// Sets the samples of the axis-aligned segments between successive points.
    fn thread(vol: &mut MaskVolume, points: &[[i64; 3]]) {
        for w in points.windows(2) {
            let (a, b) = (w[0], w[1]);
            let n = (0..3).map(|c| (b[c] - a[c]).abs()).sum::<i64>();
            for k in 0..=n {
                let p: [i64; 3] = std::array::from_fn(|c| a[c] + (b[c] - a[c]).signum() * k);
                set(vol, p, true);
            }
        }
    }

    /// Two threads from a block, each a handle with it, pass each other diagonally at a face
    /// of the plane y = 10 (A = (20, 10, 4), B = (21, 10, 5)); they are joined only through
    /// the block, 15 samples away: the far search finds the path, and the swap keeps every
    /// Betti number while the face stops being critical.
    ///
    /// ```text
    ///   plane y = 10:   z = 5   . B -- (on to x = 30, round to the block)
    ///                   z = 4   A .
    ///                   z = 3   | .  (A's thread goes on down, then along y to the block)
    ///                           x=20 21
    /// ```
    #[test]
    fn a_thread_passing_itself_far_from_where_it_joins_is_swapped() {
        let mut vol = MaskVolume::new([42, 40, 10], Frame::identity());
        for z in 1..=8 {
            for y in 1..=38 {
                for x in 1..=5 {
                    set(&mut vol, [x, y, z], true);
                }
            }
        }
        thread(
            &mut vol,
            &[
                [6, 9, 4],
                [20, 9, 4],
                [20, 10, 4],
                [20, 10, 3],
                [20, 30, 3],
                [6, 30, 3],
            ],
        );
        thread(
            &mut vol,
            &[
                [6, 35, 5],
                [30, 35, 5],
                [30, 10, 5],
                [21, 10, 5],
                [21, 25, 5],
                [6, 25, 5],
            ],
        );
        let cell = (CellKind::FaceY, [20, 10, 4]);
        assert!(is_critical(&vol, cell));
        let (a, b) = ([20, 10, 4], [21, 10, 5]);
        assert!(side_path(&vol, a, b, true, cell.1, SWAP_REACH).is_none());
        assert!(side_path(&vol, a, b, true, cell.1, FAR_SWAP_REACH).is_some());
        let (before, critical) = (betti(&vol), count_volume(&vol).total());
        let flips = mender().swap_handle(&mut vol, cell).expect("a swap");
        for p in flips {
            toggle(&mut vol, p);
        }
        assert!(!is_critical(&vol, cell));
        assert_eq!(betti(&vol), before);
        assert!(count_volume(&vol).total() < critical);
    }

    /// A rewrite's count of the critical cells round a set of flips (a copy of the cubes'
    /// corners; flips apart adding up) is the count made on the volume itself: random volumes,
    /// random sets of one to three flips, adjacent or not, in a region touching the volume's
    /// faces or not.
    #[test]
    fn a_rewrites_local_count_is_the_count_on_the_volume() {
        let mut rng = crate::test_rng::Rng(0x10ca_1c07);
        let n = 12;
        let (mut apart, mut sharing) = (0, 0);
        for round in 0..24 {
            let mut vol = crate::grid::random_mask(&mut rng, n, [30, 50, 70][round % 3]);
            let c: [i64; 3] = std::array::from_fn(|_| rng.below(n as u64 - 3) as i64);
            let (lo, hi) = (c.map(|v| v - 1), c.map(|v| v + 4));
            let mut count = LocalCount::new(&vol, lo, hi);
            let samples: Vec<[i64; 3]> = (0..40)
                .map(|_| std::array::from_fn(|k| c[k] + rng.below(4) as i64))
                .filter(|p: &[i64; 3]| p.iter().all(|&v| v < n as i64))
                .collect();
            let flips: Vec<Flip> = samples.iter().map(|&p| count.flip(p)).collect();
            for _ in 0..200 {
                let k = 1 + rng.below(3) as usize;
                let mut chosen: Vec<usize> = Vec::new();
                while chosen.len() < k {
                    let i = rng.below(samples.len() as u64) as usize;
                    if !chosen.iter().any(|&j| samples[j] == samples[i]) {
                        chosen.push(i);
                    }
                }
                let set: Vec<[i64; 3]> = chosen.iter().map(|&i| samples[i]).collect();
                let near = |a: [i64; 3], b: [i64; 3]| (0..3).all(|c| (a[c] - b[c]).abs() <= 1);
                let shares = set
                    .iter()
                    .enumerate()
                    .any(|(i, &a)| set[i + 1..].iter().any(|&b| near(a, b)));
                apart += usize::from(!shares && k > 1);
                sharing += usize::from(shares);
                assert_eq!(
                    count.change(&samples, &flips, &chosen),
                    change(&mut vol, &set),
                    "round {round}: {set:?}"
                );
            }
        }
        assert!(
            apart > 500 && sharing > 500,
            "{apart} apart, {sharing} sharing a cube"
        );
    }

    /// A look after the first tries again every cell within [`NEAR_REACH`] of a flip of the
    /// last look (on every axis), on a plane it visits, and none much farther: random flips
    /// and cells in a 300-sample cube, negative coordinates too.
    #[test]
    fn a_later_look_reaches_every_cell_a_flip_may_let_be_mended() {
        let mut rng = crate::test_rng::Rng(0x0ea5_11de);
        let mut random = |n: i64| (rng.below(n as u64 * 2) as i64) - n;
        let (mut near, mut far) = (0, 0);
        for _ in 0..200 {
            let flips: Vec<[i64; 3]> = (0..3).map(|_| [0; 3].map(|_| random(150))).collect();
            let n = Near::of(&flips);
            for _ in 0..200 {
                let c = [0; 3].map(|_| random(150));
                let apart = |f: &[i64; 3]| (0..3).map(|k| (f[k] - c[k]).abs()).max().unwrap_or(0);
                let d = flips.iter().map(apart).min().unwrap_or(i64::MAX);
                if d <= NEAR_REACH {
                    assert!(n.holds(c) && n.plane(c[2]), "{c:?}, {d} from a flip");
                    near += 1;
                } else if d > NEAR_REACH + 2 * NEAR_BLOCK {
                    assert!(!n.holds(c), "{c:?}, {d} from the flips");
                    far += 1;
                }
            }
        }
        assert!(near > 100 && far > 10_000, "{near} near, {far} far");
    }

    /// A dent of three outside samples in a block, joined to the outside only across the
    /// diagonal of the cube at the end of a channel: it is filled (from its far end, each
    /// flip simple in turn) and the cube stops being critical.
    #[test]
    fn a_dent_across_a_cube_is_filled() {
        let mut vol = MaskVolume::new([16, 16, 16], Frame::identity());
        for z in 2..13 {
            for y in 2..13 {
                for x in 2..13 {
                    let channel = x == 6 && y == 6 && z <= 6;
                    let dent = y == 7 && z == 7 && (7..10).contains(&x);
                    set(&mut vol, [x, y, z], !channel && !dent);
                }
            }
        }
        let cell = (CellKind::Cube, [6, 6, 6]);
        assert!(is_critical(&vol, cell));
        let (before, critical) = (betti(&vol), count_volume(&vol).total());
        let flips = mender().fill_dent(&mut vol, cell).expect("a fill");
        assert_eq!(flips, [[9, 7, 7], [8, 7, 7], [7, 7, 7]]);
        for p in flips {
            toggle(&mut vol, p);
        }
        assert_eq!(betti(&vol), before);
        assert_eq!(count_volume(&vol).total(), critical - 1);
    }

    /// `one_component` against labels by a plain flood fill over the padded grid, on random
    /// masks of several densities, for pairs of samples of either side (the outside joined
    /// through the padding).
    #[test]
    fn one_component_agrees_with_a_flood_fill() {
        let mut rng = crate::test_rng::Rng(0x0c0f_fee5);
        let n = [9i64, 8, 7];
        let (mut same, mut apart) = (0, 0);
        for round in 0..40 {
            let density = [0.2, 0.3, 0.5, 0.7, 0.8][round % 5];
            let mut vol = MaskVolume::new(n.map(|x| x as usize), Frame::identity());
            for z in 0..n[2] {
                for y in 0..n[1] {
                    for x in 0..n[0] {
                        set(&mut vol, [x, y, z], rng.unit() < density);
                    }
                }
            }
            for side in [true, false] {
                let label = flood_labels(&vol, n, side);
                let at = |q: [i64; 3]| ((q[2] + 1) * (n[1] + 2) + q[1] + 1) * (n[0] + 2) + q[0] + 1;
                let mut random = || [0, 1, 2].map(|k| rng.below(n[k] as u64) as i64);
                for _ in 0..300 {
                    let (a, d) = (random(), random());
                    if a == d || state(&vol, a) != side || state(&vol, d) != side {
                        continue;
                    }
                    let expected = label[at(a) as usize] == label[at(d) as usize];
                    for reach in [Reach::Near, Reach::Whole] {
                        assert_eq!(one_component(&vol, a, d, side, reach), Some(expected));
                    }
                    *if expected { &mut same } else { &mut apart } += 1;
                }
            }
        }
        assert!(same > 100 && apart > 100, "{same} joined, {apart} apart");
    }

    /// A column of inside samples 150 planes tall: its ends are one component, but beyond the
    /// planes a near search reaches from the first; near ones are found joined. The whole
    /// volume tells them all.
    #[test]
    fn one_component_near_searches_only_planes_near_the_face() {
        let near = |vol: &MaskVolume, a, d, side| one_component(vol, a, d, side, Reach::Near);
        let whole = |vol: &MaskVolume, a, d, side| one_component(vol, a, d, side, Reach::Whole);
        let mut vol = MaskVolume::new([3, 3, 150], Frame::identity());
        for z in 0..150 {
            set(&mut vol, [1, 1, z], true);
        }
        assert_eq!(near(&vol, [1, 1, 0], [1, 1, 10], true), Some(true));
        let far = COMPONENT_PLANES + 5;
        assert_eq!(near(&vol, [1, 1, 0], [1, 1, far], true), None);
        assert_eq!(whole(&vol, [1, 1, 0], [1, 1, 149], true), Some(true));
        assert!(joined_for_sure(&vol, [1, 1, 0], [1, 1, 149], true));
        // Outside, joined through the padding round the volume.
        assert_eq!(near(&vol, [0, 0, 0], [2, 2, 3], false), Some(true));
        assert_eq!(whole(&vol, [0, 0, 0], [2, 2, 149], false), Some(true));
        // Cut the column: two components, told apart where one of them is searched whole
        // within reach, not where neither is (but within the whole volume).
        set(&mut vol, [1, 1, 20], false);
        assert_eq!(near(&vol, [1, 1, 0], [1, 1, 30], true), Some(false));
        assert_eq!(near(&vol, [1, 1, 100], [1, 1, 0], true), None);
        assert_eq!(whole(&vol, [1, 1, 100], [1, 1, 0], true), Some(false));
        assert!(!joined_for_sure(&vol, [1, 1, 100], [1, 1, 0], true));
    }

    /// A slab of inside samples too wide for a near search's budget: two samples at its far
    /// corners are found joined only by the whole volume.
    #[test]
    fn one_component_near_stops_at_its_budget() {
        let n = [128, 128, 72];
        let mut vol = MaskVolume::new(n, Frame::identity());
        for z in 0..n[2] as i64 {
            for y in 0..n[1] as i64 {
                for x in 0..n[0] as i64 {
                    set(&mut vol, [x, y, z], true);
                }
            }
        }
        let (a, d) = ([0, 0, 0], [127, 127, 63]);
        assert_eq!(one_component(&vol, a, d, true, Reach::Near), None);
        assert!(joined_for_sure(&vol, a, d, true));
    }

    /// A ring 150 planes tall whose two ends meet diagonally at a face in plane 0, joined by
    /// `b`: the handle `b` opened is taken back though its other way round runs beyond a near
    /// search (lidc2 filled only at tau 3 kept one such, a route of 166 samples over 78 planes
    /// once another opening on its shorter way was taken back). With the ring cut, `b` is the
    /// only join and stays.
    ///
    /// ```text
    ///   z 149   a ====== d        plane 0:  a b      (a, d: the ring's two columns)
    ///           |        |                  . d
    ///   z 0     a -- b -- d
    /// ```
    #[test]
    fn a_handle_is_taken_back_however_far_its_other_way_runs() {
        let ring = || {
            let mut vol = MaskVolume::new([4, 4, 150], Frame::identity());
            for z in 0..150 {
                set(&mut vol, [1, 1, z], true);
                set(&mut vol, [2, 2, z], true);
            }
            set(&mut vol, [2, 1, 149], true);
            set(&mut vol, [2, 1, 0], true);
            vol
        };
        let b = [2, 1, 0];
        let mut vol = ring();
        assert!(may_hold_a_handle(&vol, Connectivity::Six, b));
        assert!(take_back(&mut vol, Connectivity::Six, b));
        assert!(!state(&vol, b));
        let mut cut = ring();
        set(&mut cut, [1, 1, 100], false);
        assert!(!take_back(&mut cut, Connectivity::Six, b));
        assert!(state(&cut, b));
    }

    /// A grain s touching four others diagonally, in the middle of a cloud of single grains two
    /// samples apart, 17 across: every place within [`TELEPORT_REACH`] lies in the cloud, where
    /// the grain would touch as many (or more) others as here, and no grain round it can let go
    /// (each is a component). Put down beyond the usual reach, clear of the cloud, it touches
    /// nothing: the four faces are mended and every component kept.
    ///
    /// ```text
    ///   # . # . # . #      plane z = c: grains at even x and y (and even z, planes
    ///   . . . . . . .      of the cloud), s at odd x, odd y: four critical faces
    ///   # . # s # . #
    ///   . . . . . . .
    ///   # . # . # . #
    /// ```
    #[test]
    fn a_grain_in_a_cloud_is_put_down_beyond_the_usual_reach() {
        let (n, mid) = (44i64, 20i64);
        let mut vol = MaskVolume::new([n as usize; 3], Frame::identity());
        for z in (mid - 8..=mid + 8).step_by(2) {
            for y in (mid - 8..=mid + 8).step_by(2) {
                for x in (mid - 8..=mid + 8).step_by(2) {
                    set(&mut vol, [x, y, z], true);
                }
            }
        }
        let grain = [mid + 1, mid + 1, mid];
        set(&mut vol, grain, true);
        assert_eq!(count_volume(&vol).total(), 4);
        let before = betti(&vol);
        let m = mender();
        assert!(m
            .teleport(&mut vol, &[grain], true, TELEPORT_REACH)
            .is_none());
        assert!(m.clear_room(&mut vol, &[grain], true).is_none());
        let c = compose_six(&mut vol, false);
        assert_eq!(c.left.total(), 0);
        assert_eq!(count_volume(&vol).total(), 0);
        assert_eq!(betti(&vol), before);
        // Grains moved, none lost or added, some put down clear of the cloud.
        let taken = c.flips.iter().filter(|(_, inside)| *inside);
        assert_eq!(2 * taken.clone().count(), c.flips.len(), "{:?}", c.flips);
        let far = |q: &[i64; 3]| q.iter().any(|&x| (x - mid).abs() > 9);
        assert!(taken.clone().any(|(q, _)| far(q)), "{:?}", c.flips);
    }

    /// Openings on random sponges, each face that shows one diagonal tried: whatever
    /// `Mender::open_handle` returns lowers the critical cells round its flips, adds exactly one
    /// handle (the oracle: the genus pass before and after), and is the best of every opening
    /// it may choose from, found here by trying them all (the filled corner alone where that
    /// lowers the count, else with each sample beside it that is simple after and keeps it the
    /// passage).
    #[test]
    fn an_opening_adds_one_handle_and_is_the_best_there_is() {
        let mut rng = crate::test_rng::Rng(0x0be2_1f11);
        let mut m = mender();
        m.open_handles = true;
        let offsets = &crate::grid::simple::neighbourhood().offsets;
        let (mut opened, mut followed) = (0, 0);
        for _ in 0..12 {
            let n = 12usize;
            let sponge = crate::test_rng::sponge(n, rng.next_u64());
            let mut vol = MaskVolume::new([n; 3], Frame::identity());
            for z in 0..n {
                for y in 0..n {
                    for x in 0..n {
                        let inside = sponge.get(x, y, z) > 0.0;
                        set(&mut vol, [x, y, z].map(|c| c as i64), inside);
                    }
                }
            }
            let (b0, b1, b2) = betti(&vol);
            let faces = (-1..n as i64).flat_map(|z| {
                (-1..n as i64).flat_map(move |y| {
                    (-1..n as i64).flat_map(move |x| {
                        [CellKind::FaceX, CellKind::FaceY, CellKind::FaceZ].map(|k| (k, [x, y, z]))
                    })
                })
            });
            for face in faces.filter(|&f| is_critical(&vol, f)).collect::<Vec<_>>() {
                let Some(flips) = m.open_handle(&mut vol, face) else {
                    continue;
                };
                let d = change(&mut vol, &flips);
                assert!(d < 0, "{face:?}: {flips:?} changes the count by {d}");
                // Every opening it could have made, through either other corner.
                let (joined, others) = face_corners(&vol, face, true).unwrap();
                let others: Vec<[i64; 3]> = others
                    .into_iter()
                    .filter(|&b| m.joins_the_two(&vol, b, joined))
                    .collect();
                for b in others {
                    let mut choices = vec![vec![b]];
                    if change(&mut vol, &[b]) >= 0 {
                        choices.clear();
                        for o in offsets {
                            let f = vec![b, shift(b, *o)];
                            if vol.contains(f[1])
                                && m.simple_after(&mut vol, &[b], f[1])
                                && m.numbers_after(&mut vol, &f, b) == (2, 1)
                            {
                                choices.push(f);
                            }
                        }
                    }
                    for c in choices {
                        let other = change(&mut vol, &c);
                        assert!(
                            other >= d || other >= 0,
                            "{face:?}: {c:?} ({other}) beats {flips:?} ({d})"
                        );
                    }
                }
                flips.iter().for_each(|&q| toggle(&mut vol, q));
                assert_eq!(betti(&vol), (b0, b1 + 1, b2), "{face:?}: {flips:?}");
                flips.iter().rev().for_each(|&q| toggle(&mut vol, q));
                opened += 1;
                followed += usize::from(flips.len() == 2);
            }
        }
        assert!(
            opened > 20 && followed > 2,
            "{opened} opened, {followed} with a flip after"
        );
    }

    /// The face a 48^3 smoothed noise (numpy seed 100, sigma 0.5, iso 0, tau 20) kept after
    /// simplify: a thread passes itself diagonally at a turn, a and d joined only round the
    /// turn. No change that keeps the topology mends it, and the handle opened through it
    /// alone makes another face critical; opened, then one sample beside it let go, no cell is
    /// critical, with one handle more (for simplify's next pass to close). The samples of the
    /// output within 6 of the face, 14 x 14 x 8, four to a hex digit (x fastest, high bit
    /// first).
    #[test]
    fn a_face_whose_opening_needs_one_simple_flip_more_is_mended() {
        const MASK: [&str; 7] = [
            "1fe6ffb08cd886385ea47a19a203ce60201287c0c00fd370007e4081",
            "080df873f1c04301de3930e60080201c8010007101f38700100cdc03",
            "7009c03040e383e3008c02601990001f10fba0060b01ec0600123860",
            "0020382e303ac2ff1b91c007601fff8060003051e10f063e08200380",
            "8e23f8ffe1d80730fc9bfff0040510147070c0eb878e003a11e85e0f",
            "c0398277ef5fe5ff03ff0f801e0208003100ec0f3c38e3e18f03b8e0",
            "63c1ff03c583f0d881e0818007040c0071cbe72f9cb033e8062c10f0",
        ];
        let n = [14usize, 14, 8];
        let bits: Vec<bool> = MASK
            .concat()
            .chars()
            .flat_map(|h| {
                let v = h.to_digit(16).unwrap();
                (0..4).rev().map(move |k| (v >> k) & 1 == 1)
            })
            .collect();
        let crop = || {
            let mut vol = MaskVolume::new(n, Frame::identity());
            for (k, &inside) in bits.iter().enumerate() {
                let p = [k % n[0], (k / n[0]) % n[1], k / (n[0] * n[1])];
                set(&mut vol, p.map(|x| x as i64), inside);
            }
            vol
        };
        let face = (CellKind::FaceZ, [6, 6, 1]);
        let mut vol = crop();
        assert_eq!(count_volume(&vol).total(), 1);
        assert!(is_critical(&vol, face));
        let (b0, b1, b2) = betti(&vol);
        // The opening's two flips lower the count (each change must, so that the step ends);
        // a cut-only step may not fill, so opens nothing.
        let mut m = mender();
        m.open_handles = true;
        let flips = m.open_handle(&mut vol, face).expect("an opening");
        assert_eq!(flips.len(), 2, "{flips:?}");
        assert!(change(&mut vol, &flips) < 0);
        m.only = Some(false);
        assert_eq!(m.open_handle(&mut vol, face), None);
        let kept = compose_six(&mut vol, false);
        assert_eq!(kept.left.total(), 1, "left unless a handle opens");
        let mut vol = crop();
        let c = compose_six(&mut vol, true);
        assert_eq!(c.left.total(), 0);
        assert_eq!(c.opened, vec![[6, 6, 1]]);
        assert_eq!(c.flips.len(), 2, "{:?}", c.flips);
        assert_eq!(betti(&vol), (b0, b1 + 1, b2));
        assert_eq!(count_volume(&vol).total(), 0);
        // Taking the handle back leaves the rest as it was: the topology of the input.
        assert!(take_back(&mut vol, Connectivity::Six, [6, 6, 1]));
        assert_eq!(betti(&vol), (b0, b1, b2));
    }

    /// A step that remembers what earlier steps found (see [`Memory`]) flips exactly what a
    /// step that tries everything again flips, step after step, with samples changed between
    /// steps near and far, handles opened and held samples that come and go.
    #[test]
    fn a_step_that_remembers_flips_what_one_trying_everything_flips() {
        let mut rng = crate::test_rng::Rng(0x5eed_cafe_f00d);
        let n = [24i64; 3];
        let (mut recalled, mut opened) = (0, 0);
        for round in 0..6 {
            // Smoothed noise at its mean: faces needing every kind of change, and some none mends.
            let sponge = crate::test_rng::sponge(n[0] as usize, rng.next_u64());
            let conn = [Connectivity::Six, Connectivity::TwentySix][round % 2];
            let only = [None, Some(true), Some(false)][round % 3];
            let mut vols = [(); 2].map(|_| {
                let mut vol = MaskVolume::new(n.map(|x| x as usize), Frame::identity());
                for z in 0..n[2] {
                    for y in 0..n[1] {
                        for x in 0..n[0] {
                            let inside = sponge.get(x as usize, y as usize, z as usize) > 0.0;
                            set(&mut vol, [x, y, z], inside);
                        }
                    }
                }
                vol
            });
            let mut memories = [Memory::default(), Memory::default()];
            memories[1].forget = true;
            let mut held: Vec<[i64; 3]> = Vec::new();
            for step in 0..3 {
                let opts = ComposeOptions {
                    only,
                    open_handles: step % 2 == 0,
                };
                let mut steps = vols.iter_mut().zip(&mut memories).map(|(vol, memory)| {
                    compose_holding(vol, conn, opts, &held, memory, &crate::progress::NoProgress)
                        .unwrap()
                });
                let (c, fresh) = (steps.next().unwrap(), steps.next().unwrap());
                let what = format!("round {round}, step {step}");
                let first_apart = c.flips.iter().zip(&fresh.flips).position(|(a, b)| a != b);
                assert!(
                    c.flips == fresh.flips,
                    "{what}: {} flips against {}, apart from flip {first_apart:?}",
                    c.flips.len(),
                    fresh.flips.len()
                );
                assert_eq!(c.opened, fresh.opened, "{what}");
                assert_eq!(
                    (c.left, c.swaps, c.rewrites),
                    (fresh.left, fresh.swaps, fresh.rewrites)
                );
                opened += c.opened.len();
                // Hold half of what was opened, let go of half of what was held.
                held = held.iter().chain(&c.opened).copied().step_by(2).collect();
                held.retain(|&b| may_hold_a_handle(&vols[0], conn, b));
                // Flip a few samples, far apart: most cells left stay far from them.
                for _ in 0..1 + step {
                    let p = [0, 1, 2].map(|k| rng.below(n[k] as u64) as i64);
                    for (vol, memory) in vols.iter_mut().zip(&mut memories) {
                        toggle(vol, p);
                        memory.changed(p);
                    }
                }
            }
            recalled += memories[0].recalled;
        }
        assert!(
            recalled > 1000 && opened > 0,
            "{recalled} answers recalled, {opened} opened"
        );
    }

    /// `each_marked_subset` against every `k`-subset in lexicographic order, filtered: the same
    /// sets in the same order (a rewrite's ties are broken by that order), for random marks.
    #[test]
    fn marked_subsets_are_every_subset_with_a_mark_in_order() {
        let mut rng = crate::test_rng::Rng(0x05eb_5e75);
        for round in 0..200 {
            let n = (round % 23) as usize;
            let marked: Vec<bool> = (0..n).map(|_| rng.unit() < 0.15).collect();
            for k in 1..=4 {
                let mut want = Vec::new();
                let mut set: Vec<usize> = (0..k).collect();
                if k <= n {
                    loop {
                        if set.iter().any(|&i| marked[i]) {
                            want.push(set.clone());
                        }
                        let Some(i) = (0..k).rev().find(|&i| set[i] < n - k + i) else {
                            break;
                        };
                        set[i] += 1;
                        for j in i + 1..k {
                            set[j] = set[j - 1] + 1;
                        }
                    }
                }
                let mut got = Vec::new();
                each_marked_subset(&marked, k, &mut |s| got.push(s.to_vec()));
                assert_eq!(got, want, "n {n}, k {k}, marked {marked:?}");
            }
        }
    }

    /// Labels of the 6-connected pieces of `side` over the grid padded by one sample (outside).
    fn flood_labels(vol: &MaskVolume, n: [i64; 3], side: bool) -> Vec<usize> {
        let p = n.map(|x| x + 2);
        let index = |q: [i64; 3]| ((q[2] * p[1] + q[1]) * p[0] + q[0]) as usize;
        let of = |q: [i64; 3]| state(vol, [q[0] - 1, q[1] - 1, q[2] - 1]);
        let mut label = vec![usize::MAX; (p[0] * p[1] * p[2]) as usize];
        let mut next = 0;
        for z in 0..p[2] {
            for y in 0..p[1] {
                for x in 0..p[0] {
                    if label[index([x, y, z])] != usize::MAX || of([x, y, z]) != side {
                        continue;
                    }
                    let mut stack = vec![[x, y, z]];
                    label[index([x, y, z])] = next;
                    while let Some(q) = stack.pop() {
                        for e in STEPS {
                            let r = [q[0] + e[0], q[1] + e[1], q[2] + e[2]];
                            let inside = (0..3).all(|k| r[k] >= 0 && r[k] < p[k]);
                            if inside && label[index(r)] == usize::MAX && of(r) == side {
                                label[index(r)] = next;
                                stack.push(r);
                            }
                        }
                    }
                    next += 1;
                }
            }
        }
        label
    }
}
