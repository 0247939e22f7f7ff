//! Components and cavities: the solid's small components go (deleted, or bridged to a component
//! that stays by a path of outside samples set inside, where that path is shorter than the
//! component is large), and its small cavities go (filled, or opened to the outside or to a
//! cavity that stays by a tunnel of inside samples set outside, where that is cheaper).
//!
//! ```text
//!   a speck beside a big component      a big cavity behind a thin wall
//!
//!     ##  .  ######                      ##########          ##########
//!     ##  .  ######    bridge: 1 sample  #........#   open:  #.........   1 sample cut
//!         ^  ######    (deleting: 4)     #........#          #........#   (filling: 24)
//!     the path                           ##########          ##########
//! ```
//!
//! A bridge or a tunnel is verified before it is kept: the samples on the unchanged side next to
//! it stay connected (nothing splits), the far end touches one part that stays, and the Euler
//! characteristic of the solid drops by exactly one, so exactly one component or cavity went and
//! no handle came or went. When the check refuses a path, up to three more are tried, each
//! avoiding the samples of those refused. Deleting a whole component or filling a whole cavity
//! is exact by construction (with the component go its handles and the cavities it alone
//! enclosed; with the cavity, the handles of its walls, and components floating in it join the
//! one around it). The job checks the result on the whole volume.
//!
//! Components are labelled by a union-find pass over the whole mask: this phase holds every
//! plane in memory, a 4-byte label per sample, and the samples of the parts that go.

use crate::error::{Error, Result};
use crate::grid::simple::{neighbourhood, FACES};
use crate::grid::{shift, MaskVolume};
use crate::progress::Progress;
use crate::surface::search::FastMap;
use crate::topology::cases::{cases, Connectivity};
use crate::unionfind::UnionFind;
use crate::volume::BBox;

use super::{Mode, SimplifyOptions};

/// A solid component or a cavity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PartKind {
    /// A connected piece of the solid.
    Component,
    /// A connected piece of the outside that does not reach the volume's border.
    Cavity,
}

/// How a part went.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PartOperation {
    /// A component set outside, every sample.
    Delete,
    /// A component joined to one that stays by a path of outside samples set inside.
    Bridge,
    /// A cavity set inside, every sample.
    Fill,
    /// A cavity joined to the outside or to a cavity that stays by a tunnel of inside samples
    /// set outside.
    Open,
}

/// A component or cavity removed.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PartRemoved {
    /// Component or cavity.
    pub part: PartKind,
    /// How it went.
    pub operation: PartOperation,
    /// Its samples (inside samples of a component, outside samples of a cavity).
    pub size: usize,
    /// Samples this operation flipped.
    pub samples_changed: usize,
    /// The box of the part (original voxel coordinates).
    pub bbox: BBox,
    /// For a bridge or a tunnel, its samples (original coordinates); for a deletion or a fill,
    /// empty (they are the part's samples, all listed in the edits).
    pub path: Vec<[i64; 3]>,
}

/// A component or cavity the options asked to remove but the mode could not (`--fill-only`
/// with no bridge to a component that stays, `--cut-only` with no tunnel).
#[derive(Clone, Debug, serde::Serialize)]
pub struct PartKept {
    /// Component or cavity.
    pub part: PartKind,
    /// Its samples.
    pub size: usize,
    /// Its box (original voxel coordinates).
    pub bbox: BBox,
}

/// What the phase did.
#[derive(Clone, Debug, Default)]
pub struct Parts {
    /// Components and cavities removed, in order.
    pub removed: Vec<PartRemoved>,
    /// Those asked for that stayed.
    pub kept: Vec<PartKept>,
    /// Bridges and tunnels found but refused by the local check (the next shortest way is then
    /// tried, four in all, before the part is deleted or filled instead).
    pub refused: usize,
    /// Components and cavities (b0, b2) after this phase (what the handles' removal then keeps);
    /// `None` when the phase did not run.
    pub after: Option<(u64, u64)>,
}

impl Parts {
    /// Components (or cavities) removed by `op`.
    pub fn count(&self, op: PartOperation) -> usize {
        self.removed.iter().filter(|r| r.operation == op).count()
    }

    /// Samples flipped to remove the components (or the cavities).
    pub fn samples_changed(&self, kind: PartKind) -> usize {
        let of_kind = self.removed.iter().filter(|r| r.part == kind);
        of_kind.map(|r| r.samples_changed).sum()
    }

    /// Components (or cavities) asked to go that the mode kept.
    pub fn kept_count(&self, kind: PartKind) -> usize {
        self.kept.iter().filter(|k| k.part == kind).count()
    }
}

/// Whether the options ask for anything of this phase.
pub(super) fn wanted(opts: &SimplifyOptions) -> bool {
    opts.min_component.is_some() || opts.largest || opts.min_cavity.is_some() || opts.fill_cavities
}

