//! `mrdrive bench ...`: benchmarks that print figures (medians), never pass/fail.

use anyhow::Result;
use clap::{Args, Subcommand};

/// `bench` arguments.
#[derive(Debug, Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    cmd: BenchCmd,
}

/// What to benchmark.
#[derive(Debug, Subcommand)]
enum BenchCmd {
    #[command(flatten)]
    Render(super::render::BenchCmd),
    #[command(flatten)]
    Policy(super::policy::BenchCommand),
    #[command(flatten)]
    Loader(super::data::BenchCommand),
}

/// Runs `bench`.
pub fn run(a: BenchArgs) -> Result<()> {
    match a.cmd {
        BenchCmd::Render(c) => super::render::bench_command(&c),
        BenchCmd::Policy(c) => super::policy::run_bench_command(c),
        BenchCmd::Loader(c) => super::data::run_bench(c),
    }
}
