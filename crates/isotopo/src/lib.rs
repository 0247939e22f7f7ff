//! # isotopo — isosurface topology simplification
//!
//! Scans and reconstructions turned into surfaces by isosurface extraction carry hundreds of tiny
//! topological handles. isotopo finds every handle of an isosurface with a slice-by-slice sweep
//! (a Reeb graph of contours and ribbons, after Wood, Hoppe, Desbrun and Schröder, *Isosurface
//! Topology Simplification*, 2002), measures each by its two shortest surface loops, and removes the
//! small ones by writing a thin wall into the volume, so the result is always a valid manifold
//! isosurface and the geometry away from each handle is untouched.
//!
//! Data flows one way, one module per stage:
//!
//! ```text
//! volume file -> slice stream -> surfels per slice -> contours + ribbons -> Reeb graph
//!   -> handles -> Reeb loop / cross loop -> closures -> edited volume (+ mesh, report)
//! ```
//!
//! - [`volume`]: reading and writing NIfTI, NRRD, MGH/MGZ, MetaImage, NumPy, raw and TIFF,
//!   streamed by z-slice.
//! - [`topology`]: the cube cases derived from the digital-topology rule, surfels of a slice, and
//!   the streaming genus pass.

// Index loops read better than iterator chains in the matrix and grid code here.
#![allow(clippy::needless_range_loop)]

pub mod closure;
pub mod error;
pub mod geometry;
pub mod loops;
pub mod mesh;
pub mod plots;
pub mod progress;
pub mod report;
pub mod simplify;
pub mod surface;
pub mod sweep;
pub mod topology;
pub mod unionfind;
pub mod volume;

pub use error::{Error, Result};
