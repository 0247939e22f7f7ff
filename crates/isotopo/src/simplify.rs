//! Handle removal (paper §2.3): sweep, measure each handle as it is found, close the small ones,
//! rebuild the Reeb graph where the volume changed, and carry on.
//!
//! ```text
//!   slice s:  step the sweep ──> handles closed at s ──> measure their loops
//!                  ^                                         │ smaller than tau?
//!                  │                                         v
//!             rewind to the lowest slice the walls touched <── close (fill or cut)
//! ```
//!
//! A closure changes samples near its loop only, and can expose handles it did not remove
//! (a wall across a nested handle) or shorten the loops of others. Rewinding re-sweeps every
//! slice the walls touched, so newly exposed handles are found and measured like any other. A
//! handle measured before a later wall landed nearby may have become smaller than `tau`, so the
//! whole sweep runs again until a pass closes nothing: the last pass is exactly an analysis of
//! the result, and what it keeps is what is reported as kept.
//!
//! Every closure is verified locally before it is kept ([`closure::close`]): it removes one handle
//! of its own surface and changes nothing else, so b0 and b2 of the solid never change, which
//! is checked again on the whole volume at the end.

use crate::closure::{self, base_thickness, opposite, Operation};
use crate::error::{Error, Result};
use crate::grid::{Axis, MaskVolume};
use crate::loops::{self, Encloses, HandleLoops, Limits, Loop, Metric, SliceCache};
use crate::progress::Progress;
use crate::surface::geometry::Geometry;
use crate::surface::search::{FastMap, Graph, GraphCache};
use crate::surface::Vertex;
use crate::sweep::{Handle, HandleKind, LocatedHandle, Sweeper};
use crate::topology::cases::{cases, Connectivity};
use crate::topology::genus::SurfaceOptions;
use crate::topology::Classifier;
use crate::volume::{Affine, BBox, DType, Samples, SliceReader, VolumeInfo};
use std::path::Path;

/// Which closures are allowed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Fill or cut, whichever loop is smaller.
    Both,
    /// Only add material (close loops around void).
    FillOnly,
    /// Only remove material (close loops around material).
    CutOnly,
}

impl Mode {
    fn allows(self, op: Operation) -> bool {
        match self {
            Mode::Both => true,
            Mode::FillOnly => op == Operation::Collapse,
            Mode::CutOnly => op == Operation::Pinch,
        }
    }
}

/// What to simplify and how. Every field has a default (`SimplifyOptions::default()`); check a
/// hand-made one with [`SimplifyOptions::validate`] (the entry point [`crate::simplify()`] does).
#[derive(Clone, Copy, Debug)]
pub struct SimplifyOptions {
    /// The isosurface: isovalue (by default 0), inside above it (by default) and the solid's
    /// connectivity (by default 6).
    pub surface: SurfaceOptions,
    /// The axis the sweep runs along; by default z. The result does not depend on it beyond
    /// which of two equally short loops is closed.
    pub axis: Axis,
    /// Handles whose size (the shorter loop, in `metric` units) is below this are removed; by
    /// default 20 voxel edges (the gap between noise and features on the real volumes);
    /// infinity removes every handle.
    pub tau: f64,
    /// What `tau` is measured in: by default voxel edges (the paper's unit); or millimetres
    /// along the interpolated surface, for anisotropic scans.
    pub metric: Metric,
    /// Which closures are allowed; by default both filling and cutting.
    pub mode: Mode,
    /// Keep handles whose longer loop is more than this many times the shorter (long skinny
    /// handles, often real); by default none are kept for it.
    pub max_ratio: Option<f64>,
    /// Planes held in memory at once (the rest wait in a scratch file); by default as many as
    /// fit in 16 MiB, the whole volume when it fits; `Some(0)`: the whole volume.
    pub max_slices: Option<usize>,
}

impl Default for SimplifyOptions {
    fn default() -> SimplifyOptions {
        SimplifyOptions {
            surface: SurfaceOptions::default(),
            axis: Axis::Z,
            tau: 20.0,
            metric: Metric::Edges,
            mode: Mode::Both,
            max_ratio: None,
            max_slices: None,
        }
    }
}

impl SimplifyOptions {
    /// Refuses options no simplification can follow: tau not positive, a ratio below 1, an
    /// isovalue that is not a number.
    pub fn validate(&self) -> Result<()> {
        if self.tau.is_nan() || self.tau <= 0.0 {
            return Err(Error::usage("tau must be positive (or inf)"));
        }
        if self.max_ratio.is_some_and(|r| r.is_nan() || r < 1.0) {
            return Err(Error::usage("the maximum ratio must be at least 1"));
        }
        if !self.surface.iso.is_finite() {
            return Err(Error::usage("the isovalue must be a finite number"));
        }
        Ok(())
    }

    /// The searches' limits: longer loops cannot change a decision.
    pub fn limits(&self) -> Limits {
        Limits {
            below: self.tau * self.max_ratio.unwrap_or(1.0).max(1.0),
            metric: self.metric,
            // The ratio of the loops needs both measured; so does a mode that may close only
            // one kind (the longer loop may be the kind it can close).
            size_only: self.max_ratio.is_none() && self.mode == Mode::Both,
        }
    }
}

/// Which of a handle's loops.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LoopKind {
    Reeb,
    Cross,
}

/// A handle that was removed.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Removed {
    /// The handle's size: its shorter loop (voxel edges, and millimetres).
    pub size: usize,
    pub size_mm: f64,
    pub reeb: Option<usize>,
    pub cross: Option<usize>,
    pub kind: HandleKind,
    /// The loop that was closed, and how.
    #[serde(rename = "loop")]
    pub closed: LoopKind,
    pub operation: Operation,
    /// Length of the closed loop (voxel edges and mm).
    pub length: usize,
    pub length_mm: f64,
    /// Half-thickness of the wall (voxels): how far from the loop's fan its samples lie (for a
    /// `peeled_box` or `peeled_along` wall, the margin of the box it lies in).
    pub thickness: f64,
    /// How the wall was made: `fan` (the samples near the loop's spanning fan), `single_sample`,
    /// `peeled` (the samples near the fan thinned by simple samples and cut at the one sample
    /// that cuts the ring the loop goes round), `peeled_box` (the same in a box round the
    /// loop) or `peeled_along` (the same in that box moved along the other loop, where the
    /// ring is cut away from this loop: its samples may lie far from `points`).
    pub wall: &'static str,
    /// Samples this closure flipped: how many, and which (original coordinates).
    pub samples_changed: usize,
    pub samples: Vec<[i64; 3]>,
    /// Handles the wall removed: 1, or more when it also closed tiny handles right beside.
    pub handles: usize,
    /// Farthest flipped sample from the loop's polyline (voxels, and mm).
    pub max_distance: f64,
    pub max_distance_mm: f64,
    /// The closed loop: polyline through edge midpoints, original voxel coordinates.
    pub points: Vec<[f64; 3]>,
    pub bbox: BBox,
    /// Pass of the sweep (1-based) and slice at which it was closed.
    pub pass: usize,
    pub slice: i64,
}

