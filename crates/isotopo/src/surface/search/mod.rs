//! Shortest loops that cross given curves an odd (or even) number of times.
//!
//! Both characteristic loops of a handle are found this way (paper §2.2): the Reeb loop crosses
//! one contour of the handle's Reeb cycle once, the cross loop crosses the Reeb loop once. The
//! search runs on the double cover of the surface graph: a state is (vertex, parity), and an
//! edge flips the parity when it crosses the cut `K`. At a vertex of `K`, the edges on the left of
//! `K` are marked; an edge's flip is the number of its marked ends, mod 2. A closed walk crosses
//! `K` an odd number of times exactly when its flips sum to 1, so the shortest odd loop through a
//! vertex `s` of `K` is the shortest path from (s, 0) to (s, 1); the shortest of those over `s` is
//! the answer, and it is a simple loop.
//!
//! ```text
//!              left of K (marked)
//!      ----x-------x-------x----->  K
//!              right of K
//! ```
//!
//! States live in dense arrays indexed by the graph's vertex numbers (one bit of parity per
//! curve), reset by generation stamps, so a search costs what it visits and nothing more.

mod weighted;

pub use weighted::{odd_loop_mm, OddLoopMm};

use crate::grid::MaskVolume;
use crate::surface::{around, Around, PieceRef, Vertex, MAX_DEGREE};
use crate::topology::cases::Case;
use std::collections::{HashMap, VecDeque};
use std::hash::{BuildHasherDefault, Hasher};

/// A fast hasher for small integer keys (vertices packed into a u64).
#[derive(Default, Clone, Copy)]
pub struct FastHasher(u64);

impl Hasher for FastHasher {
    /// The multiply leaves the low bits depending on the key's low bits only (a vertex key's
    /// x), and the table picks buckets by the low bits: without this finaliser (murmur3's) every
    /// vertex of one x column lands in one probe chain.
    fn finish(&self) -> u64 {
        let mut x = self.0;
        x ^= x >> 33;
        x = x.wrapping_mul(0xff51_afd7_ed55_8ccd);
        x ^= x >> 33;
        x = x.wrapping_mul(0xc4ce_b9fe_1a85_ec53);
        x ^ (x >> 33)
    }
    /// Slices of integers (`[i64; 3]` keys) come here as bytes: eight at a time.
    fn write(&mut self, bytes: &[u8]) {
        let mut words = bytes.chunks_exact(8);
        for w in &mut words {
            self.write_u64(u64::from_le_bytes(w.try_into().expect("8 bytes")));
        }
        for &b in words.remainder() {
            self.write_u64(b as u64);
        }
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

pub(crate) type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<FastHasher>>;

/// Packs a vertex into a u64 ([`Vertex::key`]).
#[inline]
pub fn key(v: Vertex) -> u64 {
    v.key()
}

/// The surface graph of one volume: each vertex's neighbourhood is computed once and numbered,
/// and kept for later searches; the numbers index the searches' dense state arrays.
pub struct Graph<'a> {
    /// The volume whose isosurface this is.
    pub vol: &'a MaskVolume,
    /// The cases of its connectivity.
    pub table: &'a [Case; 256],
    index: VertexIndex,
    arena: Vec<Around>,
    /// Each numbered vertex, as its key.
    verts: Vec<u64>,
    /// Numbers of each vertex's neighbours, resolved on first use (`UNRESOLVED` until then),
    /// and `BEYOND` past the last.
    nbr_num: Vec<[u32; MAX_DEGREE]>,
    scratch: Scratch,
    /// How many states the loop searches may visit (a field so that a test can run them out).
    pub(crate) budgets: Budgets,
}

/// States a loop search may visit before it stops and says its answer is not exact.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Budgets {
    /// The multi-source phase ([`FIRST_BUDGET`]).
    pub first: usize,
    /// The exact phase ([`EXACT_BUDGET`]).
    pub exact: usize,
}

impl Default for Budgets {
    fn default() -> Budgets {
        Budgets {
            first: FIRST_BUDGET,
            exact: EXACT_BUDGET,
        }
    }
}

/// A graph's numbered neighbourhoods, detached from its volume so that they can outlive an edit
/// of the volume ([`GraphCache::invalidate`] forgets what the edit changed).
#[derive(Default)]
pub struct GraphCache {
    index: VertexIndex,
    arena: Vec<Around>,
    /// Each numbered vertex, as its key.
    verts: Vec<u64>,
    nbr_num: Vec<[u32; MAX_DEGREE]>,
    scratch: Scratch,
    pub(crate) budgets: Budgets,
}

impl GraphCache {
    /// Vertices numbered.
    pub fn len(&self) -> usize {
        self.arena.len()
    }

    /// Whether no vertex is numbered.
    pub fn is_empty(&self) -> bool {
        self.arena.is_empty()
    }

    /// After samples in `lo ..= hi` changed in `vol`: recomputes the neighbourhoods that may
    /// have changed. A vertex's neighbourhood depends on the four cubes around its edge, whose
    /// corners lie within one sample of the edge's lower end, so vertices within one sample of
    /// the box are redone; their numbers stay, so the rest of the graph stays valid.
    pub fn invalidate(
        &mut self,
        vol: &MaskVolume,
        table: &[Case; 256],
        lo: [i64; 3],
        hi: [i64; 3],
    ) {
        for z in lo[2] - 1..=hi[2] + 1 {
            for y in lo[1] - 1..=hi[1] + 1 {
                for x in lo[0] - 1..=hi[0] + 1 {
                    for axis in 0..3u8 {
                        let v = Vertex { p: [x, y, z], axis };
                        let k = key(v);
                        match self.index.get(k) {
                            None => {}
                            Some(ABSENT) => {
                                self.index.remove(k);
                            }
                            Some(i) => {
                                match around(vol, table, v) {
                                    Some(a) => self.arena[i as usize] = a,
                                    None => {
                                        // Its number stays allocated but unreachable.
                                        self.index.insert(k, ABSENT);
                                        self.arena[i as usize].clear();
                                    }
                                }
                                self.nbr_num[i as usize] = unresolved(&self.arena[i as usize]);
                            }
                        }
                    }
                }
            }
        }
    }
}

const UNRESOLVED: u32 = u32::MAX - 1;

/// Marks the neighbour numbers past a vertex's last, so that a search reads its degree where
/// it reads its neighbours (the first look at a vertex's [`Around`] is a miss of the cache).
const BEYOND: u32 = u32::MAX - 3;

/// A vertex's neighbour numbers before any is resolved: `UNRESOLVED`, then `BEYOND`.
fn unresolved(a: &Around) -> [u32; MAX_DEGREE] {
    std::array::from_fn(|k| if k < a.n() { UNRESOLVED } else { BEYOND })
}

/// Marks a vertex that is not on the surface.
const ABSENT: u32 = u32::MAX;

/// The vertex numbers of a graph by position, in blocks of 4 x 4 x 4 lattice points (each with
/// its three edges, the vertices): a search steps from a vertex to its neighbours, which mostly
/// lie in the same block, so a first look is a load from a block already in the cache, where a
/// hash table of every vertex missed the cache for nearly each one (about 58 ns a look on the
/// bunny CT, 14% of its `simplify --tau inf`).
///
/// ```text
///   key    x | y << 20 | z << 40 | axis << 60         (Vertex::key)
///   block  (x >> 2) | (y >> 2) << 20 | (z >> 2) << 40
///   slot   axis * 64 + (z & 3) * 16 + (y & 3) * 4 + (x & 3)
/// ```
struct VertexIndex {
    /// Each block's number, by its key.
    blocks: FastMap<u64, u32>,
    /// Each block's slots: a vertex number, [`ABSENT`], or [`UNSEEN`].
    slots: Vec<[u32; BLOCK_SLOTS]>,
    /// The block looked up last, and its number (lookups come in runs within one block).
    last: (u64, u32),
}

const BLOCK_SLOTS: usize = 3 * 64;

/// A slot no lookup has filled yet.
const UNSEEN: u32 = u32::MAX - 2;

/// No block has this key (a key's top bits hold the axis, 0 to 2).
const NO_BLOCK: u64 = u64::MAX;

impl Default for VertexIndex {
    fn default() -> VertexIndex {
        VertexIndex {
            blocks: FastMap::default(),
            slots: Vec::new(),
            last: (NO_BLOCK, 0),
        }
    }
}

