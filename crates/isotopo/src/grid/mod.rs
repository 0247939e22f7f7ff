//! The volume as the later stages see it: inside bits per plane in a window of planes (the rest
//! in a scratch file), in the frame of the sweep axis, and the fractions along crossing edges
//! for lengths in millimetres. Everything above (the surface graph, the sweep, the loops, the
//! closures) reads and edits the volume through [`MaskVolume`].

mod fractions;
mod planes;
pub(crate) mod simple;

pub use fractions::EdgeFractions;
pub use planes::{window_for, Axis, Frame, MaskVolume, DEFAULT_WINDOW_BYTES, MIN_WINDOW};
