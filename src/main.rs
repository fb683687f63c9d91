//! `mrdrive`: the command-line program that wires the crates together. Each
//! command group lives in one file of `cli/`, which parses its arguments,
//! calls the library and prints; no rule or loop lives here.
//!
//! Its part of the data flow (`DESIGN.md`): the entry points, and the one
//! place that joins `sim` and `policy` (a scenario's policy driver is built
//! by `policy::PolicyFactory`, registered in `cli::drivers()`).
//!
//! ```text
//! mrdrive run / sweep ──▶ sim::build + sim::runner (one run) / sim::sweep (many) ──▶ tables
//!     with cli::drivers(): the expert (sim) and the policy (policy::PolicyFactory)
//! mrdrive collect / label ──▶ dataset (episodes, shards, action values)
//! mrdrive policy / train ──▶ policy (checkpoints, training, BN recalibration)
//! mrdrive map / routes / traffic ──▶ world (towns, routes, traffic soaks, Table I)
//! mrdrive render / render-demo / log / bench ──▶ sim::render, sim::recorder, benchmarks
//! ```
//!
//! | file in `cli/` | commands |
//! | --- | --- |
//! | `run.rs` | `run`: one scenario and its result table |
//! | `sweep.rs` | `sweep`, `sweep merge`, `sweep summary` |
//! | `map.rs` | `map info`, `map render`, `map generate` |
//! | `routes.rs` | `routes` |
//! | `traffic.rs` | `traffic soak`, `traffic table` |
//! | `render.rs` | `render`, `render-demo`, `render lamp-size`, `bench render` |
//! | `collect.rs` | `collect`, `label` |
//! | `policy.rs` | `policy ...`, `train`, `bench policy` |
//! | `recalibrate.rs` | `policy recalibrate` |
//! | `bench.rs` | `bench`: joins `bench render` and `bench policy` |
//! | `log.rs` | `log summary`, `log picture` |

mod cli;
mod memory;

use clap::{Parser, Subcommand};

/// A closed-loop driving simulator for multi-resolution end-to-end policies.
#[derive(Parser)]
#[command(name = "mrdrive", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Drive one scenario and print its result table.
    Run(cli::run::RunArgs),
    /// Run the cross product of scenarios, delays, scales, densities and seeds.
    Sweep(cli::sweep::SweepArgs),
    /// The paper's tables and figures from the shipped checkpoints (resumable; --quick: a smoke test).
    Paper(cli::paper::PaperArgs),
    /// The study's rerun as a chain of time-limited jobs: one pinned build, run in a worktree of its commit, records committed hourly (--pin, --hours H; neither: where it stands).
    Study(cli::study::StudyArgs),
    /// Maps: summary, picture, town generator.
    #[command(subcommand)]
    Map(cli::map::MapCommand),
    /// Plan routes over a map and print their dense lengths and commands.
    Routes(cli::routes::RoutesArgs),
    /// NPC traffic: soak runs and Table I.
    Traffic(cli::traffic::TrafficArgs),
    /// The camera: a scenario's view at a moment, lamp sizes.
    Render(cli::render::RenderArgs),
    /// Render the hand-made demo junction (colour or labels) to a PNG.
    RenderDemo(cli::render::RenderDemoArgs),
    /// Policy network tools: checkpoints, BN-bank overhead, torchvision import.
    Policy(cli::policy::PolicyArgs),
    /// Train a stage of the paper's pipeline: original, nra-<scale> or ra (`--synthetic`: a smoke run).
    Train(Box<cli::train::TrainArgs>),
    /// Benchmarks that print figures.
    Bench(cli::bench::BenchArgs),
    /// Collect driving data: the expert with noise drives planned episodes.
    Collect(cli::collect::CollectArgs),
    /// Compute world-on-rails action values for a collected dataset.
    Label(cli::collect::LabelArgs),
    /// Datasets: summary, a frame and its label as a picture.
    #[command(subcommand)]
    Data(cli::data::DataCommand),
    /// Run logs (MCAP) and records: summary, picture.
    #[command(subcommand)]
    Log(cli::log::LogCommand),
    /// Serve one environment over stdin/stdout to another process (the Python package).
    Serve,
}

/// Runs the command; a failure prints one readable message (the error and
/// its causes, no backtrace: these are the user's errors to fix) and exits 1.
fn main() -> std::process::ExitCode {
    // SAFETY: the first statement of main; no other thread exists yet.
    unsafe { sim::render::gpu::init_process() };
    // Another C library keeps its own behaviour: nothing to report.
    memory::keep_freed_memory();
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    match Cli::parse().command {
        Command::Run(a) => cli::run::run(a),
        Command::Sweep(a) => cli::sweep::run(a),
        Command::Paper(a) => cli::paper::run(a),
        Command::Study(a) => cli::study::run(a),
        Command::Map(c) => cli::map::run(c),
        Command::Routes(a) => cli::routes::run(a),
        Command::Traffic(a) => cli::traffic::run(a),
        Command::Render(a) => cli::render::render(&a),
        Command::RenderDemo(a) => cli::render::render_demo(&a),
        Command::Policy(a) => cli::policy::run_policy(a),
        Command::Train(a) => cli::train::run_train(*a),
        Command::Bench(a) => cli::bench::run(a),
        Command::Data(c) => cli::data::run(c),
        Command::Log(c) => cli::log::run(c),
        Command::Serve => cli::serve::serve(),
        Command::Collect(a) => cli::collect::collect(a),
        Command::Label(a) => cli::collect::label(a),
    }
}