impl VertexIndex {
    /// The block key and slot of a vertex key.
    #[inline]
    fn place(k: u64) -> (u64, usize) {
        const LOW: u64 = 3 | 3 << 20 | 3 << 40;
        let block = (k & !LOW & !(0xF << 60)) >> 2;
        let (x, y, z) = (k & 3, (k >> 20) & 3, (k >> 40) & 3);
        (block, ((k >> 60) * 64 + z * 16 + y * 4 + x) as usize)
    }

    #[inline]
    fn block(&mut self, b: u64) -> Option<usize> {
        if self.last.0 != b {
            self.last = (b, *self.blocks.get(&b)?);
        }
        Some(self.last.1 as usize)
    }

    /// What was inserted for `k`: a vertex number or [`ABSENT`].
    #[inline]
    fn get(&mut self, k: u64) -> Option<u32> {
        let (b, slot) = VertexIndex::place(k);
        let n = self.block(b)?;
        let i = self.slots[n][slot];
        (i != UNSEEN).then_some(i)
    }

    fn insert(&mut self, k: u64, i: u32) {
        let (b, slot) = VertexIndex::place(k);
        let n = match self.block(b) {
            Some(n) => n,
            None => {
                let n = self.slots.len();
                self.slots.push([UNSEEN; BLOCK_SLOTS]);
                self.blocks.insert(b, n as u32);
                self.last = (b, n as u32);
                n
            }
        };
        self.slots[n][slot] = i;
    }

    fn remove(&mut self, k: u64) {
        let (b, slot) = VertexIndex::place(k);
        if let Some(n) = self.block(b) {
            self.slots[n][slot] = UNSEEN;
        }
    }

    fn clear(&mut self) {
        self.blocks.clear();
        self.slots.clear();
        self.last = (NO_BLOCK, 0);
    }
}

/// Which search reached a vertex (see [`Graph::last_search`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SearchMark(u32);

/// How a reachability search ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reach {
    /// As many targets as wanted were reached.
    Reached,
    /// The surface within the region ran out first.
    Exhausted,
    /// The budget of vertices ran out first: undecided.
    Budget,
}

impl<'a> Graph<'a> {
    /// An empty graph of `vol`'s surface: neighbourhoods are computed as searches reach them.
    pub fn new(vol: &'a MaskVolume, table: &'a [Case; 256]) -> Graph<'a> {
        Graph::with_cache(vol, table, GraphCache::default())
    }

    /// A graph over `vol` that starts from neighbourhoods computed earlier on the same volume.
    pub fn with_cache(vol: &'a MaskVolume, table: &'a [Case; 256], c: GraphCache) -> Graph<'a> {
        Graph {
            vol,
            table,
            index: c.index,
            arena: c.arena,
            verts: c.verts,
            nbr_num: c.nbr_num,
            scratch: c.scratch,
            budgets: c.budgets,
        }
    }

    /// Detaches the neighbourhoods from the volume.
    pub fn into_cache(self) -> GraphCache {
        GraphCache {
            index: self.index,
            arena: self.arena,
            verts: self.verts,
            nbr_num: self.nbr_num,
            scratch: self.scratch,
            budgets: self.budgets,
        }
    }

    /// Breadth-first search over the surface from `seeds`, within the region, until `want` of
    /// the distinct `targets` are reached (`None`: all of them), visiting at most `budget`
    /// vertices.
    pub fn reach(
        &mut self,
        seeds: &[Vertex],
        targets: &[Vertex],
        want: Option<usize>,
        region: &dyn Region,
        budget: usize,
    ) -> Reach {
        self.reach_targets(seeds, targets, want, region, budget).0
    }

    /// [`Graph::reach`], and the targets not reached (on the surface but not met).
    pub fn reach_targets(
        &mut self,
        seeds: &[Vertex],
        targets: &[Vertex],
        want: Option<usize>,
        region: &dyn Region,
        budget: usize,
    ) -> (Reach, Vec<Vertex>) {
        let gen = self.scratch.next_generation();
        self.scratch.next_region();
        let mut pending: FastMap<u32, ()> = FastMap::default();
        for &t in targets {
            if let Some(i) = self.index(t) {
                pending.insert(i, ());
            }
        }
        if pending.len()
            < targets
                .iter()
                .collect::<std::collections::HashSet<_>>()
                .len()
        {
            // A target that is not on the surface is never reached.
            return (Reach::Exhausted, Vec::new());
        }
        let want = want.unwrap_or(pending.len()).min(pending.len());
        let need_left = pending.len() - want;
        let mut queue = VecDeque::new();
        let visit =
            |g: &mut Graph, i: u32, queue: &mut VecDeque<u32>, pending: &mut FastMap<u32, ()>| {
                g.scratch.ensure(g.arena.len() + 1, 0);
                if g.scratch.states[i as usize].stamp != gen {
                    g.scratch.states[i as usize].stamp = gen;
                    pending.remove(&i);
                    queue.push_back(i);
                }
            };
        for &s in seeds {
            if let Some(i) = self.index(s) {
                visit(self, i, &mut queue, &mut pending);
            }
        }
        let mut visited = 0;
        let outcome = loop {
            if pending.len() <= need_left {
                break Reach::Reached;
            }
            let Some(i) = queue.pop_front() else {
                break Reach::Exhausted;
            };
            visited += 1;
            if visited > budget {
                break Reach::Budget;
            }
            for (_, j) in self.steps(region, i) {
                visit(self, j, &mut queue, &mut pending);
            }
        };
        let left = pending.keys().map(|&i| self.vertex(i)).collect();
        (outcome, left)
    }

    /// The mark of the last [`Graph::reach_targets`] search: [`Graph::meets`] tells whether
    /// another search steps onto a vertex it reached.
    pub fn last_search(&self) -> SearchMark {
        SearchMark(self.scratch.generation)
    }

    /// Breadth-first search from `seed` within the region until it steps onto a vertex the
    /// search `met` reached (`Reached`: the two are joined), visiting at most `budget`
    /// vertices. Searched from both ends, two vertices far apart are found joined when the two
    /// searches meet half way, where one search from one end goes all the way. The vertices
    /// `met` reached keep its mark, so several searches may meet it in turn.
    pub fn meets(
        &mut self,
        seed: Vertex,
        met: SearchMark,
        region: &dyn Region,
        budget: usize,
    ) -> Reach {
        let Some(s) = self.index(seed) else {
            return Reach::Exhausted;
        };
        let gen = self.scratch.next_generation();
        if gen <= met.0 {
            // The stamps wrapped round since `met`: its marks are gone.
            return Reach::Budget;
        }
        self.scratch.next_region();
        let mut queue = VecDeque::from([s]);
        self.scratch.ensure(s as usize + 1, 0);
        if self.scratch.states[s as usize].stamp == met.0 {
            return Reach::Reached;
        }
        self.scratch.states[s as usize].stamp = gen;
        let mut visited = 0;
        while let Some(i) = queue.pop_front() {
            visited += 1;
            if visited > budget {
                return Reach::Budget;
            }
            for (_, j) in self.steps(region, i) {
                self.scratch.ensure(self.arena.len() + 1, 0);
                let stamp = &mut self.scratch.states[j as usize].stamp;
                if *stamp == met.0 {
                    return Reach::Reached;
                }
                if *stamp != gen {
                    *stamp = gen;
                    queue.push_back(j);
                }
            }
        }
        Reach::Exhausted
    }

    /// Number of `v` (computing its neighbourhood the first time), or `None` if no surface
    /// crosses that edge.
    #[inline]
    pub fn index(&mut self, v: Vertex) -> Option<u32> {
        let k = key(v);
        if let Some(i) = self.index.get(k) {
            return (i != ABSENT).then_some(i);
        }
        let i = match around(self.vol, self.table, v) {
            Some(a) => {
                self.nbr_num.push(unresolved(&a));
                self.arena.push(a);
                self.verts.push(k);
                self.arena.len() as u32 - 1
            }
            None => ABSENT,
        };
        self.index.insert(k, i);
        (i != ABSENT).then_some(i)
    }

    #[inline]
    /// The neighbourhood of vertex number `i`.
    pub fn at(&self, i: u32) -> &Around {
        &self.arena[i as usize]
    }

    #[inline]
    /// The vertex numbered `i`.
    pub fn vertex(&self, i: u32) -> Vertex {
        Vertex::from_key(self.verts[i as usize])
    }

    /// Vertices numbered so far.
    pub fn len(&self) -> usize {
        self.arena.len()
    }

    /// Whether no vertex is numbered.
    pub fn is_empty(&self) -> bool {
        self.arena.is_empty()
    }

    /// Forgets every neighbourhood (to bound memory between searches).
    pub fn clear(&mut self) {
        self.index.clear();
        self.arena.clear();
        self.verts.clear();
        self.nbr_num.clear();
        self.scratch = Scratch::default();
    }

    /// A copy of `v`'s neighbourhood.
    pub fn around(&mut self, v: Vertex) -> Option<Around> {
        self.index(v).map(|i| self.arena[i as usize])
    }

    /// Number of the `k`-th neighbour of vertex `i`.
    #[inline]
    fn neighbour(&mut self, i: u32, k: usize) -> Option<u32> {
        let cached = self.nbr_num[i as usize][k];
        if cached != UNRESOLVED {
            return (cached != ABSENT).then_some(cached);
        }
        let w = self.arena[i as usize].nbr(k);
        let n = self.index(w);
        self.nbr_num[i as usize][k] = n.unwrap_or(ABSENT);
        n
    }

    /// Bit k set: the edge to neighbour k is usable in the region (cached per region
    /// generation, so the many searches of one loop ask the region once per vertex). Where the
    /// region allows all, every bit is set, those past the vertex's degree too.
    #[inline]
    fn usable_mask(&mut self, region: &dyn Region, i: u32) -> u16 {
        if region.allows_all() {
            return u16::MAX;
        }
        let sc = &mut self.scratch;
        if sc.usable_stamp.len() <= i as usize {
            let n = (i as usize + 1).next_power_of_two();
            sc.usable_stamp.resize(n, 0);
            sc.usable_mask.resize(n, 0);
        }
        if sc.usable_stamp[i as usize] == sc.region_generation {
            return sc.usable_mask[i as usize];
        }
        let a = &self.arena[i as usize];
        let mut m = 0u16;
        for k in 0..a.n() {
            if usable(region, a, k) {
                m |= 1 << k;
            }
        }
        sc.usable_stamp[i as usize] = sc.region_generation;
        sc.usable_mask[i as usize] = m;
        m
    }
}

