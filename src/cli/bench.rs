//! `mrdrive bench ...`: benchmarks that print figures (medians), never pass/fail;
//! `bench all` runs every one and writes the benchmark page
//! ([`experiments::bench_page`]).

use std::path::PathBuf;

use anyhow::{Context, Result, anyhow};
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
    /// Every benchmark on this machine, in one go (minutes): physics and traffic,
    /// the rig per scale, policy inference and training, closed-loop real-time
    /// factors, PyTorch's reference when found, peak memory; run from the checkout.
    All {
        /// The page to write.
        #[arg(long, default_value = "docs/bench.md")]
        out: PathBuf,
    },
}

/// Runs `bench`.
pub fn run(a: BenchArgs) -> Result<()> {
    match a.cmd {
        BenchCmd::Render(c) => super::render::bench_command(&c),
        BenchCmd::Policy(c) => super::policy::run_bench_command(c),
        BenchCmd::Loader(c) => super::data::run_bench(c),
        BenchCmd::All { out } => {
            let exe = std::env::current_exe().context("finding this program")?;
            let root = std::env::current_dir().context("finding the working directory")?;
            let page =
                experiments::bench_page::write_page(&exe, &root, &|t| eprintln!("bench all: {t}"))
                    .map_err(|e| anyhow!(e))?;
            std::fs::write(&out, page).with_context(|| format!("writing {}", out.display()))?;
            eprintln!("bench all: wrote {}", out.display());
            Ok(())
        }
    }
}
