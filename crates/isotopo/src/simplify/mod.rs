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
//! Every closure is verified locally before it is kept (`closure::close`): it removes one handle
//! of its own surface and changes nothing else, so b0 and b2 of the solid never change, which
//! is checked again on the whole volume at the end.
//!
//! Before the sweep, the components and cavities the options ask to remove go (`parts.rs`: each
//! deleted or filled, or bridged or opened by a shortest path where that flips fewer samples);
//! the b0 and b2 they leave are what the handles' removal then keeps. After each pass the walls
//! are trimmed: wall samples whose flip back is simple go back to the input. With
//! `keep_handles`, a pass that closes nothing measures every handle first, and tau is set just
//! above the smallest ones to go.

pub use crate::closure::Operation;
use crate::error::{Error, Result};
use crate::grid::{Axis, MaskVolume};
use crate::loops::{HandleLoops, Limits, Loop, Metric};
use crate::progress::Progress;
use crate::surface::search::FastMap;
use crate::surface::Vertex;
use crate::sweep::{HandleKind, LocatedHandle, Sweeper};
use crate::topology::cases::Connectivity;
use crate::topology::genus::SurfaceOptions;
use crate::volume::{Affine, BBox};
use std::borrow::Cow;

mod certify;
mod measure;
mod parts;
mod plan;
mod removal;
mod walls;
mod write;

use certify::{certificate_holds, certify, Certificate, StepCurves};
use measure::{memo_key, Caches, Lasting};
pub use parts::{PartKept, PartKind, PartOperation, PartRemoved, Parts};
use plan::{plan, wall_near_loop};
use removal::removal;
use walls::{close_handle, NoCut, Refused};
use write::{changed_sides, final_edits};
pub(crate) use write::{write_edited, SliceEditor};
pub use write::{WallValues, Written};

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
    /// infinity removes every handle, 0 none (only the well-composed step then changes the
    /// volume).
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
    /// Make the output well-composed (by default, yes): after the walls, flip simple samples
    /// until no unit face shows one diagonal and no unit cube two opposite corners alone
    /// ([`crate::compose`]), and move floating-point samples equal to the isovalue just outside,
    /// so that connectivity 6 and 26, VTK and scikit-image see one topology. Integer samples at
    /// the isovalue are left (they may be a label); the report gives the isovalue between
    /// stored values that meshes the same surface without them.
    pub well_composed: bool,
    /// Solid components with fewer inside samples than this go: each deleted, or bridged to a
    /// component that stays where the bridge flips fewer samples; by default none.
    pub min_component: Option<u64>,
    /// Keep only the largest component (the others deleted or bridged likewise); by default no.
    pub largest: bool,
    /// Cavities with fewer samples than this go: each filled, or opened to the outside (or to a
    /// cavity that stays) through its thinnest wall where that flips fewer samples; by default
    /// none.
    pub min_cavity: Option<u64>,
    /// Every cavity goes (as with `min_cavity`); by default no.
    pub fill_cavities: bool,
    /// Remove handles from the smallest up until this many are left, whatever their size
    /// (`tau` is then ignored); by default none.
    pub keep_handles: Option<usize>,
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
            well_composed: true,
            min_component: None,
            largest: false,
            min_cavity: None,
            fill_cavities: false,
            keep_handles: None,
        }
    }
}

impl SimplifyOptions {
    /// Refuses options no simplification can follow: tau negative or NaN, a ratio below 1, an
    /// isovalue that is not a number.
    pub fn validate(&self) -> Result<()> {
        if self.tau.is_nan() || self.tau < 0.0 {
            return Err(Error::usage(
                "tau must be 0 (no handle removed: only a well-composed output), positive or inf",
            ));
        }
        if self.max_ratio.is_some_and(|r| r.is_nan() || r < 1.0) {
            return Err(Error::usage("the maximum ratio must be at least 1"));
        }
        if !self.surface.iso.is_finite() {
            return Err(Error::usage("the isovalue must be a finite number"));
        }
        Ok(())
    }

    /// One component, no handle, no cavity: keep the largest component, remove every cavity
    /// and every handle (`--spherical`).
    pub fn spherical(mut self) -> SimplifyOptions {
        self.largest = true;
        self.fill_cavities = true;
        self.tau = f64::INFINITY;
        self
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
    /// The Reeb loop, round the handle's cycle.
    Reeb,
    /// The cross loop, across the handle.
    Cross,
    /// Another curve found while measuring the handle, crossing one of its loops once (a
    /// top-level handle's cut, a contour of its slice; an intra-ribbon handle's first loop round
    /// its cycle or across it): closing it removes the handle too.
    Basis,
}

/// A handle that was removed.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Removed {
    /// The handle's size: its shorter loop (voxel edges, and millimetres).
    pub size: usize,
    /// The size in millimetres.
    pub size_mm: f64,
    /// The Reeb loop's length in edges (`None`: not found within the search limit).
    pub reeb: Option<usize>,
    /// The cross loop's length in edges, likewise.
    pub cross: Option<usize>,
    /// Closed by a Reeb cycle of the sweep or inside a ribbon.
    pub kind: HandleKind,
    /// The loop that was closed, and how.
    #[serde(rename = "loop")]
    pub closed: LoopKind,
    /// Fill (collapse a loop round void) or cut (pinch a loop round material).
    pub operation: Operation,
    /// Length of the closed loop (voxel edges and mm).
    pub length: usize,
    /// The closed loop's length in millimetres.
    pub length_mm: f64,
    /// Length (edges) of its partner, the curve crossing it once whose ring the wall cuts (the
    /// handle's other loop, or its cut), if it had one: a `peeled_along` wall lies in the
    /// closed loop's box moved along the partner, by at most half of it.
    pub partner: Option<usize>,
    /// Half-thickness of the wall (voxels): how far from the loop's fan its samples lie (for a
    /// `peeled_box` or `peeled_along` wall, the margin of the box it lies in).
    pub thickness: f64,
    /// How the wall was made: `fan` (the samples near the loop's spanning fan), `single_sample`,
    /// `peeled` (the samples near the fan thinned by simple samples and cut at the one sample
    /// that cuts the ring the loop goes round), `peeled_box` (the same in a box round the
    /// loop) or `peeled_along` (the same in that box moved along the `partner`, where the
    /// ring is cut away from this loop: its samples may lie far from `points`).
    pub wall: &'static str,
    /// Samples this closure flipped: how many, and which (original coordinates).
    pub samples_changed: usize,
    /// The samples flipped.
    pub samples: Vec<[i64; 3]>,
    /// Handles the wall removed: 1, or more when it also closed tiny handles right beside.
    pub handles: usize,
    /// Farthest flipped sample from the loop's polyline (voxels, and mm).
    pub max_distance: f64,
    /// The same in millimetres.
    pub max_distance_mm: f64,
    /// The closed loop: polyline through edge midpoints, original voxel coordinates.
    pub points: Vec<[f64; 3]>,
    /// The box of the handle's loops (original voxel coordinates).
    pub bbox: BBox,
    /// Pass of the sweep (1-based) and slice at which it was closed.
    pub pass: usize,
    /// The sweep's slice, in the swept frame.
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
    /// One of the `keep_handles` largest.
    KeepHandles,
}