impl Graph<'_> {
    /// The steps a search may take from vertex `i` within the region: (k, number of neighbour
    /// k), k increasing. Resolving neighbours may number new vertices, so a caller sizes its
    /// state arrays after this.
    #[inline]
    fn steps(&mut self, region: &dyn Region, i: u32) -> Steps {
        let mask = self.usable_mask(region, i);
        let mut out = Steps {
            k: [0; MAX_DEGREE],
            w: [0; MAX_DEGREE],
            n: 0,
            at: 0,
        };
        for k in 0..MAX_DEGREE {
            let cached = self.nbr_num[i as usize][k];
            if cached == BEYOND {
                break;
            }
            if (mask >> k) & 1 == 1 {
                if let Some(w) = self.neighbour(i, k) {
                    out.k[out.n as usize] = k as u8;
                    out.w[out.n as usize] = w;
                    out.n += 1;
                }
            }
        }
        out
    }
}

/// The steps from one vertex (see [`Graph::steps`]), packed small: searches take millions.
struct Steps {
    k: [u8; MAX_DEGREE],
    w: [u32; MAX_DEGREE],
    n: u8,
    at: u8,
}

impl Iterator for Steps {
    type Item = (usize, u32);

    #[inline]
    fn next(&mut self) -> Option<(usize, u32)> {
        (self.at < self.n).then(|| {
            let j = self.at as usize;
            self.at += 1;
            (self.k[j] as usize, self.w[j])
        })
    }
}

/// Which pieces the loop may use. A segment is usable when a piece on either side of it is (so
/// a region's boundary curves are usable), a vertex when one of its pieces is.
pub trait Region {
    /// Whether the loop may use piece `p`.
    fn allows(&self, p: &PieceRef) -> bool;

    /// Whether every piece is allowed (then the searches ask nothing of each edge).
    fn allows_all(&self) -> bool {
        false
    }
}

/// Every piece.
pub struct Everywhere;
impl Region for Everywhere {
    fn allows(&self, _: &PieceRef) -> bool {
        true
    }

    fn allows_all(&self) -> bool {
        true
    }
}

/// Pieces in cubes whose lower corner lies in a box (inclusive), and optionally further filtered.
pub struct InBox<F: Fn(&PieceRef) -> bool> {
    /// The box's lowest cube.
    pub lo: [i64; 3],
    /// The box's highest cube.
    pub hi: [i64; 3],
    /// Which of the pieces in the box are allowed.
    pub filter: F,
}

impl InBox<fn(&PieceRef) -> bool> {
    /// Every piece of the cubes `lo ..= hi`.
    pub fn cubes(lo: [i64; 3], hi: [i64; 3]) -> Self {
        InBox {
            lo,
            hi,
            filter: |_| true,
        }
    }
}

impl<F: Fn(&PieceRef) -> bool> InBox<F> {
    /// Is the cube with lower corner `q` in the box?
    pub fn holds_cube(&self, q: [i64; 3]) -> bool {
        (0..3).all(|k| self.lo[k] <= q[k] && q[k] <= self.hi[k])
    }
}

impl<F: Fn(&PieceRef) -> bool> Region for InBox<F> {
    fn allows(&self, p: &PieceRef) -> bool {
        self.holds_cube(p.cube) && (self.filter)(p)
    }
}

/// An explicit set of pieces (by cube and piece index; every part of a tube).
#[derive(Default)]
pub struct PieceSet(pub FastMap<([i64; 3], u8), ()>);

impl PieceSet {
    /// Allows the piece `index` of the cube at `cube`.
    pub fn insert(&mut self, cube: [i64; 3], index: u8) {
        self.0.insert((cube, index), ());
    }
}

impl Region for PieceSet {
    fn allows(&self, p: &PieceRef) -> bool {
        self.0.contains_key(&(p.cube, p.index))
    }
}

/// Most curves a search can take parities against.
const MAX_CUTS: usize = 8;

/// States (vertex, parity) the multi-source phase of one search may visit: enough to close a
/// loop around any handle of a large volume.
pub const FIRST_BUDGET: usize = 1 << 22;

/// States the exact phase (one search per vertex of the cut) may visit before settling for the
/// best loop so far. Short loops, the ones that matter for simplification, are exact well within
/// it; loops of large handles (beyond about 50 edges) may come out a few edges longer than the
/// shortest.
pub const EXACT_BUDGET: usize = 1 << 22;

/// Reusable search state: per (vertex, parity) a stamp, a distance, a predecessor state and a
/// source; per vertex the curves' marks.
#[derive(Default)]
struct Scratch {
    generation: u32,
    mark_generation: u32,
    /// Per state, side by side: a search that reaches a state reads or writes them all, so
    /// one fetch from memory serves the four (they were four arrays).
    states: Vec<State>,
    /// Per vertex: stamp of the current curves, and the marks of each curve (bit k: neighbour k
    /// is on that curve's left).
    mark_stamp: Vec<u32>,
    marks: Vec<[u16; MAX_CUTS]>,
    /// Per vertex: which edges the current region allows.
    region_generation: u32,
    usable_stamp: Vec<u32>,
    usable_mask: Vec<u16>,
    /// The searches in millimetres.
    mm: weighted::MmScratch,
}

/// One state's entry in [`Scratch`].
#[derive(Clone, Copy, Default)]
struct State {
    /// Current when equal to the scratch's generation.
    stamp: u32,
    dist: u32,
    /// The state it was reached from (`u32::MAX` for a start).
    pred: u32,
    /// Which start it was reached from (multi-source searches).
    source: u32,
}

/// The next generation of a set of stamps (an entry is set in this generation when its stamp
/// equals the result); when the counter wraps, `clear` sets every stamp to 0 so none looks
/// current.
fn advance(generation: &mut u32, clear: impl FnOnce()) -> u32 {
    *generation = generation.wrapping_add(1);
    if *generation == 0 {
        clear();
        *generation = 1;
    }
    *generation
}

impl Scratch {
    /// A fresh stamp for the state arrays.
    fn next_generation(&mut self) -> u32 {
        let states = &mut self.states;
        advance(&mut self.generation, || {
            states.iter_mut().for_each(|x| x.stamp = 0)
        })
    }

    /// A new region: forget which edges were usable.
    fn next_region(&mut self) {
        let stamps = &mut self.usable_stamp;
        advance(&mut self.region_generation, || stamps.fill(0));
    }

