//! The entry points a caller needs: a volume in (a file, or samples in memory), one options
//! struct, a typed result out. The command line, and every other front end, drive the pipeline
//! only through these.
//!
//! ```no_run
//! use isotopo::{Source, SimplifyOptions};
//!
//! let mut opts = SimplifyOptions { tau: 20.0, ..SimplifyOptions::default() };
//! opts.surface.iso = 127.5; // a grey-matter probability map in 0..255
//! let mut done = isotopo::simplify(Source::file("brain.nii.gz"), &opts, &isotopo::progress::NoProgress)?;
//! println!("genus {} -> {}", done.before.b1, done.after.b1);
//! done.write("brain-simplified.nii.gz", &isotopo::progress::NoProgress)?;
//! # Ok::<(), isotopo::Error>(())
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::grid::{Axis, MaskVolume};
use crate::loops::{HandleLoops, Limits, Metric, WorkerCaches};
use crate::progress::Progress;
use crate::simplify::{Outcome, SimplifyOptions, SliceEditor, WallValues};
use crate::sweep::HandleReport;
use crate::topology::genus::{GenusReport, SurfaceOptions};
use crate::volume::{self, InMemoryVolume, ReadOptions, Samples, SliceReader, VolumeInfo};

/// Where a job reads its volume from.
pub enum Source {
    /// A file in any format isotopo reads, with the options raw files need.
    File {
        /// The file.
        path: PathBuf,
        /// How to read it if it does not describe itself (headerless raw).
        read: ReadOptions,
    },
    /// Samples already in memory.
    Memory(InMemoryVolume),
    /// A volume already opened (the command line opens it first to check the outputs).
    Reader(Box<dyn SliceReader>),
}

impl Source {
    /// A file whose format its name or header tells.
    pub fn file(path: impl Into<PathBuf>) -> Source {
        Source::File {
            path: path.into(),
            read: ReadOptions::default(),
        }
    }

    pub(crate) fn open(self) -> Result<Box<dyn SliceReader>> {
        match self {
            Source::File { path, read } => volume::open(&path, &read),
            Source::Memory(v) => Ok(Box::new(v)),
            Source::Reader(r) => Ok(r),
        }
    }
}

impl From<InMemoryVolume> for Source {
    fn from(v: InMemoryVolume) -> Source {
        Source::Memory(v)
    }
}

/// The topology of the solid and of each of its surfaces (see [`genus`]).
#[derive(Clone, Debug)]
pub struct Topology {
    /// The input's header.
    pub info: VolumeInfo,
    /// b0, b1 (the total genus), b2, the Euler characteristic and the surfaces.
    pub solid: GenusReport,
    /// Where meshers may disagree: critical configurations, samples at the isovalue, and the
    /// Betti numbers under the other connectivity.
    pub meshers: crate::topology::genus::Agreement,
    /// Seconds the pass took, reading included.
    pub seconds: f64,
}

/// Counts components, handles and cavities of the solid in one streaming pass over the volume
/// (memory: two planes).
pub fn genus(source: Source, opts: &SurfaceOptions, progress: &dyn Progress) -> Result<Topology> {
    check_surface(opts)?;
    let mut input = source.open()?;
    let info = input.info().clone();
    let t = Instant::now();
    let (solid, meshers) = crate::topology::genus(input.as_mut(), opts, progress)?;
    Ok(Topology {
        info,
        solid,
        meshers,
        seconds: t.elapsed().as_secs_f64(),
    })
}

impl Topology {
    /// The `genus --json` report.
    pub fn to_json(&self, opts: &SurfaceOptions) -> serde_json::Value {
        let r = &self.solid;
        serde_json::json!({
            "file": self.info.path,
            "dims": self.info.dims,
            "iso": opts.iso,
            "inside": opts.inside.name(),
            "connectivity": opts.connectivity.number(),
            "b0": r.b0,
            "b1": r.b1,
            "b2": r.b2,
            "chi": r.chi,
            "surfaces": r.surfaces,
            "meshers": self.meshers,
            "seconds": self.seconds,
        })
    }
}

fn check_surface(opts: &SurfaceOptions) -> Result<()> {
    if !opts.iso.is_finite() {
        return Err(Error::usage("the isovalue must be a finite number"));
    }
    Ok(())
}