/// Why a handle was kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum KeepReason {
    /// Both loops at or above tau.
    Size,
    /// Long and skinny: loop ratio above `--max-ratio`.
    Ratio,
    /// Its small loop is of the kind `--fill-only` / `--cut-only` excludes.
    Mode,
    /// No wall across its loops removed it cleanly.
    ClosureFailed,
    /// Its Reeb loop could not be found within the search budget.
    Unmeasured,
    /// Still below tau after the last pass allowed.
    PassLimit,
}

/// A handle left in the result.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Kept {
    /// The shorter loop's length in edges, and in millimetres.
    pub size: Option<usize>,
    pub size_mm: Option<f64>,
    pub reeb: Option<usize>,
    pub cross: Option<usize>,
    pub kind: HandleKind,
    pub reason: KeepReason,
    pub bbox: BBox,
}

/// A sample to change, in original coordinates, and whether it becomes inside.
pub type Edit = ([i64; 3], bool);

/// What simplification did.
#[derive(Clone, Debug)]
pub struct Outcome {
    pub removed: Vec<Removed>,
    /// The handles of the result (the last pass's analysis).
    pub kept: Vec<Kept>,
    /// Samples whose side changed, sorted by (z, y, x).
    pub edits: Vec<Edit>,
    /// Intra-ribbon handles the first pass met on its first visit of each slice.
    pub intra_ribbon: usize,
    /// Full sweeps run (the last one closed nothing, unless the limit was reached).
    pub passes: usize,
    /// With a finite tau (both operations, no `--max-ratio`): is it proven that the result has
    /// no non-separating loop shorter than tau? Every kept handle has two closed curves that no
    /// loop below tau crosses an odd number of times, and together they span every loop of the
    /// surface (see [`crate::loops::basis`]). `None` where no such promise is made.
    pub certified: Option<bool>,
    /// How often the sweep stepped back after closures.
    pub rewinds: usize,
    /// Closures tried and refused by the local check, and why.
    pub refused: usize,
    pub refused_by: std::collections::BTreeMap<&'static str, usize>,
    /// Seconds spent stepping the sweep, measuring loops and closing them.
    pub seconds: StageSeconds,
}

/// Where the time went.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StageSeconds {
    pub sweep: f64,
    pub loops: f64,
    pub closures: f64,
}

/// How many full sweeps may run; the last must close nothing.
const MAX_PASSES: usize = 8;

/// Loops this short that no fan wall closes get a try with single samples near their centroid,
/// within this reach (voxels; reported as the wall's thickness).
const SINGLE_SAMPLE_LOOP: usize = 8;
const SINGLE_SAMPLE_REACH: f64 = 1.8;

/// Wall half-thicknesses tried beyond the base one before giving up on a loop.
const EXTRA_THICKNESS: [f64; 3] = [0.0, 0.5, 1.0];

/// The thickest fan wall: the largest base thickness (√3/2) plus the largest extra.
const MAX_FAN_THICKNESS: f64 = 0.866_025_403_784_438_6 + 1.0;

/// The surface graph's neighbourhoods and the slices' surfels, kept between the steps of the
/// sweep (measuring from scratch costs ten times more) and brought up to date after each wall.
struct Caches {
    graph: GraphCache,
    slices: SliceCache,
    /// Loops measured in this pass, by handle: after a rewind, the sweep finds the handles
    /// above the walls again, and those whose loops lie away from every wall need not be
    /// measured again. (A stale entry can only delay a closure to the next pass: the last pass
    /// closes nothing, so its measurements are all fresh.)
    memo: FastMap<u64, HandleLoops>,
    /// Handles of this pass (by [`memo_key`]) whose every wall was refused: after a rewind
    /// they are kept again without trying, unless a wall landed near their loops since
    /// (which forgets their measurement too).
    failed: FastMap<u64, ()>,
}

/// Measurements that stay exact from pass to pass: a handle's loops are searched within a reach
/// of its curves (a loop shorter than r crossing a curve lies within r/2 edges of it, so within
/// r/√2 voxels: no edge of the surface graph is longer than √2), so until a wall lands within
/// that reach, measuring it again would find the same. The last pass, which must be an exact
/// analysis of the result, then measures again only what the walls came near.
#[derive(Default)]
struct Lasting {
    /// By [`memo_key`]: the loops, and their reach (local coordinates).
    entries: FastMap<u64, (HandleLoops, Reach)>,
}

/// Where the searches of a measurement reached: the blocks of [`LASTING_BLOCK`]³ samples within
/// the margin of its curves' vertices, or for a wide margin (long loops, no limit) the box.
enum Reach {
    Blocks(FastMap<[i64; 3], ()>),
    Box(BBox),
}

/// Side of the blocks a lasting measurement's reach is kept in.
const LASTING_BLOCK: i64 = 8;

/// Margins beyond which a reach is kept as a box (a vertex's blocks would be too many).
const LASTING_MAX_BLOCK_MARGIN: i64 = 4 * LASTING_BLOCK;

impl Lasting {
    fn get(&self, key: u64) -> Option<&HandleLoops> {
        self.entries.get(&key).map(|e| &e.0)
    }

    /// Keeps a fresh measurement if its reach is known: its searches were exact (no budget ran
    /// out), in voxel edges, and stopped at a finite limit (or found both loops).
    fn offer(&mut self, key: u64, l: &HandleLoops, limits: Limits) {
        let r = if limits.below.is_finite() {
            limits.below
        } else {
            match (&l.reeb, &l.cross) {
                (Some(a), Some(b)) => a.length.max(b.length) as f64,
                _ => return,
            }
        };
        if !l.exact || limits.metric != Metric::Edges {
            return;
        }
        let margin = (r * std::f64::consts::FRAC_1_SQRT_2).ceil() as i64 + 2;
        let curves = [&l.reeb, &l.cross]
            .into_iter()
            .flatten()
            .map(|x| &x.vertices[..]);
        let basis = l.basis.iter().flat_map(|(p, q)| [&p[..], &q[..]]);
        let vertices = curves.chain(basis).flatten();
        let reach = if margin > LASTING_MAX_BLOCK_MARGIN {
            let mut b = BBox::EMPTY;
            for v in vertices {
                b.include(v.p.map(|x| x - margin));
                b.include(v.p.map(|x| x + 1 + margin));
            }
            Reach::Box(b)
        } else {
            let mut blocks = FastMap::default();
            for v in vertices {
                let lo = v.p.map(|x| (x - margin).div_euclid(LASTING_BLOCK));
                let hi = v.p.map(|x| (x + 1 + margin).div_euclid(LASTING_BLOCK));
                for z in lo[2]..=hi[2] {
                    for y in lo[1]..=hi[1] {
                        for x in lo[0]..=hi[0] {
                            blocks.insert([x, y, z], ());
                        }
                    }
                }
            }
            Reach::Blocks(blocks)
        };
        self.entries.insert(key, (l.clone(), reach));
    }