    /// A fresh stamp for the marks of a new set of curves.
    fn next_mark_generation(&mut self) -> u32 {
        let stamps = &mut self.mark_stamp;
        advance(&mut self.mark_generation, || stamps.fill(0))
    }

    fn ensure(&mut self, states: usize, vertices: usize) {
        if self.states.len() < states {
            self.states
                .resize(states.next_power_of_two(), State::default());
        }
        if self.mark_stamp.len() < vertices {
            let n = vertices.next_power_of_two();
            self.mark_stamp.resize(n, 0);
            self.marks.resize(n, [0; MAX_CUTS]);
        }
    }
}

/// The curves of one search: `bits` parity bits, state = (vertex number << bits) | parity. Their
/// marks are in the graph's scratch, stamped `mark_generation`.
struct Curves {
    bits: u32,
    mark_generation: u32,
}

impl Curves {
    /// Marks, for each vertex of each closed curve, which of its neighbours lie on its left.
    fn new(g: &mut Graph, cut: &[Vertex], even: &[&[Vertex]]) -> Option<Curves> {
        let all: Vec<&[Vertex]> = std::iter::once(cut).chain(even.iter().copied()).collect();
        if all.len() > MAX_CUTS {
            return None;
        }
        // Number every vertex first (numbering may grow the arena).
        let mut nums: Vec<Vec<u32>> = Vec::with_capacity(all.len());
        for c in &all {
            nums.push(
                c.iter()
                    .map(|&v| g.index(v))
                    .collect::<Option<Vec<u32>>>()?,
            );
        }
        let gen = g.scratch.next_mark_generation();
        let n = g.arena.len();
        g.scratch.ensure(0, n);
        for (c, (curve, num)) in all.iter().zip(&nums).enumerate() {
            let len = curve.len();
            for i in 0..len {
                let (prev, next) = (curve[(i + len - 1) % len], curve[(i + 1) % len]);
                let vi = num[i];
                let a = g.at(vi);
                let ip = a.position(prev)?;
                let inx = a.position(next)?;
                let m = a.left_of(ip, inx);
                let sc = &mut g.scratch;
                if sc.mark_stamp[vi as usize] != gen {
                    sc.mark_stamp[vi as usize] = gen;
                    sc.marks[vi as usize] = [0; MAX_CUTS];
                }
                sc.marks[vi as usize][c] |= m;
            }
        }
        Some(Curves {
            bits: all.len() as u32,
            mark_generation: gen,
        })
    }

    /// Parity flips (bit per curve) of the edge from vertex `vi` to its neighbour `k`, `wi`.
    #[inline]
    fn flip(&self, g: &Graph, vi: u32, k: usize, wi: u32) -> u32 {
        let sc = &g.scratch;
        let mut f = 0u32;
        let v_on = sc.mark_stamp.get(vi as usize) == Some(&self.mark_generation);
        let w_on = sc.mark_stamp.get(wi as usize) == Some(&self.mark_generation);
        if !v_on && !w_on {
            return 0;
        }
        let back = if w_on {
            g.at(wi).position(g.vertex(vi))
        } else {
            None
        };
        for c in 0..self.bits as usize {
            let mut b = v_on && (sc.marks[vi as usize][c] >> k) & 1 == 1;
            if let Some(j) = back {
                b ^= (sc.marks[wi as usize][c] >> j) & 1 == 1;
            }
            f |= (b as u32) << c;
        }
        f
    }

    /// Parity flips of the edge v–w (neighbours).
    fn edge_flip(&self, g: &mut Graph, v: Vertex, w: Vertex) -> u32 {
        let (Some(vi), Some(wi)) = (g.index(v), g.index(w)) else {
            return 0;
        };
        let k = g.at(vi).position(w).unwrap_or(0);
        self.flip(g, vi, k, wi)
    }
}

/// Is the edge to neighbour `k` of `a` usable in the region?
#[inline]
fn usable(region: &dyn Region, a: &Around, k: usize) -> bool {
    let (l, r) = a.sides(k);
    region.allows(&l) || region.allows(&r)
}

/// Reduces a closed walk with parity `goal` to a simple cycle with the same parity: where a
/// vertex repeats, the walk splits into two closed walks, one of which has the wanted parity
/// and is shorter.
fn simple_cycle(g: &mut Graph, curves: &Curves, mut walk: Vec<Vertex>, goal: u32) -> Vec<Vertex> {
    loop {
        let mut first: FastMap<u64, usize> = FastMap::default();
        let mut split = None;
        for (j, v) in walk.iter().enumerate() {
            if let Some(&i) = first.get(&key(*v)) {
                split = Some((i, j));
                break;
            }
            first.insert(key(*v), j);
        }
        let Some((i, j)) = split else { return walk };
        let inner: Vec<Vertex> = walk[i..j].to_vec();
        let parity = |g: &mut Graph, w: &[Vertex]| {
            (0..w.len()).fold(0u32, |p, k| {
                p ^ curves.edge_flip(g, w[k], w[(k + 1) % w.len()])
            })
        };
        walk = if parity(g, &inner) == goal {
            inner
        } else {
            let mut outer = walk[j..].to_vec();
            outer.extend_from_slice(&walk[..i]);
            outer
        };
    }
}

/// The answer of a search for the shortest loop crossing a curve an odd number of times.
#[derive(Clone, Debug, Default)]
pub struct OddLoop {
    /// The loop found, as its vertices in order: the shortest one shorter than the limit when
    /// `exact`, else the best one the budgets allowed.
    pub found: Option<Vec<Vertex>>,
    /// Is the answer certain: `found` is a shortest such loop, or (`None`) no loop crossing the
    /// curve an odd number of times is shorter than the limit?
    pub exact: bool,
}

impl OddLoop {
    /// Is it certain that no such loop is shorter than the limit?
    pub fn none_below(&self) -> bool {
        self.exact && self.found.is_none()
    }
}

/// The shortest loop through the region that crosses `cut` an odd number of times, if one is
/// shorter than `limit` edges (see [`odd_loop_with_parities`]).
pub fn odd_loop(g: &mut Graph, cut: &[Vertex], region: &dyn Region, limit: usize) -> OddLoop {
    odd_loop_with_parities(g, cut, &[], region, limit)
}

/// The shortest loop that crosses `cut` an odd number of times: [`odd_loop`] with no limit,
/// `None` if there is none or the budgets ran out first.
pub fn shortest_odd_loop(
    g: &mut Graph,
    cut: &[Vertex],
    region: &dyn Region,
    limit: usize,
) -> Option<Vec<Vertex>> {
    odd_loop(g, cut, region, limit).found
}

/// A loop crossing `cut` an odd number of times, found cheaply (the first that the search from
/// all of `cut` at once closes; at most half of `cut` longer than the shortest), or `None`.
pub fn any_odd_loop(g: &mut Graph, cut: &[Vertex], region: &dyn Region) -> Option<Vec<Vertex>> {
    any_odd_loop_below(g, cut, region, usize::MAX)
}

/// [`any_odd_loop`], searched only as deep as a loop shorter than `limit` edges needs: `None`
/// only when no loop crossing `cut` an odd number of times is shorter (or the budget ran out).
pub fn any_odd_loop_below(
    g: &mut Graph,
    cut: &[Vertex],
    region: &dyn Region,
    limit: usize,
) -> Option<Vec<Vertex>> {
    if cut.len() < 2 {
        return None;
    }
    let curves = Curves::new(g, cut, &[])?;
    g.scratch.next_region();
    let (first, _, _) = multi_source(g, &curves, cut, region, limit);
    first
        .map(|(walk, _)| simple_cycle(g, &curves, walk, 1))
        .filter(|walk| walk_in_region(g, region, walk))
}

