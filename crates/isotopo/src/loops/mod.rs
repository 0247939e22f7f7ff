//! Handle size (paper §2.2): the Reeb loop and the cross loop of each handle.
//!
//! The **Reeb loop** is the shortest loop around the handle's Reeb cycle: it runs through the
//! cycle's ribbons and crosses the cycle's shortest contour once (for handles inside one slice:
//! through the original slice, crossing the handle's cut once). The **cross loop** is the
//! shortest loop anywhere on the surface that crosses the Reeb loop once. Closing either removes
//! the handle; the handle's size is the shorter one.
//!
//! Lengths are counted in edges of the surface graph (the paper's "voxel edges": a loop around a
//! one-voxel bridge is 4) and measured in millimetres along the polyline through the edge
//! midpoints. Whether a loop encloses material or void comes from linking numbers: a loop that
//! bounds a disk inside the material does not link its partner pushed off into the void, and
//! links it once when pushed into the material.

pub mod basis;
mod linking;

pub use linking::{linking_number, Overpass, SegmentsFrom};

use crate::error::Result;
use crate::grid::{Frame, MaskVolume};
use crate::surface::geometry::Geometry;
use crate::surface::search::{
    any_odd_loop, any_odd_loop_below, crossing_parity, odd_loop, odd_simple_loop, path_to,
    shortest_odd_loop, Everywhere, FastMap, Graph, InBox, OddLoop, PieceSet, Region,
};
use crate::surface::{PieceRef, Vertex};
use crate::sweep::{CycleVolume, Handle, LocatedHandle, NodeKind};
use crate::topology::cases::{cases, Connectivity};
use crate::topology::slice::SliceSurfels;
use crate::volume::Affine;

/// What a loop's spanning disk would pass through.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Encloses {
    /// The loop goes around material: closing it cuts (pinches the handle).
    Material,
    /// The loop goes around empty space: closing it fills (collapses the handle).
    Void,
}

/// One characteristic loop.
#[derive(Clone, Debug)]
pub struct Loop {
    /// Vertices in order, in the swept volume's local coordinates.
    pub vertices: Vec<Vertex>,
    /// The closed polyline through the edge midpoints, in original voxel coordinates.
    pub points: Vec<[f64; 3]>,
    /// Length in edges of the surface graph (voxel edges).
    pub length: usize,
    /// Length in millimetres of the polyline through the vertices' positions (interpolated on
    /// their edges when the volume was read with its fractions, else the edges' midpoints).
    pub length_mm: f64,
    /// What its spanning disk passes through: which closure it calls for.
    pub encloses: Encloses,
}

impl Loop {
    /// Length in the metric's unit.
    pub fn length_in(&self, metric: Metric) -> f64 {
        match metric {
            Metric::Edges => self.length as f64,
            Metric::Millimetres => self.length_mm,
        }
    }
}

/// A handle's two loops. Either may be missing when its search stopped at a limit.
#[derive(Clone, Debug, Default)]
pub struct HandleLoops {
    /// The Reeb loop: round the handle's cycle (`None`: none within the search limit).
    pub reeb: Option<Loop>,
    /// The cross loop: across the handle, crossing the Reeb loop once.
    pub cross: Option<Loop>,
    /// Each loop found is the shortest of its kind, and each missing one has none shorter than
    /// the limit (false when a search ran out of its budget of states first, or when simplify
    /// with no limit refined an intra-ribbon handle's pair from a loop not the shortest).
    pub exact: bool,
    /// Two closed curves on the surface that cross once, such that no loop shorter than the
    /// handle's size (or the limit) crosses either an odd number of times (see [`measure`]).
    pub basis: Option<(Vec<Vertex>, Vec<Vertex>)>,
    /// A Reeb-cycle handle's cut, as points (edge midpoints, original voxel coordinates): its
    /// Reeb loop is the shortest loop crossing it once.
    pub cut_points: Option<Vec<[f64; 3]>>,
}

impl HandleLoops {
    /// Voxel bounds of the loops' points (original coordinates), if any loop was found.
    pub fn bbox(&self) -> Option<crate::volume::BBox> {
        let mut b = crate::volume::BBox::EMPTY;
        let mut any = false;
        for l in self.reeb.iter().chain(self.cross.iter()) {
            for p in &l.points {
                b.include([
                    p[0].floor() as i64,
                    p[1].floor() as i64,
                    p[2].floor() as i64,
                ]);
                b.include([p[0].ceil() as i64, p[1].ceil() as i64, p[2].ceil() as i64]);
                any = true;
            }
        }
        any.then_some(b)
    }

    /// The smaller loop length, or `None` if neither loop was found within the limits.
    pub fn size(&self) -> Option<usize> {
        match (&self.reeb, &self.cross) {
            (Some(a), Some(b)) => Some(a.length.min(b.length)),
            (Some(a), None) => Some(a.length),
            (None, Some(b)) => Some(b.length),
            (None, None) => None,
        }
    }

    /// The smaller loop's length in the metric's unit.
    pub fn size_in(&self, metric: Metric) -> Option<f64> {
        [&self.reeb, &self.cross]
            .into_iter()
            .flatten()
            .map(|l| l.length_in(metric))
            .min_by(f64::total_cmp)
    }

    /// The smaller loop: the one of fewer edges, and of two of as many the shorter in
    /// millimetres (a report's `size_mm` is its length; the Reeb loop on a whole tie).
    pub fn smallest(&self) -> Option<&Loop> {
        match (&self.reeb, &self.cross) {
            (Some(a), Some(b)) => {
                let key = |l: &Loop| (l.length, l.length_mm);
                Some(if key(b) < key(a) { b } else { a })
            }
            (a, b) => a.as_ref().or(b.as_ref()),
        }
    }
}

/// What a loop's length is measured in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Metric {
    /// Edges of the surface graph ("voxel edges", the paper's unit): a loop round a one-voxel
    /// bridge is 4 whatever the spacing.
    #[default]
    Edges,
    /// Millimetres along the segments between the vertices' positions, interpolated on their
    /// edges (where the volume was read with its fractions) and mapped by the file's affine.
    Millimetres,
}

/// Limits on the searches.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Longest loop looked for, in the metric's unit (simplify: tau, or tau times
    /// `--max-ratio`; longer loops cannot change a decision). Infinite: both loops are measured
    /// exactly, within the searches' budgets.
    pub below: f64,
    /// What loops are shortest in.
    pub metric: Metric,
    /// Only the smaller loop matters (simplify without `--max-ratio`): a Reeb loop need not be
    /// the shortest when the cross loop is surely shorter than it.
    pub size_only: bool,
}

impl Limits {
    /// Every handle goes whatever its size, and only the smaller loop matters (simplify at tau
    /// inf without `--max-ratio`): the searches that only choose where a closure goes may be
    /// cheaper than exact.
    pub fn every_handle_goes(&self) -> bool {
        self.size_only && self.below.is_infinite()
    }

    /// No limit, shortest in edges, both loops exact.
    pub const NONE: Limits = Limits {
        below: f64::INFINITY,
        metric: Metric::Edges,
        size_only: false,
    };

    /// No limit, shortest in `metric`.
    pub fn exact(metric: Metric) -> Limits {
        Limits {
            metric,
            ..Limits::NONE
        }
    }
}

/// The searches of one metric on one volume's surface graph.
pub struct Searcher<'g> {
    /// The metric loops are shortest in.
    pub metric: Metric,
    /// Where the surface graph's vertices lie (for millimetres).
    pub geometry: Geometry<'g>,
}

impl Searcher<'_> {
    /// The shortest loop crossing `curve` an odd number of times, if one is shorter than
    /// `below` (in the metric's unit), anywhere on the surface.
    pub fn odd_loop(&self, top: &mut Graph, curve: &[Vertex], below: f64) -> OddLoop {
        self.odd_loop_in(top, curve, &Everywhere, below)
    }

    /// [`Searcher::odd_loop`] within a region.
    pub fn odd_loop_in(
        &self,
        top: &mut Graph,
        curve: &[Vertex],
        region: &dyn Region,
        below: f64,
    ) -> OddLoop {
        match self.metric {
            Metric::Edges => {
                let limit = if below.is_finite() {
                    below.ceil().max(0.0) as usize
                } else {
                    usize::MAX
                };
                odd_loop(top, curve, region, limit)
            }
            Metric::Millimetres => {
                let r =
                    crate::surface::search::odd_loop_mm(top, &self.geometry, curve, region, below);
                OddLoop {
                    found: r.found.map(|(lp, _)| lp),
                    exact: r.exact,
                }
            }
        }
    }

    /// A loop's length in the metric's unit.
    pub fn length(&self, frame: &Frame, lp: &[Vertex]) -> f64 {
        match self.metric {
            Metric::Edges => lp.len() as f64,
            Metric::Millimetres => self.geometry.loop_mm(frame, lp),
        }
    }
}

/// Maps a vertex between frames (both relative to the original volume).
pub fn map_vertex(v: Vertex, from: &Frame, to: &Frame) -> Vertex {
    let o = from.to_original_i(v.p);
    let axis = from.uvw[v.axis as usize];
    let mut p = [0i64; 3];
    let mut local_axis = 0u8;
    for k in 0..3 {
        p[k] = o[to.uvw[k]] - to.offset[to.uvw[k]];
        if to.uvw[k] == axis {
            local_axis = k as u8;
        }
    }
    Vertex {
        p,
        axis: local_axis,
    }
}

/// Surfels of the swept volume's slices, built when first needed and kept for later handles,
/// within a memory budget (the least recently used go first).
pub struct SliceCache {
    conn: Connectivity,
    slices: FastMap<i64, (SliceSurfels, u64)>,
    /// Contours walked for chained loops, by plane and starting vertex: their vertices' keys
    /// (a tall cycle's loop is chained through hundreds of them, measured again after every
    /// wall nearby).
    contours: FastMap<(i64, u64), std::sync::Arc<FastMap<u64, ()>>>,
    contour_vertices: usize,
    /// The original slice's pieces in the mini-volume its latest intra-ribbon handle came from.
    mini_rows: MiniRows,
    /// The latest intra-ribbon `P` and `Q1` of [`find`] with no limit when only the size
    /// matters (see `first_loop`).
    ribbon_start: Option<(Vec<Vertex>, Vec<Vertex>)>,
    /// Cuts whose race went past [`RERACE_LIMIT`] (see [`cross_is_smaller`]), by a hash of
    /// their vertices.
    raced: FastMap<u64, Raced>,
    /// The cheap loops crossing cuts once (see [`cheap_odd_loop`]), as vertex keys, by a hash
    /// of the cut's vertices: the sweep meets the same cut again after every wall near the
    /// long loop round its tall cycle (64³ noise at tau inf: 6,515 cheap loops looked for, of
    /// 1,218 cuts).
    cheap: KeptPaths<u64>,
    /// The stretches of [`chained_reeb_loop`]'s walks, each through one ribbon from a vertex to
    /// a contour, as vertex keys: a tall cycle's walk is found afresh after a wall broke it
    /// beyond mending, and the walls since then touched few of its ribbons.
    segments: KeptPaths<SegmentKey>,
    /// Use counter: the stamp of the latest `ensure`.
    clock: u64,
    /// Heap bytes of the slices kept, and how many they may take between handles (see
    /// [`SLICE_CACHE_BYTES`]).
    bytes: usize,
    budget: usize,
    /// How many contour vertices, cheap-loop vertices and long races the cache keeps
    /// before forgetting them all ([`MAX_CONTOUR_VERTICES`], [`MAX_CHEAP_VERTICES`],
    /// [`MAX_RACED`]; fields so a test can bound them small).
    limits: CacheLimits,
}

/// See [`SliceCache::limits`].
#[derive(Clone, Copy)]
struct CacheLimits {
    contour_vertices: usize,
    cheap_vertices: usize,
    segment_vertices: usize,
    raced: usize,
}

/// Long races a cache remembers (forgotten all at once beyond).
const MAX_RACED: usize = 1 << 12;

/// Paths kept by key (as their vertices' keys), with the count of vertices held: all forgotten
/// at once when keeping one more would pass the limit.
struct KeptPaths<K> {
    paths: FastMap<K, Vec<u64>>,
    vertices: usize,
}

impl<K> Default for KeptPaths<K> {
    fn default() -> KeptPaths<K> {
        KeptPaths {
            paths: FastMap::default(),
            vertices: 0,
        }
    }
}

impl<K: std::hash::Hash + Eq> KeptPaths<K> {
    fn get(&self, key: &K) -> Option<Vec<Vertex>> {
        let keys = self.paths.get(key)?;
        Some(keys.iter().map(|&k| Vertex::from_key(k)).collect())
    }

    /// Keeps `path` under `key`, in place of any kept before.
    fn keep(&mut self, key: K, path: &[Vertex], limit: usize) {
        if self.vertices + path.len() > limit {
            self.paths.clear();
            self.vertices = 0;
        }
        self.vertices += path.len();
        let old = self
            .paths
            .insert(key, path.iter().map(Vertex::key).collect());
        self.vertices -= old.map_or(0, |o| o.len());
    }

    /// Forgets the paths whose keys fail `keep`.
    fn retain(&mut self, mut keep: impl FnMut(&K) -> bool) {
        let mut forgotten = 0;
        self.paths.retain(|k, p| {
            let kept = keep(k);
            if !kept {
                forgotten += p.len();
            }
            kept
        });
        self.vertices -= forgotten;
    }
}

/// A stretch of a chained walk: the slice and ribbon it goes through, the vertex it starts
/// from, and what it ends on (a contour: its plane and the start of its walk; the cut:
/// `u64::MAX` and the cut's key).
type SegmentKey = (i64, u32, u64, (u64, u64));

/// Vertices of the walks' stretches a cache keeps (8 MiB; forgotten all at once beyond).
const MAX_SEGMENT_VERTICES: usize = 1 << 20;

/// Vertices of the cheap loops a cache keeps (8 MiB; forgotten all at once beyond).
const MAX_CHEAP_VERTICES: usize = 1 << 20;

/// Vertices of the contours a cache keeps walked (about 4 MiB; forgotten all at once beyond).
const MAX_CONTOUR_VERTICES: usize = 1 << 18;

/// Memory the slices of a cache may take between handles (one handle's cycle may need more).
/// A walk round a tall cycle ensures each of its slices in turn: with too few kept, every walk
/// builds them all again (128³ noise at tau inf with 24 MiB: a fifth of the run rebuilding
/// slices' surfels; 48 MiB: 359 -> 232 s, peak 630 -> 640 MiB).
const SLICE_CACHE_BYTES: usize = 48 << 20;

/// Approximate heap size of a slice's surfels.
fn slice_bytes(s: &SliceSurfels) -> usize {
    s.cubes.capacity() * std::mem::size_of::<crate::topology::slice::Cube>()
        + s.piece_ribbon.capacity() * 4
        + (s.bottom.capacity() + s.top.capacity() + s.row_start.capacity()) * 4
        + s.ribbons.capacity() * std::mem::size_of::<crate::topology::slice::Ribbon>()
}

impl SliceCache {
    /// An empty cache for surfaces of connectivity `conn`.
    pub fn new(conn: Connectivity) -> SliceCache {
        SliceCache {
            conn,
            slices: FastMap::default(),
            contours: FastMap::default(),
            contour_vertices: 0,
            mini_rows: MiniRows::default(),
            ribbon_start: None,
            raced: FastMap::default(),
            cheap: KeptPaths::default(),
            segments: KeptPaths::default(),
            clock: 0,
            bytes: 0,
            budget: SLICE_CACHE_BYTES,
            limits: CacheLimits {
                contour_vertices: MAX_CONTOUR_VERTICES,
                cheap_vertices: MAX_CHEAP_VERTICES,
                segment_vertices: MAX_SEGMENT_VERTICES,
                raced: MAX_RACED,
            },
        }
    }

    fn ensure(&mut self, vol: &MaskVolume, s: i64) {
        let conn = self.conn;
        self.clock += 1;
        let clock = self.clock;
        match self.slices.entry(s) {
            std::collections::hash_map::Entry::Occupied(mut e) => e.get_mut().1 = clock,
            std::collections::hash_map::Entry::Vacant(e) => {
                let sl = SliceSurfels::build(vol.plane(s), vol.plane(s + 1), s as i32, conn);
                self.bytes += slice_bytes(&sl);
                e.insert((sl, clock));
            }
        }
    }

    /// Keeps the surfels of slice `s` built elsewhere (by the sweep), unless already kept.
    pub fn offer(&mut self, s: i64, sl: SliceSurfels) {
        self.clock += 1;
        if let std::collections::hash_map::Entry::Vacant(e) = self.slices.entry(s) {
            self.bytes += slice_bytes(&sl);
            e.insert((sl, self.clock));
            self.trim();
        }
    }

    /// The surfels of slice `s`, if cached.
    fn slice(&self, s: i64) -> Option<&SliceSurfels> {
        self.slices.get(&s).map(|(sl, _)| sl)
    }

    /// Between handles: forgets the least recently used slices beyond the budget.
    fn trim(&mut self) {
        if self.bytes <= self.budget {
            return;
        }
        let mut by_age: Vec<(u64, i64)> = self.slices.iter().map(|(&s, (_, t))| (*t, s)).collect();
        by_age.sort_unstable();
        for (_, s) in by_age {
            if self.bytes <= self.budget / 2 {
                break;
            }
            if let Some((sl, _)) = self.slices.remove(&s) {
                self.bytes -= slice_bytes(&sl);
            }
        }
    }