/// Options of [`handles`] and [`analyze`].
#[derive(Clone, Copy, Debug)]
pub struct AnalyzeOptions {
    /// The isosurface: isovalue (by default 0), inside above it (by default), connectivity 6
    /// (by default).
    pub surface: SurfaceOptions,
    /// The axis the sweep runs along; by default z.
    pub axis: Axis,
    /// Planes held in memory at once; by default as many as fit in 16 MiB (see
    /// [`SimplifyOptions::max_slices`]).
    pub max_slices: Option<usize>,
    /// Loops are measured exactly up to this length in voxel edges; a longer one is reported
    /// as "at least this long". By default all are measured exactly.
    pub tau: Option<f64>,
    /// The same in millimetres, for the lengths in millimetres.
    pub tau_mm: Option<f64>,
    /// Which lengths the loops are shortest in: by default voxel edges.
    pub lengths: Lengths,
}

/// Which metric [`analyze`] measures loops in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Lengths {
    /// Voxel edges along the surface graph (as `tau` counts).
    #[default]
    Edges,
    /// Millimetres along the interpolated surface.
    Millimetres,
    /// Both: each handle's loops shortest in each.
    Both,
}

impl Default for AnalyzeOptions {
    fn default() -> AnalyzeOptions {
        AnalyzeOptions {
            surface: SurfaceOptions::default(),
            axis: Axis::Z,
            max_slices: None,
            tau: None,
            tau_mm: None,
            lengths: Lengths::Edges,
        }
    }
}

impl AnalyzeOptions {
    /// The searches' limits in voxel edges and in millimetres.
    fn limits(&self) -> (Limits, Limits) {
        let edges = Limits {
            below: self.tau.unwrap_or(f64::INFINITY),
            ..Limits::NONE
        };
        let mm = Limits {
            below: self.tau_mm.unwrap_or(f64::INFINITY),
            metric: Metric::Millimetres,
            size_only: false,
        };
        (edges, mm)
    }

    /// Refuses a limit that is not positive, or an isovalue that is not a number.
    pub fn validate(&self) -> Result<()> {
        check_surface(&self.surface)?;
        for t in [self.tau, self.tau_mm].into_iter().flatten() {
            if t.is_nan() || t <= 0.0 {
                return Err(Error::usage("tau must be positive (or inf)"));
            }
        }
        Ok(())
    }
}

/// Every handle of the isosurface, located by the sweep (see [`handles`]).
pub struct Handles {
    /// The input's header.
    pub info: VolumeInfo,
    /// The handles (each with its Reeb cycle or mini-volume) and the genus they add up to.
    pub report: HandleReport,
    /// Seconds the sweep took, reading included.
    pub seconds: f64,
    /// The inside bits the handles were found in (the surface graph's volume, for searches).
    pub masks: MaskVolume,
}

/// Locates every handle of the isosurface: a sweep builds the Reeb graph of the contours; each
/// independent cycle is a handle, and handles within one ribbon are found in small volumes.
pub fn handles(source: Source, opts: &AnalyzeOptions, progress: &dyn Progress) -> Result<Handles> {
    opts.validate()?;
    let mut input = source.open()?;
    let info = input.info().clone();
    let t = Instant::now();
    let read = if opts.lengths == Lengths::Edges {
        MaskVolume::from_reader
    } else {
        MaskVolume::from_reader_with_fractions
    };
    let mut masks = read(
        input.as_mut(),
        &opts.surface,
        opts.axis,
        opts.max_slices,
        progress,
    )?;
    let report =
        crate::sweep::find_handles(&mut masks, opts.axis, opts.surface.connectivity, progress)?;
    Ok(Handles {
        info,
        report,
        seconds: t.elapsed().as_secs_f64(),
        masks,
    })
}

impl Handles {
    /// The `handles --json` report.
    pub fn to_json(&self, opts: &AnalyzeOptions) -> serde_json::Value {
        let mut v = header(&self.info, opts);
        v["genus"] = self.report.genus.into();
        v["handles"] = crate::report::handles_json(&self.report, &self.info).into();
        v["surfaces"] = serde_json::json!(self.report.surfaces);
        v["seconds"] = self.seconds.into();
        v
    }
}