/// The shortest loop through the region that crosses `cut` an odd number of times and each of
/// `even` an even number of times, shorter than `limit` edges.
///
/// A first breadth-first search from all of `cut` at once gives a loop (two paths from the cut
/// that meet with opposite parities, closed along `cut`) and so an upper bound, going half as
/// deep as that loop is long; then one search per vertex of `cut` that can carry
/// a shorter loop (near a vertex whose two states the first search reached early), each half
/// as deep as the best length so far, finds the shortest. Every search is bounded by the limit
/// and by a budget of states ([`FIRST_BUDGET`], [`EXACT_BUDGET`]); when a budget runs out first,
/// the answer says it is not exact.
pub fn odd_loop_with_parities(
    g: &mut Graph,
    cut: &[Vertex],
    even: &[&[Vertex]],
    region: &dyn Region,
    limit: usize,
) -> OddLoop {
    if cut.len() < 2 {
        return OddLoop {
            found: None,
            exact: true,
        };
    }
    let Some(curves) = Curves::new(g, cut, even) else {
        return OddLoop::default();
    };
    g.scratch.next_region();
    let goal: u32 = 1;
    let mut best: Option<Vec<Vertex>> = None;
    let mut best_len = limit;
    let mut sources: Vec<Vertex> = cut.to_vec();
    // Phase 1 (one curve only: closing along it must not change other parities).
    if even.is_empty() {
        let (first, conclusive, meets) = multi_source(g, &curves, cut, region, limit);
        if first.is_none() && conclusive {
            // Every state closer than `limit` was seen: no odd loop is that short.
            return OddLoop {
                found: None,
                exact: true,
            };
        }
        // Closed along `cut`, the walk may leave the region where the cut does: then it is no
        // answer, and every vertex of the cut is searched from.
        let first = first
            .map(|(walk, start)| (simple_cycle(g, &curves, walk, goal), start))
            .filter(|(walk, _)| walk_in_region(g, region, walk));
        if let Some((walk, start)) = first {
            if walk.len() < best_len {
                best_len = walk.len();
                best = Some(walk);
            }
            // Search from the loop's own start first: it finds a loop no longer than the bound.
            if let Some(p) = sources.iter().position(|&v| v == start) {
                sources.swap(0, p);
            }
            if let Some(meets) = meets {
                let near = near_short_loops(g, region, &meets, best_len);
                sources.retain(|&v| g.index(v).is_some_and(|i| near.contains_key(&i)));
            }
        }
    }
    let mut budget = g.budgets.exact;
    let mut exact = true;
    let mut tried: FastMap<u64, ()> = FastMap::default();
    for &s in &sources {
        if tried.insert(key(s), ()).is_some() {
            continue;
        }
        let Some(si) = g.index(s) else { continue };
        if g.usable_mask(region, si) == 0 {
            continue;
        }
        // Most sources have no loop shorter than the best so far: a search half as deep tells.
        let found = odd_length_through(g, &curves, region, si, goal, best_len, &mut budget);
        if budget == 0 {
            // This source's search (or a later one) was cut short.
            exact = false;
            break;
        }
        let Some((len, meeting)) = found else {
            continue;
        };
        // The loop itself as the full-depth search finds it (among equally short loops through
        // `s`, the same one whichever way the length was found); its meeting walk should that
        // search be cut short.
        let path = odd_path_through(g, &curves, region, si, goal, len).unwrap_or(meeting);
        let path = simple_cycle(g, &curves, path, goal);
        best_len = path.len();
        best = Some(path);
    }
    OddLoop { found: best, exact }
}

/// Starts a breadth-first search of the double cover at state (si, 0): a fresh generation of
/// stamps, the start stamped 0 deep. Returns the generation and the start state.
fn start_at(g: &mut Graph, bits: u32, si: u32) -> (u32, u32) {
    let gen = g.scratch.next_generation();
    g.scratch.ensure((g.arena.len() + 1) << bits, 0);
    let start = si << bits;
    g.scratch.states[start as usize].stamp = gen;
    g.scratch.states[start as usize].dist = 0;
    g.scratch.states[start as usize].pred = u32::MAX;
    (gen, start)
}

/// One step of a breadth-first search of the double cover: the states next to `st` within the
/// region and not yet stamped `gen` are stamped one deeper, with `st` as their predecessor, and
/// returned (the first `n` of the array).
fn expand(
    g: &mut Graph,
    curves: &Curves,
    region: &dyn Region,
    st: u32,
    gen: u32,
) -> ([u32; MAX_DEGREE], usize) {
    let bits = curves.bits;
    let (vi, par) = (st >> bits, st & ((1 << bits) - 1));
    let steps = g.steps(region, vi);
    g.scratch
        .ensure((g.arena.len() + 1) << bits, g.arena.len() + 1);
    let d = g.scratch.states[st as usize].dist;
    let (mut out, mut n) = ([0u32; MAX_DEGREE], 0);
    for (k, wi) in steps {
        let ns = (wi << bits) | (par ^ curves.flip(g, vi, k, wi));
        let sc = &mut g.scratch;
        if sc.states[ns as usize].stamp == gen {
            continue;
        }
        sc.states[ns as usize].stamp = gen;
        sc.states[ns as usize].dist = d + 1;
        sc.states[ns as usize].pred = st;
        out[n] = ns;
        n += 1;
    }
    (out, n)
}

/// Length of the shortest loop through vertex `si` whose parities are `goal`, if shorter than
/// `below`, with one such loop as a closed walk. Such a loop of length L shows as the two states
/// (v, p) and (v, p ^ goal) of its middle vertex v, both within ceil(L / 2) of (s, 0) — the
/// second half, run backwards and with its parities flipped by `goal`, is a path from (s, 0)
/// too — so a breadth-first search from (s, 0) need only go half as deep as the loop is long:
/// a quarter of the states on a surface.
///
/// ```text
///    (s,0) ~~~~~~> (v,p)          the loop: s ~> v, then back from v to s
///    (s,0) ~~~~~~> (v,p^goal)     along the second path, mirrored
/// ```
///
/// Each state visited is taken from `budget`; running out gives `None`.
fn odd_length_through(
    g: &mut Graph,
    curves: &Curves,
    region: &dyn Region,
    si: u32,
    goal: u32,
    below: usize,
    budget: &mut usize,
) -> Option<(usize, Vec<Vertex>)> {
    let bits = curves.bits;
    let (gen, start) = start_at(g, bits, si);
    let mut queue = VecDeque::from([start]);
    // Deepest level that can hold the middle of a loop shorter than `below`.
    let half = below.saturating_sub(1).div_ceil(2);
    // (length, the two meeting states)
    let mut best: Option<(usize, u32, u32)> = None;
    while let Some(st) = queue.pop_front() {
        let d = g.scratch.states[st as usize].dist as usize;
        // States found from here on are d + 1 deep: pairs they close are no shorter.
        if d + 1 > half || best.is_some_and(|b| d + 1 >= b.0) {
            break;
        }
        if *budget == 0 {
            return None;
        }
        *budget -= 1;
        let (reached, n) = expand(g, curves, region, st, gen);
        for &ns in &reached[..n] {
            let (sc, other) = (&g.scratch, ns ^ goal);
            if sc.states[other as usize].stamp == gen {
                let len = d + 1 + sc.states[other as usize].dist as usize;
                if len < below && best.is_none_or(|b| len < b.0) {
                    best = Some((len, ns, other));
                }
            }
            queue.push_back(ns);
        }
    }
    let (len, end, other) = best?;
    // s … v, then back along the other state's path to just after s.
    let mut walk = states_to(g, end, bits);
    let mut back = states_to(g, other, bits);
    back.pop(); // v
    back.reverse();
    back.pop(); // s
    walk.extend(back);
    if walk.len() > 1 && walk.first() == walk.last() {
        walk.pop(); // v was s: (s, goal) itself was reached
    }
    Some((len, walk))
}

/// The path of a breadth-first search from (s, 0) to (s, goal), known to be `len` long, as a
/// closed walk ending at `s`; `None` if it takes more than [`EXACT_BUDGET`] states.
fn odd_path_through(
    g: &mut Graph,
    curves: &Curves,
    region: &dyn Region,
    si: u32,
    goal: u32,
    len: usize,
) -> Option<Vec<Vertex>> {
    let bits = curves.bits;
    let (gen, start) = start_at(g, bits, si);
    let target = start | goal;
    let mut queue = VecDeque::from([start]);
    let mut budget = g.budgets.exact;
    'bfs: loop {
        let st = queue.pop_front()?;
        if g.scratch.states[st as usize].dist as usize >= len || budget == 0 {
            return None;
        }
        budget -= 1;
        let (reached, n) = expand(g, curves, region, st, gen);
        for &ns in &reached[..n] {
            if ns == target {
                break 'bfs;
            }
            queue.push_back(ns);
        }
    }
    // Walk back from (s, goal) to (s, 0): s last.
    let mut path = states_to(g, target, bits);
    path.remove(0);
    Some(path)
}

