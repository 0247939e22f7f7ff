//! # isotopo — isosurface topology simplification
//!
//! Scans and reconstructions turned into surfaces by isosurface extraction carry hundreds of tiny
//! topological handles. isotopo finds every handle of an isosurface with a slice-by-slice sweep
//! (a Reeb graph of contours and ribbons, after Wood, Hoppe, Desbrun and Schröder, *Isosurface
//! Topology Simplification*, 2002), measures each by its two shortest surface loops, and removes the
//! small ones by writing a thin wall into the volume, so the result is always a valid manifold
//! isosurface and the geometry away from each handle is untouched. The output is then made
//! well-composed ([`compose`]): other meshers (VTK, scikit-image, the other connectivity) see
//! the same topology.
//!
//! ## Use
//!
//! One call per job, a volume in (a file or samples in memory), one options struct with
//! documented defaults, a typed result out ([`simplify()`] → [`Simplified`]):
//!
//! ```
//! use isotopo::{progress::NoProgress, volume::InMemoryVolume, SimplifyOptions, Source};
//!
//! // A ball with a one-voxel ring fused to its side: one small handle.
//! let shape = |x: usize, y: usize, z: usize| {
//!     let d = |a: usize, c: f64| a as f64 - c;
//!     let ball = d(x, 8.0).hypot(d(y, 8.0)).hypot(d(z, 8.0)) < 5.0;
//!     let ring = z == 8 && d(x, 13.0).abs().max(d(y, 8.0).abs()) == 1.0;
//!     ball || ring
//! };
//! let volume = InMemoryVolume::from_mask([18, 17, 17], shape);
//! let mut opts = SimplifyOptions::default(); // tau 20 voxel edges, fill or cut, along z
//! opts.surface.iso = 0.5;
//! let done = isotopo::simplify(Source::from(volume), &opts, &NoProgress)?;
//! assert_eq!((done.before.b1, done.after.b1), (1, 0));
//! # Ok::<(), isotopo::Error>(())
//! ```
//!
//! `examples/simplify_in_memory.rs` does the same and takes the edited samples back. For
//! volumes with 100,000 handles and more, [`analyze_streamed`] gives [`analyze()`]'s report a
//! handle at a time, with memory that does not grow with the handles.
//!
//! Progress goes through [`progress::Progress`], which a caller implements (the command line
//! draws bars); its `cancelled` is asked between slices, planes and handles, and a job then stops
//! with [`Error::Cancelled`], having written nothing. The library never prints. The same
//! steps check the process's memory against a limit ([`memory`]; by default 3/4 of the
//! machine's): past it a job stops with [`Error::Memory`], naming what did not fit, rather than
//! being killed.
//!
//! Data flows one way, one module per stage:
//!
//! ```text
//! volume file -> slice stream -> surfels per slice -> contours + ribbons -> Reeb graph
//!   -> handles -> Reeb loop / cross loop -> closures -> edited volume (+ mesh, report)
//! ```
//!
//! Each module uses only those listed before it (`scripts/check_layout.py` checks that no two
//! import each other, directly or not):
//!
//! - [`volume`]: reading and writing NIfTI, NRRD, MGH/MGZ, MetaImage, NumPy, raw and TIFF,
//!   streamed by z-slice; the affine and voxel boxes.
//! - [`topology`]: the cube cases derived from the digital-topology rule, surfels of a slice, and
//!   the streaming genus pass; [`mesh`]: the isosurface as a mesh.
//! - [`grid`]: the volume as inside bits in a window of planes, in the sweep's frame, with the
//!   fractions along crossing edges; simple samples.
//! - [`surface`]: the isosurface as a graph (vertices on cube edges), where its vertices lie,
//!   and the searches on it.
//! - [`compose`]: the critical configurations mended by flips that keep the topology
//!   (well-composed output); in `simplify`, last, a handle opened through a face and closed elsewhere.
//! - [`sweep`]: contours, ribbons and the Reeb graph: every handle located.
//! - [`loops`]: each handle's Reeb loop and cross loop, the shortest on the whole surface.
//! - `closure`: walls across loops, written into the volume and verified.
//! - [`simplify`](mod@simplify): components and cavities removed as asked (deleted, bridged,
//!   filled or opened), then sweep, measure, close, rewind, until no handle below tau is left.
//! - [`report`], [`plots`]: JSON, CSV and plots of the results; [`jobs`]: the entry points.

// Index loops read better than iterator chains in the matrix and grid code here.
#![allow(clippy::needless_range_loop)]
#![warn(missing_docs)]

pub(crate) mod closure;
pub mod compose;
pub mod error;
pub mod grid;
pub mod html;
pub mod jobs;
pub mod loops;
pub mod memory;
pub mod mesh;
pub mod plots;
pub mod progress;
pub mod report;
pub mod simplify;
pub(crate) mod spool;
pub mod surface;
pub mod sweep;
#[cfg(test)]
mod test_rng;
#[cfg(test)]
mod test_shapes;
pub mod topology;
pub(crate) mod unionfind;
pub mod volume;

pub use error::{Error, Result};
pub use jobs::{
    analyze, analyze_streamed, genus, handles, simplify, Analysis, AnalyzeOptions, Handles,
    Simplified, Source, StreamedAnalysis, Topology,
};
pub use simplify::SimplifyOptions;
