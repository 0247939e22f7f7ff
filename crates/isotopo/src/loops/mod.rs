//! Handle size (paper §2.2): the Reeb loop and the cross loop of each handle.

pub mod search;