/// The volume and options every report starts with.
fn header(info: &VolumeInfo, opts: &AnalyzeOptions) -> serde_json::Value {
    let s = &opts.surface;
    serde_json::json!({
        "file": info.path,
        "dims": info.dims,
        "iso": s.iso,
        "inside": s.inside.name(),
        "connectivity": s.connectivity.number(),
        "axis": opts.axis.name(),
    })
}

/// Every handle with its two loops (see [`analyze`]).
pub struct Analysis {
    /// The input's header.
    pub info: VolumeInfo,
    /// The handles located (see [`Handles::report`]).
    pub report: HandleReport,
    /// Each handle's Reeb loop and cross loop, in the handles' order, shortest in voxel edges
    /// (or in millimetres when only those were asked for).
    pub loops: Vec<HandleLoops>,
    /// Shortest in millimetres, when asked for.
    pub loops_mm: Option<Vec<HandleLoops>>,
    /// Seconds for the sweep (reading included).
    pub seconds_sweep: f64,
    /// Seconds in all.
    pub seconds: f64,
    /// The inside bits the handles were found in (the surface graph's volume, for searches).
    pub masks: MaskVolume,
}

/// Locates every handle and measures its two loops (the paper's Reeb loop and cross loop),
/// each the shortest on the whole surface: the handle's size is the shorter.
pub fn analyze(source: Source, opts: &AnalyzeOptions, progress: &dyn Progress) -> Result<Analysis> {
    let t = Instant::now();
    let Handles {
        info,
        report,
        mut masks,
        ..
    } = handles(source, opts, progress)?;
    let seconds_sweep = t.elapsed().as_secs_f64();
    let (edges, mm) = opts.limits();
    let conn = opts.surface.connectivity;
    let mut measure = |limits| {
        crate::loops::measure_all(
            &mut masks,
            &report.handles,
            conn,
            &info.affine,
            limits,
            progress,
        )
    };
    let loops_mm = match opts.lengths {
        Lengths::Edges => None,
        _ => Some(measure(mm)?),
    };
    let loops = match (opts.lengths, &loops_mm) {
        (Lengths::Millimetres, Some(x)) => x.clone(),
        _ => measure(edges)?,
    };
    Ok(Analysis {
        info,
        report,
        loops,
        loops_mm,
        seconds_sweep,
        seconds: t.elapsed().as_secs_f64(),
        masks,
    })
}

impl Analysis {
    /// The `analyze --json` report: every handle with both loops (and in millimetres too when
    /// measured so).
    pub fn to_json(&self, opts: &AnalyzeOptions) -> serde_json::Value {
        let (info, report) = (&self.info, &self.report);
        let mut v = header(info, opts);
        v["tau"] = serde_json::json!(opts.tau.filter(|t| t.is_finite()));
        v["genus"] = report.genus.into();
        v["handles"] =
            crate::report::analysis_json(report, info, &self.loops, self.loops_mm.as_deref())
                .into();
        v["surfaces"] = serde_json::json!(report.surfaces);
        v["seconds"] = self.seconds.into();
        v["seconds_sweep"] = self.seconds_sweep.into();
        v
    }

    /// The `analyze --csv` table: a row per handle.
    pub fn to_csv(&self) -> String {
        crate::report::analysis_csv(
            &self.report,
            &self.info,
            &self.loops,
            self.loops_mm.as_deref(),
        )
    }
}

/// Handles measured at a time while [`analyze_streamed`] sweeps: enough to keep both cores
/// busy, few enough that their cycles and cuts take little memory.
const STREAM_BATCH: usize = 1024;

/// Vertices a worker's surface graph keeps in [`analyze_streamed`] before starting afresh (about
/// 300 bytes each): the handles come in the sweep's order, so the next ones are near the last.
/// On 128³ noise (53,546 handles) 2^14 and 2^16 take the same time, 2^14 a third less memory.
const STREAM_GRAPH_LIMIT: usize = 1 << 14;

/// Per handle in the report's order: where its JSON lies, and its surface.
type ReportOrder = Vec<(crate::spool::Place, u32)>;