/// A handle left in the result.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Kept {
    /// The shorter loop's length in edges, and in millimetres.
    pub size: Option<usize>,
    /// The size in millimetres.
    pub size_mm: Option<f64>,
    /// The Reeb loop's length in edges (`None`: not found within the search limit).
    pub reeb: Option<usize>,
    /// The cross loop's length in edges, likewise.
    pub cross: Option<usize>,
    /// Closed by a Reeb cycle of the sweep or inside a ribbon.
    pub kind: HandleKind,
    /// Why it was kept.
    pub reason: KeepReason,
    /// The box of its loops (original voxel coordinates).
    pub bbox: BBox,
}

/// A sample to change, in original coordinates, and whether it becomes inside.
pub type Edit = ([i64; 3], bool);

/// What simplification did.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The handles removed, in the order they were closed.
    pub removed: Vec<Removed>,
    /// The handles of the result (the last pass's analysis).
    pub kept: Vec<Kept>,
    /// Samples whose side changed, sorted by (z, y, x).
    pub edits: Vec<Edit>,
    /// Intra-ribbon handles the first pass met on its first visit of each slice.
    pub intra_ribbon: usize,
    /// Full sweeps run (the last one closed nothing, unless the limit was reached).
    pub passes: usize,
    /// What making the output well-composed did (`None` when turned off): critical cells before
    /// and left, and the samples it flipped that end on the other side (original coordinates;
    /// they are among `edits`).
    pub composition: Option<crate::compose::Composition>,
    /// With a finite tau (both operations, no `--max-ratio`): is it proven that the result has
    /// no non-separating loop shorter than tau? Every kept handle has two closed curves that no
    /// loop below tau crosses an odd number of times, and together they span every loop of the
    /// surface (see [`crate::loops::basis`]). `None` where no such promise is made.
    pub certified: Option<bool>,
    /// How often the sweep stepped back after closures.
    pub rewinds: usize,
    /// Closures tried and refused by the local check, and why.
    pub refused: usize,
    /// The refusals by reason (`nothing_to_change`, `off_the_surface`, `euler_characteristic`,
    /// `other_surface`, `falls_apart`).
    pub refused_by: std::collections::BTreeMap<&'static str, usize>,
    /// Seconds spent stepping the sweep, measuring loops and closing them.
    pub seconds: StageSeconds,
    /// The components and cavities removed (before the handles), and those the mode kept.
    pub parts: Parts,
}

impl Outcome {
    /// Handles removed by fills ([`Operation::Collapse`]) or by cuts ([`Operation::Pinch`]),
    /// counting the tiny ones a wall removed beside its own.
    pub fn handles_removed_by(&self, op: Operation) -> usize {
        let by_op = self.removed.iter().filter(|r| r.operation == op);
        by_op.map(|r| r.handles).sum()
    }

    /// Samples set inside (filled) and set outside (cut).
    pub fn samples_filled_cut(&self) -> (usize, usize) {
        let filled = self.edits.iter().filter(|e| e.1).count();
        (filled, self.edits.len() - filled)
    }

    /// How far the farthest changed sample lies from its closed loop: voxels, and mm.
    pub fn max_distance(&self) -> (f64, f64) {
        let voxels = self.removed.iter().map(|r| r.max_distance);
        let mm = self.removed.iter().map(|r| r.max_distance_mm);
        (voxels.fold(0.0, f64::max), mm.fold(0.0, f64::max))
    }
}

/// Where the time went.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StageSeconds {
    /// Removing components and cavities.
    pub parts: f64,
    /// Stepping the sweep.
    pub sweep: f64,
    /// Measuring loops.
    pub loops: f64,
    /// Trying walls.
    pub closures: f64,
}

/// How many full sweeps may run; the last must close nothing.
const MAX_PASSES: usize = 8;