    /// Forgets the measurements within reach of one of the walls (local boxes).
    fn forget_near(&mut self, walls: &[BBox]) {
        let touched: Vec<[i64; 3]> = walls
            .iter()
            .flat_map(|w| {
                let lo = w.min.map(|x| x.div_euclid(LASTING_BLOCK));
                let hi = w.max.map(|x| x.div_euclid(LASTING_BLOCK));
                (lo[2]..=hi[2]).flat_map(move |z| {
                    (lo[1]..=hi[1]).flat_map(move |y| (lo[0]..=hi[0]).map(move |x| [x, y, z]))
                })
            })
            .collect();
        self.entries.retain(|_, (_, reach)| match reach {
            Reach::Blocks(blocks) => !touched.iter().any(|b| blocks.contains_key(b)),
            Reach::Box(b) => !walls.iter().any(|w| overlaps(w, b, 0)),
        });
    }
}

/// Identity of a located handle across rewinds: its cut and where its cycle lies.
fn memo_key(h: &LocatedHandle) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut s = std::collections::hash_map::DefaultHasher::new();
    (h.kind == HandleKind::IntraRibbon).hash(&mut s);
    h.direct.hash(&mut s);
    h.cut.hash(&mut s);
    h.bbox.min.hash(&mut s);
    h.bbox.max.hash(&mut s);
    s.finish()
}

/// Neighbourhoods simplify keeps between handles before starting afresh: its searches stop at
/// tau, so a smaller graph than analyze's (`MEASURE_GRAPH_LIMIT`) serves, and memory stays near
/// the window's.
const SIMPLIFY_GRAPH_LIMIT: usize = 1 << 18;

impl Caches {
    /// Measures the handles one step of the sweep found.
    fn measure(
        &mut self,
        vol: &MaskVolume,
        new: &[LocatedHandle],
        conn: Connectivity,
        affine: &Affine,
        limits: Limits,
        lasting: &mut Lasting,
    ) -> Vec<HandleLoops> {
        if self.graph.len() > SIMPLIFY_GRAPH_LIMIT {
            self.graph = GraphCache::default();
        }
        let mut g = Graph::with_cache(vol, cases(conn), std::mem::take(&mut self.graph));
        let out = new
            .iter()
            .map(|h| {
                let key = memo_key(h);
                if let Some(l) = self.memo.get(&key).or_else(|| lasting.get(key)) {
                    return l.clone();
                }
                let h = Handle {
                    id: 0,
                    surface: 0,
                    located: h.clone(),
                };
                let l = loops::measure(&mut g, &mut self.slices, &h, conn, affine, limits);
                lasting.offer(key, &l, limits);
                self.memo.insert(key, l.clone());
                l
            })
            .collect();
        self.graph = g.into_cache();
        out
    }

    /// Forgets the measurements whose loops come near one of the walls.
    fn forget_near(&mut self, walls: &[BBox]) {
        self.memo.retain(|_, l| {
            [&l.reeb, &l.cross].into_iter().flatten().all(|x| {
                let b = loop_box(x);
                !walls.iter().any(|w| {
                    overlaps(w, &b, 2)
                        && x.vertices.iter().any(|v| {
                            let e = BBox { min: v.p, max: v.p };
                            overlaps(w, &e, 2)
                        })
                })
            })
        });
        let memo = &self.memo;
        self.failed.retain(|k, _| memo.contains_key(k));
    }
}

/// The loops worth closing, best first, or why none is.
fn plan<'l>(
    l: &'l HandleLoops,
    opts: &SimplifyOptions,
) -> std::result::Result<Vec<(LoopKind, &'l Loop)>, KeepReason> {
    let Some(reeb) = &l.reeb else {
        return Err(KeepReason::Unmeasured);
    };
    let small: Vec<(LoopKind, &Loop)> = [
        (LoopKind::Reeb, Some(reeb)),
        (LoopKind::Cross, l.cross.as_ref()),
    ]
    .into_iter()
    .filter_map(|(k, x)| x.map(|x| (k, x)))
    .filter(|(_, x)| x.length_in(opts.metric) < opts.tau)
    .collect();
    if small.is_empty() {
        return Err(KeepReason::Size);
    }
    if let Some(r) = opts.max_ratio {
        // A missing cross loop is longer than tau · ratio (the search limit), so the ratio is
        // above r whenever the Reeb loop is below tau.
        let ratio = match &l.cross {
            Some(c) => {
                let (a, b) = (reeb.length_in(opts.metric), c.length_in(opts.metric));
                a.max(b) / a.min(b).max(1e-9)
            }
            None => f64::INFINITY,
        };
        if ratio > r {
            return Err(KeepReason::Ratio);
        }
    }
    let mut allowed: Vec<(LoopKind, &Loop)> = small
        .into_iter()
        .filter(|(_, x)| opts.mode.allows(operation_for(x)))
        .collect();
    if allowed.is_empty() {
        return Err(KeepReason::Mode);
    }
    allowed.sort_by(|a, b| {
        a.1.length_in(opts.metric)
            .total_cmp(&b.1.length_in(opts.metric))
    });
    Ok(allowed)
}

/// Closing a loop around void fills; closing one around material cuts.
fn operation_for(l: &Loop) -> Operation {
    match l.encloses {
        Encloses::Void => Operation::Collapse,
        Encloses::Material => Operation::Pinch,
    }
}

/// Local box of a loop's vertices.
fn loop_box(l: &Loop) -> BBox {
    let mut b = BBox::EMPTY;
    for v in &l.vertices {
        b.include(v.p);
        b.include(v.end());
    }
    b
}

fn overlaps(a: &BBox, b: &BBox, margin: i64) -> bool {
    (0..3).all(|k| a.min[k] - margin <= b.max[k] && b.min[k] <= a.max[k] + margin)
}

/// Farthest of `samples` (original coordinates) from the polyline's points: voxels and mm.
fn max_distance(samples: &[[i64; 3]], points: &[[f64; 3]], affine: &Affine) -> (f64, f64) {
    let mut worst = (0.0f64, 0.0f64);
    for q in samples {
        let q = [q[0] as f64, q[1] as f64, q[2] as f64];
        let mut best = (f64::INFINITY, f64::INFINITY);
        for p in points {
            let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
            let vox = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let m = affine.apply_vector(d);
            let mm = (m[0] * m[0] + m[1] * m[1] + m[2] * m[2]).sqrt();
            best = (best.0.min(vox), best.1.min(mm));
        }
        worst = (worst.0.max(best.0), worst.1.max(best.1));
    }
    worst
}

