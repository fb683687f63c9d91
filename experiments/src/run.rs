//! Running a paper: its sweeps (resumable: a finished run is never redone),
//! Table I, then every table, figure and the page.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use sim::build::Drivers;
use sim::sweep::{self, RunSpec};

use crate::config::PaperConfig;
use crate::experiment::{Experiment, units_of};
use crate::results::Results;
use crate::{PaperError, page};

/// How to run a paper.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// The folder of everything (`docs/paper`): the sweeps (`sweeps/ID/`, one
    /// record per run, committed so every number can be checked), derived
    /// scenarios (`scenarios/`), the wall-time log, tables, figures and page.
    pub out: PathBuf,
    /// Runs at a time.
    pub jobs: usize,
    /// The experiments to run and write.
    pub experiments: Vec<Experiment>,
    /// Only write the tables and figures from the runs already finished.
    pub report_only: bool,
    /// "quick" or "full", written on the page.
    pub label: String,
    /// Run only the configuration's first this many seeds this time (the
    /// sweep plans still hold every seed; a later call goes on); `None`: all.
    pub seeds: Option<usize>,
}

/// What the caller is told as the run goes.
pub trait Progress: Sync {
    /// A unit starts: its id, runs already done, runs in its plan.
    fn unit(&self, id: &str, done: usize, planned: usize);
    /// A run finished (or failed).
    fn run_done(&self, spec: &RunSpec);
}

/// What a paper run did.
#[derive(Debug, Clone, Default)]
pub struct Outcome {
    /// Runs finished now.
    pub finished: usize,
    /// Runs that failed: unit, run key, why.
    pub failed: Vec<(String, String, String)>,
    /// Table, figure and page files written.
    pub written: Vec<PathBuf>,
}

/// The wall time spent running sweeps into one output folder, over every
/// invocation (a resumed run adds to it).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WallLog {
    /// Seconds spent in sweeps.
    pub sweep_s: f64,
    /// Invocations that ran at least one run.
    pub invocations: u32,
    /// Runs finished over all invocations.
    pub runs: usize,
    /// Jobs of the last invocation.
    pub jobs: usize,
}

impl WallLog {
    fn path(out: &Path) -> PathBuf {
        out.join("wall.json")
    }

    /// Reads `OUT/wall.json` (zero if there is none yet).
    pub fn read(out: &Path) -> Self {
        std::fs::read_to_string(Self::path(out))
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or_default()
    }

    fn write(&self, out: &Path) -> Result<(), PaperError> {
        let p = Self::path(out);
        let text = serde_json::to_string_pretty(self).expect("a wall log serialises");
        std::fs::write(&p, text).map_err(|e| PaperError::io("write", &p, e))
    }
}

/// Runs the sweeps the chosen experiments need (skipping finished runs),
/// then writes their tables, figures and `README.md` into `opts.out`.
pub fn run_paper(
    cfg: &PaperConfig,
    opts: &RunOptions,
    drivers: &Drivers,
    progress: &dyn Progress,
) -> Result<Outcome, PaperError> {
    let mut outcome = Outcome::default();
    std::fs::create_dir_all(&opts.out).map_err(|e| PaperError::io("create", &opts.out, e))?;
    let units = units_of(&opts.experiments, cfg);
    if !opts.report_only {
        same_backend(cfg, opts, &units)?;
        let mut clock = WallClock::start();
        let mut plans = Vec::new();
        for u in &units {
            let dir = u.dir(cfg, &opts.out);
            let plan = u.plan(cfg, &opts.out)?;
            dir.prepare(&plan)?;
            plans.push((u, dir, plan));
        }
        // Seed by seed: the first pass is the paper's own protocol (one
        // rollout per route and density) over every experiment; later seeds
        // narrow the intervals. A run cut short still has whole tables.
        for &seed in cfg.seeds.iter().take(opts.seeds.unwrap_or(usize::MAX)) {
            for (u, dir, plan) in &plans {
                let mine: Vec<&RunSpec> = plan.runs.iter().filter(|s| s.seed == seed).collect();
                let done = mine.iter().filter(|s| dir.is_done(s)).count();
                progress.unit(&format!("{} (seed {seed})", u.id(cfg)), done, mine.len());
                let o = sweep::execute(
                    dir,
                    &mine,
                    opts.jobs,
                    |spec: &RunSpec| {
                        sweep::run_spec(spec, drivers, None)
                            .map(|r| r.record)
                            .map_err(|e| sim::build::error_chain(&e))
                    },
                    |spec| progress.run_done(spec),
                );
                outcome.finished += o.finished;
                for (key, why) in o.failed {
                    outcome.failed.push((u.id(cfg), key, why));
                }
                if o.finished > 0 {
                    // The page follows the runs, so a run cut short leaves it current.
                    clock.log(opts, o.finished)?;
                    report(cfg, opts)?;
                }
            }
        }
    }
    outcome.written = report(cfg, opts)?;
    Ok(outcome)
}

/// Refuses to add policy runs to a folder holding runs rendered by any
/// other backend than this machine's (a machine without Vulkan falls back to
/// GL, whose pictures differ).
fn same_backend(
    cfg: &PaperConfig,
    opts: &RunOptions,
    units: &[crate::Unit],
) -> Result<(), PaperError> {
    if units.iter().all(|u| u.driver == crate::Driver::Expert) {
        return Ok(());
    }
    let existing = Results::load(cfg, &opts.out, &units_of(&Experiment::ALL, cfg))?.backends();
    if existing.is_empty() {
        return Ok(());
    }
    let here = sim::render::gpu::Gpu::new()?.describe();
    match existing.into_iter().find(|b| *b != here) {
        None => Ok(()),
        Some(other) => Err(PaperError::Backend {
            out: opts.out.clone(),
            existing: other,
            here,
        }),
    }
}

/// Adds the wall time of a paper invocation to `OUT/wall.json` as it goes:
/// each call logs the seconds since the last one (and the runs finished), and
/// the first also counts the invocation.
struct WallClock {
    last: Instant,
    counted: bool,
}

impl WallClock {
    fn start() -> Self {
        WallClock {
            last: Instant::now(),
            counted: false,
        }
    }

    fn log(&mut self, opts: &RunOptions, runs: usize) -> Result<(), PaperError> {
        let now = Instant::now();
        let mut wall = WallLog::read(&opts.out);
        wall.sweep_s += (now - self.last).as_secs_f64();
        wall.runs += runs;
        wall.jobs = opts.jobs;
        if !self.counted {
            wall.invocations += 1;
            self.counted = true;
        }
        self.last = now;
        wall.write(&opts.out)
    }
}

/// Rewrites every experiment's tables, figures and page section from the
/// runs that exist, so `--only` adds to the page without dropping the rest.
fn report(cfg: &PaperConfig, opts: &RunOptions) -> Result<Vec<PathBuf>, PaperError> {
    let results = Results::load(cfg, &opts.out, &units_of(&Experiment::ALL, cfg))?;
    page::write_all(cfg, opts, &results)
}
