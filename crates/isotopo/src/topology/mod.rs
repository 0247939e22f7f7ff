//! Isosurface topology: the cube cases, surfels per slice, and the streaming genus pass.

pub mod cases;
pub mod genus;
pub mod mask;
pub mod slice;
pub mod values;

pub use cases::Connectivity;
pub use genus::{genus, Bounds, GenusReport, SurfaceInfo, SurfaceOptions};
pub use mask::{Classifier, Inside, PlaneMask};