/// What [`certify`] found for a handle with no loop below tau.
enum Certificate {
    /// Closed curves that no loop below tau crosses an odd number of times.
    Curves(Vec<Vec<Vertex>>),
    /// Its ribbon's curves came with another handle of the same step.
    Shared,
    /// A loop below tau after all: the handle's loops to close (the loop, and the curve it
    /// crosses once as its partner).
    Below(HandleLoops),
    /// A search ran out of its budget: nothing is proven.
    Unsure,
}

/// The curves that prove a handle has no loop below tau, or a loop below tau found on the way.
///
/// - A Reeb-cycle handle: its cut and the loop round its cycle, from its measurement (no loop
///   below tau crosses the cut, nor that loop, an odd number of times).
/// - An intra-ribbon handle: its ribbon's homology generators (2 × the ribbon's genus closed
///   curves on the surface, shared by the ribbon's handles), each searched for a loop below tau
///   crossing it an odd number of times.
#[allow(clippy::too_many_arguments)]
fn certify(
    vol: &MaskVolume,
    h: &LocatedHandle,
    l: &HandleLoops,
    conn: Connectivity,
    limits: Limits,
    affine: &Affine,
    caches: &mut Caches,
    ribbons: &mut FastMap<(i64, u32), ()>,
) -> Certificate {
    let Some((slice, ribbon)) = h.ribbon else {
        return match (&l.basis, l.exact) {
            (Some((p, q)), true) => Certificate::Curves(vec![p.clone(), q.clone()]),
            _ => Certificate::Unsure,
        };
    };
    if ribbons.insert((slice, ribbon), ()).is_some() {
        return Certificate::Shared;
    }
    let mut g = Graph::with_cache(vol, cases(conn), std::mem::take(&mut caches.graph));
    let out = (|| {
        let Some(generators) = loops::ribbon_generators(&mut g, &mut caches.slices, slice, ribbon)
        else {
            return Certificate::Unsure;
        };
        let searcher = loops::Searcher {
            metric: limits.metric,
            geometry: Geometry {
                affine,
                fractions: vol.fractions.as_ref(),
            },
        };
        for b in &generators {
            let found = searcher.odd_loop(&mut g, b, limits.below);
            match found.found {
                Some(short) => {
                    let describe = |x: &[Vertex], p: &[Vertex]| {
                        loops::describe(vol, x, Some(p), &searcher.geometry)
                    };
                    return Certificate::Below(HandleLoops {
                        reeb: Some(describe(&short, b)),
                        cross: Some(describe(b, &short)),
                        exact: true,
                        basis: None,
                        cut_points: None,
                    });
                }
                None if !found.exact => return Certificate::Unsure,
                None => {}
            }
        }
        Certificate::Curves(generators)
    })();
    caches.graph = g.into_cache();
    out
}

/// A wall to try across a loop.
#[derive(Clone, Copy, Debug)]
enum Wall {
    /// The samples within this distance of the loop's spanning fan.
    Fan(f64),
    /// One sample near the centroid of a short loop.
    Single([i64; 3]),
    /// The samples near the fan (within this distance) thinned by simple samples, then cut at
    /// the k-th sample that cuts the ring the loop goes round (see [`closure::peel_walls`]).
    Peel(f64, usize),
    /// The same with every sample of the box round the loop, this much larger than the loop's:
    /// for a long twisted loop whose fan is far from the disk it bounds.
    PeelBox(i64, usize),
    /// The same box moved along the partner loop (the j-th of [`PEEL_ALONG`] steps round it),
    /// margin as given: where the ring cannot be cut near the loop without cutting something
    /// else too (a bar hollow there, a tunnel with a speck of material in it), it may be
    /// further on.
    PeelAlong(usize, i64, usize),
}

impl Wall {
    fn thickness(self) -> f64 {
        match self {
            Wall::Fan(d) => d,
            Wall::Single(_) => SINGLE_SAMPLE_REACH,
            Wall::Peel(d, _) => d,
            Wall::PeelBox(margin, _) | Wall::PeelAlong(_, margin, _) => margin as f64,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Wall::Fan(_) => "fan",
            Wall::Single(_) => "single_sample",
            Wall::Peel(..) => "peeled",
            Wall::PeelBox(..) => "peeled_box",
            Wall::PeelAlong(..) => "peeled_along",
        }
    }
}

/// The walls tried across a loop, in order: fans of growing thickness; for a short loop round a
/// corner or edge contact, single samples (one may do); then walls peeled down to the one sample
/// that cuts the ring the loop goes round, in regions near the fan, then in boxes round the
/// loop (see [`closure::peel_walls`]: these always remove a handle and split nothing; the
/// regions grow until one holds a cut). Or, reaching along, boxes moved along the partner.
fn walls_for(
    lp: &Loop,
    op: Operation,
    conn: Connectivity,
    partner: &[Vertex],
    reach: WallReach,
) -> Vec<Wall> {
    let wide = (lp.length as i64 / 4).max(2 * PEEL_BOX_MARGIN);
    if reach == WallReach::Along {
        if partner.is_empty() {
            return Vec::new();
        }
        let mut out = Vec::new();
        for margin in [PEEL_BOX_MARGIN, wide] {
            for j in 1..PEEL_ALONG {
                out.extend((0..PEEL_CUTS).map(|k| Wall::PeelAlong(j, margin, k)));
            }
        }
        return out;
    }
    let mut out: Vec<Wall> = EXTRA_THICKNESS
        .iter()
        .map(|extra| Wall::Fan(base_thickness(op, conn) + extra))
        .collect();
    if lp.length <= SINGLE_SAMPLE_LOOP {
        out.extend(
            closure::single_sample_walls(&lp.vertices, SINGLE_SAMPLE_REACH)
                .into_iter()
                .map(Wall::Single),
        );
    }
    for d in PEEL_REACH {
        out.extend((0..PEEL_CUTS).map(|k| Wall::Peel(d, k)));
    }
    for margin in [PEEL_BOX_MARGIN, wide] {
        out.extend((0..PEEL_CUTS).map(|k| Wall::PeelBox(margin, k)));
    }
    out
}

/// Steps round the partner loop at which the box round the loop is moved and peeled again.
const PEEL_ALONG: usize = 8;

/// Samples of a peeled region tried as the cut, nearest the loop's centroid first.
const PEEL_CUTS: usize = 8;

/// Distances from the fan of the regions peeled, tried in turn.
const PEEL_REACH: [f64; 3] = [1.5, 3.0, 5.0];

/// Margin of the first box round the loop peeled whole (the second: a quarter of the loop).
const PEEL_BOX_MARGIN: i64 = 2;

/// Samples a box peeled whole may hold (beyond, the box is not tried: peeling costs about a
/// microsecond per sample).
const MAX_PEEL_BOX: usize = 1 << 20;