/// [`analyze`]'s report, one handle at a time (see [`analyze_streamed`]).
pub struct StreamedAnalysis {
    /// The input's header.
    pub info: VolumeInfo,
    /// The sweep's axis.
    pub axis: Axis,
    /// Total genus from the Euler characteristic.
    pub genus: i64,
    /// Every closed surface, by id, with how many handles it holds.
    pub surfaces: Vec<crate::sweep::SweepSurface>,
    /// Seconds for the sweep (reading included), the loops' searches and their reports not
    /// counted.
    pub seconds_sweep: f64,
    /// Seconds in all, up to the first handle handed over.
    pub seconds: f64,
    spool: crate::spool::SpoolReader,
    order: ReportOrder,
    next: usize,
}

/// The same report as [`analyze`] with memory that does not grow with the handles: the sweep
/// hands over each step's handles, they are measured as it goes (in batches, in parallel) and
/// let go, their JSON kept in a scratch file; once the surfaces are known the handles come out
/// numbered as [`analyze`] numbers them, one [`report::measured_handle_json`] at a time, each
/// the same as in [`Analysis::to_json`]. What stays in memory is the sweep's, the searches'
/// caches, a few tens of bytes a handle, and the handles found but not yet measured: up to a
/// batch during the sweep (1,024; out of core 64), then those left at its end (on a real scan
/// with fewer, all of them, measured up the sweep axis with the window following).
///
/// [`report::measured_handle_json`]: crate::report::measured_handle_json
pub fn analyze_streamed(
    source: Source,
    opts: &AnalyzeOptions,
    progress: &dyn Progress,
) -> Result<StreamedAnalysis> {
    opts.validate()?;
    let t = Instant::now();
    let mut input = source.open()?;
    let info = input.info().clone();
    let read = if opts.lengths == Lengths::Edges {
        MaskVolume::from_reader
    } else {
        MaskVolume::from_reader_with_fractions
    };
    let s = &opts.surface;
    let mut masks = read(input.as_mut(), s, opts.axis, opts.max_slices, progress)?;
    drop(input);
    let mut spool = crate::spool::Spool::new()?;
    // Per handle found: its JSON's place, and what numbers it.
    let mut found: Vec<(crate::spool::Place, crate::sweep::NumberKey)> = Vec::new();
    let mut pending: Vec<crate::sweep::LocatedHandle> = Vec::new();
    let mut seconds_loops = 0.0;
    let conn = s.connectivity;
    // Edges and millimetres: the lengths differ, so do the searches' graphs.
    let pools = [0, 1].map(|_| WorkerCaches::new(STREAM_GRAPH_LIMIT));
    // Out of core, the planes the searches load stay until the window next moves: small batches.
    let batch_size = match masks.out_of_core() {
        true => crate::loops::MEASURE_BATCH,
        false => STREAM_BATCH,
    };
    let mut each = |vol: &MaskVolume, new: Vec<crate::sweep::LocatedHandle>, _last: bool| {
        pending.extend(new);
        // A batch at a time; what is left after the last step waits for the window to be free.
        if pending.len() < batch_size {
            return Ok(());
        }
        let t = Instant::now();
        let batch = numbered_zero(std::mem::take(&mut pending));
        let quiet = &crate::progress::StepsOnly(progress);
        let refs: Vec<&crate::sweep::Handle> = batch.iter().collect();
        let records = measure_to_json(vol, &refs, opts, &info, &pools, quiet)?;
        for (h, record) in batch.into_iter().zip(records) {
            found.push((spool.push(&record)?, h.located.number_key()));
        }
        seconds_loops += t.elapsed().as_secs_f64();
        Ok(())
    };
    let numbers = crate::sweep::find_handles_each(&mut masks, conn, progress, &mut each)?;
    // The rest (on a real scan, every handle), up the sweep axis with the window following.
    let t_rest = Instant::now();
    let rest = numbered_zero(pending);
    progress.start("loops", rest.len() as u64);
    let mut records = vec![Vec::new(); rest.len()];
    crate::loops::in_sweep_batches(
        &mut masks,
        &rest,
        batch_size,
        |vol: &MaskVolume, batch: &[&crate::sweep::Handle]| {
            measure_to_json(vol, batch, opts, &info, &pools, progress)
        },
        &mut records,
    )?;
    progress.finish();
    for (h, record) in rest.into_iter().zip(records) {
        found.push((spool.push(&record)?, h.located.number_key()));
    }
    seconds_loops += t_rest.elapsed().as_secs_f64();
    let genus = numbers.genus;
    let (surfaces, order) = number_handles(found, numbers);
    let seconds = t.elapsed().as_secs_f64();
    Ok(StreamedAnalysis {
        info,
        axis: opts.axis,
        genus,
        surfaces,
        seconds_sweep: seconds - seconds_loops,
        seconds,
        spool: spool.finish()?,
        order,
        next: 0,
    })
}

