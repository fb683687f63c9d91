//! The `mrdrive` command line.

mod cli;

use anyhow::Result;
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
    /// Policy network tools: checkpoints, BN-bank overhead, torchvision import.
    Policy(cli::policy::PolicyArgs),
    /// Train the policy (`--synthetic`: a smoke run on a toy batch).
    Train(cli::policy::TrainArgs),
    /// Benchmarks that print figures.
    Bench(cli::policy::BenchArgs),
}

fn main() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    match Cli::parse().command {
        Command::Policy(a) => cli::policy::run_policy(a),
        Command::Train(a) => cli::policy::run_train(a),
        Command::Bench(a) => cli::policy::run_bench(a),
    }
}