/// How many rounds of opening handles and taking back those no pass closed may run (see
/// `Run::passes_until_done`); each has its own [`MAX_PASSES`].
const MAX_ROUNDS: usize = 4;

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
    let mut original = FastMap::default();
    let t = std::time::Instant::now();
    let parts = if parts::wanted(opts) {
        parts::remove_parts(vol, opts, &mut original, progress)?
    } else {
        Parts::default()
    };
    let parts_seconds = t.elapsed().as_secs_f64();
    let mut run = Run::new(opts, affine, progress);
    run.original = original;
    run.parts = parts;
    run.seconds.parts = parts_seconds;
    let Some(k) = opts.keep_handles else {
        run.passes_until_done(vol)?;
        return Ok(run.outcome(vol));
    };
    // Keep the k largest handles: measure them all (a pass closing nothing), remove the rest;
    // a closure may lengthen the loops of handles near it, so measure what is left and go on
    // until k are left or nothing more can go.
    run.certifying = false;
    run.retarget(f64::INFINITY, Some(0));
    run.sweep_pass(vol)?;
    for _ in 0..MAX_PASSES {
        let left = run.kept.len();
        let removable: Vec<&Kept> = run
            .kept
            .iter()
            .map(|(_, h)| h)
            .filter(|h| matches!(h.reason, KeepReason::KeepHandles | KeepReason::Size))
            .collect();
        if left <= k || removable.is_empty() {
            break;
        }
        let tau = keep_handles_tau(&removable, opts.metric, (left - k).min(removable.len()));
        run.retarget(tau, Some(left - k));
        run.passes_until_done(vol)?;
    }
    Ok(run.outcome(vol))
}

/// The tau just above the `remove` smallest of `handles` (equal sizes at the threshold would
/// all be below it: the budget of handles to remove stops there).
fn keep_handles_tau(handles: &[&Kept], metric: Metric, remove: usize) -> f64 {
    let mut sizes: Vec<f64> = handles
        .iter()
        .map(|h| match metric {
            Metric::Edges => h.size.map_or(f64::INFINITY, |s| s as f64),
            Metric::Millimetres => h.size_mm.unwrap_or(f64::INFINITY),
        })
        .collect();
    sizes.sort_by(f64::total_cmp);
    let largest_removed = sizes[remove - 1];
    // Just above it: edges are whole numbers; millimetres, the next representable value.
    match metric {
        Metric::Edges => largest_removed + 0.5,
        Metric::Millimetres => largest_removed * (1.0 + 1e-12) + 1e-12,
    }
}

/// The samples changed (see [`changed_sides`]) and the options of a well-composed step when it
/// ended.
type StepEnd = (Vec<([i64; 3], bool)>, crate::compose::ComposeOptions);

/// What simplify carries from step to step and pass to pass.
struct Run<'a> {
    opts: SimplifyOptions,
    affine: &'a Affine,
    progress: &'a dyn Progress,
    conn: Connectivity,
    limits: Limits,
    /// Whether the result gets a certificate: closed curves that no loop below tau crosses an
    /// odd number of times for each kept handle (see `certify`), from the last pass.
    certifying: bool,
    certified: Option<bool>,
    /// Passes started so far.
    passes: usize,
    /// How many passes may run in a row ([`MAX_PASSES`]; a test lowers it to reach the limit).
    max_passes: usize,
    removed: Vec<Removed>,
    /// The samples each wall of `removed` flipped, in local coordinates.
    wall_samples: Vec<Vec<[i64; 3]>>,
    /// What the current pass keeps, with the slice it was found at.
    kept: Vec<(i64, Kept)>,
    /// The certificate's curves of the current pass, with the slice they were found at.
    basis: Vec<(i64, Vec<Vec<Vertex>>)>,
    /// First flip of each sample: local coordinates -> its original side.
    original: FastMap<[i64; 3], bool>,
    /// What the well-composed steps did: counts before the first and after the last, and every
    /// sample they flipped (local coordinates).
    composition: Option<(crate::compose::Composition, FastMap<[i64; 3], ()>)>,
    /// Samples the well-composed step flipped to open a handle (see
    /// [`crate::compose::ComposeOptions::open_handles`]): no wall flips them back, so the handle
    /// is closed elsewhere and the face it went through stays mended.
    locked: FastMap<[i64; 3], ()>,
    /// Whether the well-composed step may open handles (not right after one was taken back).
    opening: bool,
    /// The samples changed (see [`changed_sides`]) and the step's options when [`Run::compose`]
    /// last ended: run again on the same volume with the same options, the step flips nothing
    /// (it ends where a look flips nothing), so it is not run.
    composed_at: Option<StepEnd>,
    /// What the well-composed steps found, as of the end of the step `composed_at` notes (see
    /// [`crate::compose::Memory`]); none after a step whose flips were undone.
    compose_memory: Option<crate::compose::Memory>,
    lasting: Lasting,
    rewinds: usize,
    refused: Refused,
    /// Regions peeled in vain, forgotten where an edit lands (with `lasting`).
    no_cut: NoCut,
    intra_ribbon: usize,
    seconds: StageSeconds,
    parts: Parts,
    /// Handles that may still be removed (`keep_handles`); `None`: no limit.
    budget: Option<usize>,
}