/// The report's order of the handles found (as [`crate::sweep::find_handles`] numbers them: by
/// surface, then position; ties in the order found), with each one's surface; and the surfaces
/// with their counts of handles.
fn number_handles(
    found: Vec<(crate::spool::Place, crate::sweep::NumberKey)>,
    numbers: crate::sweep::SurfaceNumbers,
) -> (Vec<crate::sweep::SweepSurface>, ReportOrder) {
    let mut numbered: Vec<(usize, [i64; 3], crate::spool::Place)> = found
        .into_iter()
        .map(|(place, key)| {
            let (surface, at) = numbers.order_key(key);
            (surface, at, place)
        })
        .collect();
    numbered.sort_by_key(|&(surface, key, _)| (surface, key));
    let mut surfaces = numbers.surfaces;
    for &(surface, _, _) in &numbered {
        surfaces[surface].handles += 1;
    }
    let order = numbered.into_iter();
    let order = order.map(|(surface, _, place)| (place, surface as u32));
    (surfaces, order.collect())
}

/// Handles as the report's type, their ids and surfaces still to be given.
fn numbered_zero(located: Vec<crate::sweep::LocatedHandle>) -> Vec<crate::sweep::Handle> {
    let each = |located| crate::sweep::Handle {
        id: 0,
        surface: 0,
        located,
    };
    located.into_iter().map(each).collect()
}

/// Measures a batch of handles (in voxel edges, millimetres or both, as asked) and returns
/// each one's report as compact JSON; `progress` advances a step a handle.
fn measure_to_json(
    vol: &MaskVolume,
    batch: &[&crate::sweep::Handle],
    opts: &AnalyzeOptions,
    info: &VolumeInfo,
    pools: &[WorkerCaches; 2],
    progress: &dyn Progress,
) -> Result<Vec<Vec<u8>>> {
    let (edges, mm) = opts.limits();
    let conn = opts.surface.connectivity;
    let measure = |limits, pool| {
        crate::loops::measure_batch(vol, batch, conn, &info.affine, limits, pool, progress)
    };
    let loops_mm = match opts.lengths {
        Lengths::Edges => None,
        _ => Some(measure(mm, &pools[1])?),
    };
    let loops = match (opts.lengths, &loops_mm) {
        (Lengths::Millimetres, Some(x)) => x.clone(),
        _ => measure(edges, &pools[0])?,
    };
    batch
        .iter()
        .enumerate()
        .map(|(i, h)| {
            let mm = loops_mm.as_ref().map(|m| &m[i]);
            let v = crate::report::measured_handle_json(h, opts.axis, info, &loops[i], mm);
            serde_json::to_vec(&v).map_err(|e| Error::Internal(format!("JSON: {e}")))
        })
        .collect()
}

impl StreamedAnalysis {
    /// Handles in the report.
    pub fn len(&self) -> usize {
        self.order.len()
    }

    /// Whether the surface has no handle.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// The next handle's report, as in [`Analysis::to_json`]'s `handles`; `None` after the last.
    pub fn next_handle(&mut self) -> Result<Option<serde_json::Value>> {
        let Some(&(place, surface)) = self.order.get(self.next) else {
            return Ok(None);
        };
        let bytes = self.spool.read(place)?;
        let mut v: serde_json::Value = serde_json::from_slice(&bytes)
            .map_err(|e| Error::Internal(format!("JSON read back: {e}")))?;
        v["id"] = self.next.into();
        v["surface"] = surface.into();
        self.next += 1;
        Ok(Some(v))
    }