/// Removes the components and cavities the options ask for; every flipped sample's original
/// side goes into `original` (local coordinates).
pub(super) fn remove_parts(
    vol: &mut MaskVolume,
    opts: &SimplifyOptions,
    original: &mut FastMap<[i64; 3], bool>,
    progress: &dyn Progress,
) -> Result<Parts> {
    let mut out = Parts::default();
    let conn = opts.surface.connectivity;
    if opts.min_component.is_some() || opts.largest {
        progress.start("components", 1);
        let (comps, labels) = label(vol, Side::solid(conn))?;
        let go = components_to_remove(&comps, opts);
        let owner = Owner::new(labels, &go, comps.len());
        remove(vol, Side::solid(conn), owner, opts, original, &mut out);
        progress.finish();
        crate::progress::between_steps(progress, "components-and-cavities phase")?;
    }
    if opts.min_cavity.is_some() || opts.fill_cavities {
        progress.start("cavities", 1);
        let (spaces, labels) = label(vol, Side::space(conn))?;
        let go = cavities_to_remove(&spaces, opts);
        let owner = Owner::new(labels, &go, spaces.len());
        remove(vol, Side::space(conn), owner, opts, original, &mut out);
        progress.finish();
        crate::progress::between_steps(progress, "components-and-cavities phase")?;
    }
    out.after = Some(check_parts(vol, opts, &out)?);
    vol.keep_window(-1, -1)?;
    Ok(out)
}

/// The components to remove, smallest first: under `min_component` samples, and with `largest`
/// every one but the largest (the first of equals in scan order).
fn components_to_remove(comps: &[Part], opts: &SimplifyOptions) -> Vec<usize> {
    let min = opts.min_component.unwrap_or(0) as usize;
    let largest = (0..comps.len()).max_by_key(|&i| (comps[i].size, std::cmp::Reverse(i)));
    let mut go: Vec<usize> = (0..comps.len())
        .filter(|&i| comps[i].size < min || (opts.largest && Some(i) != largest))
        .collect();
    go.sort_by_key(|&i| (comps[i].size, i));
    go
}

/// The cavities to remove, smallest first: under `min_cavity` samples, or every one.
fn cavities_to_remove(spaces: &[Part], opts: &SimplifyOptions) -> Vec<usize> {
    let min = match (opts.fill_cavities, opts.min_cavity) {
        (true, _) => usize::MAX,
        (false, m) => m.unwrap_or(0) as usize,
    };
    let mut go: Vec<usize> = (0..spaces.len())
        .filter(|&i| !spaces[i].exterior && spaces[i].size < min)
        .collect();
    go.sort_by_key(|&i| (spaces[i].size, i));
    go
}

/// One side of the isosurface with its adjacency: the solid (6-adjacent under connectivity 6)
/// or the space round it (26-adjacent then; the reverse under 26).
#[derive(Clone, Copy)]
struct Side {
    inside: bool,
    six: bool,
    conn: Connectivity,
}

impl Side {
    fn solid(conn: Connectivity) -> Side {
        Side {
            inside: true,
            six: conn == Connectivity::Six,
            conn,
        }
    }

    fn space(conn: Connectivity) -> Side {
        Side {
            inside: false,
            six: conn != Connectivity::Six,
            conn,
        }
    }

    fn other(self) -> Side {
        Side {
            inside: !self.inside,
            six: !self.six,
            conn: self.conn,
        }
    }

    fn offsets(self) -> &'static [[i64; 3]] {
        if self.six {
            &FACES
        } else {
            &neighbourhood().offsets
        }
    }

    fn kind(self) -> PartKind {
        if self.inside {
            PartKind::Component
        } else {
            PartKind::Cavity
        }
    }
}

/// A connected set of samples of one side.
#[derive(Clone, Copy)]
struct Part {
    /// Samples in the volume (the padding round it not counted).
    size: usize,
    /// Its first sample in scan order.
    seed: [i64; 3],
    /// Does it reach the padding (the outside round the volume)?
    exterior: bool,
}

/// No part: a sample of the other side.
const NONE: u32 = u32::MAX;

/// The part of every sample of one side, over the volume and for the outside its one-sample
/// padding too (x fastest).
struct Labels {
    lo: i64,
    dims: [i64; 3],
    ids: Vec<u32>,
}

impl Labels {
    /// The memory the labels of a box of `dims` samples take: reserved before they are made.
    fn bytes(dims: [i64; 3]) -> u64 {
        dims.iter().product::<i64>() as u64 * std::mem::size_of::<u32>() as u64
    }