/// The samples of the box round the loop's points with a margin, within the volume (none if
/// there are more than [`MAX_PEEL_BOX`]).
fn box_region(vol: &MaskVolume, points: &[[f64; 3]], margin: i64) -> (Vec<[i64; 3]>, BBox) {
    let mut b = BBox::EMPTY;
    for p in points {
        b.include(p.map(|x| x.floor() as i64 - margin));
        b.include(p.map(|x| x.ceil() as i64 + margin));
    }
    let dims = vol.dims.map(|n| n as i64);
    let lo: [i64; 3] = std::array::from_fn(|k| b.min[k].max(0));
    let hi: [i64; 3] = std::array::from_fn(|k| b.max[k].min(dims[k] - 1));
    let size: i64 = (0..3).map(|k| (hi[k] - lo[k] + 1).max(0)).product();
    if size as usize > MAX_PEEL_BOX {
        return (Vec::new(), b);
    }
    let mut out = Vec::new();
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                out.push([x, y, z]);
            }
        }
    }
    (out, b)
}

/// Where a peeled wall across the loop looks for the ring it cuts: the box of the loop and its
/// partner (which runs round that ring), with a margin (without a partner, a quarter of the
/// loop), and the peeled region's box.
fn peel_target<'a>(
    points: &'a [[f64; 3]],
    partner: &[Vertex],
    length: usize,
    region: BBox,
) -> closure::PeelTarget<'a> {
    let margin = if partner.is_empty() {
        (length as i64 / 4).max(PEEL_RING_MARGIN)
    } else {
        PEEL_RING_MARGIN
    };
    let mut b = BBox::EMPTY;
    for p in points {
        b.include(p.map(|x| x.floor() as i64));
        b.include(p.map(|x| x.ceil() as i64));
    }
    for v in partner {
        b.include(v.p);
        b.include(v.end());
    }
    let (mut lo, mut hi) = (b.min.map(|x| x - margin), b.max.map(|x| x + margin));
    if region != BBox::EMPTY {
        lo = std::array::from_fn(|k| lo[k].min(region.min[k]));
        hi = std::array::from_fn(|k| hi[k].max(region.max[k]));
    }
    closure::PeelTarget {
        loop_points: points,
        lo,
        hi,
    }
}

/// Where a peeled wall is wanted: where the loop's partner crosses it (the partner, pushed off
/// the surface, is the ring the wall must cut), else the loop's centroid. The region is peeled
/// towards it, and cuts are tried nearest it first.
fn peel_centre(points: &[[f64; 3]], partner: &[Vertex]) -> [f64; 3] {
    let d2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
    let crossing = points
        .iter()
        .flat_map(|&p| partner.iter().map(move |v| (d2(p, v.midpoint()), p)))
        .min_by(|a, b| a.0.total_cmp(&b.0));
    match crossing {
        Some((_, p)) => p,
        None => crate::surface::geometry::centroid(points),
    }
}

