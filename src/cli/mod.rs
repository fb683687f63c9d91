//! Subcommands of the `mrdrive` program.

pub mod map;
pub mod routes;
