//! One file per command: its flags and what it runs and prints.

pub(crate) mod analyze;
pub(crate) mod convert;
pub(crate) mod genus;
pub(crate) mod handles;
pub(crate) mod info;
pub(crate) mod mesh;
pub(crate) mod simplify;
