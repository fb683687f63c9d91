//! `mrdrive data ...`: look at a collected dataset.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};
use dataset::info::{Summary, towns_from_maps};
use dataset::show::show;

/// Dataset subcommands.
#[derive(Subcommand)]
pub enum DataCommand {
    /// Print what a dataset holds: frames, hours, commands, red lights, speeds, towns, routes, labels, disk.
    Info(InfoArgs),
    /// Draw one frame and its label to a PNG, for a person to check.
    Show(ShowArgs),
}

/// `data info` arguments.
#[derive(Args)]
pub struct InfoArgs {
    /// The dataset directory (`mrdrive collect --out`).
    pub dir: PathBuf,
}

/// `data show` arguments.
#[derive(Args)]
pub struct ShowArgs {
    /// The dataset directory (`mrdrive collect --out`).
    pub dir: PathBuf,
    /// The frame, counted over the whole dataset in index order.
    #[arg(long)]
    pub frame: u64,
    /// The camera view (0: as mounted; then the index's other yaws).
    #[arg(long, default_value_t = 0)]
    pub view: usize,
    /// Output PNG.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs a `data` subcommand.
pub fn run(c: DataCommand) -> anyhow::Result<()> {
    match c {
        DataCommand::Info(a) => {
            let summary = Summary::of(&a.dir, &mut towns_from_maps())?;
            print!("{summary}");
        }
        DataCommand::Show(a) => {
            let img = show(&a.dir, a.frame, a.view, &mut towns_from_maps())?;
            img.save(&a.out)
                .with_context(|| format!("writing {}", a.out.display()))?;
            println!(
                "wrote {} ({} x {} px)",
                a.out.display(),
                img.width(),
                img.height()
            );
        }
    }
    Ok(())
}
