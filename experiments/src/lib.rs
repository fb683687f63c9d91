//! The paper's experiments (`mrdrive paper`, `cargo xtask paper`): which runs
//! make each of its tables and figures, running them as resumable sweeps, and
//! the tables, plots and the page that sets our numbers beside the paper's.
//!
//! - [`config`]: what a run covers ([`PaperConfig::full`], [`PaperConfig::quick`]).
//! - [`units`]: the sweeps ([`Unit`]: one driver at one delay, or one
//!   switcher under one envelope), each a folder `OUT/sweeps/ID/`.
//! - [`experiment`]: the tables and figures ([`Experiment`]) and the units each needs.
//! - [`results`]: the records of a unit, each beside its run's settings.
//! - [`report`]: Tables I-III, the figures' data, CSV and Markdown.
//! - [`figures`]: the plots (PNG and SVG).
//! - [`loss_plot`]: a training run's loss curves (`mrdrive train`, `mrdrive policy losses`).
//! - [`page`]: `README.md`, our numbers beside the paper's.
//! - [`run`]: running the units and writing everything.
//! - [`registration`]: the study's rules, registered before its runs
//!   (`mrdrive paper --register`), and the check that every record's build
//!   descends from the registering commit.
//! - [`pipeline`]: the training pipeline as a plan ([`pipeline::TrainPlan`]:
//!   datasets, the Original's phases, the retargeting lanes, the bar), run as
//!   commands of this binary (`mrdrive train --all`).
//! - [`collector`]: the build that collects and labels the study's data, pinned
//!   so that they stay the bytes their hashes list when the simulator changes.
//! - [`study`]: the study's rerun as a chain of time-limited jobs, one pinned
//!   build run in a worktree of its commit, its records committed hourly
//!   (`mrdrive study`).
//! - [`progress`]: how far the pipeline is and how long the rest will take.
//! - [`bench_page`]: every benchmark in one go, into `docs/bench.md`
//!   (`mrdrive bench all`).
//! - [`bar`]: the training issue's closed-loop table (`mrdrive policy table`)
//!   from one sweep folder per driver.

pub mod bar;
pub mod bench_page;
pub mod collector;
pub mod config;
pub mod experiment;
pub mod figures;
pub mod loss_plot;
pub mod options;
pub mod page;
pub mod pipeline;
pub mod progress;
pub mod registration;
pub mod report;
pub mod results;
pub mod run;
pub mod study;
pub mod units;

use std::path::{Path, PathBuf};

pub use config::{Envelope, Models, PaperConfig, Route};
pub use experiment::Experiment;
pub use options::{RunOptions, WallLog};
pub use run::{Progress, run_paper};
pub use units::{Driver, Selection, Unit};

/// What can go wrong in a paper run.
#[derive(Debug, thiserror::Error)]
pub enum PaperError {
    /// A file or folder could not be used.
    #[error("could not {action} {path}: {source}")]
    Io {
        /// What was being done.
        action: &'static str,
        /// The file or folder.
        path: PathBuf,
        /// Why it failed.
        source: std::io::Error,
    },
    /// A scenario file to derive from is not what it should be.
    #[error("scenario {path}: {problem}")]
    Scenario {
        /// The file.
        path: PathBuf,
        /// What is wrong and how to fix it.
        problem: String,
    },
    /// An experiment name on the command line is not one of ours.
    #[error("--only {name}: no such experiment; choose from {}", Experiment::ids().join(", "))]
    UnknownExperiment {
        /// The name given.
        name: String,
    },
    /// A sweep failed to prepare or to read.
    #[error(transparent)]
    Sweep(#[from] sim::sweep::SweepError),
    /// Loading a route for Table I failed.
    #[error("Table I, {path}: {problem}")]
    TableOne {
        /// The scenario file.
        path: PathBuf,
        /// What failed.
        problem: String,
    },
    /// A plot could not be drawn or written.
    #[error("plot {path}: {problem}")]
    Plot {
        /// The output file.
        path: PathBuf,
        /// What failed.
        problem: String,
    },
    /// The study's registration is missing what it needs, or a record breaks it.
    #[error("registration, {path}: {problem}")]
    Registration {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong and how to fix it.
        problem: String,
    },
    /// The study's chain of jobs cannot go on (`mrdrive study`).
    #[error("study, {path}: {problem}")]
    Study {
        /// The file or folder.
        path: PathBuf,
        /// What is wrong and how to fix it.
        problem: String,
    },
    /// This build is not the one that made the runs already in the folder.
    #[error(
        "{out}: its runs were made by `{existing}`, but this is `{here}`; the study's rule is \
         one build for every record of the page. Check out the commit that made them (and build) \
         to go on, write to another --out, or pass --mixed-builds to add runs of this build \
         anyway (the page then says how many builds it holds)"
    )]
    Build {
        /// The output folder.
        out: PathBuf,
        /// A build of its runs.
        existing: String,
        /// This binary's.
        here: String,
    },
    /// This machine renders with another backend than the runs already in the folder.
    #[error(
        "{out}: its runs were rendered by `{existing}`, but this machine renders with `{here}`; \
         software rasterisers differ pixel by pixel, so the tables would mix two simulators. \
         Install the same driver (`cargo xtask setup` installs Mesa's Vulkan, lavapipe) or \
         write to another --out"
    )]
    Backend {
        /// The output folder.
        out: PathBuf,
        /// The backend of its runs.
        existing: String,
        /// This machine's.
        here: String,
    },
    /// No renderer for the policy runs.
    #[error("the policy runs need the camera: {0}")]
    Gpu(#[from] sim::render::gpu::GpuError),
    /// A CSV table could not be written.
    #[error("CSV: {0}")]
    Csv(#[from] csv::Error),
}

impl PaperError {
    /// An I/O error on `path`.
    pub fn io(action: &'static str, path: &Path, source: std::io::Error) -> Self {
        PaperError::Io {
            action,
            path: path.to_path_buf(),
            source,
        }
    }
}