    /// Writes the whole `analyze --json` report to `out`, the handles streamed into it from the
    /// first not yet taken: the same text as [`Analysis::to_json`] printed compact, or pretty
    /// (two-space indents), without holding it all.
    pub fn write_json(
        &mut self,
        opts: &AnalyzeOptions,
        pretty: bool,
        out: &mut dyn std::io::Write,
    ) -> Result<()> {
        let text = |v: &serde_json::Value| {
            let s = match pretty {
                true => serde_json::to_string_pretty(v),
                false => serde_json::to_string(v),
            };
            s.map_err(|e| Error::Internal(format!("JSON: {e}")))
        };
        let whole = text(&self.to_json(opts))?;
        let slot = if pretty {
            "\"handles\": []"
        } else {
            "\"handles\":[]"
        };
        let at = whole
            .find(slot)
            .ok_or_else(|| Error::Internal("no place for the handles in the report".into()))?;
        let stdout_error = |e| Error::io(Path::new("<output>"), "writing", e);
        let mut put = |s: &str| out.write_all(s.as_bytes()).map_err(stdout_error);
        // Up to the list's opening bracket; in pretty text each handle is indented 4 more.
        put(&whole[..at + slot.len() - 1])?;
        let (first, next, close) = match pretty {
            true => ("\n    ", ",\n    ", "\n  ]"),
            false => ("", ",", "]"),
        };
        let mut any = false;
        while let Some(h) = self.next_handle()? {
            put(if any { next } else { first })?;
            let item = text(&h)?;
            put(&match pretty {
                true => item.replace('\n', "\n    "),
                false => item,
            })?;
            any = true;
        }
        put(if any { close } else { "]" })?;
        put(&whole[at + slot.len()..])
    }

    /// Starts again from the first handle.
    pub fn rewind(&mut self) {
        self.next = 0;
    }

    /// The `analyze --json` report but its handles, which go in `handles` (empty here).
    pub fn to_json(&self, opts: &AnalyzeOptions) -> serde_json::Value {
        let mut v = header(&self.info, opts);
        v["tau"] = serde_json::json!(opts.tau.filter(|t| t.is_finite()));
        v["genus"] = self.genus.into();
        v["handles"] = serde_json::json!([]);
        v["surfaces"] = serde_json::json!(self.surfaces);
        v["seconds"] = self.seconds.into();
        v["seconds_sweep"] = self.seconds_sweep.into();
        v
    }
}

/// What [`simplify`] did, with the input kept so the edited volume can be written or returned.
pub struct Simplified {
    /// The input's header (grid, sample type, affine, file).
    pub info: VolumeInfo,
    /// Topology of the solid before (b0 and b2 stay the same unless components or cavities
    /// were asked to go, by construction and by a check of the whole volume).
    pub before: GenusReport,
    /// Topology of the solid after: `b1` is the number of handles kept.
    pub after: GenusReport,
    /// The same Betti numbers under the other connectivity (equal to `after` when the output
    /// is well-composed).
    pub after_other: GenusReport,
    /// The handles removed and kept, every sample changed, and what making the output
    /// well-composed did.
    pub outcome: Outcome,
    /// The values written into the changed samples (just inside / just outside the isovalue,
    /// in the input's sample type).
    pub wall_values: WallValues,
    /// What writing the output (or [`Simplified::edited`]) changed besides the edits: samples at
    /// the isovalue, the largest move. `None` until then.
    pub written: Option<crate::simplify::Written>,
    /// Seconds spent reading (classifying the samples).
    pub seconds_read: f64,
    /// Seconds spent simplifying (every pass, the certificate included).
    pub seconds_simplify: f64,
    classifier: crate::topology::Classifier,
    input: Box<dyn SliceReader>,
}

impl std::fmt::Debug for Simplified {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Simplified")
            .field("before", &self.before.b1)
            .field("after", &self.after.b1)
            .field("samples_changed", &self.outcome.edits.len())
            .finish_non_exhaustive()
    }
}

