//! `mrdrive log summary RUN.mcap`: what a recorded run log holds;
//! `mrdrive log picture RUN.mcap|RUN.json`: the run's picture.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use sim::recorder::read_summary;

/// Log subcommands.
#[derive(Subcommand)]
pub enum LogCommand {
    /// Print a log's topics (with schemas), message counts, sim-time duration,
    /// infractions and result record.
    Summary(SummaryArgs),
    /// Draw a run's picture (the route on the map, the path driven coloured by input
    /// scale, each infraction) from its MCAP log or its JSON record.
    Picture(PictureArgs),
}

/// `log picture` arguments.
#[derive(Args)]
pub struct PictureArgs {
    /// The run's MCAP log (`mrdrive run --record`) or JSON record (`--json`, a sweep's `runs/*.json`).
    pub run: PathBuf,
    /// The PNG to write [default: beside the run's file, with the extension .png].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `log summary` arguments.
#[derive(Args)]
pub struct SummaryArgs {
    /// The MCAP log (written by `mrdrive run SCENARIO --record FILE`).
    pub log: PathBuf,
}

/// Runs a `log` subcommand.
pub fn run(c: LogCommand) -> anyhow::Result<()> {
    match c {
        LogCommand::Summary(a) => {
            let summary = read_summary(&a.log)?;
            print!("{}", summary.report(&a.log.display().to_string()));
            Ok(())
        }
        LogCommand::Picture(a) => {
            let result = sim::picture::read_result(&a.run)?;
            let img = sim::picture::picture_of(&result)?;
            let out = a.out.unwrap_or_else(|| a.run.with_extension("png"));
            sim::picture::save(&img, &out)?;
            println!("picture: {}", out.display());
            Ok(())
        }
    }
}
