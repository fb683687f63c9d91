//! `mrdrive data ...`: look at a collected dataset; `mrdrive bench loader`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use clap::{Args, Subcommand};
use dataset::info::{Summary, towns_from_maps};
use dataset::show::show;
use dataset::synthetic::{self, SyntheticSpec};
use experiments::pipeline::{self, Group, TrainPlan};
use policy::bench;
use policy::train::Preset;
use policy::train::loader::TrainSet;

/// Dataset subcommands.
#[derive(Subcommand)]
pub enum DataCommand {
    /// Print what a dataset holds: frames, hours, commands, red lights, speeds, towns, routes, labels, disk.
    Info(InfoArgs),
    /// Draw one frame and its label to a PNG, for a person to check.
    Show(ShowArgs),
    /// Collect and label the study's two datasets into <cache>/data/original and
    /// <cache>/data/retarget (the cache: $MRDRIVE_CACHE, else ~/.cache/mrdrive;
    /// resumable: finished episodes and labels are kept; `cargo xtask data`).
    Study(StudyArgs),
    /// The SHA-256 of datasets' shard and label files (`sha256sum`'s format): write the
    /// list to commit beside the plan, or check regenerated data against it.
    Hashes(HashesArgs),
}

/// `data hashes` arguments.
#[derive(Args)]
pub struct HashesArgs {
    /// The dataset directories (e.g. <cache>/data/original <cache>/data/retarget).
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Write the list to this file (replaced).
    #[arg(long, conflicts_with = "check")]
    pub out: Option<PathBuf>,
    /// Check the datasets against this list: every listed file present must match;
    /// exits 1 if one differs.
    #[arg(long)]
    pub check: Option<PathBuf>,
}

/// The study's data hash list, committed with the training chain's state
/// (`mrdrive data hashes --out`); `data study` checks what it made against it.
pub const DATA_HASHES: &str = "models/train-state/data.sha256";

/// `data study` arguments.
#[derive(Args)]
pub struct StudyArgs {
    /// Two episodes of 20 s each into <cache>/data/*-quick: the plumbing, in minutes.
    #[arg(long)]
    pub quick: bool,
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
        DataCommand::Study(a) => {
            let cache = dataset::cache::root();
            let plan = if a.quick {
                TrainPlan::quick(Path::new("."), &cache, false)
            } else {
                TrainPlan::full(Path::new("."), &cache, false)
            };
            eprintln!(
                "data study: into {} (${} sets another folder)",
                cache.join("data").display(),
                dataset::cache::ENV
            );
            let mut groups: Vec<Group> = plan.data_steps().into_iter().map(Group::One).collect();
            // The data's own build where one is pinned (`experiments::collector`).
            let list = Path::new(DATA_HASHES);
            if !a.quick
                && let Some(dir) = list.parent()
                && let Some(bin) =
                    experiments::collector::data_build(dir, Path::new("."), &cache, &|s| {
                        eprintln!("data study: {s}")
                    })?
            {
                pipeline::data_by(&mut groups, &bin);
            }
            let exe = std::env::current_exe().context("finding this program")?;
            pipeline::execute(&exe, Path::new("."), &groups, &|s| {
                eprintln!("data study: {s}")
            })?;
            // Regenerated data must be the data the committed list was made from.
            if !a.quick && list.exists() {
                let dirs = plan.datasets.iter().map(|d| d.dir.clone()).collect();
                hashes(&HashesArgs {
                    dirs,
                    out: None,
                    check: Some(list.to_path_buf()),
                })?;
            }
        }
        DataCommand::Hashes(a) => hashes(&a)?,
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

/// The loader benchmark.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// The training loader's rate against the training step of the default model.
    Loader {
        /// A labelled dataset at the default model's S0 (240 x 96); without
        /// one, a synthetic dataset (3 views, 2 x 100 frames) is written to a
        /// temporary directory.
        #[arg(long)]
        dataset: Option<PathBuf>,
        /// Batch size.
        #[arg(long, default_value_t = 32)]
        batch: usize,
        /// Loader worker threads.
        #[arg(long, default_value_t = 1)]
        workers: usize,
        /// Timed loader batches (after 1 untimed).
        #[arg(long, default_value_t = 20)]
        batches: usize,
        /// Timed training steps, alone and fed by the loader (after 1 warm-up); 0 skips training.
        #[arg(long, default_value_t = 3)]
        train_steps: usize,
    },
}

/// Runs the loader benchmark.
pub fn run_bench(c: BenchCommand) -> anyhow::Result<()> {
    let BenchCommand::Loader {
        dataset,
        batch,
        workers,
        batches,
        train_steps,
    } = c;
    let config = Preset::Cpu.config(&[0.75, 1.0]);
    let scratch = tempfile::tempdir().context("making a temporary directory")?;
    let dir = match dataset {
        Some(d) => d,
        None => {
            let spec = SyntheticSpec {
                s0: [config.input_width as u32, config.input_height as u32],
                ..SyntheticSpec::tiny(2, 100)
            };
            synthetic::write(scratch.path(), &spec)?;
            scratch.path().to_path_buf()
        }
    };
    let set = Arc::new(TrainSet::open(&dir, &config)?);
    for s in &set.skipped {
        eprintln!("warning: skipped {}: {}", s.path.display(), s.why);
    }
    let run = bench::report::LoaderRun {
        batch,
        workers,
        batches,
        train_steps,
    };
    bench::report::loader_bench(&dir, set, &config, &run, &mut std::io::stdout())?;
    Ok(())
}

/// `mrdrive data hashes`: write or check a dataset hash list.
fn hashes(a: &HashesArgs) -> anyhow::Result<()> {
    let mut found = std::collections::BTreeMap::new();
    for dir in &a.dirs {
        found.extend(dataset::hashes::of_dataset(dir)?);
    }
    let text = dataset::hashes::to_text(&found);
    match (&a.out, &a.check) {
        (Some(out), _) => {
            std::fs::write(out, text).with_context(|| format!("writing {}", out.display()))?;
            println!("wrote {} ({} files)", out.display(), found.len());
        }
        (None, Some(list)) => {
            let listed = std::fs::read_to_string(list)
                .with_context(|| format!("reading {}", list.display()))?;
            let listed = dataset::hashes::from_text(&listed, list).map_err(anyhow::Error::msg)?;
            let c = dataset::hashes::check(&found, &listed);
            println!(
                "{}: {} files the same, {} differ, {} listed but missing (collect and label again), {} not listed",
                list.display(),
                c.same.len(),
                c.differ.len(),
                c.missing.len(),
                c.new.len()
            );
            for f in &c.differ {
                println!("  differs: {f}");
            }
            if !c.differ.is_empty() {
                anyhow::bail!(
                    "{} files differ from {}: this data is not the data the list was made from \
                     (another build, Mesa or plan); regenerate it with the build the list names",
                    c.differ.len(),
                    list.display()
                );
            }
        }
        (None, None) => print!("{text}"),
    }
    Ok(())
}
