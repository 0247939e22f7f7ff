//! Isosurface topology: the cube cases, surfels per slice, the streaming genus pass, and the
//! critical configurations where meshers disagree.

pub mod cases;
pub mod critical;
pub mod genus;
pub mod mask;
pub mod slice;
pub mod values;

pub use cases::Connectivity;
pub use genus::{genus, Bounds, GenusReport, SurfaceInfo, SurfaceOptions};
pub use mask::{Classifier, Inside, PlaneMask};
