//! Command-line front ends, one file per area.

pub mod policy;
