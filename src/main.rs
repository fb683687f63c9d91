//! `mrdrive`: the command-line program that wires the crates together.

mod cli;

use anyhow::Result;
use clap::{Parser, Subcommand};

/// A closed-loop driving simulator for multi-resolution end-to-end policies.
#[derive(Debug, Parser)]
#[command(name = "mrdrive", version)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Debug, Subcommand)]
enum Cmd {
    /// Render the hand-made demo junction (colour or labels) to a PNG.
    RenderDemo(cli::render::RenderDemoArgs),
    /// Camera measurements (lamp-size).
    Render(cli::render::RenderArgs),
    /// Benchmarks that print figures.
    Bench(cli::render::BenchArgs),
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match &cli.cmd {
        Cmd::RenderDemo(a) => cli::render::render_demo(a),
        Cmd::Render(a) => cli::render::render(a),
        Cmd::Bench(a) => cli::render::bench(a),
    }
}