    fn index(&self, q: [i64; 3]) -> Option<usize> {
        let p = q.map(|x| x - self.lo);
        let d = self.dims;
        if (0..3).any(|a| p[a] < 0 || p[a] >= d[a]) {
            return None;
        }
        Some(((p[2] * d[1] + p[1]) * d[0] + p[0]) as usize)
    }

    /// The part of `q`, or [`NONE`] (the other side, or beyond the padding).
    fn get(&self, q: [i64; 3]) -> u32 {
        self.index(q).map_or(NONE, |i| self.ids[i])
    }
}

/// Every connected part of `side` (the padding included for the outside: the part holding it
/// is the exterior) in scan order of their first sample, and each sample's part. One pass in
/// scan order joins each sample to its neighbours already seen (a union-find of provisional
/// labels), a second gives each sample its part.
fn label(vol: &MaskVolume, side: Side) -> Result<(Vec<Part>, Labels)> {
    let lo = if side.inside { 0 } else { -1 };
    let hi = vol.dims.map(|d| d as i64 - lo);
    let dims = hi.map(|h| h - lo);
    crate::memory::reserve(
        "the labels of the components-and-cavities phase (4 bytes a sample)",
        Labels::bytes(dims),
    )?;
    let mut labels = Labels {
        lo,
        dims,
        ids: vec![NONE; (dims[0] * dims[1] * dims[2]) as usize],
    };
    let seen_before = |d: &[i64; 3]| (d[2], d[1], d[0]) < (0, 0, 0);
    let step = |d: [i64; 3]| (d, ((-d[2] * dims[1] - d[1]) * dims[0] - d[0]) as usize);
    let back: Vec<([i64; 3], usize)> = side
        .offsets()
        .iter()
        .filter(|d| seen_before(d))
        .map(|&d| step(d))
        .collect();
    // When the sample on the left is of the side, it was joined to its own neighbours seen
    // before it: only the left one and those it does not touch are left to look at (5 of 13
    // under 26-adjacency; all 3 under 6).
    let touches_left = |d: &[i64; 3]| side.offsets().contains(&[d[0] + 1, d[1], d[2]]);
    let after_left: Vec<([i64; 3], usize)> = std::iter::once(step([-1, 0, 0]))
        .chain(
            back.iter()
                .copied()
                .filter(|(d, _)| *d != [-1, 0, 0] && !touches_left(d)),
        )
        .collect();
    let mut uf = UnionFind::new(0);
    let mut i = 0;
    for z in lo..hi[2] {
        // The provisional labels' union-find grows with the parts met.
        crate::memory::check("components-and-cavities phase")?;
        let plane = vol.plane_once(z);
        for y in lo..hi[1] {
            for x in lo..hi[0] {
                if plane.get(x as isize, y as isize) == side.inside {
                    let left = x > lo && labels.ids[i - 1] != NONE;
                    let look = if left { &after_left } else { &back };
                    // Away from the faces (but the top: no neighbour seen before is above),
                    // every neighbour is in range.
                    let inner = x > lo && y > lo && z > lo && x + 1 < hi[0] && y + 1 < hi[1];
                    let mut mine = NONE;
                    for &(d, back) in look {
                        if !inner {
                            let n = [x + d[0], y + d[1], z + d[2]];
                            if (0..3).any(|a| n[a] < lo || n[a] >= hi[a]) {
                                continue;
                            }
                        }
                        let l = labels.ids[i - back];
                        if l == NONE || l == mine {
                            continue;
                        }
                        if mine == NONE {
                            mine = l;
                        } else {
                            uf.union(mine, l);
                        }
                    }
                    labels.ids[i] = if mine == NONE { uf.push() } else { mine };
                }
                i += 1;
            }
        }
    }
    let (part_of, k) = uf.labels();
    let mut parts = vec![
        Part {
            size: 0,
            seed: [i64::MAX; 3],
            exterior: false,
        };
        k
    ];
    let mut i = 0;
    for z in lo..hi[2] {
        for y in lo..hi[1] {
            for x in lo..hi[0] {
                let l = labels.ids[i];
                if l != NONE {
                    let p = part_of[l as usize];
                    labels.ids[i] = p;
                    let part = &mut parts[p as usize];
                    if part.seed[0] == i64::MAX {
                        part.seed = [x, y, z];
                    }
                    if vol.contains([x, y, z]) {
                        part.size += 1;
                    } else {
                        part.exterior = true;
                    }
                }
                i += 1;
            }
        }
    }
    Ok((parts, labels))
}

/// Which of the parts that go (numbered in their order) each sample of the side belongs to; the
/// rest of the side stays. Samples flipped since the labelling are not looked up: they are on
/// the other side now, or (a bridge, a tunnel) belong to what stays.
struct Owner {
    labels: Labels,
    /// Part -> its number among those that go, or [`NONE`].
    slot: Vec<u32>,
    /// Number -> part.
    go: Vec<usize>,
}