/// The loop's points moved along its partner by `j` of [`PEEL_ALONG`] steps from where the
/// partner crosses the loop (`centre`), and where that step lands.
fn moved_along(
    points: &[[f64; 3]],
    centre: [f64; 3],
    partner: &[Vertex],
    j: usize,
) -> (Vec<[f64; 3]>, [f64; 3]) {
    let d2 = |a: [f64; 3], b: [f64; 3]| (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>();
    let start = (0..partner.len())
        .min_by(|&a, &b| {
            d2(partner[a].midpoint(), centre).total_cmp(&d2(partner[b].midpoint(), centre))
        })
        .unwrap_or(0);
    let at = partner[(start + j * partner.len() / PEEL_ALONG) % partner.len()].midpoint();
    let shift: [f64; 3] = std::array::from_fn(|k| at[k] - centre[k]);
    let moved = points
        .iter()
        .map(|p| std::array::from_fn(|k| p[k] + shift[k]))
        .collect();
    (moved, at)
}

/// Margin of the box round a loop and its partner where a peeled wall's ring is looked for.
const PEEL_RING_MARGIN: i64 = 3;

/// Tries the walls across `lp` by each of `ops` until one is kept (see [`closure::close`]).
fn close_loop(
    vol: &mut MaskVolume,
    conn: Connectivity,
    lp: &Loop,
    partner: &[Vertex],
    ops: &[Operation],
    (reach, graph, refused): (WallReach, &mut GraphCache, &mut Refused),
) -> Option<(closure::Applied, Wall)> {
    let points: Vec<[f64; 3]> = lp.vertices.iter().map(|v| v.midpoint()).collect();
    let centre = peel_centre(&points, partner);
    let mut peeled: Vec<Vec<[i64; 3]>> = Vec::new();
    // The samples near the fan, gathered once as far as the walls tried so far need.
    let mut near: Option<closure::NearFan> = None;
    let mut near_fan = |d: f64| -> Vec<[i64; 3]> {
        if near.as_ref().is_none_or(|n| n.reach < d) {
            // Fans need up to their thickest; peeled regions, the widest reach at once.
            let reach = if d <= MAX_FAN_THICKNESS {
                MAX_FAN_THICKNESS
            } else {
                PEEL_REACH[PEEL_REACH.len() - 1]
            };
            near = Some(closure::NearFan::new(&points, reach.max(d)));
        }
        near.as_ref().expect("set above").within(d)
    };
    for &op in ops {
        for w in walls_for(lp, op, conn, partner, reach) {
            let samples = match w {
                Wall::Fan(d) => near_fan(d),
                Wall::Single([u, v, w]) if vol.get(u, v, w) == op.target() => continue,
                Wall::Single(q) => vec![q],
                // Peeled once per region; its cuts are tried in turn.
                Wall::Peel(_, k) | Wall::PeelBox(_, k) | Wall::PeelAlong(_, _, k) if k > 0 => {
                    match peeled.get(k) {
                        Some(x) => x.clone(),
                        None => continue,
                    }
                }
                // Peeled in a region: near the fan, a box round the loop, or that box moved
                // along the partner (towards where the partner lands).
                Wall::Peel(..) | Wall::PeelBox(..) | Wall::PeelAlong(..) => {
                    let (region, b, at) = match w {
                        Wall::Peel(d, _) => (near_fan(d), BBox::EMPTY, centre),
                        Wall::PeelBox(margin, _) => {
                            let (region, b) = box_region(vol, &points, margin);
                            (region, b, centre)
                        }
                        Wall::PeelAlong(j, margin, _) => {
                            let (moved, at) = moved_along(&points, centre, partner, j);
                            let (region, b) = box_region(vol, &moved, margin);
                            (region, b, at)
                        }
                        Wall::Fan(_) | Wall::Single(_) => unreachable!("matched above"),
                    };
                    let target = peel_target(&points, partner, lp.length, b);
                    peeled = closure::peel_walls(vol, conn, &region, at, op, &target, PEEL_CUTS);
                    match peeled.first() {
                        Some(x) => x.clone(),
                        None => continue,
                    }
                }
            };
            let attempt = closure::Attempt {
                lp: &lp.vertices,
                partner,
                op,
                wall: samples,
                certified: !matches!(w, Wall::Fan(_) | Wall::Single(_)),
            };
            let r = closure::close(vol, conn, attempt, graph);
            match r {
                Ok(applied) => return Some((applied, w)),
                Err(why) => {
                    refused.total += 1;
                    *refused.by.entry(why.name()).or_default() += 1;
                }
            }
        }
    }
    None
}

/// Closes one of a handle's loops: the candidates (loops below tau, shortest first), then, if
/// every wall across them is refused, the handle's other loop whatever its length (measured now
/// if its search stopped at tau). Walls across the loops come first; walls moved along their
/// partners (slower, and farther from the loop) only when no loop has one. Returns the loop
/// closed, how, and with which wall.
fn close_handle<'l>(
    vol: &mut MaskVolume,
    opts: &SimplifyOptions,
    l: &'l HandleLoops,
    candidates: &[(LoopKind, &'l Loop)],
    affine: &Affine,
    graph: &mut GraphCache,
    refused: &mut Refused,
) -> Option<(LoopKind, std::borrow::Cow<'l, Loop>, closure::Applied, Wall)> {
    let mut by = |reach: WallReach| {
        close_handle_by(vol, opts, l, candidates, affine, (graph, refused), reach)
    };
    by(WallReach::Across).or_else(|| by(WallReach::Along))
}

/// Walls the local check refused: how many, and why (by [`closure::Refusal::name`]).
#[derive(Default)]
struct Refused {
    total: usize,
    by: std::collections::BTreeMap<&'static str, usize>,
}

/// Where the walls tried across a loop lie.
#[derive(Clone, Copy, PartialEq, Eq)]
enum WallReach {
    /// Across the loop: fans, single samples, regions near the fan and boxes round the loop.
    Across,
    /// In the box round the loop moved along its partner.
    Along,
}

/// [`close_handle`] with the walls of one reach.
fn close_handle_by<'l>(
    vol: &mut MaskVolume,
    opts: &SimplifyOptions,
    l: &'l HandleLoops,
    candidates: &[(LoopKind, &'l Loop)],
    affine: &Affine,
    (graph, refused): (&mut GraphCache, &mut Refused),
    reach: WallReach,
) -> Option<(LoopKind, std::borrow::Cow<'l, Loop>, closure::Applied, Wall)> {
    let conn = opts.surface.connectivity;
    let partner_of = |which: LoopKind| match which {
        LoopKind::Reeb => l.cross.as_ref(),
        LoopKind::Cross => l.reeb.as_ref(),
    };
    // Without a partner loop, the side the loop goes round was judged from its fan alone: if
    // no wall of that kind closes it, try the other kind (every wall is verified either way).
    let ops_for = |lp: &Loop, has_partner: bool| {
        let op = operation_for(lp);
        if !has_partner && opts.mode == Mode::Both {
            vec![op, opposite(op)]
        } else {
            vec![op]
        }
    };
    for &(which, lp) in candidates {
        let partner = partner_of(which).map_or(&[][..], |x| &x.vertices);
        let ops = ops_for(lp, !partner.is_empty());
        if let Some((a, w)) = close_loop(vol, conn, lp, partner, &ops, (reach, graph, refused)) {
            return Some((which, std::borrow::Cow::Borrowed(lp), a, w));
        }
    }
    // The other loop of the shortest candidate, however long.
    let &(which, lp) = candidates.first()?;
    let other = match which {
        LoopKind::Reeb => LoopKind::Cross,
        LoopKind::Cross => LoopKind::Reeb,
    };
    let found = match partner_of(which) {
        Some(x) => std::borrow::Cow::Borrowed(x),
        None => {
            let mut g = Graph::with_cache(vol, cases(conn), std::mem::take(graph));
            let x = loops::cross_loop(&mut g, &lp.vertices, usize::MAX);
            *graph = g.into_cache();
            let geometry = Geometry {
                affine,
                fractions: vol.fractions.as_ref(),
            };
            std::borrow::Cow::Owned(loops::describe(vol, &x?, Some(&lp.vertices), &geometry))
        }
    };
    let ops = ops_for(&found, true);
    let ops: Vec<Operation> = ops.into_iter().filter(|&op| opts.mode.allows(op)).collect();
    if let Some((a, w)) = close_loop(
        vol,
        conn,
        &found,
        &lp.vertices,
        &ops,
        (reach, graph, refused),
    ) {
        return Some((other, found, a, w));
    }
    // Last, the handle's two curves that cross once (its cut and the loop round its cycle): a
    // closure of either removes the handle too, and the cut, a contour, spans a flat region.
    let (p, q) = l.basis.as_ref()?;
    for (x, y) in [(p, q), (q, p)] {
        let geometry = Geometry {
            affine,
            fractions: vol.fractions.as_ref(),
        };
        let lx = loops::describe(vol, x, Some(y), &geometry);
        let ops: Vec<Operation> = [Operation::Collapse, Operation::Pinch]
            .into_iter()
            .filter(|&op| opts.mode.allows(op))
            .collect();
        if let Some((a, w)) = close_loop(vol, conn, &lx, y, &ops, (reach, graph, refused)) {
            return Some((other, std::borrow::Cow::Owned(lx), a, w));
        }
    }
    None
}

/// A closure done: which of the handle's loops, the loop, the wall's samples and how it was made.
struct Closure<'c> {
    which: LoopKind,
    lp: &'c Loop,
    applied: &'c closure::Applied,
    wall: Wall,
}

/// The report of a handle removed by `closure` at `(pass, slice)`, in original coordinates.
fn removal(
    vol: &MaskVolume,
    h: &LocatedHandle,
    l: &HandleLoops,
    closure: Closure,
    affine: &Affine,
    (pass, slice): (usize, i64),
) -> Removed {
    let Closure {
        which,
        lp,
        applied,
        wall,
    } = closure;
    let changed: Vec<[i64; 3]> = applied
        .changed
        .iter()
        .map(|q| vol.frame.to_original_i(*q))
        .collect();
    let (dist, dist_mm) = max_distance(&changed, &lp.points, affine);
    Removed {
        size: l.size().unwrap_or(lp.length),
        size_mm: l.size_in(Metric::Millimetres).unwrap_or(lp.length_mm),
        reeb: l.reeb.as_ref().map(|x| x.length),
        cross: l.cross.as_ref().map(|x| x.length),
        kind: h.kind,
        closed: which,
        operation: applied.op,
        length: lp.length,
        length_mm: lp.length_mm,
        thickness: wall.thickness(),
        wall: wall.name(),
        samples_changed: changed.len(),
        samples: changed,
        handles: applied.handles,
        max_distance: dist,
        max_distance_mm: dist_mm,
        points: lp.points.clone(),
        bbox: l.bbox().unwrap_or(h.bbox),
        pass,
        slice,
    }
}

/// The certificate of the last pass: every handle kept for its size, and the crossing matrix of
/// their curves of full rank (2 × kept), so no loop below tau is left.
fn certificate_holds(
    vol: &MaskVolume,
    conn: Connectivity,
    kept: &[(i64, Kept)],
    basis: &[(i64, Vec<Vec<Vertex>>)],
    progress: &dyn Progress,
) -> bool {
    if kept.iter().any(|(_, k)| k.reason != KeepReason::Size) {
        return false;
    }
    let curves: Vec<Vec<Vertex>> = basis.iter().flat_map(|(_, c)| c.clone()).collect();
    let mut g = Graph::new(vol, cases(conn));
    let rank = loops::basis::crossing_rank(&mut g, &curves);
    progress.trace(format_args!(
        "certificate: {} curves, rank {rank:?}, {} kept",
        curves.len(),
        kept.len()
    ));
    rank == Some(2 * kept.len())
}

/// The samples that end on the other side (`original`: each flipped sample's first side),
/// in original coordinates, plane by plane (out of core, each plane read once).
fn final_edits(vol: &mut MaskVolume, original: FastMap<[i64; 3], bool>) -> Vec<Edit> {
    let mut flipped: Vec<([i64; 3], bool)> = original.into_iter().collect();
    flipped.sort_unstable_by_key(|(q, _)| [q[2], q[1], q[0]]);
    let mut edits: Vec<Edit> = Vec::new();
    for same_plane in flipped.chunk_by(|a, b| a.0[2] == b.0[2]) {
        let plane = vol.plane_once(same_plane[0].0[2]);
        for &(q, was) in same_plane {
            if plane.get(q[0] as isize, q[1] as isize) != was {
                edits.push((vol.frame.to_original_i(q), !was));
            }
        }
    }
    edits.sort_by_key(|(p, _)| [p[2], p[1], p[0]]);
    edits
}

/// After the last allowed pass closed something, its measurements may be stale: a handle kept
/// for its size that measured below tau says so.
fn mark_stale(kept: &mut [(i64, Kept)], opts: &SimplifyOptions) {
    for (_, k) in kept {
        let size = match opts.metric {
            Metric::Edges => k.size.map(|s| s as f64),
            Metric::Millimetres => k.size_mm,
        };
        if size.is_some_and(|s| s < opts.tau) && k.reason == KeepReason::Size {
            k.reason = KeepReason::PassLimit;
        }
    }
}

/// Removes every handle of `vol` smaller than `opts.tau` (see the module documentation). `vol`
/// is edited in place; the outcome lists the edits in original coordinates.
pub fn simplify(
    vol: &mut MaskVolume,
    opts: &SimplifyOptions,
    affine: &Affine,
    progress: &dyn Progress,
) -> Result<Outcome> {
    let conn = opts.surface.connectivity;
    let limits = opts.limits();
    let mut removed: Vec<Removed> = Vec::new();
    // First flip of each sample: local coordinates -> its original side.
    let mut original: FastMap<[i64; 3], bool> = FastMap::default();
    let (mut rewinds, mut refused) = (0, Refused::default());
    let mut intra_ribbon = 0;
    let mut kept: Vec<(i64, Kept)> = Vec::new();
    let mut pass = 0;
    let mut seconds = StageSeconds::default();
    // The certificate: closed curves that no loop below tau crosses an odd number of times,
    // from the last pass (see `certify`), and whether every kept handle has them.
    let certifying = opts.tau.is_finite() && opts.mode == Mode::Both && opts.max_ratio.is_none();
    let mut basis: Vec<(i64, Vec<Vec<Vertex>>)> = Vec::new();
    let mut certified = None;
    let mut lasting = Lasting::default();
    loop {
        pass += 1;
        kept.clear();
        basis.clear();
        let closed_before = removed.len();
        let mut sweeper = Sweeper::new(conn);
        let mut caches = Caches {
            graph: GraphCache::default(),
            slices: SliceCache::new(conn),
            memo: FastMap::default(),
            failed: FastMap::default(),
        };
        progress.start(&format!("pass {pass}"), vol.dims[2] as u64 + 1);
        // Highest slice stepped so far: slices above it are seen for the first time.
        let mut high = -2;
        while !sweeper.done(vol) {
            let s = sweeper.next;
            let t = std::time::Instant::now();
            let n = sweeper.step(vol)?;
            if let Some((at, surfels)) = sweeper.take_surfels() {
                // The loops of the handles found here need this slice's ribbons too.
                caches.slices.offer(at, surfels);
            }
            vol.follow_sweep(sweeper.next)?;
            seconds.sweep += t.elapsed().as_secs_f64();
            let first_visit = s > high;
            if first_visit {
                progress.advance((s - high) as u64);
                progress.message(&format!("{} removed", removed.len()));
                high = s;
            }
            if n == 0 {
                continue;
            }
            let all = sweeper.handles();
            let new: Vec<LocatedHandle> = all[all.len() - n..]
                .iter()
                .map(|(_, h)| h.clone())
                .collect();
            sweeper.release_handles();
            if pass == 1 && first_visit {
                intra_ribbon += new
                    .iter()
                    .filter(|h| h.kind == HandleKind::IntraRibbon)
                    .count();
            }
            let t = std::time::Instant::now();
            let measured = caches.measure(vol, &new, conn, affine, limits, &mut lasting);
            seconds.loops += t.elapsed().as_secs_f64();
            for (h, l) in new.iter().zip(&measured) {
                progress.trace(format_args!(
                    "measured {:?} at slice {s}: reeb {:?} cross {:?}, cycle of {} nodes",
                    h.kind,
                    l.reeb.as_ref().map(|x| x.length),
                    l.cross.as_ref().map(|x| x.length),
                    h.cycle.len()
                ));
            }
            let t = std::time::Instant::now();
            let mut order: Vec<usize> = (0..n).collect();
            let size = |i: usize| measured[i].size_in(opts.metric).unwrap_or(f64::INFINITY);
            order.sort_by(|&a, &b| size(a).total_cmp(&size(b)));
            // Ribbons of this step whose generators were checked.
            let mut ribbons: FastMap<(i64, u32), ()> = FastMap::default();
            // Walls written at this step, as local boxes; the lowest slice they touched.
            let mut walls: Vec<BBox> = Vec::new();
            let mut lowest = i64::MAX;
            for i in order {
                let (h, l) = (&new[i], &measured[i]);
                let keep = |reason| Kept {
                    size: l.size(),
                    size_mm: l.size_in(Metric::Millimetres),
                    reeb: l.reeb.as_ref().map(|x| x.length),
                    cross: l.cross.as_ref().map(|x| x.length),
                    kind: h.kind,
                    reason,
                    bbox: l.bbox().unwrap_or(h.bbox),
                };
                // A handle with no loop below tau is kept once its curves are certified: no
                // loop below tau crosses them (see `certify`); else the loop found is closed.
                let found_loops;
                let (l, candidates) = match plan(l, opts) {
                    Ok(c) => (l, c),
                    Err(KeepReason::Size) if certifying => {
                        match certify(vol, h, l, conn, limits, affine, &mut caches, &mut ribbons) {
                            Certificate::Curves(curves) => {
                                basis.push((s, curves));
                                kept.push((s, keep(KeepReason::Size)));
                                continue;
                            }
                            Certificate::Shared => {
                                kept.push((s, keep(KeepReason::Size)));
                                continue;
                            }
                            Certificate::Unsure => {
                                kept.push((s, keep(KeepReason::Unmeasured)));
                                continue;
                            }
                            Certificate::Below(short) => {
                                found_loops = short;
                                let c = plan(&found_loops, opts).expect("a loop below tau");
                                (&found_loops, c)
                            }
                        }
                    }
                    Err(reason) => {
                        kept.push((s, keep(reason)));
                        continue;
                    }
                };
                // Measured before this step's walls: if one landed near, measure again after
                // the rewind.
                if candidates
                    .iter()
                    .any(|(_, x)| walls.iter().any(|w| overlaps(w, &loop_box(x), 2)))
                {
                    continue;
                }
                let key = memo_key(h);
                if caches.failed.contains_key(&key) {
                    kept.push((s, keep(KeepReason::ClosureFailed)));
                    continue;
                }
                let done = close_handle(
                    vol,
                    opts,
                    l,
                    &candidates,
                    affine,
                    &mut caches.graph,
                    &mut refused,
                );
                let Some((which, lp, applied, wall_kind)) = done else {
                    caches.failed.insert(key, ());
                    kept.push((s, keep(KeepReason::ClosureFailed)));
                    continue;
                };
                let mut wall = BBox::EMPTY;
                for q in &applied.changed {
                    wall.include(*q);
                    original.entry(*q).or_insert(!applied.op.target());
                }
                lowest = lowest.min(wall.min[2]);
                caches.slices.invalidate(wall.min[2], wall.max[2]);
                walls.push(wall);
                let closure = Closure {
                    which,
                    lp: &lp,
                    applied: &applied,
                    wall: wall_kind,
                };
                removed.push(removal(vol, h, l, closure, affine, (pass, s)));
            }
            seconds.closures += t.elapsed().as_secs_f64();
            if !walls.is_empty() {
                // Slice lowest - 1 has a corner in the wall's lowest plane; redo from there,
                // and at least from s (this step's handles, measured before the walls).
                let to = (lowest - 1).min(s);
                caches.forget_near(&walls);
                lasting.forget_near(&walls);
                sweeper.rewind(vol, to);
                kept.retain(|(at, _)| *at < to);
                basis.retain(|(at, _)| *at < to);
                rewinds += 1;
                vol.follow_sweep(sweeper.next)?;
            }
        }
        progress.finish();
        if removed.len() == closed_before {
            // The last pass: what it kept is the result; check its certificate.
            certified = certifying.then(|| certificate_holds(vol, conn, &kept, &basis, progress));
        }
        vol.follow_sweep(sweeper.next)?;
        progress.trace(format_args!(
            "pass {pass} done: {} closed, {rewinds} rewinds so far, refused {:?}, {seconds:?}",
            removed.len() - closed_before,
            refused.by
        ));
        if removed.len() == closed_before {
            break;
        }
        if pass == MAX_PASSES {
            mark_stale(&mut kept, opts);
            break;
        }
    }
    if certifying && certified.is_none() {
        // The pass limit was reached: the last pass closed something.
        certified = Some(false);
    }
    let edits = final_edits(vol, original);
    Ok(Outcome {
        removed,
        kept: kept.into_iter().map(|(_, k)| k).collect(),
        edits,
        intra_ribbon,
        passes: pass,
        certified,
        rewinds,
        refused: refused.total,
        refused_by: refused.by,
        seconds,
    })
}

/// Stored values written for inside and outside samples: the representable values nearest the
/// isovalue on each side (for floating-point samples, a relative margin of 2^-10 keeps the new
/// surface from sitting exactly on the samples).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct WallValues {
    pub inside: Option<f64>,
    pub outside: Option<f64>,
}

impl WallValues {
    pub fn new(dtype: DType, classifier: &Classifier) -> WallValues {
        let s = classifier.scaling;
        // The isovalue in stored units.
        let raw_iso = (classifier.iso - s.inter) / s.slope;
        let (lo, hi) = dtype.range();
        let ok = |raw: f64, inside: bool| -> bool {
            raw.is_finite()
                && raw >= lo
                && raw <= hi
                && round_trip(dtype, raw) == raw
                && classifier.inside_raw(raw) == inside
        };
        let pick = |inside: bool| -> Option<f64> {
            let mut candidates: Vec<f64> = Vec::new();
            if dtype.is_float() {
                let eps = raw_iso.abs().max(1.0) / 1024.0;
                for k in [1.0, 2.0, 4.0] {
                    candidates.push(round_trip(dtype, raw_iso + k * eps));
                    candidates.push(round_trip(dtype, raw_iso - k * eps));
                }
            } else {
                let f = raw_iso.floor();
                for k in -2..=3 {
                    candidates.push((f + k as f64).clamp(lo, hi));
                }
            }
            candidates
                .into_iter()
                .filter(|&r| ok(r, inside))
                .min_by(|a, b| (a - raw_iso).abs().total_cmp(&(b - raw_iso).abs()))
        };
        WallValues {
            inside: pick(true),
            outside: pick(false),
        }
    }
}

/// The nearest value of the type (for floats; integers are passed through).
fn round_trip(dtype: DType, v: f64) -> f64 {
    match dtype {
        DType::F32 => v as f32 as f64,
        _ => v,
    }
}

/// Streams `reader` to a new file `out`, with the edited samples set to the wall values.
pub fn write_edited(
    reader: &mut dyn SliceReader,
    out: &Path,
    edits: &[Edit],
    values: &WallValues,
    progress: &dyn Progress,
) -> Result<()> {
    reader.rewind()?;
    let info: VolumeInfo = reader.info().clone();
    let [nx, ny, nz] = info.dims;
    let mut writer = crate::volume::create(out, &info)?;
    let mut slice = Samples::new(info.dtype);
    let mut next = 0;
    progress.start("write", nz as u64);
    for z in 0..nz {
        reader.read_slice(&mut slice)?;
        while next < edits.len() && edits[next].0[2] == z as i64 {
            let ([x, y, _], inside) = edits[next];
            let v = if inside {
                values.inside
            } else {
                values.outside
            }
            .ok_or_else(|| {
                Error::Internal(format!(
                    "no {} value representable in {}",
                    if inside { "inside" } else { "outside" },
                    info.dtype
                ))
            })?;
            debug_assert!((x as usize) < nx && (y as usize) < ny);
            slice.set_f64(y as usize * nx + x as usize, v);
            next += 1;
        }
        writer.write_slice(&slice)?;
        progress.advance(1);
    }
    progress.finish();
    let info = reader.info().clone();
    writer.finish(&info)
}