/// The vertices of the search path that ends in state `st` (`bits` parity bits), its source
/// first.
fn states_to(g: &Graph, mut st: u32, bits: u32) -> Vec<Vertex> {
    let mut path = Vec::new();
    while st != u32::MAX {
        path.push(g.vertex(st >> bits));
        st = g.scratch.states[st as usize].pred;
    }
    path.reverse();
    path
}

/// The vertices within reach of a loop shorter than `below` through them (with their distance
/// from the nearest meet), given the `meets` of
/// the first phase: a vertex `s` of the cut has such a loop only if its middle vertex `v`, at
/// most (below - 1) / 2 edges from `s`, has both states closer to the cut than the loop is
/// long together (each half of the loop is a path from the cut). Most of a long cut is far from
/// every such `v`, and its vertices need no search of their own.
///
/// ```text
///      s ~~~~~~~~~ v          v: (v, 0) and (v, 1) both near the cut
///      |           |             (sum of their distances < below)
///  ----s--- cut ---------     s: within (below - 1) / 2 of some v
/// ```
fn near_short_loops(
    g: &mut Graph,
    region: &dyn Region,
    meets: &[(u32, usize)],
    below: usize,
) -> FastMap<u32, u32> {
    let reach = (below.saturating_sub(1) / 2) as u32;
    let mut near: FastMap<u32, u32> = FastMap::default();
    let mut queue = VecDeque::new();
    for &(v, sum) in meets {
        if sum < below && near.insert(v, 0).is_none() {
            queue.push_back(v);
        }
    }
    while let Some(v) = queue.pop_front() {
        let d = near[&v];
        if d == reach {
            continue;
        }
        for (_, w) in g.steps(region, v) {
            if let std::collections::hash_map::Entry::Vacant(e) = near.entry(w) {
                e.insert(d + 1);
                queue.push_back(w);
            }
        }
    }
    near
}

/// Breadth-first search from every vertex of `cut` at once, each state remembering its source.
/// A vertex whose two states are both reached closes a loop: the path from one source to it,
/// back to the other source (crossing `cut` an odd number of times in all), then along `cut` to
/// where it started. Returns the shortest such walk found (not yet simple) and its start, and
/// whether the search was conclusive (it did not run out of budget): then no walk means that no
/// loop crossing `cut` an odd number of times is shorter than `limit`.
///
/// ```text
///   src_a ~~~~~~~> v <~~~~~~~ src_b      (v, 0) reached from src_a, (v, 1) from src_b:
///     |                         |        both halves of a loop meet in its middle, so the
///   --+---------- cut ----------+--      search goes half as deep as the loop is long
/// ```
///
/// A loop of length `L` through a vertex `s` of `cut` has a middle vertex whose two states are
/// each at most `ceil(L / 2)` from `s`: the search stops at that depth for the best walk so far
/// (or `limit`), having seen every pair of states that a shorter loop makes meet.
///
/// When conclusive and a walk was found, also returns every vertex whose two states were both
/// reached, with the sum of their distances (see [`near_short_loops`]).
type FirstWalk = Option<(Vec<Vertex>, Vertex)>;
type Meets = Option<Vec<(u32, usize)>>;
fn multi_source(
    g: &mut Graph,
    curves: &Curves,
    cut: &[Vertex],
    region: &dyn Region,
    limit: usize,
) -> (FirstWalk, bool, Meets) {
    let n = cut.len();
    let Some(nums) = cut
        .iter()
        .map(|&v| g.index(v))
        .collect::<Option<Vec<u32>>>()
    else {
        return (None, false, None);
    };
    let gen = g.scratch.next_generation();
    g.scratch.ensure((g.arena.len() + 1) << 1, 0);
    let mut queue: VecDeque<u32> = VecDeque::new();
    // Every state reached, for the meets.
    let mut seen: Vec<u32> = Vec::new();
    let mut best: Option<(usize, u32, u32)> = None; // (length, the two meeting states)
    let along = |a: usize, b: usize| {
        let d = a.abs_diff(b);
        d.min(n - d)
    };
    for (i, &vi) in nums.iter().enumerate() {
        let st = vi << 1;
        let sc = &mut g.scratch;
        if sc.states[st as usize].stamp != gen {
            sc.states[st as usize].stamp = gen;
            sc.states[st as usize].dist = 0;
            sc.states[st as usize].pred = u32::MAX;
            sc.states[st as usize].source = i as u32;
            queue.push_back(st);
            seen.push(st);
        }
    }
    // Deepest level that can hold the middle of a loop shorter than `below`.
    let half = |below: usize| below.saturating_sub(1).div_ceil(2);
    let mut budget = g.budgets.first;
    while let Some(st) = queue.pop_front() {
        let (d, src) = (
            g.scratch.states[st as usize].dist,
            g.scratch.states[st as usize].source,
        );
        let below = best.map_or(limit, |b| b.0.min(limit));
        if d as usize + 1 > half(below) || budget == 0 {
            break;
        }
        budget -= 1;
        let (reached, k) = expand(g, curves, region, st, gen);
        // Sources first: a state's partner may be among the states just reached.
        for &ns in &reached[..k] {
            g.scratch.states[ns as usize].source = src;
        }
        for &ns in &reached[..k] {
            let sc = &g.scratch;
            let other = ns ^ 1;
            if sc.states[other as usize].stamp == gen {
                let far = sc.states[other as usize].source as usize;
                let total = d as usize + 1 + sc.states[other as usize].dist as usize;
                let total = total + along(src as usize, far);
                if best.is_none_or(|b| total < b.0) {
                    best = Some((total, ns, other));
                }
            }
            queue.push_back(ns);
            seen.push(ns);
        }
    }
    let conclusive = budget > 0;
    let Some((_, end, other)) = best else {
        return (None, conclusive, None);
    };
    let sc = &g.scratch;
    let meets = conclusive.then(|| {
        seen.iter()
            .filter(|&&st| st & 1 == 0 && sc.states[(st | 1) as usize].stamp == gen)
            .map(|&st| {
                let sum = sc.states[st as usize].dist + sc.states[(st | 1) as usize].dist;
                (st >> 1, sum as usize)
            })
            .collect()
    });
    (Some(meeting_walk(g, cut, end, other)), conclusive, meets)
}

/// The closed walk of [`multi_source`] through the meeting states `end` and `other` (the two
/// states of one vertex), and its start: from `end`'s source to the meeting vertex, back to
/// `other`'s source, then along the cut, the shorter way, to the start (nothing when the two
/// sources are one).
fn meeting_walk(g: &Graph, cut: &[Vertex], end: u32, other: u32) -> (Vec<Vertex>, Vertex) {
    let n = cut.len();
    let sc = &g.scratch;
    let (a, b) = (
        sc.states[end as usize].source as usize,
        sc.states[other as usize].source as usize,
    );
    let mut walk = states_to(g, end, 1);
    let mut back = states_to(g, other, 1);
    back.pop(); // the meeting vertex
    back.reverse();
    walk.extend(back);
    if a == b {
        walk.pop();
    } else {
        let forward = (a + n - b) % n; // steps from b forward to a
        let step = if forward <= n - forward { 1 } else { -1 };
        push_along_cut(&mut walk, cut, b, a, step);
    }
    (walk, cut[a])
}

/// Closes a walk along `cut`: the cut's vertices strictly between positions `from` and `to`,
/// stepping `step` (1 or -1) from `from`.
fn push_along_cut(walk: &mut Vec<Vertex>, cut: &[Vertex], from: usize, to: usize, step: isize) {
    let n = cut.len() as isize;
    let mut i = from as isize;
    loop {
        i = (i + step).rem_euclid(n);
        if i as usize == to {
            break;
        }
        walk.push(cut[i as usize]);
    }
}

/// The shortest path within the region from `from` to a vertex `is_target` accepts (`from`
/// first, the target last), visiting at most `budget` vertices.
pub fn path_to(
    g: &mut Graph,
    from: Vertex,
    region: &dyn Region,
    is_target: &mut dyn FnMut(&mut Graph, u32) -> bool,
    budget: usize,
) -> Option<Vec<Vertex>> {
    g.scratch.next_region();
    let si = g.index(from)?;
    let gen = g.scratch.next_generation();
    g.scratch.ensure(g.arena.len() + 1, 0);
    g.scratch.states[si as usize].stamp = gen;
    g.scratch.states[si as usize].pred = u32::MAX;
    let mut queue = VecDeque::from([si]);
    let mut visited = 0;
    let end = 'bfs: loop {
        let vi = queue.pop_front()?;
        if is_target(g, vi) {
            break 'bfs vi;
        }
        visited += 1;
        if visited > budget {
            return None;
        }
        let steps = g.steps(region, vi);
        g.scratch.ensure(g.arena.len() + 1, 0);
        for (_, wi) in steps {
            let sc = &mut g.scratch;
            if sc.states[wi as usize].stamp != gen {
                sc.states[wi as usize].stamp = gen;
                sc.states[wi as usize].pred = vi;
                queue.push_back(wi);
            }
        }
    };
    let mut path = Vec::new();
    let mut i = end;
    while i != u32::MAX {
        path.push(g.vertex(i));
        i = g.scratch.states[i as usize].pred;
    }
    path.reverse();
    Some(path)
}