impl Owner {
    fn new(labels: Labels, go: &[usize], parts: usize) -> Owner {
        let mut slot = vec![NONE; parts];
        for (k, &p) in go.iter().enumerate() {
            slot[p] = k as u32;
        }
        Owner {
            labels,
            slot,
            go: go.to_vec(),
        }
    }

    fn of(&self, q: [i64; 3]) -> Option<u32> {
        let l = self.labels.get(q);
        (l != NONE && self.slot[l as usize] != NONE).then(|| self.slot[l as usize])
    }

    /// Part `k` stays from now on (it was joined to what stays).
    fn stays(&mut self, k: u32) {
        self.slot[self.go[k as usize]] = NONE;
    }

    /// The samples of each part that goes, in scan order.
    fn members(&self) -> Vec<Vec<[i64; 3]>> {
        let mut out = vec![Vec::new(); self.go.len()];
        let d = self.labels.dims;
        let mut i = 0;
        for z in 0..d[2] {
            for y in 0..d[1] {
                for x in 0..d[0] {
                    let l = self.labels.ids[i];
                    if l != NONE && self.slot[l as usize] != NONE {
                        let q = [x, y, z].map(|c| c + self.labels.lo);
                        out[self.slot[l as usize] as usize].push(q);
                    }
                    i += 1;
                }
            }
        }
        out
    }
}

/// Removes the parts of `side` that go (those `owner` numbers, in that order): each by whichever
/// of its two operations flips fewer samples and the mode allows.
fn remove(
    vol: &mut MaskVolume,
    side: Side,
    mut owner: Owner,
    opts: &SimplifyOptions,
    original: &mut FastMap<[i64; 3], bool>,
    out: &mut Parts,
) {
    let members = owner.members();
    // A component bridges by filling (adding material), a cavity opens by cutting.
    let (join_allowed, whole_allowed) = match (opts.mode, side.inside) {
        (Mode::Both, _) => (true, true),
        (Mode::FillOnly, inside) => (inside, !inside),
        (Mode::CutOnly, inside) => (!inside, inside),
    };
    for (k, m) in members.iter().enumerate() {
        let size = m.len();
        let budget = if whole_allowed { size - 1 } else { usize::MAX };
        let bbox = original_box(vol, m);
        let mut joined = None;
        // A refused path's samples are not tried again: the next shortest goes elsewhere.
        let mut refused: FastMap<[i64; 3], ()> = FastMap::default();
        let attempts = if join_allowed && budget > 0 {
            JOIN_ATTEMPTS
        } else {
            0
        };
        for _ in 0..attempts {
            let Some(path) = shortest_join(vol, side, m, &owner, k as u32, budget, &refused) else {
                break;
            };
            // verify_join leaves the path flipped when it keeps it.
            if verify_join(vol, side, &path, &owner, k as u32) {
                joined = Some(path);
                break;
            }
            out.refused += 1;
            refused.extend(path.iter().map(|&q| (q, ())));
        }
        let removed = match joined {
            Some(path) => {
                // Joined parts stay from now on: later ones may join them.
                owner.stays(k as u32);
                for &q in &path {
                    original.entry(q).or_insert(!side.inside);
                }
                PartRemoved {
                    part: side.kind(),
                    operation: join_operation(side),
                    size,
                    samples_changed: path.len(),
                    bbox,
                    path: path.iter().map(|&q| vol.frame.to_original_i(q)).collect(),
                }
            }
            None if whole_allowed => {
                set_all(vol, m, !side.inside);
                for &q in m {
                    original.entry(q).or_insert(side.inside);
                }
                PartRemoved {
                    part: side.kind(),
                    operation: whole_operation(side),
                    size,
                    samples_changed: size,
                    bbox,
                    path: Vec::new(),
                }
            }
            None => {
                let part = side.kind();
                out.kept.push(PartKept { part, size, bbox });
                continue;
            }
        };
        out.removed.push(removed);
    }
}

fn join_operation(side: Side) -> PartOperation {
    if side.inside {
        PartOperation::Bridge
    } else {
        PartOperation::Open
    }
}

fn whole_operation(side: Side) -> PartOperation {
    if side.inside {
        PartOperation::Delete
    } else {
        PartOperation::Fill
    }
}

/// The box of local samples, in original coordinates.
fn original_box(vol: &MaskVolume, samples: &[[i64; 3]]) -> BBox {
    let mut b = BBox::EMPTY;
    for &q in samples {
        b.include(vol.frame.to_original_i(q));
    }
    b
}

/// What a sample of `side` next to a path is: of the part being joined, of another part that
/// goes (the path may not touch it), or of what stays.
#[derive(PartialEq)]
enum Touch {
    Mine,
    Blocked,
    Stays,
}