    /// The keys of the vertices of the contour of plane `w` through `start`, walked once.
    fn contour(
        &mut self,
        top: &mut Graph,
        start: Vertex,
        w: i64,
    ) -> Option<std::sync::Arc<FastMap<u64, ()>>> {
        if let Some(c) = self.contours.get(&(w, start.key())) {
            return Some(c.clone());
        }
        let walked = crate::surface::search::walk_contour(top, start, w)?;
        let keys: FastMap<u64, ()> = walked.iter().map(|v| (v.key(), ())).collect();
        let keys = std::sync::Arc::new(keys);
        if self.contour_vertices + keys.len() > self.limits.contour_vertices {
            self.contours.clear();
            self.contour_vertices = 0;
        }
        self.contour_vertices += keys.len();
        self.contours.insert((w, start.key()), keys.clone());
        Some(keys)
    }

    /// The cheap loop kept for the cut of key `key` (see [`cheap_odd_loop`]).
    fn kept_cheap(&self, key: u64) -> Option<Vec<Vertex>> {
        self.cheap.get(&key)
    }

    /// Keeps a cheap loop for the cut of key `key`, in place of any kept before.
    fn keep_cheap(&mut self, key: u64, lp: &[Vertex]) {
        self.cheap.keep(key, lp, self.limits.cheap_vertices);
    }

    /// The stretch of a walk kept under `key` (see [`chained_reeb_loop`]).
    fn segment(&self, key: &SegmentKey) -> Option<Vec<Vertex>> {
        self.segments.get(key)
    }

    /// Keeps a stretch of a walk under `key`.
    fn keep_segment(&mut self, key: SegmentKey, path: &[Vertex]) {
        self.segments.keep(key, path, self.limits.segment_vertices);
    }

    /// Forgets the slices with a corner in planes `w0 ..= w1` (after an edit there), the
    /// contours of the planes whose cubes those slices hold, and the walks' stretches through
    /// slices one plane nearer still: a stretch through slice s steps along edges whose
    /// neighbourhoods take the cubes of slices s - 1 to s + 1, corners in planes s - 1 to s + 2.
    pub fn invalidate(&mut self, w0: i64, w1: i64) {
        self.segments.retain(|&(s, ..)| s + 2 < w0 || s - 1 > w1);
        let mut forgotten = 0;
        self.contours.retain(|&(w, _), c| {
            let keep = w + 1 < w0 || w > w1 + 1;
            if !keep {
                forgotten += c.len();
            }
            keep
        });
        self.contour_vertices -= forgotten;
        let mut freed = 0;
        self.slices.retain(|&s, (sl, _)| {
            let keep = s + 1 < w0 || s > w1;
            if !keep {
                freed += slice_bytes(sl);
            }
            keep
        });
        self.bytes -= freed;
    }
}

/// One ribbon of the swept volume, as a region: ribbon `ribbon` of the surfels `sl` of slice
/// `slice`.
struct OneRibbon<'c> {
    sl: &'c SliceSurfels,
    slice: i64,
    ribbon: u32,
}

impl Region for OneRibbon<'_> {
    fn allows(&self, p: &PieceRef) -> bool {
        let sl = self.sl;
        p.cube[2] == self.slice
            && sl
                .find_cube((p.cube[0] + 1) as u32, (p.cube[1] + 1) as u32)
                .is_some_and(|q| {
                    sl.piece_ribbon[sl.cubes[q].first_piece as usize + p.index as usize]
                        == self.ribbon
                })
    }
}

/// Cubes `lo ..= hi` (lower corners, local coordinates, inclusive).
type CubeBox = ([i64; 3], [i64; 3]);

/// The homology generators of ribbon `ribbon` of slice `slice` of the swept volume, its
/// boundary contours capped: 2 × its genus closed curves on the surface that span every loop of
/// the capped ribbon (a tree–cotree decomposition, see `sweep::local`).
pub fn ribbon_generators(
    top: &mut Graph,
    cache: &mut SliceCache,
    slice: i64,
    ribbon: u32,
) -> Option<Vec<Vec<Vertex>>> {
    ribbon_generators_within(top, cache, slice, ribbon, None)
}

/// [`ribbon_generators`] of the part of the ribbon in a box of cubes (its other boundary curves
/// capped too), or of all of it.
fn ribbon_generators_within(
    top: &mut Graph,
    cache: &mut SliceCache,
    slice: i64,
    ribbon: u32,
    within: Option<CubeBox>,
) -> Option<Vec<Vec<Vertex>>> {
    cache.ensure(top.vol, slice);
    let cache: &SliceCache = cache;
    let sl = cache.slice(slice)?;
    let whole = OneRibbon { sl, slice, ribbon };
    let part = within.map(|(lo, hi)| InBox {
        lo,
        hi,
        filter: |p: &PieceRef| whole.allows(p),
    });
    let table = top.table;
    let mut verts = Vec::new();
    for cube in &sl.cubes {
        let case = &table[cube.case as usize];
        let q = [cube.i as i64 - 1, cube.j as i64 - 1, slice];
        if part.as_ref().is_some_and(|b| !b.holds_cube(q)) {
            continue;
        }
        for k in 0..case.n_pieces as usize {
            if sl.piece_ribbon[cube.first_piece as usize + k] == ribbon {
                for lp in &case.pieces[k].loops {
                    verts.extend(lp.iter().map(|&e| crate::surface::vertex_of(q, e)));
                }
            }
        }
    }
    verts.sort();
    verts.dedup();
    match &part {
        None => crate::sweep::local::generators(top, &verts, &whole),
        Some(part) => crate::sweep::local::generators(top, &verts, part),
    }
}

/// A first loop around a top-level Reeb cycle, chained ribbon by ribbon: from a vertex of the
/// cut, the shortest path through each ribbon of the cycle to the contour it shares with the
/// next, until the cut is reached again from its other side; then along the cut to the start.
///
/// ```text
///        R2 ----- C2 ----- R3           each ribbon Ri is crossed from the contour it
///        |                  |           shares with R(i-1) to the one it shares with
///        C1                C3           R(i+1): a few edges each, so the whole loop
///        |                  |           costs about its length, where a search around
///        R1 -- C0 (cut) -- R4           the cycle visits every ribbon's whole area.
/// ```
///
/// Not the shortest loop, but it goes once round the cycle, which is all the cross loop needs.
/// `None` if the cycle is not top-level or a path is not found (the caller searches instead).
///
/// Each stretch is kept in the cache by its ribbon, the vertex it starts from and the contour
/// it ends on, until an edit comes near its slice: a tall cycle is walked again after each wall
/// that broke its kept loop beyond mending, and walls elsewhere leave most of its ribbons as
/// they were (64³ noise at tau inf: 53,000 of 86,000 stretches taken from the cache). The same
/// path either way, so the same loops.
pub(crate) fn chained_reeb_loop(
    top: &mut Graph,
    cache: &mut SliceCache,
    l: &LocatedHandle,
) -> Option<Vec<Vertex>> {
    let (cycle, n) = (&l.cycle, l.cycle.len());
    if !matches!(l.volume, CycleVolume::Top)
        || l.cut.len() < 2
        || n < 4
        || !n.is_multiple_of(2)
        || l.contour_starts.len() != n
        || cycle[l.cut_at].kind != NodeKind::Contour
    {
        return None;
    }
    // After the cut's contour: ribbon, contour, ribbon, …, the last ribbon back to the cut.
    let after = |k: usize| (l.cut_at + k) % n;
    let start = l.cut[0];
    let mut walk = vec![start];
    let mut cur = start;
    for k in (1..n).step_by(2) {
        let r = cycle[after(k)];
        let end = StretchEnd::of(l, k);
        let ends_on = match end {
            StretchEnd::Contour { level, start } => (level as u64, start.key()),
            StretchEnd::Cut => (u64::MAX, cut_key(&l.cut)),
        };
        let key = (r.level as i64, r.local, cur.key(), ends_on);
        let path = match cache.segment(&key) {
            Some(path) => path,
            None => {
                let path = ribbon_stretch(top, cache, l, k, cur, end)?;
                cache.keep_segment(key, &path);
                path
            }
        };
        walk.extend_from_slice(&path[1..]);
        cur = *path.last()?;
    }
    // Back along the cut, the shorter way, to the start (excluded: the walk is closed).
    let j = l.cut.iter().position(|&v| v == cur)?;
    let m = l.cut.len();
    let step = if j <= m - j { m - 1 } else { 1 };
    let mut i = (j + step) % m;
    while i != 0 {
        walk.push(l.cut[i]);
        i = (i + step) % m;
    }
    odd_simple_loop(top, &l.cut, walk)
}

/// Where the stretch of [`chained_reeb_loop`]'s walk through the `k`-th node after the cut (a
/// ribbon) ends: the contour after it, or, from the last ribbon, the cut. A kept stretch is
/// found again by it, so the key and the search read it from one place.
#[derive(Clone, Copy)]
enum StretchEnd {
    /// The contour at `level` that the walk along the plane from `start` goes round.
    Contour {
        level: i32,
        start: Vertex,
    },
    Cut,
}

impl StretchEnd {
    fn of(l: &LocatedHandle, k: usize) -> StretchEnd {
        let n = l.cycle.len();
        if k + 1 < n {
            let at = (l.cut_at + k + 1) % n;
            StretchEnd::Contour {
                level: l.cycle[at].level,
                start: l.contour_starts[at],
            }
        } else {
            StretchEnd::Cut
        }
    }
}

/// The stretch of [`chained_reeb_loop`]'s walk through the `k`-th node after the cut (a
/// ribbon): the shortest path within the ribbon from `cur` to its `end`.
fn ribbon_stretch(
    top: &mut Graph,
    cache: &mut SliceCache,
    l: &LocatedHandle,
    k: usize,
    cur: Vertex,
    end: StretchEnd,
) -> Option<Vec<Vertex>> {
    let r = l.cycle[(l.cut_at + k) % l.cycle.len()];
    // The contour the path through this ribbon ends on, as vertex numbers.
    let targets: std::sync::Arc<FastMap<u64, ()>> = match end {
        StretchEnd::Contour { level, start } => cache.contour(top, start, level as i64)?,
        StretchEnd::Cut => std::sync::Arc::new(
            l.cut
                .iter()
                .filter(|&&v| v != l.cut[0])
                .map(|v| (v.key(), ()))
                .collect(),
        ),
    };
    cache.trim();
    cache.ensure(top.vol, r.level as i64);
    let region = OneRibbon {
        sl: cache.slice(r.level as i64)?,
        slice: r.level as i64,
        ribbon: r.local,
    };
    let mut is_target = |g: &mut Graph, vi: u32| targets.contains_key(&g.vertex(vi).key());
    path_to(top, cur, &region, &mut is_target, usize::MAX)
}

/// The pieces of a mini-volume within its original slice, with their ribbons, slice by slice of
/// its sweep: what [`mini_cycle_region`] picks from for every intra-ribbon handle of one
/// ribbon (a few hundred in a sponge's slice), built once for all of them rather than a whole
/// slice of surfels per handle and per slice of its cycle.
///
/// Each piece packs into a `u64` (its cube's position along the row, the piece's index in
/// the cube, its ribbon): under a megabyte for a whole 256-wide slice.
#[derive(Default)]
struct MiniRows {
    /// The mini-volume and box the rows are of.
    of: Option<(std::sync::Arc<MaskVolume>, CubeBox)>,
    rows: FastMap<i64, Vec<u64>>,
}

impl MiniRows {
    /// The row of slice `s` of `mini`'s sweep (the cubes of `allowed`, one row thick): each
    /// piece as `cube's first coordinate << 40 | piece index << 32 | ribbon`.
    fn row(
        &mut self,
        mini: &std::sync::Arc<MaskVolume>,
        s: i64,
        allowed: CubeBox,
        conn: Connectivity,
    ) -> &[u64] {
        // The row packs a cube by its first coordinate: the box is one row, from 0 on.
        debug_assert!(allowed.0[0] >= 0 && allowed.0[1] == allowed.1[1]);
        if !self
            .of
            .as_ref()
            .is_some_and(|(m, b)| std::sync::Arc::ptr_eq(m, mini) && *b == allowed)
        {
            self.of = Some((mini.clone(), allowed));
            self.rows.clear();
        }
        self.rows.entry(s).or_insert_with(|| {
            let table = cases(conn);
            let sl = SliceSurfels::build(mini.plane(s), mini.plane(s + 1), s as i32, conn);
            let within = InBox::cubes(allowed.0, allowed.1);
            let mut row = Vec::new();
            for cube in &sl.cubes {
                let q = [cube.i as i64 - 1, cube.j as i64 - 1, s];
                if !within.holds_cube(q) {
                    continue;
                }
                for k in 0..table[cube.case as usize].n_pieces as usize {
                    let ribbon = sl.piece_ribbon[cube.first_piece as usize + k];
                    row.push((q[0] as u64) << 40 | (k as u64) << 32 | ribbon as u64);
                }
            }
            row
        })
    }
}

/// The cube's first coordinate of a piece of a [`MiniRows`] row (-1 for the padding's cubes:
/// the shift keeps the sign).
fn row_cube(piece: u64) -> i64 {
    (piece as i64) >> 40
}

/// Pieces of the given ribbons of a mini-volume's cycle, within the original slice.
fn mini_cycle_region(
    mini: &std::sync::Arc<MaskVolume>,
    h: &Handle,
    allowed: CubeBox,
    conn: Connectivity,
    rows: &mut MiniRows,
) -> PieceSet {
    let mut set = PieceSet::default();
    let mut by_slice: FastMap<i64, Vec<u32>> = FastMap::default();
    for n in &h.located.cycle {
        if n.kind == NodeKind::Ribbon {
            by_slice.entry(n.level as i64).or_default().push(n.local);
        }
    }
    // The original slice is one row of cubes: its second coordinate is the box's.
    let v = allowed.0[1];
    for (&s, ribbons) in &by_slice {
        for &piece in rows.row(mini, s, allowed, conn) {
            if ribbons.contains(&(piece as u32)) {
                set.insert([row_cube(piece), v, s], (piece >> 32) as u8);
            }
        }
    }
    set
}

/// A loop crossing the handle's cut once, in the swept volume's local coordinates, found in the
/// capped mini-volume of an intra-ribbon handle: around the cycle within the original slice,
/// failing that anywhere in the slice. `None` for a handle of the swept volume itself.
fn mini_volume_loop(
    h: &Handle,
    conn: Connectivity,
    vol: &MaskVolume,
    rows: &mut MiniRows,
) -> Option<Vec<Vertex>> {
    let l = &h.located;
    let CycleVolume::Mini(mini) = &l.volume else {
        return None;
    };
    let allowed = l.allowed?;
    let mut g = Graph::new(mini, cases(conn));
    let mut found = None;
    if !l.direct {
        let region = mini_cycle_region(mini, h, allowed, conn, rows);
        found = odd_loop(&mut g, &l.cut, &region, usize::MAX).found;
    }
    let found = found.or_else(|| shortest_odd_loop_near(&mut g, &l.cut, allowed))?;
    let mapped: Vec<Vertex> = found
        .into_iter()
        .map(|v| map_vertex(v, &mini.frame, &vol.frame))
        .collect();
    Some(mapped)
}

/// The shortest loop within the box `allowed` (cubes, inclusive) crossing `cut` an odd number
/// of times, looked for in growing boxes round the cut before the whole of `allowed`.
///
/// A loop of `L` edges crossing the cut strays at most `L / 2` edges from it, and an edge moves
/// at most one voxel along each axis: the cubes of its pieces lie within `L / 2 + 1` voxels of
/// the cut's. So a loop shorter than `2 m` edges found in the box `m` voxels beyond the cut's
/// cubes is the shortest in all of `allowed`; a longer one is looked for in the next box.
///
/// ```text
///   +-------------------------+  allowed (a slice of a sponge: thousands of handles)
///   |      +-----------+      |
///   |      |  +-----+  |      |  the cut's cubes, then m = 4, 16, 64 voxels round them:
///   |      |  | cut |  |      |  a noise handle's loop (a few edges) is settled in the
///   |      |  +-----+  |      |  first box, where a search of the slice visited thousands
///   |      +-----------+      |  of vertices
///   +-------------------------+
/// ```
fn shortest_odd_loop_near(g: &mut Graph, cut: &[Vertex], allowed: CubeBox) -> Option<Vec<Vertex>> {
    let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
    for v in cut {
        for k in 0..3 {
            // The cubes round vertex v have lower corners v.p - 1 ..= v.p.
            lo[k] = lo[k].min(v.p[k] - 1);
            hi[k] = hi[k].max(v.p[k]);
        }
    }
    for &m in &NEAR_LOOP_MARGINS {
        let b_lo: [i64; 3] = std::array::from_fn(|k| (lo[k] - m).max(allowed.0[k]));
        let b_hi: [i64; 3] = std::array::from_fn(|k| (hi[k] + m).min(allowed.1[k]));
        if b_lo == allowed.0 && b_hi == allowed.1 {
            break;
        }
        let r = odd_loop(g, cut, &InBox::cubes(b_lo, b_hi), 2 * m as usize);
        if r.found.is_some() && r.exact {
            return r.found;
        }
    }
    odd_loop(g, cut, &InBox::cubes(allowed.0, allowed.1), usize::MAX).found
}

/// Margins (voxels) of the boxes round a cut in which [`shortest_odd_loop_near`] looks first.
const NEAR_LOOP_MARGINS: [i64; 3] = [4, 16, 64];