/// Removes every handle of the isosurface smaller than `opts.tau`, and the components and
/// cavities the options ask to remove (see [`crate::simplify`](mod@crate::simplify) for how).
/// The whole result is checked before it is returned: components and cavities as the options
/// asked (unchanged by default), genus after equal to the handles kept; otherwise an internal
/// error, and nothing to write.
pub fn simplify(
    source: Source,
    opts: &SimplifyOptions,
    progress: &dyn Progress,
) -> Result<Simplified> {
    opts.validate()?;
    let mut input = source.open()?;
    let info = input.info().clone();
    let surface = &opts.surface;
    let t0 = Instant::now();
    // Lengths in millimetres follow the interpolated surface: keep the fractions along the
    // crossing edges when tau is in millimetres.
    let read = if opts.metric == Metric::Millimetres {
        MaskVolume::from_reader_with_fractions
    } else {
        MaskVolume::from_reader
    };
    let mut masks = read(
        input.as_mut(),
        surface,
        opts.axis,
        opts.max_slices,
        progress,
    )?;
    let seconds_read = t0.elapsed().as_secs_f64();
    let before = masks.genus(surface.connectivity)?;
    let t = Instant::now();
    let outcome = crate::simplify::simplify(&mut masks, opts, &info.affine, progress)?;
    let seconds_simplify = t.elapsed().as_secs_f64();
    let after = masks.genus(surface.connectivity)?;
    // Only the components-and-cavities phase may change b0 and b2; the handles' removal keeps
    // what it left.
    let (b0, b2) = outcome.parts.after.unwrap_or((before.b0, before.b2));
    if after.b0 != b0 || after.b2 != b2 {
        return Err(Error::Internal(format!(
            "removing handles changed the solid's components or cavities (b0 {b0} -> {}, b2 {b2} -> {}); nothing written",
            after.b0, after.b2
        )));
    }
    if after.b1 as usize != outcome.kept.len() {
        return Err(Error::Internal(format!(
            "genus after is {} but the last sweep kept {} handles; nothing written",
            after.b1,
            outcome.kept.len()
        )));
    }
    let after_other = masks.genus(surface.connectivity.other())?;
    let betti = |g: &GenusReport| (g.b0, g.b1, g.b2);
    if outcome
        .composition
        .as_ref()
        .is_some_and(|c| c.well_composed())
        && betti(&after) != betti(&after_other)
    {
        return Err(Error::Internal(format!(
            "the output is well-composed but its Betti numbers differ between connectivity {} {:?} and {} {:?}; nothing written",
            surface.connectivity.number(),
            betti(&after),
            surface.connectivity.other().number(),
            betti(&after_other)
        )));
    }
    let classifier = surface.classifier(&info);
    let wall_values = WallValues::new(info.dtype, &classifier);
    Ok(Simplified {
        classifier,
        info,
        before,
        after,
        after_other,
        outcome,
        wall_values,
        written: None,
        seconds_read,
        seconds_simplify,
        input,
    })
}

impl Simplified {
    /// Writes the edited volume to `path` (format from its extension, the input's header
    /// otherwise kept), atomically: the file appears whole or not at all.
    pub fn write(&mut self, path: impl AsRef<Path>, progress: &dyn Progress) -> Result<()> {
        let path = path.as_ref();
        volume::check_output_path(path, &self.info)?;
        // Built from the fields (not `self.editor()`): the input is borrowed mutably beside it.
        let edits = &self.outcome.edits;
        let move_at_iso = self.moves_at_iso();
        let editor = SliceEditor::new(edits, &self.wall_values, self.classifier, move_at_iso);
        let written = crate::simplify::write_edited(self.input.as_mut(), path, editor, progress)?;
        self.written = Some(written);
        Ok(())
    }

    /// The edited volume in memory (the input's sample type and grid).
    pub fn edited(&mut self) -> Result<InMemoryVolume> {
        self.input.rewind()?;
        let mut out = InMemoryVolume::from_reader(self.input.as_mut())?;
        let mut editor = self.editor();
        let nx = self.info.dims[0];
        for (z, slice) in out.slices.iter_mut().enumerate() {
            editor.apply(z, nx, slice)?;
        }
        self.written = Some(editor.written);
        Ok(out)
    }

    /// Applies the edits to a copy of the input that the caller holds (the Python package's
    /// output array), z-slice by z-slice in order: `read(z, slice)` fills `slice` with z-slice
    /// `z` of the copy (`nx·ny` samples, x fastest), `write(z, slice)` stores it back edited.
    pub fn edit_with(
        &mut self,
        mut read: impl FnMut(usize, &mut Samples) -> Result<()>,
        mut write: impl FnMut(usize, &Samples) -> Result<()>,
    ) -> Result<()> {
        let mut editor = self.editor();
        let nx = self.info.dims[0];
        let mut slice = Samples::new(self.info.dtype);
        for z in 0..self.info.nz() {
            read(z, &mut slice)?;
            editor.apply(z, nx, &mut slice)?;
            write(z, &slice)?;
        }
        self.written = Some(editor.written);
        Ok(())
    }

