//! Subcommands of the `mrdrive` program, one file each.

pub mod bench;
pub mod collect;
pub mod log;
pub mod map;
pub mod policy;
pub mod recalibrate;
pub mod render;
pub mod routes;
pub mod run;
pub mod sweep;
pub mod traffic;