/// For an intra-ribbon handle whose capped mini-volume gave no loop on the original surface
/// (one found directly whose curve runs through the caps): the generator of its ribbon's
/// homology (on the swept surface itself) nearest to where the handle was found. It goes round
/// a handle of that ribbon, the same one or a neighbour of it; the searches from it then
/// measure a handle of the ribbon rather than none.
///
/// The generators of the part of the ribbon round the handle come first, in growing boxes: in
/// a sponge the ribbon is the whole slice, with thousands of handles, and all its generators
/// took tens of megabytes. One is taken when a loop in a box round it crosses it once (so it
/// goes round a handle of the surface, not only of the cropped part); failing that, the nearest
/// generator of the whole ribbon.
fn ribbon_loop(top: &mut Graph, cache: &mut SliceCache, h: &Handle) -> Option<Vec<Vertex>> {
    let (slice, ribbon) = h.located.ribbon?;
    let vol = top.vol;
    let b = &h.located.bbox;
    let centre = b.cube_centre();
    let nearest = |cycles: Vec<Vec<Vertex>>| nearest_loop(&vol.frame, centre, cycles);
    // An empty box (none in practice) goes straight to the whole ribbon.
    let near = (b.min[0] <= b.max[0]).then(|| vol.frame.to_local_box(b));
    let margins = if near.is_some() {
        &RIBBON_LOOP_MARGINS[..]
    } else {
        &[]
    };
    let (lo, hi) = near.unwrap_or_default();
    let grow = |m: i64| -> CubeBox { (lo.map(|x| x - m), hi.map(|x| x + m)) };
    for &margin in margins {
        let near = ribbon_generators_within(top, cache, slice, ribbon, Some(grow(margin)));
        let Some(lp) = near.and_then(nearest) else {
            continue;
        };
        let (lo, hi) = grow(2 * margin);
        if odd_loop(top, &lp, &InBox::cubes(lo, hi), usize::MAX)
            .found
            .is_some()
        {
            return Some(lp);
        }
    }
    nearest(ribbon_generators(top, cache, slice, ribbon)?)
}

/// Of `cycles` (local coordinates), the one with a vertex nearest to `centre` (original
/// coordinates); cycles of fewer than 3 vertices are not loops.
fn nearest_loop(frame: &Frame, centre: [f64; 3], cycles: Vec<Vec<Vertex>>) -> Option<Vec<Vertex>> {
    let distance = |lp: &Vec<Vertex>| {
        lp.iter()
            .map(|v| {
                let p = frame.to_original(v.midpoint());
                (0..3).map(|k| (p[k] - centre[k]).powi(2)).sum::<f64>()
            })
            .fold(f64::INFINITY, f64::min)
    };
    cycles
        .into_iter()
        .filter(|c| c.len() >= 3)
        .min_by(|a, b| distance(a).total_cmp(&distance(b)))
}

/// Margins (voxels) round an intra-ribbon handle's box in which [`ribbon_loop`] looks first.
const RIBBON_LOOP_MARGINS: [i64; 3] = [4, 16, 64];

/// A loop crossing `curve` once, for when none is shorter than the limit and any will do: for a
/// top-level handle's cut, chained through its cycle's ribbons (cheap round a tall cycle); else
/// the first the search from all of `curve` closes.
fn some_odd_loop(
    top: &mut Graph,
    cache: &mut SliceCache,
    h: &Handle,
    curve: &[Vertex],
) -> Option<Vec<Vertex>> {
    let is_cut = matches!(h.located.volume, CycleVolume::Top) && curve == h.located.cut;
    let chained = is_cut
        .then(|| chained_reeb_loop(top, cache, &h.located))
        .flatten();
    chained.or_else(|| any_odd_loop(top, curve, &Everywhere))
}

/// A loop crossing the cut once found near it (below [`CHEAP_SEARCH_LIMIT`]) or else
/// [`some_odd_loop`], kept by cut: the loop found for the same cut before, mended where walls
/// broke it since, while it still crosses `curve` an odd number of times. Any loop crossing the
/// cut once will do for the race and for the search of `Q2` from it, so a loop found before the
/// latest walls serves as well as one found after them; mending it costs a search round each
/// wall that broke it, where finding it again costs a search round the handle's whole cycle.
/// (The sweep meets the same cut again after every wall near the long loop round its tall
/// cycle; on 64³ noise at tau inf, 6,515 cheap loops were looked for, of 1,218 cuts, and
/// three in four of those kept had been broken by a wall.)
fn cheap_odd_loop(
    top: &mut Graph,
    cache: &mut SliceCache,
    h: &Handle,
    curve: &[Vertex],
) -> Option<Vec<Vertex>> {
    // By cut alone: a handle's cycle is renumbered by every wall in its planes. The handles
    // round several cycles may share a cut (the embryo: one contour of 192 vertices, the cut
    // of cycles of 16 to 56 nodes); a loop round any of them crosses the cut once.
    let key = cut_key(curve);
    if let Some(kept) = cache.kept_cheap(key) {
        if let Some(lp) = mend_walk(top, &kept).and_then(|w| odd_simple_loop(top, curve, w)) {
            return Some(lp);
        }
    }
    let found = any_odd_loop_below(top, curve, &Everywhere, CHEAP_SEARCH_LIMIT)
        .or_else(|| some_odd_loop(top, cache, h, curve))?;
    cache.keep_cheap(key, &found);
    Some(found)
}

/// Below this many edges, the loop crossing a cut once that [`cheap_odd_loop`] keeps is looked
/// for from the cut before walking round its cycle. The walk round a tall cycle is long: on 64³
/// noise at tau inf, 174 edges on average where the shortest loop crossing the cut has 45
/// (median 3.2 times as long), and each later step pays for that length (the search for the
/// loop crossing it once starts from each of its vertices; mending visits each; the wall check
/// walks along it). A search from the cut finds a loop at most half the cut longer than the
/// shortest, at a cost that grows with the area it covers (the walk's with the cycle's
/// length); past about 48 edges the walk is the cheaper (128³ noise at tau inf, user time
/// with a mutation run beside: 126 s with the walk alone, 101 s at 32, 98 s at 48, 112 s at
/// 64).
const CHEAP_SEARCH_LIMIT: usize = 48;

/// A closed walk on the surface that follows `kept` where it still is one: each stretch that is
/// not (a vertex gone, a step no longer an edge), replaced by the shortest path round it between
/// its ends. `None` if none of it is left, or a path would visit more than [`MEND_BUDGET`]
/// vertices.
///
/// ```text
///   kept:  a - b - c - d - e - f      c, d gone under a wall
///   mended a - b - x - y - z - e - f  b to e round the wall
/// ```
fn mend_walk(top: &mut Graph, kept: &[Vertex]) -> Option<Vec<Vertex>> {
    let n = kept.len();
    let on: Vec<bool> = kept.iter().map(|&v| top.around(v).is_some()).collect();
    // A step holds while it is an edge of the surface (so both ends are on it).
    let step_holds = |top: &mut Graph, k: usize| {
        let (v, w) = (kept[k], kept[(k + 1) % n]);
        top.around(v).is_some_and(|a| a.position(w).is_some())
    };
    // Start at a vertex still on the surface; walk round to it again.
    let start = on.iter().position(|&x| x)?;
    let at = |i: usize| (start + i) % n;
    let mut walk = vec![kept[start]];
    let mut i = 0;
    while i < n {
        if step_holds(top, at(i)) {
            i += 1;
        } else {
            // The next vertex on the surface after the break (at the latest, `start` again).
            let j = (i + 1..=n).find(|&j| on[at(j)])?;
            let target = kept[at(j)];
            let mut is_target = |g: &mut Graph, vi: u32| g.vertex(vi) == target;
            let path = path_to(top, kept[at(i)], &Everywhere, &mut is_target, MEND_BUDGET)?;
            if path.len() < 2 {
                return None; // round to the start: nothing of the walk is left
            }
            walk.extend_from_slice(&path[1..path.len() - 1]);
            i = j;
        }
        if i < n {
            walk.push(kept[at(i)]);
        }
    }
    Some(walk)
}

/// Vertices a search round one break of a kept loop may visit (see [`mend_walk`]).
const MEND_BUDGET: usize = 1024;

/// The cross loop: the shortest loop anywhere on the surface crossing `reeb` once.
pub fn cross_loop(top: &mut Graph, reeb: &[Vertex], limit: usize) -> Option<Vec<Vertex>> {
    shortest_odd_loop(top, reeb, &Everywhere, limit)
}

/// The two loops of a handle as vertex lists, before they are described.
struct Found {
    reeb: Option<Vec<Vertex>>,
    cross: Option<Vec<Vertex>>,
    exact: bool,
    basis: Option<(Vec<Vertex>, Vec<Vertex>)>,
}

/// Finds both loops of a handle (see [`measure`]). Each handle has a closed curve `P` on the
/// surface: a top-level handle its cut (a contour of its Reeb cycle), an intra-ribbon handle a
/// loop round its cycle found in its capped mini-volume. Then `Q1` is the shortest loop crossing
/// `P` once and `Q2` the shortest crossing `Q1` once, both searched over the whole surface. A
/// top-level handle's Reeb loop is `Q1` and its cross loop `Q2` (paper §2.2); an intra-ribbon
/// handle's cross loop is `Q1` and its Reeb loop `Q2` (no longer than `P`, which crosses `Q1`
/// once), refined until each is the shortest loop crossing the other once (with no limit when
/// only the size matters: within the swept part of the surface, see [`refined_within`]).
///
/// With a finite limit only loops shorter than it are looked for; when there is none, `Q1` is
/// some loop crossing `P` once (any will do to look for `Q2`). Either way `(P, Q1)` cross once and
/// no loop shorter than the handle's size (or the limit) crosses either of them an odd number of
/// times: simplify's check that the whole surface has no loop that short left takes these pairs.
fn find(
    top: &mut Graph,
    cache: &mut SliceCache,
    h: &Handle,
    conn: Connectivity,
    limits: Limits,
    searcher: &Searcher,
) -> Found {
    let vol = top.vol;
    let top_level = matches!(h.located.volume, CycleVolume::Top);
    let Some(p) = (if top_level {
        Some(h.located.cut.clone())
    } else {
        mini_volume_loop(h, conn, vol, &mut cache.mini_rows).or_else(|| ribbon_loop(top, cache, h))
    }) else {
        return Found {
            reeb: None,
            cross: None,
            exact: false,
            basis: None,
        };
    };
    let frame = vol.frame;
    let len = |lp: &[Vertex]| searcher.length(&frame, lp);
    // What the race already searched is not searched again.
    let mut searched = None;
    let raced = limits.size_only && top_level;
    if raced {
        match cross_is_smaller(top, cache, h, searcher, &p, limits) {
            Race::Cross(found) => return found,
            Race::Reeb { search } => searched = Some(search),
            Race::Undecided { .. } => {}
        }
    }
    let (first, kept) = match searched {
        Some(search) => (search, false),
        None => first_loop(top, cache, searcher, &p, top_level, limits),
    };
    if let Some(q1) = first
        .found
        .as_ref()
        .filter(|q| raced && len(q) > RERACE_LIMIT)
    {
        // The cut's next race walks this Reeb loop (see `cross_is_smaller`).
        cache.keep_cheap(cut_key(&p), q1);
    }
    // A Q1 kept from the handle before (see `first_loop`) is refined from, like a cheap Q2.
    let refine = limits.below.is_infinite() && (first.exact || kept);
    let mut exact = first.exact;
    let q1 = match first.found {
        Some(q) => Some(q),
        // The walk round the handle's own cycle, fresh: here it is the loop reported, and a
        // certificate's curve (the race's cheap loop may be mended, longer, or found near the
        // cut round another cycle through it; the curves of the step's handles would then not
        // span their handles: random 18³ noise at tau 5).
        None => some_odd_loop(top, cache, h, &p),
    };
    let Some(q1) = q1 else {
        return Found {
            reeb: (!top_level).then_some(p),
            cross: None,
            exact: false,
            basis: None,
        };
    };
    // Q1 found beyond the limit is not the shortest: only what crosses it matters.
    let swept = refined_within(h, limits);
    let second = second_loop(top, searcher, &q1, top_level, limits, &swept);
    exact &= second.exact;
    let basis = Some((p.clone(), q1.clone()));
    if top_level {
        return Found {
            reeb: Some(q1),
            cross: second.found,
            exact,
            basis,
        };
    }
    // Intra-ribbon: the Reeb loop is the shorter of P and Q2; refine the pair until each loop
    // is the shortest crossing the other (lengths only fall, so this ends).
    let (mut reeb, mut cross) = match second.found {
        Some(q2) if len(&q2) < len(&p) => (q2, q1),
        _ => (p, q1),
    };
    if refine {
        loop {
            let better = searcher.odd_loop_in(top, &reeb, &swept, len(&cross));
            exact &= better.exact;
            let Some(c) = better.found else { break };
            cross = c;
            let better = searcher.odd_loop_in(top, &cross, &swept, len(&reeb));
            exact &= better.exact;
            let Some(r) = better.found else { break };
            reeb = r;
        }
    }
    let cross = (len(&cross) < limits.below).then_some(cross);
    Found {
        reeb: Some(reeb),
        cross,
        exact,
        basis,
    }
}

/// Where an intra-ribbon handle's `Q2` and refinement look: with no limit when only the size
/// matters, the part of the surface the sweep has passed (cubes up to the handle's slice);
/// else (and for top-level handles) everywhere.
///
/// ```text
///   z above s:  not swept yet, its handles not found yet  . o . o . o .  (noise handles)
///   ---------- slice s: the ribbon's handle ------------  ====[  ]=====
///   z below s:  swept, every handle found there closed
/// ```
///
/// Refined over the whole surface, the pair drifts onto a noise handle above the sweep, which
/// is closed instead of the handle; the sweep finds the handle again at slice `s` and the
/// measurement drifts onto the next one (MNI `--spherical`: one ribbon's handle measured 73
/// times in a row, 25 ms each, its loops 5 and 3 edges long 20 slices above). Within the
/// swept part the pair is the handle's own, and the noise handles above are closed where the
/// sweep finds them, at a fraction of a millisecond each.
fn refined_within(h: &Handle, limits: Limits) -> InBox<fn(&PieceRef) -> bool> {
    let all = [i64::MAX / 4; 3];
    match h.located.ribbon {
        Some((s, _)) if limits.every_handle_goes() => {
            InBox::cubes(all.map(|x| -x), [all[0], all[1], s])
        }
        _ => InBox::cubes(all.map(|x| -x), all),
    }
}

/// `Q1` of [`find`]: the shortest loop crossing `p` below the limit. For an intra-ribbon handle
/// with no limit when only the smaller loop matters, the pair is refined from any loop crossing
/// `p` (see `second_loop`): the `Q1` of the handle before is kept and taken again (not exact)
/// when `p` is the same and it still crosses `p` once on the surface as it is now.
///
/// Round a long cycle `P` is long, and the same handle may be measured again after a wall
/// elsewhere changed little (MNI `--spherical`: a 148-node cycle's `P` of 164 edges, with a
/// 118-edge `Q1` that cost 17 ms).
/// Says whether the `Q1` is the one kept.
fn first_loop(
    top: &mut Graph,
    cache: &mut SliceCache,
    searcher: &Searcher,
    p: &[Vertex],
    top_level: bool,
    limits: Limits,
) -> (OddLoop, bool) {
    let reuse = !top_level && limits.every_handle_goes();
    if !reuse {
        return (searcher.odd_loop(top, p, limits.below), false);
    }
    if let Some((kept_p, q1)) = &cache.ribbon_start {
        if kept_p == p && crossing_parity(top, q1, p) == Some(1) {
            let first = OddLoop {
                found: Some(q1.clone()),
                exact: false,
            };
            return (first, true);
        }
    }
    let first = searcher.odd_loop(top, p, limits.below);
    if let Some(q1) = &first.found {
        cache.ribbon_start = Some((p.to_vec(), q1.clone()));
    }
    (first, false)
}

/// `Q2` of [`find`]: the shortest loop crossing `q1` below the limit. For an intra-ribbon
/// handle with no limit when only the smaller loop matters (every handle goes whatever its
/// size), any loop crossing `q1` (not exact), within `swept` if there is one (see
/// [`refined_within`]): the pair is refined from it anyway. Round a ribbon of many handles `P`
/// and `Q1` are long, and the shortest loop crossing `Q1` costs a search that deep from every
/// vertex of `Q1` (MNI `--spherical`: 148-node cycle, up to 0.4 s each time), while the
/// refinement finds the small pair from any loop.
fn second_loop(
    top: &mut Graph,
    searcher: &Searcher,
    q1: &[Vertex],
    top_level: bool,
    limits: Limits,
    swept: &dyn Region,
) -> OddLoop {
    if !top_level && limits.every_handle_goes() {
        let q2 = any_odd_loop(top, q1, swept).or_else(|| any_odd_loop(top, q1, &Everywhere));
        if let Some(q2) = q2 {
            return OddLoop {
                found: Some(q2),
                exact: false,
            };
        }
    }
    searcher.odd_loop(top, q1, limits.below)
}

