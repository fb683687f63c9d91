//! `mrdrive sweep SCENARIO... --delays ... --scales ... --densities ... --seeds ...`
//! runs the cross product in parallel, one record per run; `sweep merge`
//! joins shard folders; `sweep summary` prints a folder's tables.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, Subcommand};
use sim::sweep::{self, RunSpec, SweepDir, SweepPlan};

/// `sweep` arguments.
#[derive(Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct SweepArgs {
    #[command(subcommand)]
    pub command: Option<SweepCommand>,
    #[command(flatten)]
    pub run: SweepRunArgs,
}

/// Sweep subcommands besides running one.
#[derive(Subcommand)]
pub enum SweepCommand {
    /// Join shard folders into one and check that no run is missing.
    Merge {
        /// The shard folders.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// The merged folder.
        #[arg(long)]
        out: PathBuf,
    },
    /// Print the aggregate tables of a sweep folder (and rewrite them).
    Summary {
        /// The sweep folder.
        dir: PathBuf,
    },
}

/// Arguments of a sweep run.
#[derive(Args)]
pub struct SweepRunArgs {
    /// Scenario files.
    #[arg(required = true)]
    pub scenarios: Vec<PathBuf>,
    /// Injected delays D (milliseconds), comma-separated; default: each scenario's.
    #[arg(long, value_delimiter = ',')]
    pub delays: Vec<f64>,
    /// Fixed input scales, comma-separated; default: each scenario's selector.
    #[arg(long, value_delimiter = ',')]
    pub scales: Vec<f64>,
    /// Traffic densities VEHICLES:PEDESTRIANS, comma-separated; default: each scenario's.
    #[arg(long, value_delimiter = ',')]
    pub densities: Vec<String>,
    /// Traffic seeds, comma-separated (or a range A..B, B excluded).
    #[arg(long, default_value = "0")]
    pub seeds: String,
    /// The sweep's folder (records, plan, tables).
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
    /// Run only shard INDEX/COUNT of the plan (for array jobs).
    #[arg(long)]
    pub shard: Option<String>,
    /// Runs at a time.
    #[arg(long, default_value_t = 2)]
    pub jobs: usize,
    /// Also record an MCAP log per run (in OUT/logs).
    #[arg(long)]
    pub record: bool,
    #[command(flatten)]
    pub driver: super::run::DriverFlags,
}

/// Runs `sweep`.
pub fn run(a: SweepArgs) -> anyhow::Result<()> {
    match a.command {
        Some(SweepCommand::Merge { shards, out }) => {
            let missing = sweep::merge(&shards, &out)?;
            write_tables(&SweepDir { root: out.clone() })?;
            if !missing.is_empty() {
                anyhow::bail!(
                    "{} run(s) missing from the merged sweep {}:\n  {}",
                    missing.len(),
                    out.display(),
                    missing.join("\n  ")
                );
            }
            println!(
                "merged {} shard folders into {}: complete",
                shards.len(),
                out.display()
            );
            Ok(())
        }
        Some(SweepCommand::Summary { dir }) => write_tables(&SweepDir { root: dir }),
        None => run_sweep(a.run),
    }
}

fn run_sweep(a: SweepRunArgs) -> anyhow::Result<()> {
    for s in &a.scenarios {
        sim::scenario::Scenario::from_file(s)?;
    }
    let densities = a
        .densities
        .iter()
        .map(|d| sweep::parse_density(d))
        .collect::<Result<Vec<_>, _>>()?;
    let plan = SweepPlan::of_lists(
        &a.scenarios,
        &a.delays,
        &a.scales,
        &densities,
        &sweep::parse_seeds(&a.seeds)?,
        a.driver.driver().as_ref(),
    );
    let (index, count) = match &a.shard {
        Some(s) => sweep::parse_shard(s)?,
        None => (0, 1),
    };
    let dir = SweepDir {
        root: a.out.clone(),
    };
    dir.prepare(&plan)?;
    let mine = plan.shard(index, count);
    let logs = a.out.join("logs");
    if a.record {
        std::fs::create_dir_all(&logs).with_context(|| format!("creating {}", logs.display()))?;
    }
    let done_before = mine.iter().filter(|s| dir.is_done(s)).count();
    let bar = indicatif::ProgressBar::new(mine.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} runs {msg}",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
    bar.set_position(done_before as u64);
    eprintln!(
        "sweep: {} runs in the plan, {} in this shard ({index}/{count}), {done_before} already done, {} jobs",
        plan.runs.len(),
        mine.len(),
        a.jobs
    );
    let drivers = super::drivers();
    let log_dir = a.record.then_some(logs.as_path());
    let outcome = sweep::execute(
        &dir,
        &mine,
        a.jobs,
        |spec: &RunSpec| {
            let done = sweep::run_spec(spec, &drivers, log_dir)
                .map_err(|e| sim::build::error_chain(&e))?;
            for w in &done.warnings {
                bar.suspend(|| eprintln!("sweep: run {}: warning: {w}", spec.key()));
            }
            Ok::<_, String>(done.record)
        },
        |_, _| bar.inc(1),
    );
    bar.finish_and_clear();
    for (key, why) in &outcome.failed {
        eprintln!("sweep: run {key} failed: {why}");
    }
    eprintln!(
        "sweep: {} finished now, {} skipped (done before), {} failed",
        outcome.finished,
        outcome.skipped,
        outcome.failed.len()
    );
    write_tables(&dir)?;
    anyhow::ensure!(
        outcome.failed.is_empty(),
        "{} run(s) failed; rerun the same command to retry them",
        outcome.failed.len()
    );
    Ok(())
}

/// Writes the folder's tables and prints the summary table.
fn write_tables(dir: &SweepDir) -> anyhow::Result<()> {
    let tables = sweep::write_tables(dir)?;
    println!("{}", sweep::tables::summary_markdown(&tables.summary));
    println!(
        "tables: {}/summary.md, summary.csv, detail.csv",
        dir.root.display()
    );
    Ok(())
}