fn touch(owner: &Owner, me: u32, q: [i64; 3]) -> Touch {
    match owner.of(q) {
        Some(k) if k == me => Touch::Mine,
        Some(_) => Touch::Blocked,
        None => Touch::Stays,
    }
}

/// The shortest path of samples of the other side (at most `budget` of them, in the volume,
/// consecutive ones adjacent under `side`'s adjacency) from the part `me` (its samples `from`)
/// to a sample of `side` that stays, touching no other part that goes; from the part to the far
/// end.
fn shortest_join(
    vol: &MaskVolume,
    side: Side,
    from: &[[i64; 3]],
    owner: &Owner,
    me: u32,
    budget: usize,
    refused: &FastMap<[i64; 3], ()>,
) -> Option<Vec<[i64; 3]>> {
    let mut parent: FastMap<[i64; 3], [i64; 3]> = FastMap::default();
    // A path sample's neighbours of `side`: does it touch what stays (an end), or another part
    // that goes (unusable)?
    let classify = |q: [i64; 3]| {
        let mut stays = false;
        for &d in side.offsets() {
            let n = shift(q, d);
            if vol.get(n[0], n[1], n[2]) == side.inside {
                match touch(owner, me, n) {
                    Touch::Blocked => return None,
                    Touch::Stays => stays = true,
                    Touch::Mine => {}
                }
            }
        }
        Some(stays)
    };
    // Layer by layer out from the part's own samples; each path sample's parent is the one
    // before it, the first's itself.
    let mut layer: Vec<[i64; 3]> = from.to_vec();
    let mut length = 0;
    while !layer.is_empty() && length < budget {
        length += 1;
        let mut next = Vec::new();
        for &q in &layer {
            for &d in side.offsets() {
                let n = shift(q, d);
                if !vol.contains(n)
                    || vol.get(n[0], n[1], n[2]) == side.inside
                    || parent.contains_key(&n)
                    || refused.contains_key(&n)
                {
                    continue;
                }
                parent.insert(n, if length == 1 { n } else { q });
                match classify(n) {
                    Some(true) => return Some(path_to(&parent, n)),
                    Some(false) => next.push(n),
                    None => {}
                }
            }
        }
        layer = next;
    }
    None
}

/// The path ending at `end`, from its first sample.
fn path_to(parent: &FastMap<[i64; 3], [i64; 3]>, end: [i64; 3]) -> Vec<[i64; 3]> {
    let mut path = vec![end];
    let mut q = end;
    while parent[&q] != q {
        q = parent[&q];
        path.push(q);
    }
    path.reverse();
    path
}

/// Paths tried for one part before it is deleted or filled instead (or kept, when the mode
/// allows only joins): each avoids the samples of those refused before it.
const JOIN_ATTEMPTS: usize = 4;

/// Margins round a path within which what must stay connected is looked for.
const MARGINS: [i64; 2] = [2, 8];

/// Flips `path` to `side` and keeps it if it joined the part to exactly one that stays and
/// changed nothing else (see the module documentation); otherwise flips it back. Returns
/// whether it was kept.
fn verify_join(
    vol: &mut MaskVolume,
    side: Side,
    path: &[[i64; 3]],
    owner: &Owner,
    me: u32,
) -> bool {
    let end = *path.last().expect("a path has samples");
    // The far end's neighbours that stay: one part, connected without the path.
    let ends: Vec<[i64; 3]> = side
        .offsets()
        .iter()
        .map(|&d| shift(end, d))
        .filter(|n| {
            vol.get(n[0], n[1], n[2]) == side.inside && touch(owner, me, *n) == Touch::Stays
        })
        .collect();
    // The other side's samples next to the path: one part before, one after.
    let space = side.other();
    let mut beside: Vec<[i64; 3]> = Vec::new();
    for &q in path {
        for &d in space.offsets() {
            let n = shift(q, d);
            if vol.get(n[0], n[1], n[2]) == space.inside && !path.contains(&n) {
                beside.push(n);
            }
        }
    }
    beside.sort();
    beside.dedup();
    let cubes = touched_cubes(path);
    let before = chi4(vol, side.conn, &cubes);
    if !connected_near(vol, side, &ends, path) {
        return false;
    }
    set_all(vol, path, side.inside);
    let after = chi4(vol, side.conn, &cubes);
    if after - before == -8 && connected_near(vol, space, &beside, path) {
        return true;
    }
    set_all(vol, path, space.inside);
    false
}

/// Sets the samples (in the volume) inside or outside.
fn set_all(vol: &mut MaskVolume, samples: &[[i64; 3]], inside: bool) {
    for &q in samples {
        let [u, v, w] = q.map(|x| x as usize);
        vol.set(u, v, w, inside);
    }
}