/// When only the smaller loop matters (the handle's size): some loop crossing `p` once, found
/// cheaply (`first`: near the cut, or else chained round a tall cycle; see
/// [`cheap_odd_loop`]), and the shortest loop `c` crossing it once; if
/// no loop shorter than `c` crosses `p` once, `c` is the handle's smaller loop and the shortest
/// loop crossing `p` (long round a tall cycle) need not be measured.
///
/// A search for the shortest loop crossing a long curve is cheap only when that loop is short,
/// and both curves are long here. So the two searches race, bounded by the same limit, doubled
/// until one finds a loop: the cost is about that of the shorter answer. When the loop crossing
/// `p` is found first it is the Reeb loop, and the cross loop is looked for from it (a short
/// curve), not from `first`: `first` may go round other handles too, and then the loops crossing
/// it once are longer than the handle's cross loop.
///
/// Such a handle is large, and the sweep may find it again and again, after each wall a
/// measurement of it led to elsewhere: its Reeb loop runs above the sweep, where a noise handle
/// not found yet crosses it, and that one is closed. So a cut whose race went past
/// [`RERACE_LIMIT`] is raced again only that far, from the Reeb loop its measurement found
/// (kept as the cut's cheap loop), which the next such noise handle crosses; past that, a race
/// that had run out of budget is not run again (the exact search follows), one that had
/// decided is run whole. On the embryo at tau inf a 192-vertex cut was met 42 times, and its
/// exact search round the cycle (after a race that ran out of budget at limit 256) cost
/// 0.4-1.7 s each time: 34 s of the run's 47 s of loop searches; a 40-node cycle's race
/// decided at limit 128 each time, 0.2-0.7 s.
fn cross_is_smaller(
    top: &mut Graph,
    cache: &mut SliceCache,
    h: &Handle,
    searcher: &Searcher,
    p: &[Vertex],
    limits: Limits,
) -> Race {
    let key = cut_key(p);
    if let Some(before) = cache.raced.get(&key).copied() {
        let cap = before.reached.min(RERACE_LIMIT).min(limits.below);
        if cap >= RACE_START {
            let capped = Limits {
                below: cap,
                ..limits
            };
            match race(top, cache, h, searcher, p, capped) {
                Race::Cross(found) => return Race::Cross(found),
                Race::Reeb { search } if search.found.is_some() => return Race::Reeb { search },
                _ => {}
            }
        }
        if before.undecided {
            return Race::Undecided {
                reached: before.reached,
            };
        }
    }
    let decided = race(top, cache, h, searcher, p, limits);
    let went_past = match &decided {
        Race::Undecided { reached } => Some(Raced {
            reached: *reached,
            undecided: true,
        }),
        Race::Reeb { search, .. } => search
            .found
            .as_ref()
            .filter(|q| searcher.length(&top.vol.frame, q) > RERACE_LIMIT)
            .map(|_| Raced {
                reached: RERACE_LIMIT,
                undecided: false,
            }),
        Race::Cross(_) => None,
    };
    if let Some(raced) = went_past {
        if cache.raced.len() >= cache.limits.raced {
            cache.raced.clear();
        }
        cache.raced.insert(key, raced);
    }
    decided
}

/// How a cut's race went, when it went past [`RERACE_LIMIT`].
#[derive(Clone, Copy)]
struct Raced {
    /// Neither loop was shorter than this.
    reached: f64,
    /// The budgets ran out.
    undecided: bool,
}

/// How far a cut's race runs again once a race of it went past this limit (see
/// [`cross_is_smaller`]): the noise handles that cross a tall cycle's Reeb loop are a few edges
/// long; beyond them the exact search or the whole race follows anyway.
const RERACE_LIMIT: f64 = 2.0 * RACE_START;

/// A hash of a cut's vertices, in order.
fn cut_key(p: &[Vertex]) -> u64 {
    p.iter().fold(p.len() as u64, |h, v| {
        (h ^ v.key())
            .wrapping_mul(0x9e37_79b9_7f4a_7c15)
            .rotate_left(29)
    })
}

/// The race of [`cross_is_smaller`], run.
fn race(
    top: &mut Graph,
    cache: &mut SliceCache,
    h: &Handle,
    searcher: &Searcher,
    p: &[Vertex],
    limits: Limits,
) -> Race {
    // The cheap loop is looked for only once the first search found nothing: most handles are
    // noise, whose loop crossing `p` is shorter than the first limit.
    let mut first = None;
    let mut limit = RACE_START.min(limits.below);
    // Neither loop is shorter than this (both searches were exact below it).
    let mut reached = 0.0;
    loop {
        let r = searcher.odd_loop(top, p, limit);
        if !r.exact {
            return Race::Undecided { reached };
        }
        if r.found.is_some() {
            return Race::Reeb { search: r };
        }
        if first.is_none() {
            first = cheap_odd_loop(top, cache, h, p);
        }
        let Some(first) = &first else {
            return Race::Undecided { reached: 0.0 };
        };
        let c = searcher.odd_loop(top, first, limit);
        if let Some(c) = c.found {
            // Shorter than the limit, which no loop crossing `p` is.
            return Race::Cross(Found {
                reeb: Some(first.clone()),
                cross: Some(c),
                exact: false,
                basis: Some((p.to_vec(), first.clone())),
            });
        }
        if !c.exact {
            return Race::Undecided { reached };
        }
        if limit >= limits.below {
            // Neither loop is shorter than the limit: `r` is the search `find` would make.
            return Race::Reeb { search: r };
        }
        reached = limit;
        limit = (limit * 2.0).min(limits.below);
    }
}

/// What [`cross_is_smaller`]'s race found.
enum Race {
    /// A loop crossing the cheap loop once is shorter than any crossing `p`: the handle's loops.
    Cross(Found),
    /// The exact search for the shortest loop crossing `p` below the race's last limit (the
    /// Reeb loop, or none below the caller's limit).
    Reeb { search: OddLoop },
    /// The budgets ran out first, at the limit after `reached` (no loop crossing `p` or the
    /// cheap loop once is shorter than `reached`; 0 when there was no cheap loop).
    Undecided { reached: f64 },
}

/// The first limit of [`cross_is_smaller`]'s race (edges or millimetres): a noise handle's
/// loops are a few edges long.
const RACE_START: f64 = 16.0;

/// Measures both loops of a handle of the volume whose surface graph is `top` (see `find`),
/// shortest in `limits.metric`; lengths in millimetres along the vertices' interpolated
/// positions where the volume has its fractions.
pub fn measure(
    top: &mut Graph,
    cache: &mut SliceCache,
    h: &Handle,
    conn: Connectivity,
    affine: &Affine,
    limits: Limits,
) -> HandleLoops {
    let vol = top.vol;
    let geometry = Geometry {
        affine,
        fractions: vol.fractions.as_ref(),
    };
    let searcher = Searcher {
        metric: limits.metric,
        geometry,
    };
    let found = find(top, cache, h, conn, limits, &searcher);
    let (reeb, cross) = (found.reeb, found.cross);
    let mut r = reeb
        .as_ref()
        .map(|lp| describe(vol, lp, cross.as_deref(), &geometry));
    let mut c = cross
        .as_ref()
        .map(|lp| describe(vol, lp, reeb.as_deref(), &geometry));
    if let (Some(a), Some(b)) = (&mut r, &mut c) {
        one_side_each(vol, a, b);
    }
    let cut_points = matches!(h.located.volume, CycleVolume::Top).then(|| {
        h.located
            .cut
            .iter()
            .map(|v| vol.frame.to_original(v.midpoint()))
            .collect()
    });
    HandleLoops {
        reeb: r,
        cross: c,
        exact: found.exact,
        basis: found.basis,
        cut_points,
    }
}

/// Exactly one of a handle's two loops encloses material (paper §2.2). Where their linkings
/// gave both the same side, the loop whose linking with the other is the stronger (the first
/// on a tie) keeps its side, and the other takes the opposite.
fn one_side_each(vol: &MaskVolume, a: &mut Loop, b: &mut Loop) {
    if a.encloses == b.encloses {
        let (la, lb) = (
            link_strength(vol, &a.vertices, &b.vertices),
            link_strength(vol, &b.vertices, &a.vertices),
        );
        if la >= lb {
            b.encloses = opposite(a.encloses);
        } else {
            a.encloses = opposite(b.encloses);
        }
    }
}

/// A loop of `vol` (vertices in its local coordinates) with its points, lengths and what it
/// goes round (from its linking with `partner`, a loop crossing it once, or else its fan).
pub fn describe(
    vol: &MaskVolume,
    lp: &[Vertex],
    partner: Option<&[Vertex]>,
    geometry: &Geometry,
) -> Loop {
    let points: Vec<[f64; 3]> = lp
        .iter()
        .map(|v| vol.frame.to_original(v.midpoint()))
        .collect();
    Loop {
        length: lp.len(),
        length_mm: geometry.loop_mm(&vol.frame, lp),
        encloses: match partner {
            Some(x) => encloses(vol, lp, x),
            None => encloses_by_fan(vol, lp),
        },
        vertices: lp.to_vec(),
        points,
    }
}

fn opposite(e: Encloses) -> Encloses {
    match e {
        Encloses::Material => Encloses::Void,
        Encloses::Void => Encloses::Material,
    }
}

/// Length in millimetres of a closed polyline given in voxel coordinates.
pub fn polyline_mm(points: &[[f64; 3]], affine: &Affine) -> f64 {
    let n = points.len();
    (0..n)
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % n]);
            let d = affine.apply_vector([b[0] - a[0], b[1] - a[1], b[2] - a[2]]);
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        })
        .sum()
}

/// The partner loop pushed a quarter voxel along each of its edges, toward the inside sample
/// (`into_material`) or the outside one.
fn pushed(vol: &MaskVolume, lp: &[Vertex], into_material: bool) -> Vec<[f64; 3]> {
    lp.iter()
        .map(|v| {
            let inside_at_start = vol.get(v.p[0], v.p[1], v.p[2]);
            // Toward the start of the edge when that end is on the wanted side.
            let toward_start = inside_at_start == into_material;
            let mut m = v.midpoint();
            m[v.axis as usize] += if toward_start { -0.25 } else { 0.25 };
            m
        })
        .collect()
}

fn midpoints(lp: &[Vertex]) -> Vec<[f64; 3]> {
    lp.iter().map(|v| v.midpoint()).collect()
}

/// |Lk(loop, partner pushed into the material)| - |Lk(loop, partner pushed into the void)|:
/// positive when the loop bounds a disk in the material.
fn link_strength(vol: &MaskVolume, lp: &[Vertex], partner: &[Vertex]) -> i64 {
    let a = midpoints(lp);
    let lin = linking_number(&a, &pushed(vol, partner, true)).abs();
    let lout = linking_number(&a, &pushed(vol, partner, false)).abs();
    (lin - lout).abs()
}

/// Does the loop go around material or void? See the module notes.
pub fn encloses(vol: &MaskVolume, lp: &[Vertex], partner: &[Vertex]) -> Encloses {
    let a = midpoints(lp);
    let lin = linking_number(&a, &pushed(vol, partner, true)).abs();
    let lout = linking_number(&a, &pushed(vol, partner, false)).abs();
    if lin > lout {
        Encloses::Material
    } else {
        Encloses::Void
    }
}

/// Without a partner loop (its search stopped at a limit): the side of the samples nearest to
/// the inner part of the loop's spanning fan (the fan about its centroid, shrunk so that the
/// loop's own edges, which have one end on each side, do not count). A short loop round a tunnel
/// spans empty space; one round a bar spans material.
pub fn encloses_by_fan(vol: &MaskVolume, lp: &[Vertex]) -> Encloses {
    let points = midpoints(lp);
    let c = crate::surface::geometry::centroid(&points);
    let (mut inside, mut outside) = (0usize, 0usize);
    const STEPS: usize = 4;
    for i in 0..points.len() {
        let (a, b) = (points[i], points[(i + 1) % points.len()]);
        // Points c + s (a - c) + t (b - c) with s + t <= 3/4.
        for si in 0..STEPS {
            for ti in 0..STEPS - si {
                let (s, t) = (
                    0.75 * si as f64 / STEPS as f64,
                    0.75 * ti as f64 / STEPS as f64,
                );
                let q: [i64; 3] = std::array::from_fn(|k| {
                    (c[k] + s * (a[k] - c[k]) + t * (b[k] - c[k])).round() as i64
                });
                if vol.get(q[0], q[1], q[2]) {
                    inside += 1;
                } else {
                    outside += 1;
                }
            }
        }
    }
    if inside > outside {
        Encloses::Material
    } else {
        Encloses::Void
    }
}

/// Vertices a worker's surface graph keeps between handles before starting afresh, when
/// `analyze` measures every handle (one graph per worker thread, each handle's loops searched
/// in full; simplify keeps fewer: see its `SIMPLIFY_GRAPH_LIMIT`).
const MEASURE_GRAPH_LIMIT: usize = 1 << 21;

/// Handles measured between two moves of an out-of-core volume's window.
pub(crate) const MEASURE_BATCH: usize = 64;

/// Measures every handle of a sweep's report, in parallel (each worker keeps its own cache of
/// the surface graph). Out of core, the handles go in batches up the sweep axis, and between
/// batches the volume keeps only the planes the next batch starts from.
pub fn measure_all(
    vol: &mut MaskVolume,
    handles: &[Handle],
    conn: Connectivity,
    affine: &Affine,
    limits: Limits,
    progress: &dyn crate::progress::Progress,
) -> Result<Vec<HandleLoops>> {
    progress.start("loops", handles.len() as u64);
    let mut out: Vec<Option<HandleLoops>> = vec![None; handles.len()];
    let batch = if vol.out_of_core() {
        MEASURE_BATCH
    } else {
        handles.len().max(1)
    };
    let pool = WorkerCaches::new(MEASURE_GRAPH_LIMIT);
    in_sweep_batches(
        vol,
        handles,
        batch,
        |vol: &MaskVolume, batch: &[&Handle]| {
            let measured = measure_batch(vol, batch, conn, affine, limits, &pool, progress)?;
            Ok(measured.into_iter().map(Some).collect())
        },
        &mut out,
    )?;
    progress.finish();
    Ok(out
        .into_iter()
        .map(|l| l.expect("every handle measured"))
        .collect())
}

/// Runs `each` over `handles` in batches of `batch` up the sweep axis (by the slice where each
/// one's cycle closed), the window of planes moved to each batch first: out of core, the
/// planes the searches load stay within it and a batch. What `each` returns for a batch lands
/// at its handles' places in `out`.
pub fn in_sweep_batches<T, F>(
    vol: &mut MaskVolume,
    handles: &[Handle],
    batch: usize,
    mut each: F,
    out: &mut [T],
) -> Result<()>
where
    F: FnMut(&MaskVolume, &[&Handle]) -> Result<Vec<T>>,
{
    let w_axis = vol.frame.uvw[2];
    let w_offset = vol.frame.offset[w_axis];
    let top_slice = |h: &Handle| h.located.bbox.max[w_axis] - w_offset;
    let mut order: Vec<usize> = (0..handles.len()).collect();
    order.sort_by_key(|&i| top_slice(&handles[i]));
    for ids in order.chunks(batch.max(1)) {
        vol.follow_sweep(top_slice(&handles[ids[0]]))?;
        let batch: Vec<&Handle> = ids.iter().map(|&i| &handles[i]).collect();
        for (&i, x) in ids.iter().zip(each(vol, &batch)?) {
            out[i] = x;
        }
    }
    Ok(())
}

/// The workers' caches of neighbourhoods and slices, kept from batch to batch of
/// [`measure_batch`] over one volume whose samples do not change (only its window moves).
pub struct WorkerCaches {
    kept: std::sync::Mutex<Vec<(crate::surface::search::GraphCache, SliceCache)>>,
    /// Vertices a worker's graph may number before it starts afresh (between handles).
    graph_limit: usize,
}

impl WorkerCaches {
    /// Caches whose graphs start afresh beyond `graph_limit` vertices (a few hundred bytes
    /// each).
    pub fn new(graph_limit: usize) -> WorkerCaches {
        WorkerCaches {
            kept: Default::default(),
            graph_limit,
        }
    }
}

/// One worker's graph and slices, given back to the pool when the worker is done.
struct Worker<'a> {
    graph: Option<Graph<'a>>,
    slices: Option<SliceCache>,
    pool: &'a WorkerCaches,
}

impl<'a> Worker<'a> {
    fn take(pool: &'a WorkerCaches, vol: &'a MaskVolume, conn: Connectivity) -> Worker<'a> {
        let kept = pool.kept.lock().ok().and_then(|mut p| p.pop());
        let (g, slices) = kept.unwrap_or_else(|| {
            (
                crate::surface::search::GraphCache::default(),
                SliceCache::new(conn),
            )
        });
        Worker {
            graph: Some(Graph::with_cache(vol, cases(conn), g)),
            slices: Some(slices),
            pool,
        }
    }
}

impl Drop for Worker<'_> {
    /// Gives the caches back, but not a graph grown past the limit (one long search): cleared,
    /// it would still hold its memory.
    fn drop(&mut self) {
        let (Some(g), Some(s)) = (self.graph.take(), self.slices.take()) else {
            return;
        };
        let Ok(mut pool) = self.pool.kept.lock() else {
            return;
        };
        // Rayon may run more workers than threads at once (one waiting steals another's work);
        // keep as many caches as threads.
        if pool.len() < rayon::current_num_threads() {
            let g = match g.len() > self.pool.graph_limit {
                true => Default::default(),
                false => g.into_cache(),
            };
            pool.push((g, s));
        }
    }
}