impl<'a> Run<'a> {
    fn new(opts: &SimplifyOptions, affine: &'a Affine, progress: &'a dyn Progress) -> Run<'a> {
        Run {
            opts: *opts,
            affine,
            progress,
            conn: opts.surface.connectivity,
            limits: opts.limits(),
            certifying: opts.tau.is_finite() && opts.mode == Mode::Both && opts.max_ratio.is_none(),
            certified: None,
            passes: 0,
            max_passes: MAX_PASSES,
            removed: Vec::new(),
            wall_samples: Vec::new(),
            kept: Vec::new(),
            basis: Vec::new(),
            original: FastMap::default(),
            composition: None,
            locked: FastMap::default(),
            opening: true,
            composed_at: None,
            compose_memory: None,
            lasting: Lasting::default(),
            rewinds: 0,
            refused: Refused::default(),
            no_cut: NoCut::default(),
            intra_ribbon: 0,
            seconds: StageSeconds::default(),
            parts: Parts::default(),
            budget: None,
        }
    }

    /// Sweeps, closes and makes the volume well-composed, pass after pass, until a pass closes
    /// nothing and the step flips nothing (or the pass limit). A handle the step opened that
    /// no pass could close (its loops at least tau, every wall refused) is taken back at the
    /// end, and the passes run again without opening any: the face it went through is left
    /// (see [`crate::compose::ComposeOptions::open_handles`]).
    ///
    /// Taking back and closing change the faces left, so a face no first opening met may now
    /// be mended by one: the step, opening handles again, and the passes then run in rounds
    /// until a round ends where it began (or [`MAX_ROUNDS`]). The result is then its own fixed
    /// point: simplify run again on it, which starts with such a round, changes nothing. A
    /// round whose step opens its way back to where the last round's openings settled would
    /// repeat that round (the same volume, the same passes): its step is undone and the round
    /// skipped, which spares the two passes that would find so.
    fn passes_until_done(&mut self, vol: &mut MaskVolume) -> Result<()> {
        // The samples changed where the last round's openings settled: a round whose step
        // opens its way back there would repeat that round, and end where it begins.
        let mut opened_at: Option<Vec<([i64; 3], bool)>> = None;
        // Each round begins where the last ended.
        let mut began = changed_sides(vol, &self.original);
        for round in 1..=MAX_ROUNDS {
            self.opening = true;
            let settled = match opened_at.take() {
                None => self.passes_while_changing(vol)?,
                // The volume is as the last pass left it: the round starts with the step.
                Some(there) => {
                    let sides = changed_sides(vol, &self.original);
                    let (c, memory) = self.composed(vol, true, &sides)?;
                    let known = c.flips.iter().all(|(q, _)| self.original.contains_key(q));
                    if known && changed_sides(vol, &self.original) == there {
                        for &(q, inside) in &c.flips {
                            vol.set(q[0] as usize, q[1] as usize, q[2] as usize, !inside);
                        }
                        self.progress.trace(format_args!(
                            "round {round} would repeat the last: its step taken back, done"
                        ));
                        return Ok(());
                    }
                    if self.record(c) == 0 {
                        return Ok(());
                    }
                    self.step_ended(vol, self.compose_options(true), memory);
                    self.passes_while_changing(vol)?
                }
            };
            if !settled || self.kept.is_empty() {
                return Ok(());
            }
            let opened = changed_sides(vol, &self.original);
            if self.take_back_opened(vol) == 0 {
                return Ok(());
            }
            self.opening = false;
            if !self.passes_while_changing(vol)? {
                return Ok(());
            }
            let ended = changed_sides(vol, &self.original);
            if ended == began {
                return Ok(());
            }
            began = ended;
            opened_at = Some(opened);
            self.progress.trace(format_args!(
                "round {round} changed the volume: opening handles again"
            ));
        }
        Ok(())
    }

    /// Flips back each sample the step opened a handle with whose handle is still there (the
    /// sample's two pieces round it are one component without it: the flip removes exactly
    /// one handle, and no component or cavity); returns how many.
    fn take_back_opened(&mut self, vol: &mut MaskVolume) -> usize {
        let mut opened: Vec<[i64; 3]> = self.locked.keys().copied().collect();
        opened.sort_unstable();
        let mut taken = Vec::new();
        for b in opened {
            if crate::compose::take_back(vol, self.conn, b) {
                self.locked.remove(&b);
                taken.push(b);
            }
        }
        if let Some((c, _)) = &mut self.composition {
            c.opened.retain(|q| !taken.contains(q));
        }
        self.forget_near_samples(taken.iter().copied());
        taken.len()
    }

    /// [`Run::passes_until_done`] without taking back. Returns whether the passes settled
    /// (false: the pass limit was reached).
    fn passes_while_changing(&mut self, vol: &mut MaskVolume) -> Result<bool> {
        let first = self.passes;
        while self.passes < first + self.max_passes {
            let from = self.removed.len();
            let closed = self.sweep_pass(vol)?;
            self.trim_walls(vol, from);
            // Well-composed after every pass that changed something, so that the last pass (the
            // one that closes nothing) analyses and certifies the volume as it is written. A
            // handle opened needs a pass after it to be closed.
            let another = self.passes < first + self.max_passes;
            let flipped = if self.opts.well_composed {
                self.compose(vol, another)?
            } else {
                0
            };
            if closed == 0 && flipped == 0 {
                return Ok(true);
            }
        }
        mark_stale(&mut self.kept, &self.opts);
        if self.certifying {
            // The pass limit was reached: the last pass closed something.
            self.certified = Some(false);
        }
        Ok(false)
    }

    /// Closes handles below `tau` from now on, at most `budget` more of them.
    fn retarget(&mut self, tau: f64, budget: Option<usize>) {
        self.opts.tau = tau;
        self.limits = self.opts.limits();
        self.budget = budget;
    }

    /// One sweep over the whole volume, closing what it can; returns how many handles it closed.
    /// A pass that closes nothing is the last: what it kept is the result, and its certificate
    /// is checked.
    fn sweep_pass(&mut self, vol: &mut MaskVolume) -> Result<usize> {
        self.passes += 1;
        self.kept.clear();
        self.basis.clear();
        let closed_before = self.removed.len();
        let mut sweeper = Sweeper::new(self.conn);
        let mut caches = Caches::new(self.conn);
        let progress = self.progress;
        progress.start(&format!("pass {}", self.passes), vol.dims[2] as u64 + 1);
        // Highest slice stepped so far: slices above it are seen for the first time.
        let mut high = -2;
        while !sweeper.done(vol) {
            let s = sweeper.next;
            let new = self.step(vol, &mut sweeper, &mut caches)?;
            let first_visit = s > high;
            if first_visit {
                progress.advance((s - high) as u64);
                progress.message(&format!("{} removed", self.removed.len()));
                high = s;
            }
            crate::progress::between_steps(progress, "sweep")?;
            if new.is_empty() {
                continue;
            }
            if self.passes == 1 && first_visit {
                let intra = new.iter().filter(|h| h.kind == HandleKind::IntraRibbon);
                self.intra_ribbon += intra.count();
            }
            let measured = self.measure(vol, &mut caches, &new, s);
            let t = std::time::Instant::now();
            let walls = self.close_small(vol, &mut caches, &new, &measured, s);
            self.seconds.closures += t.elapsed().as_secs_f64();
            if !walls.is_empty() {
                self.rewind(vol, &mut sweeper, &mut caches, &walls, s)?;
            }
        }
        progress.finish();
        let closed = self.removed.len() - closed_before;
        if closed == 0 && self.certifying {
            let holds = certificate_holds(vol, self.conn, &self.kept, &self.basis, progress)?;
            self.certified = Some(holds);
        }
        vol.follow_sweep(sweeper.next)?;
        progress.trace(format_args!(
            "pass {} done: {closed} closed, {} rewinds so far, refused {:?}, {:?}",
            self.passes, self.rewinds, self.refused.by, self.seconds
        ));
        Ok(closed)
    }

    /// Steps the sweep one slice; returns the handles it found.
    fn step(
        &mut self,
        vol: &mut MaskVolume,
        sweeper: &mut Sweeper,
        caches: &mut Caches,
    ) -> Result<Vec<LocatedHandle>> {
        let t = std::time::Instant::now();
        let n = sweeper.step(vol)?;
        if let Some((at, surfels)) = sweeper.take_surfels() {
            // The loops of the handles found here need this slice's ribbons too.
            caches.slices.offer(at, surfels);
        }
        vol.follow_sweep(sweeper.next)?;
        self.seconds.sweep += t.elapsed().as_secs_f64();
        if n == 0 {
            return Ok(Vec::new());
        }
        let all = sweeper.handles();
        let new = all[all.len() - n..]
            .iter()
            .map(|(_, h)| h.clone())
            .collect();
        sweeper.release_handles();
        Ok(new)
    }

    /// The loops of the handles found at slice `s`.
    fn measure(
        &mut self,
        vol: &MaskVolume,
        caches: &mut Caches,
        new: &[LocatedHandle],
        s: i64,
    ) -> Vec<HandleLoops> {
        let t = std::time::Instant::now();
        let (conn, affine, limits) = (self.conn, self.affine, self.limits);
        let measured = caches.measure(vol, new, conn, affine, limits, &mut self.lasting);
        let took = t.elapsed().as_secs_f64();
        self.seconds.loops += took;
        self.progress.trace(format_args!(
            "measuring {} handles at slice {s} took {took:.6} s",
            new.len()
        ));
        for (h, l) in new.iter().zip(&measured) {
            self.progress.trace(format_args!(
                "measured {:?} at slice {s}: reeb {:?} cross {:?}, cycle of {} nodes",
                h.kind,
                l.reeb.as_ref().map(|x| x.length),
                l.cross.as_ref().map(|x| x.length),
                h.cycle.len()
            ));
        }
        measured
    }

    /// Closes the small handles found at slice `s`, smallest first; returns the walls written,
    /// as local boxes.
    fn close_small(
        &mut self,
        vol: &mut MaskVolume,
        caches: &mut Caches,
        new: &[LocatedHandle],
        measured: &[HandleLoops],
        s: i64,
    ) -> Vec<BBox> {
        let mut order: Vec<usize> = (0..new.len()).collect();
        let size = |i: usize| {
            measured[i]
                .size_in(self.opts.metric)
                .unwrap_or(f64::INFINITY)
        };
        order.sort_by(|&a, &b| size(a).total_cmp(&size(b)));
        // What this step's certificates share.
        let mut step = StepCurves::default();
        let mut walls: Vec<BBox> = Vec::new();
        for i in order {
            let at = Found {
                handle: &new[i],
                loops: &measured[i],
                slice: s,
            };
            if let Some(wall) = self.settle(vol, caches, &mut step, &walls, at) {
                walls.push(wall);
            }
        }
        walls
    }

    /// Closes one handle or keeps it (and says why); returns the wall written, if any.
    fn settle(
        &mut self,
        vol: &mut MaskVolume,
        caches: &mut Caches,
        step: &mut StepCurves,
        walls: &[BBox],
        at: Found,
    ) -> Option<BBox> {
        let Found {
            handle: h,
            slice: s,
            ..
        } = at;
        let l = self.loops_to_close(vol, caches, step, at)?;
        let candidates = plan(&l, &self.opts).expect("a loop below tau");
        // Measured before this step's walls: if one landed near, measure again after the
        // rewind.
        let near = |x: &Loop| walls.iter().any(|w| wall_near_loop(w, x, 2));
        if candidates.iter().any(|(_, x)| near(x)) {
            return None;
        }
        if self.budget == Some(0) {
            self.kept.push((s, at.kept(KeepReason::KeepHandles)));
            return None;
        }
        let key = memo_key(h);
        if caches.failed.contains_key(&key) {
            self.kept.push((s, at.kept(KeepReason::ClosureFailed)));
            return None;
        }
        let (opts, affine) = (&self.opts, self.affine);
        let graph = &mut caches.graph;
        let walling = (graph, &mut self.refused, &self.locked, &mut self.no_cut);
        let done = close_handle(vol, opts, &l, &candidates, affine, walling);
        let Some(closed) = done else {
            caches.failed.insert(key, ());
            self.kept.push((s, at.kept(KeepReason::ClosureFailed)));
            return None;
        };
        let applied = &closed.applied;
        if let Some(b) = &mut self.budget {
            *b = b.saturating_sub(applied.handles);
        }
        let mut wall = BBox::EMPTY;
        for q in &applied.changed {
            wall.include(*q);
            self.original.entry(*q).or_insert(!applied.op.target());
        }
        caches.slices.invalidate(wall.min[2], wall.max[2]);
        self.no_cut.forget_near(&[wall]);
        let at_pass = (self.passes, s);
        self.removed
            .push(removal(vol, h, &l, &closed, affine, at_pass));
        self.wall_samples.push(closed.applied.changed);
        Some(wall)
    }

    /// The loops to close for a handle, or `None` once it is kept. A handle with no loop below
    /// tau is kept once its curves are certified: no loop below tau crosses them (see
    /// `certify`); if the search for that finds a loop below tau, that one is closed.
    fn loops_to_close<'l>(
        &mut self,
        vol: &MaskVolume,
        caches: &mut Caches,
        step: &mut StepCurves,
        at: Found<'l>,
    ) -> Option<Cow<'l, HandleLoops>> {
        let (h, l, s) = (at.handle, at.loops, at.slice);
        let reason = match plan(l, &self.opts) {
            Ok(_) => return Some(Cow::Borrowed(l)),
            Err(KeepReason::Size) if self.certifying => {
                let (conn, limits, affine) = (self.conn, self.limits, self.affine);
                match certify(vol, h, l, conn, limits, affine, caches, step) {
                    Certificate::Curves(curves) => {
                        self.basis.push((s, curves));
                        KeepReason::Size
                    }
                    Certificate::Shared => KeepReason::Size,
                    Certificate::Unsure => KeepReason::Unmeasured,
                    Certificate::Below(short) => return Some(Cow::Owned(short)),
                }
            }
            Err(reason) => reason,
        };
        self.kept.push((s, at.kept(reason)));
        None
    }

    /// Walls are often thicker than their handles need (a fan wall fills its whole disc): flips
    /// back every sample of the walls from `removed[from]` on whose flip back is simple (changes
    /// no topology of either side), pass after pass, so that only the samples holding the
    /// handles closed stay changed. After the pass rather than wall by wall: the sweep would
    /// meet each thinned wall as new surface and measure the handles round it again.
    fn trim_walls(&mut self, vol: &mut MaskVolume, from: usize) {
        let mut back: FastMap<[i64; 3], ()> = FastMap::default();
        for target in [true, false] {
            let walls = self.removed[from..].iter().zip(&self.wall_samples[from..]);
            let cand: Vec<[i64; 3]> = walls
                .filter(|(r, _)| r.operation.target() == target)
                .flat_map(|(_, w)| w.iter().copied())
                // Only samples whose flip back restores the input (not one a later wall of the
                // other kind flipped back already).
                .filter(|q| vol.get(q[0], q[1], q[2]) == target)
                .filter(|q| self.original.get(q) == Some(&!target))
                .collect();
            let flipped = crate::closure::flip_simple(vol, self.conn, &cand, !target);
            back.extend(flipped.into_iter().map(|q| (q, ())));
        }
        if back.is_empty() {
            return;
        }
        self.forget_near_samples(back.keys().copied());
        for (r, w) in self.removed[from..]
            .iter_mut()
            .zip(&mut self.wall_samples[from..])
        {
            w.retain(|q| !back.contains_key(q));
            r.samples = w.iter().map(|&q| vol.frame.to_original_i(q)).collect();
            r.samples_changed = r.samples.len();
            (r.max_distance, r.max_distance_mm) =
                removal::max_distance(&r.samples, &r.points, self.affine);
        }
    }

    /// Forgets the lasting measurements whose searches reached next to one of these flipped
    /// samples.
    fn forget_near_samples(&mut self, samples: impl Iterator<Item = [i64; 3]>) {
        let near: Vec<BBox> = samples
            .map(|q| BBox {
                min: q.map(|x| x - 1),
                max: q.map(|x| x + 1),
            })
            .collect();
        self.lasting.forget_near(&near);
        self.no_cut.forget_near(&near);
    }

    /// After walls were written at slice `s`: sweep again from the lowest slice they touched.
    fn rewind(
        &mut self,
        vol: &mut MaskVolume,
        sweeper: &mut Sweeper,
        caches: &mut Caches,
        walls: &[BBox],
        s: i64,
    ) -> Result<()> {
        let lowest = walls.iter().map(|w| w.min[2]).min().unwrap_or(i64::MAX);
        // Slice lowest - 1 has a corner in the wall's lowest plane; redo from there, and at
        // least from s (this step's handles, measured before the walls).
        let to = (lowest - 1).min(s);
        caches.forget_near(walls);
        self.lasting.forget_near(walls);
        sweeper.rewind(vol, to)?;
        self.kept.retain(|(at, _)| *at < to);
        self.basis.retain(|(at, _)| *at < to);
        self.rewinds += 1;
        vol.follow_sweep(sweeper.next)
    }

    /// Makes the volume well-composed (see [`crate::compose`]); returns how many samples it
    /// flipped. Fill-only flips only to inside, cut-only only to outside. The step may open a
    /// handle to mend a face when this run closes handles below a tau (not `--keep-handles`)
    /// and `another` pass follows to close it; the sample is then locked (and taken back, to
    /// its side in the input, if no pass closes that handle).
    fn compose(&mut self, vol: &mut MaskVolume, another: bool) -> Result<usize> {
        let at = (
            changed_sides(vol, &self.original),
            self.compose_options(another),
        );
        if self.composed_at.as_ref() == Some(&at) {
            self.progress.trace(format_args!(
                "composed after pass {}: nothing changed since the step last ended",
                self.passes
            ));
            return Ok(0);
        }
        let (c, memory) = self.composed(vol, another, &at.0)?;
        let flipped = self.record(c);
        self.step_ended(vol, at.1, memory);
        Ok(flipped)
    }

    /// Notes where a well-composed step run with `options` ended (see [`Run::composed_at`]).
    fn step_ended(
        &mut self,
        vol: &mut MaskVolume,
        options: crate::compose::ComposeOptions,
        memory: crate::compose::Memory,
    ) {
        self.composed_at = Some((changed_sides(vol, &self.original), options));
        self.compose_memory = Some(memory);
    }

    /// What the well-composed step may do now (see [`Run::compose`]).
    fn compose_options(&self, another: bool) -> crate::compose::ComposeOptions {
        let only = match self.opts.mode {
            Mode::Both => None,
            Mode::FillOnly => Some(true),
            Mode::CutOnly => Some(false),
        };
        crate::compose::ComposeOptions {
            only,
            open_handles: another && self.opening && self.opts.tau > 0.0 && self.budget.is_none(),
        }
    }

    /// The well-composed step on `vol`, whose samples changed are `sides` (see
    /// [`changed_sides`]), not yet recorded (see [`Run::compose`]), and what it and the steps
    /// before found (for [`Run::step_ended`]).
    fn composed(
        &mut self,
        vol: &mut MaskVolume,
        another: bool,
        sides: &[([i64; 3], bool)],
    ) -> Result<(crate::compose::Composition, crate::compose::Memory)> {
        let opts = self.compose_options(another);
        // What the last step found holds where nothing changed since it ended.
        let mut memory = self.compose_memory.take().unwrap_or_default();
        if let Some((ended, _)) = &self.composed_at {
            memory.changed_between(ended, sides);
        }
        // The handles opened before and not closed since stay where they can be taken back.
        let mut held: Vec<[i64; 3]> = self.locked.keys().copied().collect();
        held.retain(|&b| crate::compose::may_hold_a_handle(vol, self.conn, b));
        let c = crate::compose::compose_holding(
            vol,
            self.conn,
            opts,
            &held,
            &mut memory,
            self.progress,
        )?;
        // The first few opened samples locate them; a noisy scan opens thousands.
        let shown = &c.opened[..c.opened.len().min(8)];
        self.progress.trace(format_args!(
            "composed after pass {}: {} critical cells before, {} left, {} flipped, {} opened {shown:?}{}",
            self.passes,
            c.before.total(),
            c.left.total(),
            c.flips.len(),
            c.opened.len(),
            if shown.len() < c.opened.len() { " ..." } else { "" }
        ));
        Ok((c, memory))
    }

    /// Keeps what the step did (see [`Run::compose`]); returns how many samples it flipped.
    fn record(&mut self, c: crate::compose::Composition) -> usize {
        self.locked.extend(c.opened.iter().map(|&q| (q, ())));
        let flipped = c.flips.len();
        self.forget_near_samples(c.flips.iter().map(|&(q, _)| q));
        let (total, samples) = self.composition.get_or_insert_with(|| {
            (
                crate::compose::Composition {
                    before: c.before,
                    ..Default::default()
                },
                FastMap::default(),
            )
        });
        for &(q, inside) in &c.flips {
            self.original.entry(q).or_insert(!inside);
            samples.insert(q, ());
        }
        total.left = c.left;
        total.pairs += c.pairs;
        total.moves += c.moves;
        total.swaps += c.swaps;
        total.rewrites += c.rewrites;
        total.opened.extend(c.opened);
        flipped
    }

    fn outcome(self, vol: &mut MaskVolume) -> Outcome {
        let edits = final_edits(vol, &self.original);
        let composition = self.composition.map(|(mut c, samples)| {
            let composed: FastMap<[i64; 3], ()> = samples
                .into_keys()
                .map(|q| (vol.frame.to_original_i(q), ()))
                .collect();
            c.flips = edits
                .iter()
                .filter(|e| composed.contains_key(&e.0))
                .copied()
                .collect();
            c.opened = c
                .opened
                .iter()
                .map(|&q| vol.frame.to_original_i(q))
                .collect();
            c
        });
        Outcome {
            composition,
            removed: self.removed,
            kept: self.kept.into_iter().map(|(_, k)| k).collect(),
            edits,
            intra_ribbon: self.intra_ribbon,
            passes: self.passes,
            certified: self.certified,
            rewinds: self.rewinds,
            refused: self.refused.total,
            refused_by: self.refused.by,
            seconds: self.seconds,
            parts: self.parts,
        }
    }
}

