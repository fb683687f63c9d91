//! Loading an OpenDRIVE file (through the `xodr` crate) into a [`crate::Town`].

mod load;

pub use load::*;