/// Measures `handles` of `vol` in parallel, each worker with caches from `pool`, advancing
/// `progress` by one a handle; stops at the first cancellation or memory error.
pub fn measure_batch(
    vol: &MaskVolume,
    handles: &[&Handle],
    conn: Connectivity,
    affine: &Affine,
    limits: Limits,
    pool: &WorkerCaches,
    progress: &dyn crate::progress::Progress,
) -> Result<Vec<HandleLoops>> {
    use rayon::prelude::*;
    // Why the batch stopped early: cancelled, or past the memory limit.
    let stop = std::sync::OnceLock::new();
    let measured: Vec<Option<HandleLoops>> = handles
        .par_iter()
        .map_init(
            || Worker::take(pool, vol, conn),
            |w, h| {
                if stop.get().is_some() {
                    return None;
                }
                if let Err(e) = crate::progress::between_steps(progress, "loop searches") {
                    let _ = stop.set(e);
                    return None;
                }
                let (Some(g), Some(cache)) = (&mut w.graph, &mut w.slices) else {
                    return None;
                };
                // The cache of neighbourhoods is a speed-up, not a need: bound its memory.
                if g.len() > pool.graph_limit {
                    g.clear();
                }
                let l = measure(g, cache, h, conn, affine, limits);
                progress.advance(1);
                Some(l)
            },
        )
        .collect();
    if let Some(e) = stop.into_inner() {
        return Err(e);
    }
    Ok(measured
        .into_iter()
        .map(|l| l.expect("every handle measured"))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_rng::Rng;

    /// The row of a mini-volume's slice holds the pieces of exactly the cubes of the box's row
    /// that the surface passes through (corners not all on one side), told from the samples.
    #[test]
    fn mini_rows_hold_the_cubes_of_their_row() {
        let mut vol = MaskVolume::new([7, 5, 4], Frame::identity());
        let mut rng = Rng(0x1234_5678_9abc_def1);
        for z in 0..4 {
            for y in 0..5 {
                for x in 0..7 {
                    vol.set(x, y, z, rng.next_u64().is_multiple_of(3));
                }
            }
        }
        let mini = std::sync::Arc::new(vol);
        let inside = |x: i64, y: i64, z: i64| {
            (0..7).contains(&x) && (0..5).contains(&y) && (0..4).contains(&z) && mini.get(x, y, z)
        };
        let mut rows = MiniRows::default();
        let mut rows_seen = 0;
        for v in -1..5 {
            for s in -1..4 {
                let allowed = ([-1, v, -1], [6, v, 3]);
                let mut got: Vec<i64> = rows
                    .row(&mini, s, allowed, Connectivity::Six)
                    .iter()
                    .map(|&piece| row_cube(piece))
                    .collect();
                got.dedup();
                let want: Vec<i64> = (-1..7)
                    .filter(|&x| {
                        let corners =
                            (0..8).map(|c| inside(x + (c & 1), v + (c >> 1 & 1), s + (c >> 2)));
                        let n = corners.filter(|&b| b).count();
                        n > 0 && n < 8
                    })
                    .collect();
                assert_eq!(got, want, "row y = {v}, slice {s}");
                rows_seen += !want.is_empty() as usize;
            }
        }
        assert!(rows_seen > 20, "{rows_seen}");
    }

    /// The square loop of edge midpoints from lo + 0.5 to hi + 0.5 in the plane z, corners left
    /// out.
    fn square_loop(lo: i64, hi: i64, z: i64) -> Vec<Vertex> {
        let mut lp = Vec::new();
        lp.extend((lo + 1..=hi).map(|y| Vertex {
            p: [lo, y, z],
            axis: 0,
        }));
        lp.extend((lo + 1..=hi).map(|x| Vertex {
            p: [x, hi, z],
            axis: 1,
        }));
        lp.extend((lo + 1..=hi).rev().map(|y| Vertex {
            p: [hi, y, z],
            axis: 0,
        }));
        lp.extend((lo + 1..=hi).rev().map(|x| Vertex {
            p: [x, lo, z],
            axis: 1,
        }));
        lp
    }

    /// The fan of [`square_loop`] from `lo` to `hi` says `want` in every plane of `vol`'s 5,
    /// with the loop's vertices in either order.
    fn assert_fan_says(vol: &MaskVolume, lo: i64, hi: i64, want: Encloses, at: &str) {
        for z in 0..5 {
            let mut lp = square_loop(lo, hi, z);
            assert_eq!(encloses_by_fan(vol, &lp), want, "{at}, z {z}");
            lp.reverse();
            assert_eq!(encloses_by_fan(vol, &lp), want, "{at}, z {z}, reversed");
        }
    }

    /// Without a partner loop, the side a loop spans is read off its fan: round a bar of
    /// 3 × 3 samples, material; round a hole of the same size through a block, void; the
    /// same loop at any height of the bar and with its vertices in either order.
    ///
    /// A loop wider than the bar (or the hole) it goes round spans both sides: the fan's inner
    /// part (within 0.56 of the way to the loop) reaches a voxel beyond the bar, and the side
    /// that holds most of it wins. Square loop from 1.5 to 9.5 round a bar of 4..=7: the fan's
    /// points reach 3.25 and 7.75, so the rows 3 and 8 of its samples are outside.
    ///
    /// ```text
    ///   1.5          9.5
    ///    +-----------+      loop (edge midpoints)
    ///    |  .......  |      . fan samples outside the bar (rows 3 and 8): under half
    ///    |  :#####:  |      # the bar (4..=7): most of them
    ///    |  :#####:  |
    ///    |  .......  |
    ///    +-----------+
    /// ```
    ///
    /// The whole fan votes, not its centre: round a bar 3..=8 with a core of the other side
    /// (5..=6) where the fan's centre lies, the bar's side still wins.
    #[test]
    fn a_fan_spans_the_bar_it_goes_round_or_the_hole() {
        // (bar from, bar to, loop lo, loop hi, core): the loop on the bar's surface, then
        // wider, then round a bar 3..=8 with a core of the other side 5..=6 round the fan's
        // centre (most of the fan is still in the bar, so the bar's side wins).
        let cases = [
            (4, 6, 3, 6, None),
            (4, 7, 1, 9, None),
            (3, 8, 1, 9, Some(5..=6)),
        ];
        for (from, to, lo, hi, core) in cases {
            for hole in [false, true] {
                let mut vol = MaskVolume::new([11, 11, 5], Frame::identity());
                for z in 0..5 {
                    for y in 0..11 {
                        for x in 0..11 {
                            let within = |r: &std::ops::RangeInclusive<usize>| {
                                r.contains(&x) && r.contains(&y)
                            };
                            let in_bar = within(&(from..=to)) && !core.as_ref().is_some_and(within);
                            vol.set(x, y, z, in_bar != hole);
                        }
                    }
                }
                let want = if hole {
                    Encloses::Void
                } else {
                    Encloses::Material
                };
                let at = format!("bar {from}..={to}, core {core:?}, loop {lo}..{hi}, hole {hole}");
                assert_fan_says(&vol, lo, hi, want, &at);
            }
        }
    }

    /// The fan votes by area: its samples fill each triangle (centroid, midpoint, next
    /// midpoint) out to 3/4 of the way, so there are more of them far from the centroid than
    /// near it. A square loop from 1.5 to 13.5 round a pillar 6..=9 (a third of the fan's inner
    /// part): void, and material round a shaft of the same size
    /// through a block. Weighted towards the centroid (the samples kept along the spokes), the
    /// pillar's side would win.
    ///
    /// ```text
    ///   1.5                13.5
    ///    +------------------+     the fan's samples reach 4.1 and 10.9 on the axes:
    ///    |    ..........    |     . the other side (rows 4, 5, 10, 11): most of them
    ///    |    :  ####  :    |     # the pillar 6..=9
    ///    |    :  ####  :    |
    ///    |    ..........    |
    ///    +------------------+
    /// ```
    #[test]
    fn a_fan_votes_by_area_not_by_nearness_to_its_centre() {
        for shaft in [false, true] {
            let mut vol = MaskVolume::new([15, 15, 5], Frame::identity());
            for (x, y, z) in (0..15 * 15 * 5).map(|k| (k % 15, (k / 15) % 15, k / 225)) {
                let pillar = (6..=9).contains(&x) && (6..=9).contains(&y);
                vol.set(x, y, z, pillar != shaft);
            }
            let want = if shaft {
                Encloses::Material
            } else {
                Encloses::Void
            };
            assert_fan_says(&vol, 1, 13, want, &format!("shaft {shaft}"));
        }
        // A block beside the pillar's place, filling the fan's inner part up to a third of
        // the way from one side (x <= 6, and its mirror images y <= 6, x >= 9, y >= 9): void,
        // whichever vertex the loop starts from (a vote leaning towards the first vertex says
        // material from there).
        for side in 0..4 {
            let mut vol = MaskVolume::new([15, 15, 5], Frame::identity());
            for (x, y, z) in (0..15 * 15 * 5).map(|k| (k % 15, (k / 15) % 15, k / 225)) {
                let (u, flip) = (if side % 2 == 0 { x } else { y }, side >= 2);
                vol.set(x, y, z, if flip { u >= 9 } else { u <= 6 });
            }
            let lp = square_loop(1, 13, 2);
            for start in 0..lp.len() {
                let mut turned = lp.clone();
                turned.rotate_left(start);
                let got = encloses_by_fan(&vol, &turned);
                assert_eq!(
                    got,
                    Encloses::Void,
                    "block side {side}, from vertex {start}"
                );
            }
        }
    }

    /// The smaller loop is the one of fewer edges, and of two of as many the shorter in
    /// millimetres, whichever is the Reeb loop; alone, it is the smaller.
    #[test]
    fn the_smaller_loop_is_shorter_in_edges_then_in_millimetres() {
        let lp = |length: usize, length_mm: f64| Loop {
            vertices: Vec::new(),
            points: Vec::new(),
            length,
            length_mm,
            encloses: Encloses::Void,
        };
        let pairs = [
            (lp(4, 6.0), lp(5, 2.0), 6.0),
            (lp(4, 6.0), lp(4, 4.5), 4.5),
            (lp(4, 4.5), lp(4, 6.0), 4.5),
            (lp(4, 4.5), lp(4, 4.5), 4.5),
        ];
        for (a, b, want) in pairs {
            for (reeb, cross) in [(a.clone(), b.clone()), (b.clone(), a.clone())] {
                let what = format!("{reeb:?} {cross:?}");
                let l = HandleLoops {
                    reeb: Some(reeb),
                    cross: Some(cross),
                    ..HandleLoops::default()
                };
                assert_eq!(l.smallest().map(|s| s.length_mm), Some(want), "{what}");
            }
        }
        let alone = HandleLoops {
            cross: Some(lp(7, 9.0)),
            ..HandleLoops::default()
        };
        assert_eq!(alone.smallest().map(|s| s.length), Some(7));
    }

    /// A handle measured after a wall elsewhere removed it (simplify measures a step's
    /// handles one after another, closing each): no loop crosses its cut once any more, and it
    /// is reported with no loops (not with its cut as a Reeb loop: the cut bounds a disk now).
    /// A square ring standing across the sweep, its one handle found, then the ring cut
    /// through on the side away from the cut.
    #[test]
    fn a_handle_whose_cut_no_loop_crosses_has_no_loops() {
        let conn = Connectivity::Six;
        let mut vol = standing_ring(2);
        let r = sweep_z(&mut vol, conn);
        assert_eq!(r.handles.len(), 1);
        let h = &r.handles[0];
        assert!(matches!(h.located.volume, CycleVolume::Top));
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let limits = [
            Limits::NONE,
            Limits {
                size_only: true,
                ..Limits::NONE
            },
        ];
        for limits in limits {
            let mut g = Graph::new(&vol, cases(conn));
            let mut cache = SliceCache::new(conn);
            let l = measure(&mut g, &mut cache, h, conn, &affine, limits);
            assert!(l.reeb.is_some() && l.cross.is_some(), "the ring's handle");
        }
        // The cut goes round one leg of the ring (x 2..4 or 10..12): cut the other leg.
        let cut_x = h.located.cut.iter().map(|v| v.p[0]).sum::<i64>() / h.located.cut.len() as i64;
        let far: std::ops::Range<usize> = if cut_x < 7 { 10..12 } else { 2..4 };
        for x in far {
            for y in 2..4 {
                vol.set(x, y, 7, false);
            }
        }
        assert_eq!(vol.genus(conn).unwrap().b1, 0);
        for limits in limits {
            let mut g = Graph::new(&vol, cases(conn));
            let mut cache = SliceCache::new(conn);
            let l = measure(&mut g, &mut cache, h, conn, &affine, limits);
            let got = (l.reeb.map(|r| r.length), l.cross.map(|c| c.length));
            assert_eq!(got, (None, None), "size only: {}", limits.size_only);
        }
    }

    /// How strongly a loop says which side it goes round: for each of two square rings standing
    /// side by side, its Reeb loop and its cross loop link each other's copy pushed to one side
    /// once and the other's not at all (strength 1 both ways); a loop of one ring and a loop of
    /// the other link no copy (strength 0).
    #[test]
    fn a_loop_links_its_partners_copy_on_one_side_only() {
        let mut vol = MaskVolume::new([30, 8, 14], Frame::identity());
        for (x, y, z) in (0..30 * 8 * 14).map(|k| (k % 30, (k / 30) % 8, k / 240)) {
            let x0 = if x < 14 { 2 } else { 16 };
            let outer = (x0..x0 + 10).contains(&x) && (2..12).contains(&z);
            let hole = (x0 + 2..x0 + 8).contains(&x) && (4..10).contains(&z);
            vol.set(x, y, z, outer && !hole && (2..4).contains(&y));
        }
        let conn = Connectivity::Six;
        let r = sweep_z(&mut vol, conn);
        assert_eq!(r.handles.len(), 2);
        let mut g = Graph::new(&vol, cases(conn));
        let mut cache = SliceCache::new(conn);
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let pairs: Vec<(Vec<Vertex>, Vec<Vertex>)> = r
            .handles
            .iter()
            .map(|h| {
                let l = measure(&mut g, &mut cache, h, conn, &affine, Limits::NONE);
                (l.reeb.unwrap().vertices, l.cross.unwrap().vertices)
            })
            .collect();
        for (reeb, cross) in &pairs {
            assert_eq!(link_strength(&vol, reeb, cross), 1);
            assert_eq!(link_strength(&vol, cross, reeb), 1);
        }
        let ((a, b), (c, d)) = (&pairs[0], &pairs[1]);
        for (x, y) in [(a, c), (a, d), (b, c), (b, d)] {
            assert_eq!(link_strength(&vol, x, y), 0);
        }
    }

    /// Linked like a chain's links, two square rings: the loop that runs along one ring (round
    /// its hole) links the other ring's such loop whichever side that one is pushed to, so it
    /// says nothing of sides: strength 0 (the difference of the two linkings, not their sum), while each
    /// ring's own loops still have strength 1 both ways.
    #[test]
    fn a_loop_linked_on_both_sides_says_nothing() {
        let n = 26;
        let mut vol = MaskVolume::new([n; 3], Frame::identity());
        let annulus = |u: usize, v: usize, lo: [usize; 2], hi: [usize; 2]| {
            let within = |w: usize, a: usize, b: usize| (a..b).contains(&w);
            within(u, lo[0], hi[0])
                && within(v, lo[1], hi[1])
                && !(within(u, lo[0] + 2, hi[0] - 2) && within(v, lo[1] + 2, hi[1] - 2))
        };
        for (x, y, z) in (0..n * n * n).map(|k| (k % n, (k / n) % n, k / (n * n))) {
            // Ring a stands in the xz-plane, ring b lies in the xy-plane through a's hole.
            let a = (12..14).contains(&y) && annulus(x, z, [4, 4], [16, 16]);
            let b = (9..11).contains(&z) && annulus(x, y, [10, 8], [22, 18]);
            vol.set(x, y, z, a || b);
        }
        let conn = Connectivity::Six;
        let r = sweep_z(&mut vol, conn);
        assert_eq!(r.handles.len(), 2);
        let mut g = Graph::new(&vol, cases(conn));
        let mut cache = SliceCache::new(conn);
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let mut loops: Vec<[Vec<Vertex>; 2]> = Vec::new();
        for h in &r.handles {
            let l = measure(&mut g, &mut cache, h, conn, &affine, Limits::NONE);
            let (reeb, cross) = (l.reeb.unwrap().vertices, l.cross.unwrap().vertices);
            assert_eq!(link_strength(&vol, &reeb, &cross), 1);
            assert_eq!(link_strength(&vol, &cross, &reeb), 1);
            loops.push([reeb, cross]);
        }
        let mut both_sides = 0;
        for x in &loops[0] {
            for y in &loops[1] {
                for (p, q) in [(x, y), (y, x)] {
                    let m = midpoints(p);
                    let lin = linking_number(&m, &pushed(&vol, q, true)).abs();
                    let lout = linking_number(&m, &pushed(&vol, q, false)).abs();
                    assert_eq!(lin, lout);
                    both_sides += usize::from(lin == 1);
                    assert_eq!(link_strength(&vol, p, q), 0);
                }
            }
        }
        // The loops along the two rings, each with the other.
        assert_eq!(both_sides, 2);
    }

    /// The key of the races kept tells cuts apart: random cuts (3 to 40 vertices of a 16³
    /// grid) with their reverses, 20,000 distinct ones in all, have 20,000 distinct keys; so do
    /// a cut and its near twins, each with one vertex moved one step along one axis (a cut found
    /// again after a wall nearby). A collision would cut short the race of a cut never measured.
    #[test]
    fn cut_keys_tell_cuts_apart() {
        let mut rng = Rng(0xd1b5_4a32_d192_ed03);
        let mut next = |n: u64| rng.below(n);
        let mut cuts = std::collections::HashSet::new();
        while cuts.len() < 20_000 {
            let len = 3 + next(38) as usize;
            let cut: Vec<Vertex> = (0..len)
                .map(|_| Vertex {
                    p: [next(16) as i64, next(16) as i64, next(16) as i64],
                    axis: next(3) as u8,
                })
                .collect();
            let mut back = cut.clone();
            back.reverse();
            if back != cut {
                cuts.insert(cut);
                cuts.insert(back);
            }
        }
        let keys: std::collections::HashSet<u64> = cuts.iter().map(|c| cut_key(c)).collect();
        assert_eq!(keys.len(), cuts.len());
        for cut in cuts.iter().take(200) {
            let mut twins = std::collections::HashSet::from([cut.clone()]);
            for k in 0..cut.len() {
                for a in 0..3 {
                    let mut twin = cut.clone();
                    twin[k].p[a] += 1;
                    twins.insert(twin);
                }
            }
            let keys: std::collections::HashSet<u64> = twins.iter().map(|c| cut_key(c)).collect();
            assert_eq!(
                keys.len(),
                twins.len(),
                "a cut of {} and its twins",
                cut.len()
            );
        }
    }

    /// A loop round a square ring, broken where a bump is added to the ring's outer face, is
    /// mended round the bump: a closed walk on the new surface that keeps every vertex of the
    /// loop still on it, in order, and leaves it only next to the bump. Unbroken, it comes back
    /// as it was; with the ring gone, there is nothing to mend. A step that is no longer an
    /// edge, its two vertices still there, is mended too.
    ///
    /// ```text
    ///   y                 the loop: the ring's outer contour in plane z = 5
    ///   ^  +---------+    the bump: samples x = 14, y = 7 ..= 9, z = 4 ..= 6
    ///   |  |  +---+  |#
    ///   |  |  |   |  |#
    ///   |  +--+---+--+
    ///   +--------------> x
    /// ```
    #[test]
    fn a_loop_broken_by_a_wall_is_mended_round_it() {
        let ring = |bump: bool, gone: bool| {
            let mut vol = MaskVolume::new([16, 16, 10], Frame::identity());
            for z in 2..8usize {
                for y in 2..14usize {
                    for x in 2..14usize {
                        let d = x.abs_diff(8).max(y.abs_diff(8));
                        vol.set(x, y, z, (3..=5).contains(&d) && !gone);
                    }
                }
            }
            if bump {
                for (y, z) in (7..=9).flat_map(|y| (4..=6).map(move |z| (y, z))) {
                    vol.set(14, y, z, true);
                }
            }
            vol
        };
        let conn = Connectivity::Six;
        let before = ring(false, false);
        let start = Vertex {
            p: [13, 8, 5],
            axis: 0,
        };
        let kept =
            crate::surface::search::walk_contour(&Graph::new(&before, cases(conn)), start, 5)
                .expect("the outer contour");
        assert!(kept.len() >= 40, "{}", kept.len());
        let mut top = Graph::new(&before, cases(conn));
        assert_eq!(mend_walk(&mut top, &kept), Some(kept.clone()), "unbroken");

        let after = ring(true, false);
        let mut top = Graph::new(&after, cases(conn));
        let left: Vec<Vertex> = kept
            .iter()
            .copied()
            .filter(|&v| top.around(v).is_some())
            .collect();
        assert!(
            left.len() < kept.len(),
            "the bump takes vertices of the loop"
        );
        let mended = mend_walk(&mut top, &kept).expect("mended");
        assert!(crate::surface::search::is_closed_walk(&mut top, &mended));
        // The vertices left, in the loop's order, with the new ones only next to the bump.
        let old: Vec<Vertex> = mended
            .iter()
            .copied()
            .filter(|v| kept.contains(v))
            .collect();
        assert_eq!(old, left);
        for v in mended.iter().filter(|v| !kept.contains(v)) {
            let near = (13..=15).contains(&v.p[0])
                && (6..=10).contains(&v.p[1])
                && (3..=7).contains(&v.p[2]);
            assert!(near, "{v:?} is away from the bump");
        }
        assert!(mended.len() > left.len());

        let none = ring(false, true);
        assert_eq!(mend_walk(&mut Graph::new(&none, cases(conn)), &kept), None);

        // Every vertex still there but a stretch of steps gone: 5..=10 left out, 4 to 11 is
        // no edge; it is mended by a path between them.
        let mut top = Graph::new(&before, cases(conn));
        let (a, b) = (kept[4], kept[11]);
        assert!(top.around(a).is_some_and(|n| n.position(b).is_none()));
        let skipping: Vec<Vertex> = [&kept[..5], &kept[11..]].concat();
        let mended = mend_walk(&mut top, &skipping).expect("mended");
        assert!(crate::surface::search::is_closed_walk(&mut top, &mended));
        assert!(mended.len() > skipping.len());
    }

    /// A slice's bytes as the cache counts them hold at least its surfels' elements, and
    /// exactly those once the vectors hold no spare room.
    #[test]
    fn a_slices_bytes_cover_its_surfels() {
        let conn = Connectivity::Six;
        let vol = sponge(16, 0x2545_f491_4f6c_dd1d);
        for s in 0..15 {
            let mut sl = SliceSurfels::build(vol.plane(s), vol.plane(s + 1), s as i32, conn);
            let elements = sl.cubes.len() * std::mem::size_of::<crate::topology::slice::Cube>()
                + sl.piece_ribbon.len() * 4
                + (sl.bottom.len() + sl.top.len() + sl.row_start.len()) * 4
                + sl.ribbons.len() * std::mem::size_of::<crate::topology::slice::Ribbon>();
            assert!(slice_bytes(&sl) >= elements, "slice {s}");
            assert!(s == 0 || !sl.cubes.is_empty());
            sl.cubes.shrink_to(0);
            sl.piece_ribbon.shrink_to(0);
            sl.bottom.shrink_to(0);
            sl.top.shrink_to(0);
            sl.row_start.shrink_to(0);
            sl.ribbons.shrink_to(0);
            assert_eq!(slice_bytes(&sl), elements, "slice {s}, shrunk");
        }
    }

    /// The generator taken for an intra-ribbon handle is the one that comes nearest its
    /// centre, in original coordinates: of a square round (20, 20, 5) and one round (4, 4, 5),
    /// nearer the origin, the first for a centre at (18, 18, 5) and the second for (6, 6, 5);
    /// two vertices are no loop.
    #[test]
    fn the_nearest_generator_is_the_one_nearest_the_centre() {
        let square = |c: i64| -> Vec<Vertex> {
            [[c - 1, c, 5], [c, c + 1, 5], [c + 1, c, 5], [c, c - 1, 5]]
                .map(|p| Vertex { p, axis: 2 })
                .to_vec()
        };
        let (far, near) = (square(20), square(4));
        let frame = Frame::identity();
        let pick = |frame: &Frame, centre, cycles: &[&Vec<Vertex>]| {
            nearest_loop(frame, centre, cycles.iter().map(|c| (*c).clone()).collect())
        };
        assert_eq!(
            pick(&frame, [18.0, 18.0, 5.0], &[&near, &far]).as_ref(),
            Some(&far)
        );
        assert_eq!(
            pick(&frame, [6.0, 6.0, 5.0], &[&far, &near]).as_ref(),
            Some(&near)
        );
        let pair = square(19)[..2].to_vec();
        assert_eq!(
            pick(&frame, [19.0, 19.0, 5.0], &[&pair, &near]).as_ref(),
            Some(&near)
        );
        assert_eq!(pick(&frame, [0.0; 3], &[&pair]), None);
    }

    /// Past its budget the cache forgets the least recently used slices down to half of it,
    /// and counts the bytes of exactly the slices it keeps: a sponge's slices ensured in turn,
    /// with slice 0 used again after each, under a budget of about four slices.
    #[test]
    fn a_trimmed_cache_keeps_the_recent_slices_within_its_budget() {
        let conn = Connectivity::Six;
        let vol = sponge(16, 0x2545_f491_4f6c_dd1d);
        let mut cache = SliceCache::new(conn);
        let one = slice_bytes(&SliceSurfels::build(vol.plane(7), vol.plane(8), 7, conn));
        cache.budget = 4 * one;
        let mut trimmed = 0;
        for s in 1..15 {
            cache.ensure(&vol, s);
            cache.ensure(&vol, 0);
            let before = cache.slices.len();
            cache.trim();
            trimmed += usize::from(cache.slices.len() < before);
            let held: usize = cache.slices.values().map(|(sl, _)| slice_bytes(sl)).sum();
            assert_eq!(cache.bytes, held, "after slice {s}");
            assert!(
                cache.bytes <= cache.budget,
                "after slice {s}: {} bytes",
                cache.bytes
            );
            assert!(cache.slices.contains_key(&0) && cache.slices.contains_key(&s));
            // What is kept is what was used last: slice 0, then the latest ones.
            let mut kept: Vec<i64> = cache.slices.keys().copied().filter(|&k| k > 0).collect();
            kept.sort_unstable();
            assert_eq!(kept, (s + 1 - kept.len() as i64..=s).collect::<Vec<_>>());
        }
        assert!(trimmed > 3, "trimmed {trimmed} times");
    }

    /// A vertex of a contour of every plane of a 16³ volume that the surface crosses (with its
    /// plane): the first edge along x there that crosses the surface.
    fn contour_starts(vol: &MaskVolume) -> Vec<(Vertex, i64)> {
        (0..16)
            .filter_map(|w| {
                let p = (0..15 * 16)
                    .map(|k| [k % 15, k / 15, w])
                    .find(|&[x, y, z]| vol.get(x, y, z) != vol.get(x + 1, y, z))?;
                Some((Vertex { p, axis: 0 }, w))
            })
            .collect()
    }

    /// Slices cached before an edit are built again once `invalidate` names the planes
    /// edited: the cache then serves the edited surface, slice for slice as a fresh build.
    /// The contours of the planes the forgotten slices hold are forgotten too, and only they
    /// (with their vertices' count).
    #[test]
    fn an_invalidated_cache_serves_the_edited_slices() {
        let conn = Connectivity::Six;
        let mut vol = sponge(16, 0x2545_f491_4f6c_dd1d);
        let mut cache = SliceCache::new(conn);
        for s in 0..15 {
            cache.ensure(&vol, s);
        }
        let mut g = Graph::new(&vol, cases(conn));
        for (v, w) in contour_starts(&vol) {
            cache.contour(&mut g, v, w).unwrap();
        }
        let planes = |cache: &SliceCache| -> std::collections::BTreeSet<i64> {
            cache.contours.keys().map(|&(w, _)| w).collect()
        };
        assert!(planes(&cache).len() > 10, "{:?}", planes(&cache));
        let mut kept = planes(&cache);
        kept.retain(|w| !(5..=9).contains(w));
        // Planes 6 ..= 8 edited: slices 5 ..= 8 hold them.
        for z in 6..=8 {
            for y in 5..=7 {
                for x in 5..=7 {
                    let inside = vol.get(x, y, z);
                    vol.set(x as usize, y as usize, z as usize, !inside);
                }
            }
        }
        cache.invalidate(6, 8);
        assert_eq!(
            planes(&cache),
            kept,
            "the contours of planes 5 ..= 9 forgotten"
        );
        let vertices: usize = cache.contours.values().map(|c| c.len()).sum();
        assert_eq!(cache.contour_vertices, vertices);
        let cubes = |sl: &SliceSurfels| -> Vec<(u32, u32, u8)> {
            sl.cubes.iter().map(|c| (c.i, c.j, c.case)).collect()
        };
        let mut changed = 0;
        for s in 0..15 {
            let fresh = SliceSurfels::build(vol.plane(s), vol.plane(s + 1), s as i32, conn);
            changed += usize::from(
                cache
                    .slices
                    .get(&s)
                    .is_none_or(|(sl, _)| cubes(sl) != cubes(&fresh)),
            );
            cache.ensure(&vol, s);
            assert_eq!(cubes(&cache.slices[&s].0), cubes(&fresh), "slice {s}");
        }
        assert_eq!(changed, 4, "slices 5 ..= 8 forgotten, the others kept");
    }

    /// A ribbon as a region holds exactly its pieces. The oracle: pieces of one slice that
    /// share a vertex lie on one sheet within the slice (a vertex's neighbourhood on the surface
    /// is a disk, cut by the slab in a half-disk), so the ribbons are the classes of pieces
    /// joined by shared vertices. Each class is one ribbon's, each piece allowed by one
    /// ribbon only, and no piece of another slice is allowed.
    #[test]
    fn a_ribbon_region_holds_the_pieces_its_vertices_join() {
        let conn = Connectivity::Six;
        let vol = sponge(16, 0x9e37_79b9_7f4a_7c15);
        let table = cases(conn);
        let (mut later_pieces, mut ribbons) = (0, 0);
        for s in 0..15 {
            let sl = SliceSurfels::build(vol.plane(s), vol.plane(s + 1), s as i32, conn);
            let mut pieces = Vec::new();
            let mut classes = crate::unionfind::UnionFind::new(sl.piece_ribbon.len());
            let mut first_at: FastMap<u64, u32> = FastMap::default();
            for cube in &sl.cubes {
                let q = [cube.i as i64 - 1, cube.j as i64 - 1, s];
                for (k, piece) in table[cube.case as usize].pieces.iter().enumerate() {
                    let id = cube.first_piece + k as u32;
                    pieces.push((
                        PieceRef {
                            cube: q,
                            index: k as u8,
                            part: 0,
                        },
                        id,
                    ));
                    later_pieces += usize::from(k > 0);
                    for &e in piece.loops.iter().flatten() {
                        let key = crate::surface::vertex_of(q, e).key();
                        let other = *first_at.entry(key).or_insert(id);
                        classes.union(other, id);
                    }
                }
            }
            let mut class_of_ribbon: FastMap<u32, u32> = FastMap::default();
            for ribbon in 0..sl.ribbons.len() as u32 {
                let region = OneRibbon {
                    sl: &sl,
                    slice: s,
                    ribbon,
                };
                for &(p, id) in &pieces {
                    let class = classes.find(id);
                    if region.allows(&p) {
                        let c = *class_of_ribbon.entry(ribbon).or_insert(class);
                        assert_eq!(c, class, "slice {s}, ribbon {ribbon}, piece {p:?}");
                    }
                    let elsewhere = PieceRef {
                        cube: [p.cube[0], p.cube[1], s + 1],
                        ..p
                    };
                    assert!(!region.allows(&elsewhere));
                }
            }
            for &(p, id) in &pieces {
                let owners: Vec<u32> = (0..sl.ribbons.len() as u32)
                    .filter(|&ribbon| {
                        OneRibbon {
                            sl: &sl,
                            slice: s,
                            ribbon,
                        }
                        .allows(&p)
                    })
                    .collect();
                assert_eq!(owners.len(), 1, "slice {s}, piece {p:?}: {owners:?}");
                assert_eq!(class_of_ribbon[&owners[0]], classes.find(id));
            }
            let distinct: std::collections::HashSet<u32> =
                class_of_ribbon.values().copied().collect();
            assert_eq!(
                distinct.len(),
                sl.ribbons.len(),
                "slice {s}: one class a ribbon"
            );
            ribbons += sl.ribbons.len();
        }
        assert!(ribbons > 40, "{ribbons} ribbons");
        assert!(
            later_pieces > 24,
            "{later_pieces} pieces not first in their cube"
        );
    }

    /// The contours and cheap loops a cache keeps stay within their limits: past one, all are
    /// forgotten and counting starts again, and the count is always that of what is held.
    /// A sponge's contours, one per plane, under a limit of about three of them; cheap loops
    /// kept by key, one key kept twice (the second replaces the first).
    #[test]
    fn a_caches_contours_and_cheap_loops_stay_within_their_limits() {
        let conn = Connectivity::Six;
        let vol = sponge(16, 0x2545_f491_4f6c_dd1d);
        let mut cache = SliceCache::new(conn);
        let mut g = Graph::new(&vol, cases(conn));
        let starts = contour_starts(&vol);
        let sizes: Vec<usize> = starts
            .iter()
            .map(|&(v, w)| cache.contour(&mut g, v, w).unwrap().len())
            .collect();
        assert!(sizes.len() > 10, "{sizes:?}");
        let held = |cache: &SliceCache| cache.contours.values().map(|c| c.len()).sum::<usize>();
        assert_eq!(cache.contour_vertices, held(&cache));
        let limit = 3 * sizes.iter().max().unwrap();
        let mut cache = SliceCache::new(conn);
        cache.limits.contour_vertices = limit;
        let mut cleared = 0;
        for &(v, w) in &starts {
            let before = cache.contours.len();
            cache.contour(&mut g, v, w).unwrap();
            cleared += usize::from(cache.contours.len() <= before);
            assert_eq!(cache.contour_vertices, held(&cache), "plane {w}");
            assert!(cache.contour_vertices <= limit, "plane {w}");
            assert!(cache.contours.contains_key(&(w, v.key())), "plane {w}");
        }
        assert!(cleared >= 2, "forgotten {cleared} times");
        // Exactly at the limit nothing is forgotten; one vertex over it, all is.
        for extra in [0, 1] {
            let mut cache = SliceCache::new(conn);
            cache.limits.contour_vertices = sizes[0] + sizes[1] - extra;
            for &(v, w) in &starts[..2] {
                cache.contour(&mut g, v, w).unwrap();
            }
            assert_eq!(cache.contours.len(), 2 - extra, "limit {} less", extra);
        }

        let mut cache = SliceCache::new(conn);
        cache.limits.cheap_vertices = 20;
        let held = |cache: &SliceCache| cache.cheap.paths.values().map(|c| c.len()).sum::<usize>();
        // 6 + 8, then 4 in place of 6 (12 held), 8 (20: at the limit, all kept), then 9 and
        // 20 each forget all.
        let mut kept = Vec::new();
        for (key, n) in [(1, 6), (2, 8), (1, 4), (3, 8), (4, 9), (5, 20)] {
            cache.keep_cheap(key, &row(n));
            assert_eq!(cache.cheap.vertices, held(&cache), "key {key}");
            assert!(cache.cheap.vertices <= 20, "key {key}");
            assert_eq!(cache.kept_cheap(key), Some(row(n)), "key {key}");
            kept.push(cache.cheap.paths.len());
        }
        assert_eq!(kept, [1, 2, 2, 3, 1, 1]);
        // The walks' stretches, the same way.
        let mut cache = SliceCache::new(conn);
        cache.limits.segment_vertices = 20;
        let held = |cache: &SliceCache| {
            cache
                .segments
                .paths
                .values()
                .map(|c| c.len())
                .sum::<usize>()
        };
        let mut kept = Vec::new();
        for (key, n) in [(1, 6), (2, 8), (1, 4), (3, 8), (4, 9), (5, 20)] {
            let key = (key, 0, 0, (0, 0));
            cache.keep_segment(key, &row(n));
            assert_eq!(cache.segments.vertices, held(&cache), "key {key:?}");
            assert!(cache.segments.vertices <= 20, "key {key:?}");
            assert_eq!(cache.segment(&key), Some(row(n)), "key {key:?}");
            kept.push(cache.segments.paths.len());
        }
        assert_eq!(kept, [1, 2, 2, 3, 1, 1]);
    }

    /// `n` vertices in a row along x: a path for the caches' bookkeeping, which reads only keys.
    fn row(n: usize) -> Vec<Vertex> {
        (0..n as i64)
            .map(|i| Vertex {
                p: [i, 0, 0],
                axis: 1,
            })
            .collect()
    }

    /// A new cache keeps 2^20 vertices of cheap loops and 2^20 of walk stretches (8 MiB each):
    /// sixteen paths of 2^16, all held; one vertex more forgets them.
    #[test]
    fn a_new_cache_keeps_a_million_vertices_of_cheap_loops_and_of_stretches() {
        let mut cache = SliceCache::new(Connectivity::Six);
        let long = row(1 << 16);
        for key in 0..16 {
            cache.keep_cheap(key, &long);
            cache.keep_segment((key as i64, 0, 0, (0, 0)), &long);
        }
        assert_eq!(
            (cache.cheap.paths.len(), cache.segments.paths.len()),
            (16, 16)
        );
        cache.keep_cheap(16, &row(1));
        cache.keep_segment((16, 0, 0, (0, 0)), &row(1));
        assert_eq!(
            (cache.cheap.paths.len(), cache.segments.paths.len()),
            (1, 1)
        );
    }

    /// Between handles the cache keeps the sweep's slices up to 48 MiB (a walk round a tall
    /// cycle needs each of its slices in turn; rebuilding them was a fifth of a run on noise);
    /// past that it forgets the least recently offered until half is left.
    #[test]
    fn the_slice_cache_keeps_48_mib_and_forgets_the_oldest() {
        // `bottom` holds u32s: 1 MiB per 2^18 of capacity.
        let slice = |mib: usize| crate::topology::slice::SliceSurfels {
            bottom: Vec::with_capacity(mib << 18),
            ..Default::default()
        };
        let mut cache = SliceCache::new(Connectivity::Six);
        // Twelve of 4 MiB, offered from the highest down: 48 MiB, all kept.
        for s in (0..12).rev() {
            cache.offer(s, slice(4));
        }
        assert_eq!(cache.slices.len(), 12);
        // One more: the seven offered first (11 down to 5) go, 24 MiB are left.
        cache.offer(100, slice(4));
        let mut kept: Vec<i64> = cache.slices.keys().copied().collect();
        kept.sort_unstable();
        assert_eq!(kept, [0, 1, 2, 3, 4, 100]);
    }

    /// A closed polyline's length in millimetres: a rectangle 3 × 2 voxels with spacing
    /// (0.5, 2, 1) mm is 2 × (1.5 + 4) mm round, its closing edge included, and a rotation
    /// of the axes does not change it; stood up with its long side along z, 2 × (3 + 4) mm; a
    /// triangle closes along its diagonal; one point alone has no length.
    #[test]
    fn polyline_lengths_close_the_loop_in_millimetres() {
        let rect = [
            [0.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [3.0, 2.0, 0.0],
            [0.0, 2.0, 0.0],
        ];
        let spacing = Affine::from_spacing([0.5, 2.0, 1.0], [10.0, -4.0, 7.0]);
        assert!((polyline_mm(&rect, &spacing) - 11.0).abs() < 1e-12);
        let turned = Affine::from_parts(
            [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            [0.5, 2.0, 1.0],
            [0.0; 3],
        );
        assert!((polyline_mm(&rect, &turned) - 11.0).abs() < 1e-12);
        // The same rectangle stood up in the y-z plane: 3 voxels along z (1 mm), 2 along y.
        let standing = rect.map(|[x, y, _]| [0.0, y, x]);
        assert!((polyline_mm(&standing, &spacing) - 14.0).abs() < 1e-12);
        // Three points: the closing edge is the diagonal, 1.5 mm by 4 mm.
        let diagonal = (1.5f64 * 1.5 + 4.0 * 4.0).sqrt();
        assert!((polyline_mm(&rect[..3], &spacing) - (1.5 + 4.0 + diagonal)).abs() < 1e-12);
        assert_eq!(polyline_mm(&rect[..1], &spacing), 0.0);
    }

    /// Smoothed random noise (`n`³, a 3×3×3 box filter), thresholded at its median: a sponge
    /// whose slices hold many intra-ribbon handles.
    fn sponge(n: usize, seed: u64) -> MaskVolume {
        let mut rng = Rng(seed);
        let mut next = || rng.unit();
        let raw: Vec<f64> = (0..n * n * n).map(|_| next()).collect();
        let at = |x: usize, y: usize, z: usize| raw[(z * n + y) * n + x];
        let mut vol = MaskVolume::new([n, n, n], Frame::identity());
        for z in 1..n - 1 {
            for y in 1..n - 1 {
                for x in 1..n - 1 {
                    let mut sum = 0.0;
                    for (dx, dy, dz) in box_offsets() {
                        sum += at(x + dx - 1, y + dy - 1, z + dz - 1);
                    }
                    vol.set(x, y, z, sum > 13.5);
                }
            }
        }
        vol
    }

    /// A square ring standing across the sweep (in the xz-plane, x and z 2..12), its tube `w`
    /// voxels thick (and deep along y), in 14 × 8 × 14.
    fn standing_ring(w: usize) -> MaskVolume {
        let mut vol = MaskVolume::new([14, 8, 14], Frame::identity());
        for (x, y, z) in (0..14 * 8 * 14).map(|k| (k % 14, (k / 14) % 8, k / 112)) {
            let outer = (2..12).contains(&x) && (2..12).contains(&z);
            let hole = (2 + w..12 - w).contains(&x) && (2 + w..12 - w).contains(&z);
            vol.set(x, y, z, outer && !hole && (2..2 + w).contains(&y));
        }
        vol
    }

    /// The handles a sweep along z finds in `vol`.
    fn sweep_z(vol: &mut MaskVolume, conn: Connectivity) -> crate::sweep::HandleReport {
        let progress = crate::progress::NoProgress;
        crate::sweep::find_handles(vol, crate::grid::Axis::Z, conn, &progress).unwrap()
    }

    /// The intra-ribbon tests' cases: a sponge of each side in `sides` (seeded `seed` ^ its
    /// place in the list) under each connectivity, with the handles a sweep along z finds.
    fn swept_sponges(
        sides: &[usize],
        seed: u64,
    ) -> impl Iterator<Item = (usize, Connectivity, MaskVolume, crate::sweep::HandleReport)> + '_
    {
        sides.iter().enumerate().flat_map(move |(round, &n)| {
            [Connectivity::Six, Connectivity::TwentySix].map(move |conn| {
                let mut vol = sponge(n, seed ^ round as u64);
                let r = sweep_z(&mut vol, conn);
                (n, conn, vol, r)
            })
        })
    }

    /// The 27 offsets (each 0, 1 or 2) of a 3×3×3 box.
    fn box_offsets() -> impl Iterator<Item = (usize, usize, usize)> {
        (0..27).map(|k| (k % 3, (k / 3) % 3, k / 9))
    }

    /// The loop looked for in boxes round an intra-ribbon handle's cut is as short as the one
    /// the search of its whole original slice finds (a loop under 2m edges found m voxels out
    /// cannot be beaten by one farther away): every intra-ribbon handle of random sponges.
    #[test]
    fn the_loop_near_a_cut_is_as_short_as_the_whole_slices() {
        let (mut checked, mut beyond_first_box) = (0, 0);
        for (n, conn, _, r) in swept_sponges(&[24, 32, 40], 0x9e37_79b9_7f4a_7c15) {
            for h in &r.handles {
                let CycleVolume::Mini(mini) = &h.located.volume else {
                    continue;
                };
                let allowed = h.located.allowed.unwrap();
                let cut = &h.located.cut;
                let mut g = Graph::new(mini, cases(conn));
                let near = shortest_odd_loop_near(&mut g, cut, allowed);
                let whole = InBox::cubes(allowed.0, allowed.1);
                let whole = odd_loop(&mut g, cut, &whole, usize::MAX);
                assert!(whole.exact);
                let (a, b) = (near.map(|l| l.len()), whole.found.map(|l| l.len()));
                assert_eq!(a, b, "n {n} {conn:?}: handle at {:?}", h.located.bbox);
                checked += 1;
                beyond_first_box += usize::from(a.is_some_and(|l| l >= 8));
            }
        }
        assert!(checked > 300, "{checked} handles checked");
        assert!(
            beyond_first_box > 10,
            "{beyond_first_box} loops beyond the first box"
        );
    }

    /// The pieces picked round an intra-ribbon handle's cycle in its mini-volume are those of
    /// the cycle's ribbons, within the original slice (some for every cycle), and for most
    /// handles a loop crossing the cut once lies among them (the others are looked for in the
    /// whole slice): every intra-ribbon handle of sponges found by a mini-volume's sweep.
    #[test]
    fn a_loop_round_a_mini_cycle_lies_among_its_ribbons_pieces() {
        let (mut checked, mut found) = (0, 0);
        for (_, conn, _, r) in swept_sponges(&[24, 32], 0x2545_f491_4f6c_dd1d) {
            let mut rows = MiniRows::default();
            for h in &r.handles {
                let l = &h.located;
                let CycleVolume::Mini(mini) = &l.volume else {
                    continue;
                };
                if l.direct {
                    continue;
                }
                let allowed = l.allowed.unwrap();
                let region = mini_cycle_region(mini, h, allowed, conn, &mut rows);
                assert!(!region.0.is_empty(), "no piece round the cycle");
                // Every piece is of a ribbon of the cycle, told from a fresh slice.
                let table = cases(conn);
                for &(cube, k) in region.0.keys() {
                    let s = cube[2];
                    let sl = SliceSurfels::build(mini.plane(s), mini.plane(s + 1), s as i32, conn);
                    let c = sl
                        .find_cube((cube[0] + 1) as u32, (cube[1] + 1) as u32)
                        .unwrap();
                    assert!((k as usize) < table[sl.cubes[c].case as usize].n_pieces as usize);
                    let ribbon = sl.piece_ribbon[sl.cubes[c].first_piece as usize + k as usize];
                    assert!(l.cycle.iter().any(|n| n.kind == NodeKind::Ribbon
                        && n.level as i64 == s
                        && n.local == ribbon));
                    assert_eq!(cube[1], allowed.0[1]);
                }
                let mut g = Graph::new(mini, cases(conn));
                let lp = odd_loop(&mut g, &l.cut, &region, usize::MAX).found;
                checked += 1;
                found += usize::from(lp.is_some());
            }
        }
        // Measured: 345 of 396 (the others' loops leave the cycle's ribbons).
        assert!(
            checked > 300 && found * 10 >= checked * 8,
            "{found} of {checked}"
        );
    }

    /// A torus lying within one slice (two C's in consecutive planes, open on opposite sides:
    /// the paper's figure 7) is a ribbon of genus 1: with its boundary contours capped, two
    /// generators. The C's faces in the slices below and above are disks: none.
    ///
    /// ```text
    ///   plane 4   C open towards -x      together: a ring whose two halves
    ///   plane 3   C open towards +x      overlap where the C's do
    /// ```
    #[test]
    fn a_torus_within_one_slice_gives_its_ribbon_two_generators() {
        let conn = Connectivity::Six;
        let mut vol = MaskVolume::new([26, 26, 8], Frame::identity());
        for (x, y, z) in (0..26).flat_map(|x| (0..26).flat_map(move |y| [(x, y, 3), (x, y, 4)])) {
            let (dx, dy) = (x as f64 - 12.6, y as f64 - 12.4);
            let (r, a) = (dx.hypot(dy), dy.atan2(dx).to_degrees());
            let opening = if z == 3 {
                a.abs() < 35.0
            } else {
                a.abs() > 145.0
            };
            vol.set(x, y, z, (2.5..8.5).contains(&r) && !opening);
        }
        let mut g = Graph::new(&vol, cases(conn));
        let mut cache = SliceCache::new(conn);
        let mut counts = Vec::new();
        for s in 0..7 {
            cache.ensure(&vol, s);
            let n = cache.slices.get(&s).map_or(0, |(sl, _)| sl.ribbons.len());
            for r in 0..n as u32 {
                let gens = ribbon_generators(&mut g, &mut cache, s, r).unwrap_or_default();
                counts.push((s, gens.len()));
            }
        }
        assert_eq!(counts, [(2, 0), (3, 2), (4, 0)]);
    }

    /// The generators of the part of a ribbon in a box lie in the box: on a sponge, for every
    /// ribbon of a slice with generators, the box round its first generator (two cubes wider)
    /// gives generators again, every vertex of them within it.
    #[test]
    fn generators_of_a_ribbon_within_a_box_lie_in_it() {
        let conn = Connectivity::Six;
        let vol = sponge(24, 0x5851_f42d_4c95_7f2d);
        let mut g = Graph::new(&vol, cases(conn));
        let mut cache = SliceCache::new(conn);
        let (mut ribbons, mut found) = (0, 0);
        for s in 0..23 {
            cache.ensure(&vol, s);
            let n = cache.slices.get(&s).map_or(0, |(sl, _)| sl.ribbons.len());
            for r in 0..n as u32 {
                let all = ribbon_generators(&mut g, &mut cache, s, r).unwrap_or_default();
                let Some(first) = all.first() else { continue };
                // The cubes round vertex v have lower corners v.p - 1 ..= v.p.
                let lo: [i64; 3] =
                    std::array::from_fn(|k| first.iter().map(|v| v.p[k]).min().unwrap() - 3);
                let hi: [i64; 3] =
                    std::array::from_fn(|k| first.iter().map(|v| v.p[k]).max().unwrap() + 2);
                let (lo, hi) = ([lo[0], lo[1], s], [hi[0], hi[1], s]);
                // A box round the whole slice holds all of the ribbon's generators.
                let whole = ([-1, -1, s], [24, 24, s]);
                let within = ribbon_generators_within(&mut g, &mut cache, s, r, Some(whole));
                assert_eq!(within.as_ref(), Some(&all), "slice {s} ribbon {r}");
                let near = ribbon_generators_within(&mut g, &mut cache, s, r, Some((lo, hi)));
                let near = near.unwrap_or_default();
                for v in near.iter().flatten() {
                    let within = (0..2).all(|k| v.p[k] >= lo[k] && v.p[k] <= hi[k] + 1);
                    assert!(
                        within,
                        "slice {s} ribbon {r}: {v:?} outside {lo:?} ..= {hi:?}"
                    );
                }
                ribbons += 1;
                found += usize::from(!near.is_empty());
            }
        }
        assert!(ribbons > 20, "{ribbons} ribbons with generators");
        assert!(
            found * 2 > ribbons,
            "{found} of {ribbons} boxes hold generators"
        );
    }

    /// The slice cache keeps to its budget: a slice offered beyond it sends the least recently
    /// used ones away (down to half the budget), never the newest; under it nothing goes.
    #[test]
    fn the_slice_cache_keeps_to_its_budget() {
        let conn = Connectivity::Six;
        let vol = sponge(24, 0x5eed_cafe);
        let build = |s: i64| SliceSurfels::build(vol.plane(s), vol.plane(s + 1), s as i32, conn);
        let total: usize = (0..23).map(|s| slice_bytes(&build(s))).sum();
        let (mut tight, mut roomy) = (SliceCache::new(conn), SliceCache::new(conn));
        tight.budget = total / 4;
        // Room for all, though not for all twice.
        roomy.budget = total + total / 2;
        for s in 0..23 {
            tight.offer(s, build(s));
            roomy.offer(s, build(s));
            let held: usize = tight.slices.values().map(|(sl, _)| slice_bytes(sl)).sum();
            assert_eq!(tight.bytes, held);
            assert!(
                tight.bytes <= tight.budget,
                "slice {s}: {} bytes",
                tight.bytes
            );
            assert!(tight.slice(s).is_some(), "slice {s} forgotten at once");
        }
        assert!(tight.slices.len() < 23);
        assert_eq!(roomy.slices.len(), 23);
    }

    /// The loop chained round a top-level handle's Reeb cycle (ribbon by ribbon, then along the
    /// cut the shorter way) is found for every such handle of random sponges, is simple and
    /// crosses the cut once.
    #[test]
    fn a_chained_loop_goes_once_round_every_top_level_cycle() {
        let conn = Connectivity::Six;
        // Square rings standing across the sweep, of tubes 1 to 3 voxels thick: a path along
        // a flat side comes back to the vertex of the cut it left from.
        let volumes = (1..=3)
            .map(standing_ring)
            .chain((0..3u64).map(|seed| sponge(24, 0x9e37_79b9_7f4a_7c15 ^ seed)));
        let mut chained = 0;
        for mut vol in volumes {
            let r = sweep_z(&mut vol, conn);
            let mut g = Graph::new(&vol, cases(conn));
            let mut cache = SliceCache::new(conn);
            for h in &r.handles {
                let l = &h.located;
                let (n, m) = (l.cycle.len(), l.cut.len());
                let eligible = matches!(l.volume, CycleVolume::Top)
                    && m >= 2
                    && n >= 4
                    && n.is_multiple_of(2)
                    && l.contour_starts.len() == n
                    && l.cycle[l.cut_at].kind == NodeKind::Contour;
                if !eligible {
                    continue;
                }
                let lp = chained_reeb_loop(&mut g, &mut cache, &h.located);
                let lp = lp.unwrap_or_else(|| panic!("no chained loop round a cycle of {n}"));
                assert_eq!(crossing_parity(&mut g, &lp, &l.cut), Some(1));
                let distinct: std::collections::HashSet<Vertex> = lp.iter().copied().collect();
                assert_eq!(distinct.len(), lp.len(), "not simple");
                // Back along the cut the shorter way: at most half of it ends the walk.
                let back = lp.iter().rev().take_while(|v| l.cut.contains(v)).count();
                assert!(back <= m / 2, "{back} of a cut of {m} walked back");
                chained += 1;
            }
        }
        assert!(chained > 20, "{chained} chained");
    }

    /// The stretches of the chained walks, kept by ribbon, entry and end: walked again on the
    /// same volume, every stretch comes from the cache (nothing new is kept) and the walks are
    /// the same; after an edit across the middle planes, the walks from the cache (its stretches
    /// near the edit forgotten) are those a fresh cache finds.
    #[test]
    fn a_walk_from_kept_stretches_is_the_walk_found_afresh() {
        let conn = Connectivity::Six;
        let mut walked = 0;
        for seed in 0..3u64 {
            let mut vol = sponge(24, 0x51ed_270b_1a2e_9c3d ^ seed);
            let r = sweep_z(&mut vol, conn);
            let eligible: Vec<&Handle> = r
                .handles
                .iter()
                .filter(|h| h.located.cycle.len() >= 4 && h.located.cut.len() >= 2)
                .collect();
            let mut cache = SliceCache::new(conn);
            let walks = |vol: &MaskVolume, cache: &mut SliceCache| -> Vec<Option<Vec<Vertex>>> {
                let mut g = Graph::new(vol, cases(conn));
                eligible
                    .iter()
                    .map(|h| chained_reeb_loop(&mut g, cache, &h.located))
                    .collect()
            };
            let first = walks(&vol, &mut cache);
            let kept = cache.segments.paths.len();
            assert!(kept > 20, "{kept} stretches kept");
            assert_eq!(walks(&vol, &mut cache), first, "walked again");
            assert_eq!(
                cache.segments.paths.len(),
                kept,
                "every stretch served by the cache"
            );
            for z in 11..=12 {
                for y in 4..20 {
                    for x in 8..=9 {
                        let inside = vol.get(x, y, z);
                        vol.set(x as usize, y as usize, z as usize, !inside);
                    }
                }
            }
            cache.invalidate(11, 12);
            assert!(
                cache.segments.paths.len() < kept,
                "stretches near the edit forgotten"
            );
            let fresh = walks(&vol, &mut SliceCache::new(conn));
            assert_eq!(walks(&vol, &mut cache), fresh, "seed {seed}");
            walked += fresh.iter().flatten().count();
        }
        assert!(walked > 20, "{walked} walks");
    }

    /// An edit of planes `w0 ..= w1` forgets the stretches through slices `w0 - 2 ..= w1 + 1`
    /// (their edges' neighbourhoods take corners from a plane below and two above) and keeps
    /// the others, with the count of vertices held.
    #[test]
    fn an_edit_forgets_the_stretches_whose_neighbourhoods_it_touches() {
        let mut cache = SliceCache::new(Connectivity::Six);
        for s in 0..15 {
            cache.keep_segment((s, 0, 7, (1, 2)), &row(s as usize + 1));
        }
        cache.invalidate(6, 8);
        let left: Vec<i64> = {
            let mut v: Vec<i64> = cache.segments.paths.keys().map(|k| k.0).collect();
            v.sort_unstable();
            v
        };
        assert_eq!(left, [0, 1, 2, 3, 10, 11, 12, 13, 14]);
        let held: usize = cache.segments.paths.values().map(|p| p.len()).sum();
        assert_eq!(cache.segments.vertices, held);
        assert_eq!(cache.segment(&(3, 0, 7, (1, 2))), Some(row(4)));
        assert_eq!(cache.segment(&(3, 1, 7, (1, 2))), None, "another ribbon");
    }

    /// The `Q1` kept for the next intra-ribbon handle with the same `P` (see `first_loop`) is
    /// taken again only while it still crosses `P` once: measured again on the same volume the
    /// handle gets the same loops, and on a volume where the kept `Q1` was broken (its samples
    /// flipped) it is not taken, and the handle gets the same loops as with no kept `Q1`. Nor is
    /// it taken for a top-level cut, or under a limit.
    #[test]
    fn a_kept_first_loop_is_taken_again_only_while_it_still_crosses_p() {
        let limits = Limits {
            size_only: true,
            ..Limits::NONE
        };
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let conn = Connectivity::Six;
        let (mut kept, mut broken) = (0, 0);
        for seed in 0..3u64 {
            let seed = 0x9e37_79b9_7f4a_7c15 ^ seed;
            let mut vol = sponge(24, seed);
            let r = sweep_z(&mut vol, conn);
            let loops = |l: &HandleLoops| {
                let v = |x: &Option<Loop>| x.as_ref().map(|x| x.vertices.clone());
                (v(&l.reeb), v(&l.cross))
            };
            for h in &r.handles {
                if !matches!(h.located.volume, CycleVolume::Mini(_)) {
                    continue;
                }
                let mut cache = SliceCache::new(conn);
                let fresh = {
                    let mut g = Graph::new(&vol, cases(conn));
                    measure(&mut g, &mut cache, h, conn, &affine, limits)
                };
                let Some((_, q1)) = cache.ribbon_start.clone() else {
                    continue;
                };
                let cut = fresh.basis.as_ref().unwrap().0.clone();
                let geometry = Geometry {
                    affine: &affine,
                    fractions: None,
                };
                let searcher = Searcher {
                    metric: limits.metric,
                    geometry,
                };
                let mut g = Graph::new(&vol, cases(conn));
                let (_, taken) = first_loop(&mut g, &mut cache, &searcher, &cut, false, limits);
                assert!(taken, "the kept Q1 still crosses P once");
                // A top-level cut, or a limit (the loops must then be the shortest): never.
                let finite = Limits {
                    below: 1e9,
                    ..limits
                };
                let exact = Limits {
                    size_only: false,
                    ..limits
                };
                for (top_level, l) in [(true, limits), (false, finite), (false, exact)] {
                    let (_, taken) = first_loop(&mut g, &mut cache, &searcher, &cut, top_level, l);
                    assert!(!taken, "taken at top level {top_level} under {l:?}");
                }
                let again = measure(&mut g, &mut cache, h, conn, &affine, limits);
                assert_eq!(loops(&again), loops(&fresh));
                kept += 1;
                // Flip the samples round the kept Q1's first vertex: it no longer lies on
                // the surface as it was.
                let mut edited = sponge(24, seed);
                let p = q1[0].p;
                for (dx, dy, dz) in box_offsets() {
                    let q = [
                        p[0] + dx as i64 - 1,
                        p[1] + dy as i64 - 1,
                        p[2] + dz as i64 - 1,
                    ];
                    if (0..3).all(|k| q[k] > 0 && q[k] < 23) {
                        let (x, y, z) = (q[0] as usize, q[1] as usize, q[2] as usize);
                        let inside = edited.get(q[0], q[1], q[2]);
                        edited.set(x, y, z, !inside);
                    }
                }
                let mut g = Graph::new(&edited, cases(conn));
                if crossing_parity(&mut g, &q1, &cut) == Some(1) {
                    continue;
                }
                let (_, taken) = first_loop(&mut g, &mut cache, &searcher, &cut, false, limits);
                assert!(!taken, "a broken Q1 taken again");
                cache.ribbon_start = Some((cut.clone(), q1.clone()));
                let with_kept = measure(&mut g, &mut cache, h, conn, &affine, limits);
                let mut g = Graph::new(&edited, cases(conn));
                let mut empty = SliceCache::new(conn);
                let without = measure(&mut g, &mut empty, h, conn, &affine, limits);
                assert_eq!(loops(&with_kept), loops(&without));
                broken += 1;
            }
        }
        assert!(kept > 20 && broken > 20, "{kept} kept, {broken} broken");
    }

    /// With a limit (analyze, simplify at a finite tau) an intra-ribbon handle's pair is not
    /// refined: the cross loop `Q1` is the shortest crossing the cut `P`, and the Reeb loop is
    /// the shorter of `P` and `Q2`, the shortest crossing `Q1`; so when the searches are exact,
    /// no loop crossing the cross loop is shorter than the Reeb loop. Whether only the size
    /// matters or not: only with no limit too are the searches cheaper.
    #[test]
    fn an_intra_ribbon_reeb_loop_is_the_shortest_crossing_its_cross_loop() {
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let (mut checked, mut not_the_cut) = ([0; 2], 0);
        let sponges: Vec<_> = swept_sponges(&[24, 32], 0x2545_f491_4f6c_dd1d).collect();
        for (&(n, conn, ref vol, ref r), size_only) in
            sponges.iter().flat_map(|s| [(s, false), (s, true)])
        {
            let limits = Limits {
                below: 1000.0,
                size_only,
                ..Limits::NONE
            };
            let mut g = Graph::new(vol, cases(conn));
            let mut cache = SliceCache::new(conn);
            for h in &r.handles {
                if !matches!(h.located.volume, CycleVolume::Mini(_)) {
                    continue;
                }
                let l = measure(&mut g, &mut cache, h, conn, &affine, limits);
                let (Some(a), Some(b), true) = (&l.reeb, &l.cross, l.exact) else {
                    continue;
                };
                let (a, b) = (&a.vertices, &b.vertices);
                let within = refined_within(h, limits);
                let shorter = odd_loop(&mut g, b, &within, a.len());
                assert!(shorter.exact);
                let at = h.located.bbox;
                assert!(
                    shorter.found.is_none(),
                    "n {n} {conn:?}: handle at {at:?}: Reeb loop of {}, one of {} crosses \
                         the cross loop",
                    a.len(),
                    shorter.found.map_or(0, |x| x.len())
                );
                checked[usize::from(size_only)] += 1;
                let cut = &l.basis.as_ref().unwrap().0;
                not_the_cut += usize::from(a.len() < cut.len());
            }
        }
        // The same handles said exact whether only the size matters or not.
        assert_eq!(checked[0], checked[1]);
        assert!(
            checked[0] > 200 && not_the_cut > 40,
            "{checked:?} checked, {not_the_cut} not P"
        );
    }

    /// With no limit and only the size wanted (simplify at tau inf), an intra-ribbon handle's
    /// pair is refined from any loop crossing its cross loop, not the shortest. The two loops
    /// cross once, the refinement ends with one of them the shortest crossing the other within
    /// the swept part of the surface (no loop there crossing the Reeb loop is shorter than the
    /// cross loop, or none crossing the cross loop is shorter than the Reeb loop), the Reeb
    /// loop lies there (it does not drift onto a handle above the sweep), and the measurement
    /// is not said to be exact; the Reeb loop is no longer than the loop round the handle's mini
    /// cycle it started from.
    #[test]
    fn an_intra_ribbon_pair_refined_from_any_loop_ends_locally_shortest() {
        let limits = Limits {
            size_only: true,
            ..Limits::NONE
        };
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let mut checked = 0;
        for (n, conn, vol, r) in swept_sponges(&[24, 32], 0x2545_f491_4f6c_dd1d) {
            let mut g = Graph::new(&vol, cases(conn));
            let mut cache = SliceCache::new(conn);
            for h in &r.handles {
                if !matches!(h.located.volume, CycleVolume::Mini(_)) {
                    continue;
                }
                let l = measure(&mut g, &mut cache, h, conn, &affine, limits);
                let at = h.located.bbox;
                let (Some(a), Some(b)) = (&l.reeb, &l.cross) else {
                    panic!("n {n} {conn:?}: handle at {at:?} has no pair");
                };
                let (a, b) = (&a.vertices, &b.vertices);
                // The pair starts from the loop round the handle's mini cycle, or a shorter
                // one crossing `Q1`, and only gets shorter.
                let p = mini_volume_loop(h, conn, &vol, &mut cache.mini_rows)
                    .or_else(|| ribbon_loop(&mut g, &mut cache, h))
                    .unwrap();
                assert!(
                    a.len() <= p.len(),
                    "n {n} {conn:?}: {} > {}",
                    a.len(),
                    p.len()
                );
                let within = refined_within(h, limits);
                let shorter = |g: &mut Graph, x: &[Vertex], than: usize| {
                    let r = odd_loop(g, x, &within, than);
                    assert!(r.exact);
                    r.found.is_some()
                };
                assert_eq!(crossing_parity(&mut g, a, b), Some(1), "n {n} {conn:?}");
                // Refined from a loop that is not the shortest crossing `Q1`: not exact,
                // so not kept from pass to pass as if it were.
                assert!(!l.exact, "n {n} {conn:?}: handle at {at:?} said exact");
                let s = h.located.ribbon.unwrap().0;
                let inside = |x: &[Vertex]| x.iter().all(|v| v.p[2] <= s + 1);
                assert!(inside(a), "n {n} {conn:?}: Reeb loop above slice {s}");
                assert!(
                    !shorter(&mut g, a, b.len()) || !shorter(&mut g, b, a.len()),
                    "n {n} {conn:?}: handle at {at:?}: loops of {} and {} not refined",
                    a.len(),
                    b.len()
                );
                checked += 1;
            }
        }
        assert!(checked > 200, "{checked} handles checked");
    }

    /// The generator [`ribbon_loop`] takes for an intra-ribbon handle is one near where the
    /// handle was found: for every intra-ribbon handle of random sponges, the distance from the
    /// centre of the handle's box to the loop's nearest vertex. Measured: 1,048 of 1,268 within 2
    /// voxels, 1,170 within 4 (a loop nearest some other point of the ribbon: 674 and 863); and
    /// 1,228 lie wholly within the handle's box grown by 4 voxels, the first box looked in
    /// (the nearest generator of the whole ribbon: 799).
    #[test]
    fn a_ribbons_loop_passes_near_its_handle() {
        let mut distances = Vec::new();
        let mut in_box = 0;
        for (_, conn, vol, r) in swept_sponges(&[24, 32, 40], 0x2545_f491_4f6c_dd1d) {
            let mut g = Graph::new(&vol, cases(conn));
            let mut cache = SliceCache::new(conn);
            for h in r.handles.iter().filter(|h| h.located.ribbon.is_some()) {
                let b = &h.located.bbox;
                let centre = b.cube_centre();
                let lp = ribbon_loop(&mut g, &mut cache, h).expect("a ribbon loop");
                let distance = |v: &Vertex| {
                    let p = vol.frame.to_original(v.midpoint());
                    (0..3).map(|k| (p[k] - centre[k]).powi(2)).sum::<f64>()
                };
                distances.push(lp.iter().map(distance).fold(f64::INFINITY, f64::min).sqrt());
                let beyond = |v: &Vertex| {
                    let p = vol.frame.to_original(v.midpoint());
                    (0..3)
                        .map(|k| (b.min[k] as f64 - p[k]).max(p[k] - b.max[k] as f64 - 1.0))
                        .fold(0.0, f64::max)
                };
                in_box += usize::from(lp.iter().map(beyond).fold(0.0, f64::max) <= 4.0);
            }
        }
        let n = distances.len();
        let within = |d: f64| distances.iter().filter(|&&x| x <= d).count();
        assert!(n > 1000, "{n} intra-ribbon handles");
        assert!(within(2.0) * 4 >= n * 3, "{} of {n} within 2", within(2.0));
        assert!(within(4.0) * 10 >= n * 9, "{} of {n} within 4", within(4.0));
        assert!(
            in_box * 10 >= n * 9,
            "{in_box} of {n} within the box grown by 4"
        );
    }

    /// Where linking gave a handle's two loops the same side, the stronger link keeps its side
    /// and the other loop takes the opposite; sides that differ stay. A torus's equator and
    /// meridian (their linkings tell the sides apart: equator round void, meridian round
    /// material), given each pair of sides, in both orders.
    #[test]
    fn a_handles_two_loops_go_round_opposite_sides() {
        use Encloses::{Material, Void};
        let vol = crate::test_shapes::torus(24, 7.0, 2.6);
        let mut g = Graph::new(&vol, cases(Connectivity::Six));
        let (equator, meridian) = crate::surface::search::torus_equator_and_meridian(&mut g);
        let geometry = Geometry {
            affine: &Affine::from_spacing([1.0; 3], [0.0; 3]),
            fractions: None,
        };
        let eq = describe(&vol, &equator, Some(&meridian), &geometry);
        let me = describe(&vol, &meridian, Some(&equator), &geometry);
        assert_eq!((eq.encloses, me.encloses), (Void, Material));
        for (x, y) in [(&eq, &me), (&me, &eq)] {
            let stronger_first = link_strength(&vol, &x.vertices, &y.vertices)
                >= link_strength(&vol, &y.vertices, &x.vertices);
            for (sx, sy) in [
                (Void, Void),
                (Material, Material),
                (Void, Material),
                (Material, Void),
            ] {
                let (mut a, mut b) = (x.clone(), y.clone());
                (a.encloses, b.encloses) = (sx, sy);
                one_side_each(&vol, &mut a, &mut b);
                let want = if sx != sy {
                    (sx, sy)
                } else if stronger_first {
                    (sx, opposite(sx))
                } else {
                    (opposite(sy), sy)
                };
                assert_eq!((a.encloses, b.encloses), want, "{sx:?} {sy:?}");
            }
        }
    }

    /// A peeled wall moved along its loop's partner lies within half the partner of the loop
    /// (simplify's `Removed::partner`), because curves that cross once share a vertex and a
    /// curve's consecutive edge midpoints are at most a voxel apart on each axis. Checked on
    /// every handle's loops and basis curves (its cut and first loop) on sponges.
    #[test]
    fn crossing_curves_share_a_vertex_and_step_at_most_a_voxel() {
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let apart =
            |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f64::max);
        let mut pairs = 0;
        for (n, conn, vol, r) in swept_sponges(&[16, 20, 24], 0x0bad_5eed_1234_5678) {
            let mut g = Graph::new(&vol, cases(conn));
            let mut cache = SliceCache::new(conn);
            for h in &r.handles {
                let l = measure(&mut g, &mut cache, h, conn, &affine, Limits::NONE);
                let loops = l
                    .reeb
                    .iter()
                    .zip(&l.cross)
                    .map(|(a, b)| (&a.vertices, &b.vertices));
                for (a, b) in loops.chain(l.basis.iter().map(|(p, q)| (p, q))) {
                    for c in [a, b] {
                        for (k, v) in c.iter().enumerate() {
                            let next = c[(k + 1) % c.len()].midpoint();
                            assert!(apart(v.midpoint(), next) <= 1.0, "n {n} {conn:?}: a step");
                        }
                    }
                    assert!(
                        a.iter().any(|v| b.contains(v)),
                        "n {n} {conn:?}: no shared vertex"
                    );
                    pairs += 1;
                }
            }
        }
        assert!(pairs > 1000, "{pairs} pairs");
    }
}
