//! `mrdrive`: the command line that wires the crates together.

mod cli;

use clap::{Parser, Subcommand};

/// A closed-loop driving simulator for multi-resolution end-to-end policies.
#[derive(Debug, Parser)]
#[command(name = "mrdrive", version)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// NPC traffic: soak runs and Table I.
    Traffic(cli::traffic::TrafficArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Traffic(a) => cli::traffic::run(a),
    }
}