/// Are `seeds` (samples of `side`) connected to each other through `side` within a margin of
/// the path's box?
fn connected_near(vol: &MaskVolume, side: Side, seeds: &[[i64; 3]], path: &[[i64; 3]]) -> bool {
    let Some(&first) = seeds.first() else {
        return true;
    };
    let mut b = BBox::EMPTY;
    for &q in path.iter().chain(seeds) {
        b.include(q);
    }
    MARGINS.iter().any(|&m| {
        let (lo, hi) = (b.min.map(|x| x - m), b.max.map(|x| x + m));
        let inside_box = |q: [i64; 3]| (0..3).all(|a| q[a] >= lo[a] && q[a] <= hi[a]);
        let mut seen: FastMap<[i64; 3], ()> = FastMap::default();
        seen.insert(first, ());
        let mut stack = vec![first];
        while let Some(q) = stack.pop() {
            for &d in side.offsets() {
                let n = shift(q, d);
                if inside_box(n)
                    && vol.get(n[0], n[1], n[2]) == side.inside
                    && seen.insert(n, ()).is_none()
                {
                    stack.push(n);
                }
            }
        }
        seeds.iter().all(|q| seen.contains_key(q))
    })
}

/// Cubes (lower corners) with a corner among the samples.
fn touched_cubes(samples: &[[i64; 3]]) -> Vec<[i64; 3]> {
    let mut set: FastMap<[i64; 3], ()> = FastMap::default();
    for q in samples {
        for b in 0..8i64 {
            set.insert(
                [q[0] - (b & 1), q[1] - (b >> 1 & 1), q[2] - (b >> 2 & 1)],
                (),
            );
        }
    }
    set.into_keys().collect()
}

/// Four times the Euler characteristic of the isosurface inside these cubes (eight times the
/// solid's, summed over them).
fn chi4(vol: &MaskVolume, conn: Connectivity, cubes: &[[i64; 3]]) -> i64 {
    let table = cases(conn);
    cubes
        .iter()
        .map(|&q| {
            let case = &table[crate::surface::cube_case(vol, q) as usize];
            case.chi4[..case.pieces.len()]
                .iter()
                .map(|&c| c as i64)
                .sum::<i64>()
        })
        .sum()
}