/// Reduces a closed walk that crosses `cut` an odd number of times to a simple loop that still
/// does; `None` if the walk crosses it an even number of times (or is not on the surface).
pub fn odd_simple_loop(g: &mut Graph, cut: &[Vertex], walk: Vec<Vertex>) -> Option<Vec<Vertex>> {
    let curves = Curves::new(g, cut, &[])?;
    let n = walk.len();
    let mut parity = 0;
    for k in 0..n {
        let (v, w) = (walk[k], walk[(k + 1) % n]);
        let a = g.around(v)?;
        a.position(w)?;
        parity ^= curves.edge_flip(g, v, w);
    }
    (parity == 1).then(|| simple_cycle(g, &curves, walk, 1))
}

/// Is every edge of the closed walk usable in the region?
fn walk_in_region(g: &mut Graph, region: &dyn Region, walk: &[Vertex]) -> bool {
    let n = walk.len();
    (0..n).all(|k| {
        g.around(walk[k]).is_some_and(|a| {
            a.position(walk[(k + 1) % n])
                .is_some_and(|j| usable(region, &a, j))
        })
    })
}

/// Is `lp` a closed walk on the surface: every vertex a crossing point, each next to the one
/// before it (and the last to the first)?
pub fn is_closed_walk(g: &mut Graph, lp: &[Vertex]) -> bool {
    let n = lp.len();
    n >= 3
        && (0..n).all(|k| {
            g.around(lp[k])
                .is_some_and(|a| a.position(lp[(k + 1) % n]).is_some())
        })
}

/// Parity of the number of times the closed walk `a` crosses the closed curve `b` (both on the
/// surface; `None` if either is not).
pub fn crossing_parity(g: &mut Graph, a: &[Vertex], b: &[Vertex]) -> Option<u32> {
    if !is_closed_walk(g, a) || !is_closed_walk(g, b) {
        return None;
    }
    let curves = Curves::new(g, b, &[])?;
    let n = a.len();
    Some((0..n).fold(0, |p, k| p ^ curves.edge_flip(g, a[k], a[(k + 1) % n])))
}

/// Is the loop non-separating on the surface (within the region)? It is exactly when, starting
/// on one side of it at one of its vertices, the other side of that vertex can be reached
/// without crossing it: one search of the double cover.
pub fn is_nonseparating(g: &mut Graph, lp: &[Vertex], region: &dyn Region) -> bool {
    let Some(curves) = Curves::new(g, lp, &[]) else {
        return false;
    };
    g.scratch.next_region();
    let Some(si) = g.index(lp[0]) else {
        return false;
    };
    let gen = g.scratch.next_generation();
    g.scratch.ensure((g.arena.len() + 1) << 1, 0);
    let (start, target) = (si << 1, (si << 1) | 1);
    g.scratch.states[start as usize].stamp = gen;
    let mut stack = vec![start];
    while let Some(st) = stack.pop() {
        let (vi, par) = (st >> 1, st & 1);
        let steps = g.steps(region, vi);
        g.scratch
            .ensure((g.arena.len() + 1) << 1, g.arena.len() + 1);
        for (k, wi) in steps {
            let ns = (wi << 1) | (par ^ curves.flip(g, vi, k, wi));
            if ns == target {
                return true;
            }
            if g.scratch.states[ns as usize].stamp != gen {
                g.scratch.states[ns as usize].stamp = gen;
                stack.push(ns);
            }
        }
    }
    false
}

/// The contour through `start` (a crossing on an edge lying in plane `w`), as its vertices in
/// order: walk along the neighbours that stay in the plane. The neighbourhoods are computed, not
/// numbered in the graph: a tall cycle's contours would fill it with vertices no search visits.
pub(crate) fn walk_contour(g: &Graph, start: Vertex, w: i64) -> Option<Vec<Vertex>> {
    let in_plane = |x: &Vertex| x.axis != 2 && x.p[2] == w;
    let mut out = vec![start];
    let mut prev = start;
    let mut cur = start;
    loop {
        let a = crate::surface::around(g.vol, g.table, cur)?;
        // Along segments in the plane (never a diagonal through a tube).
        let next = (0..a.n())
            .filter(|&k| !a.diagonal(k))
            .map(|k| a.nbr(k))
            .find(|x| in_plane(x) && *x != prev)?;
        if next == start {
            return Some(out);
        }
        if out.len() > 1 << 24 {
            return None;
        }
        out.push(next);
        prev = cur;
        cur = next;
    }
}