/// A handle found at a slice of the sweep, with its loops as measured.
#[derive(Clone, Copy)]
struct Found<'l> {
    handle: &'l LocatedHandle,
    loops: &'l HandleLoops,
    slice: i64,
}

impl Found<'_> {
    /// The report of the handle kept, by its loops as measured.
    fn kept(&self, reason: KeepReason) -> Kept {
        let (h, l) = (self.handle, self.loops);
        Kept {
            size: l.size(),
            size_mm: l.size_in(Metric::Millimetres),
            reeb: l.reeb.as_ref().map(|x| x.length),
            cross: l.cross.as_ref().map(|x| x.length),
            kind: h.kind,
            reason,
            bbox: l.bbox().unwrap_or(h.bbox),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kept(size: usize, size_mm: f64) -> Kept {
        Kept {
            size: Some(size),
            size_mm: Some(size_mm),
            reeb: Some(size),
            cross: None,
            kind: HandleKind::ReebCycle,
            reason: KeepReason::Size,
            bbox: BBox::EMPTY,
        }
    }

    /// `--keep-handles`: the tau just above the `remove` smallest sizes, in edges and in
    /// millimetres; a handle without a size counts as the largest.
    #[test]
    fn keep_handles_tau_lies_just_above_the_smallest_to_remove() {
        let (a, b, c) = (kept(9, 4.5), kept(4, 2.25), kept(6, 3.0));
        let mut unsized_ = kept(1, 0.1);
        (unsized_.size, unsized_.size_mm) = (None, None);
        let hs = [&a, &b, &unsized_, &c];
        assert_eq!(keep_handles_tau(&hs, Metric::Edges, 1), 4.5);
        assert_eq!(keep_handles_tau(&hs, Metric::Edges, 2), 6.5);
        assert_eq!(keep_handles_tau(&hs, Metric::Edges, 3), 9.5);
        for (remove, size) in [(1, 2.25), (2, 3.0), (3, 4.5)] {
            let tau = keep_handles_tau(&hs, Metric::Millimetres, remove);
            assert!(tau > size && tau < size + 1e-9, "{remove}: {tau}");
        }
        assert_eq!(keep_handles_tau(&hs, Metric::Edges, 4), f64::INFINITY);
    }

    /// A thin torus (its handle below tau) and a thick one (above) in one volume.
    fn two_tori() -> MaskVolume {
        let mut vol = MaskVolume::new([44, 24, 12], crate::grid::Frame::identity());
        for (x, y, z) in (0..44 * 24 * 12).map(|k| (k % 44, k / 44 % 24, k / (44 * 24))) {
            let torus = |cx: f64, big: f64, small: f64| {
                let (dx, dy, dz) = (x as f64 - cx, y as f64 - 11.5, z as f64 - 5.5);
                ((dx * dx + dy * dy).sqrt() - big).hypot(dz) < small
            };
            vol.set(x, y, z, torus(8.5, 4.0, 1.6) || torus(30.5, 9.0, 3.4));
        }
        vol
    }

    /// A sample flipped back after a pass (`trim_walls`) forgets the lasting measurements whose
    /// reach comes within one sample of it, on either side. The reach of a loop through the x
    /// edge at the origin, searched below 6, is the blocks of 8 samples within 7 of it: x from
    /// -8 to 15.
    #[test]
    fn a_flip_forgets_the_measurements_reaching_next_to_it() {
        let opts = SimplifyOptions::default();
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let lp = Loop {
            vertices: vec![crate::surface::Vertex {
                p: [0, 0, 0],
                axis: 0,
            }],
            points: Vec::new(),
            length: 4,
            length_mm: 4.0,
            encloses: crate::loops::Encloses::Void,
        };
        let measured = HandleLoops {
            reeb: Some(lp),
            exact: true,
            ..HandleLoops::default()
        };
        let limits = Limits {
            below: 6.0,
            ..Limits::NONE
        };
        for (x, forgotten) in [(16, true), (17, false), (-9, true), (-10, false)] {
            let mut run = Run::new(&opts, &affine, &crate::progress::NoProgress);
            run.lasting.offer(7, &measured, limits);
            assert!(run.lasting.get(7).is_some());
            run.forget_near_samples([[x, 0, 0]].into_iter());
            assert_eq!(run.lasting.get(7).is_none(), forgotten, "flip at x = {x}");
        }
    }

    /// The pass limit: passes stop at it, even though the last closed something, and the
    /// result is then not certified; one pass more and the pass closing nothing certifies the
    /// same volume.
    #[test]
    fn passes_stop_at_the_limit_uncertified() {
        let opts = SimplifyOptions {
            tau: 20.0,
            ..SimplifyOptions::default()
        };
        let affine = Affine::from_spacing([1.0; 3], [0.0; 3]);
        let run_with = |max_passes| {
            let mut vol = two_tori();
            let mut run = Run::new(&opts, &affine, &crate::progress::NoProgress);
            run.max_passes = max_passes;
            run.passes_until_done(&mut vol).unwrap();
            let kept: Vec<KeepReason> = run.kept.iter().map(|(_, k)| k.reason).collect();
            let bits: Vec<bool> = (0..44 * 24 * 12)
                .map(|k| vol.get(k % 44, k / 44 % 24, k / (44 * 24)))
                .collect();
            (run.passes, run.certified, run.removed.len(), kept, bits)
        };
        let (passes, certified, removed, kept, limited) = run_with(1);
        assert_eq!((passes, certified, removed), (1, Some(false), 1));
        assert_eq!(kept, [KeepReason::Size]);
        let (passes, certified, removed, kept, done) = run_with(2);
        assert_eq!((passes, certified, removed), (2, Some(true), 1));
        assert_eq!(kept, [KeepReason::Size]);
        assert!(limited == done, "the second pass changed nothing");
    }

    /// After the last allowed pass closed something: a handle kept for its size that measured
    /// below tau (in the metric's unit) is marked kept at the pass limit; one at or above tau,
    /// or kept for another reason, keeps its reason.
    #[test]
    fn only_handles_kept_for_a_size_below_tau_are_stale() {
        let opts = SimplifyOptions {
            tau: 10.0,
            ..SimplifyOptions::default()
        };
        let mut failed = kept(4, 2.0);
        failed.reason = KeepReason::ClosureFailed;
        let mut list = [(0, kept(4, 20.0)), (1, kept(12, 2.0)), (2, failed)];
        mark_stale(&mut list, &opts);
        let reasons = |list: &[(i64, Kept)]| list.iter().map(|(_, k)| k.reason).collect::<Vec<_>>();
        use KeepReason::*;
        assert_eq!(reasons(&list), [PassLimit, Size, ClosureFailed]);
        let mm = SimplifyOptions {
            metric: Metric::Millimetres,
            ..opts
        };
        let mut list = [(0, kept(4, 20.0)), (1, kept(12, 2.0))];
        mark_stale(&mut list, &mm);
        assert_eq!(reasons(&list), [Size, PassLimit]);
    }
}