/// Checks the phase's result on the whole volume: every component and cavity the options ask
/// to remove is gone, but those the mode kept; returns the components and cavities left (the
/// job checks them again with the genus pass, which counts them another way).
fn check_parts(vol: &MaskVolume, opts: &SimplifyOptions, out: &Parts) -> Result<(u64, u64)> {
    let conn = opts.surface.connectivity;
    let comps = label(vol, Side::solid(conn))?.0;
    let spaces = label(vol, Side::space(conn))?.0;
    // With neither option of a kind asked, its list of parts to remove is empty.
    let left = [
        (
            PartKind::Component,
            "components",
            components_to_remove(&comps, opts),
        ),
        (
            PartKind::Cavity,
            "cavities",
            cavities_to_remove(&spaces, opts),
        ),
    ];
    for (kind, name, left) in left {
        if left.len() != out.kept_count(kind) {
            return Err(Error::Internal(format!(
                "after removing {name}, {} are left that should have gone ({} kept by the mode); nothing written",
                left.len(),
                out.kept_count(kind)
            )));
        }
    }
    let cavities = spaces.iter().filter(|s| !s.exterior).count();
    Ok((comps.len() as u64, cavities as u64))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Frame;

    fn removed(part: PartKind, operation: PartOperation, samples_changed: usize) -> PartRemoved {
        PartRemoved {
            part,
            operation,
            size: samples_changed,
            samples_changed,
            bbox: BBox::EMPTY,
            path: Vec::new(),
        }
    }

    /// The labels reserve the memory they then take: 4 bytes a sample, over the volume for the
    /// solid and over the volume and its padding for the space round it.
    #[test]
    fn the_labels_reserve_the_memory_they_take() {
        let vol = MaskVolume::new([3, 4, 5], Frame::identity());
        for (side, samples) in [
            (Side::solid(Connectivity::Six), 3 * 4 * 5),
            (Side::space(Connectivity::Six), 5 * 6 * 7),
        ] {
            let (_, labels) = label(&vol, side).unwrap();
            assert_eq!(labels.ids.len(), samples);
            assert_eq!(Labels::bytes(labels.dims), 4 * samples as u64);
        }
    }

    /// The report's totals add up each kind's parts and each operation's, and only those; the
    /// parts kept are counted by kind.
    #[test]
    fn totals_count_each_kind_and_operation_apart() {
        let kept = |part: PartKind| PartKept {
            part,
            size: 1,
            bbox: BBox::EMPTY,
        };
        let parts = Parts {
            kept: vec![
                kept(PartKind::Cavity),
                kept(PartKind::Component),
                kept(PartKind::Cavity),
            ],
            removed: vec![
                removed(PartKind::Component, PartOperation::Delete, 5),
                removed(PartKind::Cavity, PartOperation::Fill, 7),
                removed(PartKind::Component, PartOperation::Bridge, 11),
                removed(PartKind::Cavity, PartOperation::Open, 13),
                removed(PartKind::Cavity, PartOperation::Fill, 17),
            ],
            ..Parts::default()
        };
        assert_eq!(parts.samples_changed(PartKind::Component), 16);
        assert_eq!(parts.samples_changed(PartKind::Cavity), 37);
        assert_eq!(parts.count(PartOperation::Fill), 2);
        assert_eq!(parts.count(PartOperation::Delete), 1);
        assert_eq!(parts.count(PartOperation::Open), 1);
        assert_eq!(parts.kept_count(PartKind::Component), 1);
        assert_eq!(parts.kept_count(PartKind::Cavity), 2);
    }

    /// A hollow square pipe (walls 3 x 3 round a hollow core, centreline a square of side 29 in
    /// z = 4), cut open across at x = 20 on its side y = 5, and a speck of one sample at
    /// (20, 9, 4) to be bridged to it. The pipe's wall is a thickened tube, its core a tunnel
    /// open at the cut.
    ///
    /// ```text
    ///   plane z = 4, near the cut:     y = 9   . . . s . . .     s the speck
    ///                                  y = 7   . . . + . . .     + a bridge sample
    ///                                  y = 6   # # # . # # #     the pipe's wall
    ///                                  y = 5   . . . . . . .     its hollow core (open at the cut)
    ///                                  y = 4   # # # . # # #
    ///                                         x = 20 is the cut
    /// ```
    fn cut_pipe_and_speck() -> MaskVolume {
        let mut vol = MaskVolume::new([40, 40, 9], Frame::identity());
        let from_line = |c: i64| (c - 5).abs().min((c - 34).abs());
        for (x, y, z) in (0..40 * 40 * 9).map(|k| (k % 40, (k / 40) % 40, k / 1600)) {
            let [xi, yi, zi] = [x, y, z].map(|c| c as i64);
            // The wall reaches one sample past the centreline's ends, closing the corners.
            let along_x = (4..=35).contains(&xi) && from_line(yi) <= 1;
            let along_y = (4..=35).contains(&yi) && from_line(xi) <= 1;
            let tube = (along_x || along_y) && (zi - 4).abs() <= 1;
            let core = zi == 4
                && ((5..=34).contains(&xi) && from_line(yi) == 0
                    || (5..=34).contains(&yi) && from_line(xi) == 0);
            let cut = xi == 20 && yi <= 6;
            vol.set(x, y, z, tube && !core && !cut);
        }
        vol.set(20, 9, 4, true);
        vol
    }

    /// A bridge is kept only if it changes nothing but the one join, even where the Euler
    /// characteristic cannot tell: a bridge from the speck that also closes the pipe's cut (its
    /// far end going round the wall's cross-section there) joins the speck (b0 - 1), closes the
    /// wall into a torus (b1 + 1) and the core into a cavity (b2 + 1), so the characteristic
    /// drops by one as for a plain join. The far end's neighbours on the wall are connected only
    /// the long way round the pipe, and the core beside the bridge is cut off: it is refused and
    /// flipped back. A plain bridge beside it is kept.
    #[test]
    fn a_bridge_that_also_closes_a_handle_and_a_cavity_is_refused() {
        let conn = Connectivity::Six;
        let mut vol = cut_pipe_and_speck();
        let side = Side::solid(conn);
        let owner = speck_owner(&vol, [20, 9, 4]);
        // Down to the cut, then round the wall's cross-section there (x = 20, y and z 3..=5).
        let round = [
            [6, 4],
            [6, 5],
            [5, 5],
            [4, 5],
            [4, 4],
            [4, 3],
            [5, 3],
            [6, 3],
        ];
        let closing: Vec<[i64; 3]> = [[20, 8, 4], [20, 7, 4]]
            .into_iter()
            .chain(round.map(|[y, z]| [20, y, z]))
            .collect();
        let cubes = touched_cubes(&closing);
        let (before, b) = (chi4(&vol, conn, &cubes), betti(&vol, conn));
        assert_eq!(b, [2, 1, 0], "the speck, the cut pipe round its core");
        set_all(&mut vol, &closing, true);
        assert_eq!(
            betti(&vol, conn),
            [1, 2, 1],
            "joined, a torus round a cavity"
        );
        assert_eq!(chi4(&vol, conn, &cubes) - before, -8, "as a plain join");
        set_all(&mut vol, &closing, false);
        let unchanged = samples(&vol);
        assert!(!verify_join(&mut vol, side, &closing, &owner, 0));
        assert!(
            samples(&vol) == unchanged,
            "the refused bridge is flipped back"
        );
        let plain = [[20, 8, 4], [20, 7, 4], [21, 7, 4]];
        assert!(verify_join(&mut vol, side, &plain, &owner, 0));
        assert!(plain.iter().all(|q| vol.get(q[0], q[1], q[2])));
    }

    /// A bridge whose far end's neighbours are connected and whose sides stay connected, but
    /// that touches what stays twice, is refused by the Euler characteristic: a speck between
    /// the arms of a U, bridged to the right arm where the path starts and to the left arm
    /// where it ends, closes the U into a ring (b0 - 1, b1 + 1). A bridge to one arm is kept.
    ///
    /// ```text
    ///   plane z = 8:   y = 11   # # . + + + + # #     # the U's arms (joined at z = 1..=2)
    ///                  y = 10   # # . . s + . # #     s the speck, + the bridge
    ///                          x = 6 7 8 9 10 11 12 13
    /// ```
    #[test]
    fn a_bridge_touching_what_stays_twice_is_refused() {
        let conn = Connectivity::Six;
        let mut vol = MaskVolume::new([20, 20, 12], Frame::identity());
        for (x, y, z) in (0..20 * 20 * 12).map(|k| (k % 20, (k / 20) % 20, k / 400)) {
            let arm = (6..=7).contains(&x) || (12..=13).contains(&x);
            let bottom = (6..=13).contains(&x) && (1..=2).contains(&z);
            let u = (arm && (1..=9).contains(&z) || bottom) && (9..=11).contains(&y);
            vol.set(x, y, z, u);
        }
        vol.set(10, 10, 8, true);
        let side = Side::solid(conn);
        let owner = speck_owner(&vol, [10, 10, 8]);
        let twice = [
            [11, 10, 8],
            [11, 11, 8],
            [10, 11, 8],
            [9, 11, 8],
            [8, 11, 8],
        ];
        assert_eq!(betti(&vol, conn), [2, 0, 0]);
        set_all(&mut vol, &twice, true);
        assert_eq!(betti(&vol, conn), [1, 1, 0], "joined into a ring");
        set_all(&mut vol, &twice, false);
        let unchanged = samples(&vol);
        assert!(!verify_join(&mut vol, side, &twice, &owner, 0));
        assert!(
            samples(&vol) == unchanged,
            "the refused bridge is flipped back"
        );
        let once = [[9, 10, 8], [8, 10, 8]];
        assert!(verify_join(&mut vol, side, &once, &owner, 0));
        assert_eq!(betti(&vol, conn), [1, 0, 0]);
    }

    /// The space on either side of a solid wall that crosses the volume is one part through the
    /// padding beyond the volume's faces, and the check finds it so next to the low faces too:
    /// its box round the path reaches `margin` samples below the path, into the padding.
    ///
    /// ```text
    ///   y=3  . . . . .    outside ('.'), joined only round the wall's end at x = -1
    ///   y=2  # # # # #    the wall (a whole plane y = 2 of the 20 x 5 x 20 volume)
    ///   y=1  . . . . .    (x = 0 is the volume's low face; the high faces are too far)
    /// ```
    #[test]
    fn the_space_round_a_wall_is_joined_through_the_padding_by_the_low_faces() {
        let mut vol = MaskVolume::new([20, 5, 20], Frame::identity());
        for (x, z) in (0..20).flat_map(|x| (0..20).map(move |z| (x, z))) {
            vol.set(x, 2, z, true);
        }
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            let space = Side::space(conn);
            let path = [[0, 2, 1]];
            assert!(connected_near(&vol, space, &[[0, 1, 1], [0, 3, 1]], &path));
            // Away from the faces no margin reaches round the wall.
            let path = [[10, 2, 10]];
            assert!(!connected_near(
                &vol,
                space,
                &[[10, 1, 10], [10, 3, 10]],
                &path
            ));
        }
    }

    /// The bookkeeping of a solid speck's removal: it is the one part that goes.
    fn speck_owner(vol: &MaskVolume, speck: [i64; 3]) -> Owner {
        let (parts, labels) = label(vol, Side::solid(Connectivity::Six)).unwrap();
        let k = parts.iter().position(|p| p.seed == speck).unwrap();
        Owner::new(labels, &[k], parts.len())
    }

    fn betti(vol: &MaskVolume, conn: Connectivity) -> [u64; 3] {
        let g = vol.genus(conn).unwrap();
        [g.b0, g.b1, g.b2]
    }

    /// Every sample of the volume, x fastest.
    fn samples(vol: &MaskVolume) -> Vec<bool> {
        let [nx, ny, nz] = vol.dims.map(|n| n as i64);
        (0..nx * ny * nz)
            .map(|k| vol.get(k % nx, (k / nx) % ny, k / (nx * ny)))
            .collect()
    }
}