/// For the unit tests, on `test_shapes::torus(24, 7.0, 2.6)`: its outer equator (the contour
/// round the hole in plane 11) and the shortest loop crossing it once (a meridian, round the
/// tube).
#[cfg(test)]
pub(crate) fn torus_equator_and_meridian(g: &mut Graph) -> (Vec<Vertex>, Vec<Vertex>) {
    let start = (12..24)
        .rev()
        .map(|x| Vertex {
            p: [x, 12, 11],
            axis: 0,
        })
        .find(|&v| crate::surface::is_crossing(g.vol, v))
        .expect("the torus crosses row y 12 of plane 11");
    let equator = walk_contour(g, start, 11).expect("a contour");
    let meridian = shortest_odd_loop(g, &equator, &Everywhere, usize::MAX).expect("a meridian");
    (equator, meridian)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{Frame, MaskVolume};
    use crate::topology::cases::{cases, Connectivity};

    use crate::test_shapes::torus;

    /// The blocked vertex index answers as a hash map of keys does, through inserts, removals
    /// and clears, for vertices of all three axes packed close (one block, its neighbours) and
    /// far apart, at the coordinates' ends (-1, the 20-bit key's last) too.
    #[test]
    fn the_vertex_index_answers_as_a_map_of_keys() {
        let mut rng = crate::test_rng::Rng(0x9e37_79b9_7f4a_7c15);
        let mut index = VertexIndex::default();
        let mut oracle: std::collections::HashMap<u64, u32> = Default::default();
        let coordinate = |rng: &mut crate::test_rng::Rng| match rng.below(4) {
            0 => [-1, 0xF_FFFE][rng.below(2) as usize],
            1 => rng.below(8) as i64 - 1,
            _ => rng.below(40) as i64 + 1000,
        };
        for round in 0..40_000 {
            let v = Vertex {
                p: [0; 3].map(|_| coordinate(&mut rng)),
                axis: rng.below(3) as u8,
            };
            let k = v.key();
            match rng.below(8) {
                0 => {
                    index.remove(k);
                    oracle.remove(&k);
                }
                1..=3 => {
                    let i = [ABSENT, rng.below(1 << 20) as u32][rng.below(2) as usize];
                    index.insert(k, i);
                    oracle.insert(k, i);
                }
                _ => assert_eq!(index.get(k), oracle.get(&k).copied(), "{v:?}"),
            }
            if round == 20_000 {
                index.insert(k, 7);
                index.clear();
                oracle.clear();
                assert_eq!(index.get(k), None, "cleared, yet {v:?} is found");
            }
        }
        assert!(
            oracle.len() > 1_000,
            "the test filled too few keys: {}",
            oracle.len()
        );
        for (&k, &i) in &oracle {
            assert_eq!(index.get(k), Some(i), "{:?}", Vertex::from_key(k));
        }
    }

    /// The contour in plane `w` through the first crossing found along +x from the centre line.
    fn contour_from(g: &mut Graph, w: i64, start_x: i64, y: i64) -> Vec<Vertex> {
        let mut x = start_x;
        loop {
            let v = Vertex {
                p: [x, y, w],
                axis: 0,
            };
            if crate::surface::is_crossing(g.vol, v) {
                return walk_contour(g, v, w).unwrap();
            }
            x += 1;
        }
    }

    #[test]
    fn torus_loops_cross_each_other_once() {
        let vol = torus(24, 7.0, 2.6);
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            let t = cases(conn);
            let mut g = Graph::new(&vol, t);
            let mid = 11;
            // The inner equator (the contour around the hole in the middle plane): the shortest
            // loop crossing it once goes around the tube (a meridian), about 2πr long.
            let c = (24.0 - 1.0) / 2.0;
            let inner = contour_from(&mut g, mid, c as i64, c as i64);
            assert!(is_nonseparating(&mut g, &inner, &Everywhere));
            let meridian = shortest_odd_loop(&mut g, &inner, &Everywhere, usize::MAX).unwrap();
            let m = meridian.len() as f64;
            assert!(
                m > 2.0 * std::f64::consts::PI * 2.0 && m < 2.0 * std::f64::consts::PI * 3.6,
                "meridian length {m}"
            );
            // And the shortest loop crossing that meridian goes around the hole.
            let around_hole =
                shortest_odd_loop(&mut g, &meridian, &Everywhere, usize::MAX).unwrap();
            assert!(
                around_hole.len() as f64 > 2.0 * std::f64::consts::PI * (7.0 - 2.6),
                "{}",
                around_hole.len()
            );
        }
    }

    /// Length of the shortest odd loop through `s`: a plain breadth-first search of the double
    /// cover from (s, 0) to (s, 1), as the searches before the half-depth one did it.
    fn full_depth_length(g: &mut Graph, curves: &Curves, s: Vertex) -> Option<usize> {
        let si = g.index(s)?;
        let (start, target) = (si << 1, (si << 1) | 1);
        let mut dist: FastMap<u32, usize> = FastMap::default();
        dist.insert(start, 0);
        let mut queue = VecDeque::from([start]);
        while let Some(st) = queue.pop_front() {
            let d = dist[&st];
            let steps: Vec<(usize, u32)> = g.steps(&Everywhere, st >> 1).collect();
            for (k, wi) in steps {
                let ns = (wi << 1) | ((st & 1) ^ curves.flip(g, st >> 1, k, wi));
                if ns == target {
                    return Some(d + 1);
                }
                if let std::collections::hash_map::Entry::Vacant(e) = dist.entry(ns) {
                    e.insert(d + 1);
                    queue.push_back(ns);
                }
            }
        }
        None
    }

    #[test]
    fn half_depth_and_pruned_searches_find_the_full_searches_lengths() {
        let vol = torus(24, 7.0, 2.6);
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            let mut g = Graph::new(&vol, cases(conn));
            let c = (24.0 - 1.0) / 2.0;
            let inner = contour_from(&mut g, 11, c as i64, c as i64);
            let meridian = shortest_odd_loop(&mut g, &inner, &Everywhere, usize::MAX).unwrap();
            for cut in [&inner, &meridian] {
                let curves = Curves::new(&mut g, cut, &[]).unwrap();
                g.scratch.next_region();
                let mut least = usize::MAX;
                for &s in cut.iter() {
                    let full = full_depth_length(&mut g, &curves, s).unwrap();
                    least = least.min(full);
                    let si = g.index(s).unwrap();
                    let mut budget = usize::MAX;
                    let half = odd_length_through(
                        &mut g,
                        &curves,
                        &Everywhere,
                        si,
                        1,
                        usize::MAX,
                        &mut budget,
                    );
                    let (len, walk) = half.unwrap();
                    assert_eq!(len, full, "through {s:?}");
                    // Just deep enough for it.
                    let mut budget = usize::MAX;
                    let just = odd_length_through(
                        &mut g,
                        &curves,
                        &Everywhere,
                        si,
                        1,
                        full + 1,
                        &mut budget,
                    );
                    assert_eq!(just.map(|x| x.0), Some(full));
                    // The meeting walk is a closed walk of that length through s.
                    assert_eq!(walk.len(), len);
                    assert_eq!(walk[0], s);
                    // Nothing shorter than the loop itself.
                    let mut budget = usize::MAX;
                    let below =
                        odd_length_through(&mut g, &curves, &Everywhere, si, 1, full, &mut budget);
                    assert!(below.is_none());
                }
                // The search skipping the cut's far vertices still finds the shortest.
                let found = shortest_odd_loop(&mut g, cut, &Everywhere, usize::MAX).unwrap();
                assert_eq!(found.len(), least);
            }
        }
    }

    /// On random volumes (many small handles, loops of every length), the shortest odd loop
    /// across each contour, with and without a limit, has the length of the shortest of the
    /// full searches from every vertex of the contour.
    #[test]
    fn shortest_odd_loops_of_random_contours_match_the_full_searches() {
        let mut rng = crate::test_rng::Rng(0x2545_f491_4f6c_dd1d);
        let mut random = || rng.next_u64();
        let mut compared = 0;
        for round in 0..6 {
            let n = 14;
            let mut vol = MaskVolume::new([n, n, n], Frame::identity());
            for z in 1..n - 1 {
                for y in 1..n - 1 {
                    for x in 1..n - 1 {
                        vol.set(x, y, z, random() % 100 < 55);
                    }
                }
            }
            let conn = [Connectivity::Six, Connectivity::TwentySix][round % 2];
            let mut g = Graph::new(&vol, cases(conn));
            let mut seen: FastMap<u64, ()> = FastMap::default();
            for w in 2..n as i64 - 2 {
                for y in 1..n as i64 - 1 {
                    for x in 0..n as i64 {
                        let v = Vertex {
                            p: [x, y, w],
                            axis: 0,
                        };
                        if seen.contains_key(&key(v)) || !crate::surface::is_crossing(&vol, v) {
                            continue;
                        }
                        let cut = walk_contour(&g, v, w).unwrap();
                        for c in &cut {
                            seen.insert(key(*c), ());
                        }
                        if cut.len() < 4 {
                            continue;
                        }
                        let curves = Curves::new(&mut g, &cut, &[]).unwrap();
                        g.scratch.next_region();
                        let least = cut
                            .iter()
                            .filter_map(|&s| full_depth_length(&mut g, &curves, s))
                            .min();
                        for limit in [usize::MAX, 9] {
                            let found = shortest_odd_loop(&mut g, &cut, &Everywhere, limit)
                                .map(|l| l.len());
                            assert_eq!(found, least.filter(|&l| l < limit), "cut {cut:?}");
                        }
                        compared += 1;
                    }
                }
            }
        }
        assert!(compared > 100, "{compared} contours");
    }

    /// The bounded search for any loop crossing a curve oddly: on the torus, none when the
    /// limit is the meridian's length less one or lower, and from just above that length a
    /// loop that crosses the equator an odd number of times and is at most half the equator
    /// longer than the meridian (the walk closes along the curve).
    #[test]
    fn any_odd_loop_below_keeps_to_its_limit() {
        let vol = torus(24, 7.0, 2.6);
        for conn in [Connectivity::Six, Connectivity::TwentySix] {
            let mut g = Graph::new(&vol, cases(conn));
            let (equator, meridian) = torus_equator_and_meridian(&mut g);
            let m = meridian.len();
            for limit in [0, 1, m / 2, m - 1] {
                let found = any_odd_loop_below(&mut g, &equator, &Everywhere, limit);
                assert!(
                    found.is_none(),
                    "{conn:?}: a loop below {limit}, the meridian is {m}"
                );
            }
            for limit in [m + 1, m + 8, usize::MAX] {
                let lp = any_odd_loop_below(&mut g, &equator, &Everywhere, limit)
                    .unwrap_or_else(|| panic!("{conn:?}: no loop below {limit}"));
                assert_eq!(crossing_parity(&mut g, &lp, &equator), Some(1), "{conn:?}");
                assert!(
                    lp.len() <= m + equator.len() / 2,
                    "{conn:?}: {} edges",
                    lp.len()
                );
            }
        }
    }

    #[test]
    fn a_sphere_has_no_non_separating_loop() {
        let mut vol = MaskVolume::new([12, 12, 12], Frame::identity());
        for z in 0..12 {
            for y in 0..12 {
                for x in 0..12 {
                    let d = ((x as f64 - 5.6).powi(2)
                        + (y as f64 - 5.4).powi(2)
                        + (z as f64 - 5.5).powi(2))
                    .sqrt();
                    vol.set(x, y, z, d < 4.3);
                }
            }
        }
        let mut g = Graph::new(&vol, cases(Connectivity::Six));
        let equator = contour_from(&mut g, 5, 0, 5);
        assert!(!is_nonseparating(&mut g, &equator, &Everywhere));
    }
}
