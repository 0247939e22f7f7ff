//! The entry points a caller needs: a volume in (a file, or samples in memory), one options
//! struct, a typed result out. The command line, and every other front end, drive the pipeline
//! only through these.
//!
//! ```no_run
//! use isotopo::{Source, SimplifyOptions};
//!
//! let opts = SimplifyOptions { tau: 20.0, ..SimplifyOptions::default() };
//! let mut done = isotopo::simplify(Source::file("brain.nii.gz"), &opts, &isotopo::progress::NoProgress)?;
//! println!("genus {} -> {}", done.before.b1, done.after.b1);
//! done.write("brain-simplified.nii.gz", &isotopo::progress::NoProgress)?;
//! # Ok::<(), isotopo::Error>(())
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::loops::Metric;
use crate::progress::Progress;
use crate::simplify::{Outcome, SimplifyOptions, WallValues};
use crate::sweep::MaskVolume;
use crate::topology::genus::GenusReport;
use crate::volume::{self, InMemoryVolume, ReadOptions, SliceReader, VolumeInfo};

/// Where a job reads its volume from.
pub enum Source {
    /// A file in any format isotopo reads, with the options raw files need.
    File { path: PathBuf, read: ReadOptions },
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

    fn open(self) -> Result<Box<dyn SliceReader>> {
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

/// What [`simplify`] did, with the input kept so the edited volume can be written or returned.
pub struct Simplified {
    /// The input's header (grid, sample type, affine, file).
    pub info: VolumeInfo,
    /// Topology of the solid before and after (b0 and b2 are the same, by construction and by
    /// a check of the whole volume).
    pub before: GenusReport,
    pub after: GenusReport,
    /// The handles removed and kept, and every sample changed.
    pub outcome: Outcome,
    /// The values written into the changed samples (just inside / just outside the isovalue,
    /// in the input's sample type).
    pub wall_values: WallValues,
    /// Seconds spent reading (classifying the samples) and simplifying.
    pub seconds_read: f64,
    pub seconds_simplify: f64,
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

/// Removes every handle of the isosurface smaller than `opts.tau` (see [`crate::simplify`](mod@crate::simplify) for
/// how). The whole result is checked before it is returned: components and cavities unchanged,
/// genus after equal to the handles kept; otherwise an internal error, and nothing to write.
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
    if after.b0 != before.b0 || after.b2 != before.b2 {
        return Err(Error::Internal(format!(
            "simplification changed the solid's components or cavities (b0 {} -> {}, b2 {} -> {}); nothing written",
            before.b0, after.b0, before.b2, after.b2
        )));
    }
    if after.b1 as usize != outcome.kept.len() {
        return Err(Error::Internal(format!(
            "genus after is {} but the last sweep kept {} handles; nothing written",
            after.b1,
            outcome.kept.len()
        )));
    }
    let wall_values = WallValues::new(info.dtype, &surface.classifier(&info));
    Ok(Simplified {
        info,
        before,
        after,
        outcome,
        wall_values,
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
        crate::simplify::write_edited(
            self.input.as_mut(),
            path,
            &self.outcome.edits,
            &self.wall_values,
            progress,
        )
    }

    /// The edited volume in memory (the input's sample type and grid).
    pub fn edited(&mut self) -> Result<InMemoryVolume> {
        self.input.rewind()?;
        let mut out = InMemoryVolume::from_reader(self.input.as_mut())?;
        for &([x, y, z], inside) in &self.outcome.edits {
            let v = if inside {
                self.wall_values.inside
            } else {
                self.wall_values.outside
            };
            let v = v.ok_or_else(|| {
                Error::Internal(format!(
                    "no wall value representable in {}",
                    self.info.dtype
                ))
            })?;
            out.set(x as usize, y as usize, z as usize, v);
        }
        Ok(out)
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
            "wall_values": self.wall_values,
            "seconds_read": self.seconds_read,
            "seconds_simplify": self.seconds_simplify,
        });
        if let (Some(obj), serde_json::Value::Object(e)) = (v.as_object_mut(), extra) {
            obj.extend(e);
        }
        v
    }
}