    /// Reads the input once more from its first slice, handing each z-slice to `f` as it was
    /// and as edited (the HTML report's meshes before and after).
    pub fn for_each_slice(
        &mut self,
        mut f: impl FnMut(usize, &Samples, &Samples) -> Result<()>,
    ) -> Result<()> {
        self.input.rewind()?;
        let mut editor = SliceEditor::new(
            &self.outcome.edits,
            &self.wall_values,
            self.classifier,
            self.moves_at_iso(),
        );
        let nx = self.info.dims[0];
        let mut before = Samples::new(self.info.dtype);
        for z in 0..self.info.nz() {
            self.input.read_slice(&mut before)?;
            let mut after = before.clone();
            editor.apply(z, nx, &mut after)?;
            f(z, &before, &after)?;
        }
        Ok(())
    }

    /// The isovalue to give another mesher (VTK, scikit-image) for the surface isotopo
    /// simplified: the isovalue itself, or for integer samples with the isovalue on a stored
    /// value, halfway to the next stored value inside (the same samples inside, none on it).
    pub fn mesh_iso(&self) -> f64 {
        let c = &self.classifier;
        if self.info.dtype.is_float() || c.raw_iso().fract() != 0.0 {
            return c.iso;
        }
        let half = c.scaling.slope.abs() / 2.0;
        match c.inside {
            crate::topology::Inside::Above => c.iso + half,
            crate::topology::Inside::Below => c.iso - half,
        }
    }

    /// The editor that applies the edits to the input's slices, in order.
    fn editor(&self) -> SliceEditor<'_> {
        SliceEditor::new(
            &self.outcome.edits,
            &self.wall_values,
            self.classifier,
            self.moves_at_iso(),
        )
    }

    /// Whether samples at the isovalue are moved outside when writing (see
    /// [`SimplifyOptions::well_composed`]).
    fn moves_at_iso(&self) -> bool {
        self.outcome.composition.is_some() && self.info.dtype.is_float()
    }

    /// The report (the CLI's `--report`): the outcome, both topologies, the options and timings.
    pub fn report(&self, opts: &SimplifyOptions) -> serde_json::Value {
        let mut v =
            crate::report::simplify_json(&self.outcome, &self.before, &self.after, &self.info);
        let surface = &opts.surface;
        let tau = if opts.tau.is_finite() {
            serde_json::json!(opts.tau)
        } else {
            serde_json::json!("inf")
        };
        let extra = serde_json::json!({
            "file": self.info.path,
            "dims": self.info.dims,
            "dtype": self.info.dtype.name(),
            "iso": surface.iso,
            "inside": surface.inside.name(),
            "connectivity": surface.connectivity.number(),
            "axis": opts.axis.name(),
            "tau": tau,
            "metric": opts.metric,
            "mode": opts.mode,
            "max_ratio": opts.max_ratio,
            "min_component": opts.min_component,
            "largest": opts.largest,
            "min_cavity": opts.min_cavity,
            "fill_cavities": opts.fill_cavities,
            "keep_handles": opts.keep_handles,
            "wall_values": self.wall_values,
            "well_composed": self.outcome.composition.as_ref().map(|c| serde_json::json!({
                "critical_before": c.before,
                "critical_left": c.left,
                "well_composed": c.well_composed(),
                "samples_flipped": c.flips.len(),
                "pair_moves": c.pairs,
                "samples": c.flips.iter().map(|f| f.0).collect::<Vec<_>>(),
            })),
            // The removed handles add up to genus_before - genus_after + handles_opened.
            "handles_opened": self.outcome.composition.as_ref().map_or(0, |c| c.opened.len()),
            "other_connectivity": surface.connectivity.other().number(),
            "b0_after_other": self.after_other.b0,
            "genus_after_other": self.after_other.b1,
            "b2_after_other": self.after_other.b2,
            "samples_at_iso": self.written.map(|w| w.samples_at_iso),
            "at_iso_moved": self.written.map(|w| w.at_iso_moved),
            "largest_move": self.written.map(|w| w.largest_move),
            "mesh_iso": self.mesh_iso(),
            "seconds_read": self.seconds_read,
            "seconds_simplify": self.seconds_simplify,
        });
        if let (Some(obj), serde_json::Value::Object(e)) = (v.as_object_mut(), extra) {
            obj.extend(e);
        }
        v
    }
}
