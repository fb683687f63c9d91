//! The command-line subcommands, one file each.

pub mod render;
