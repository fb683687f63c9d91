//! Running a paper: its sweeps (resumable: a finished run is never redone),
//! Table I, then every table, figure and the page.

use std::path::PathBuf;
use std::time::Instant;

use sim::build::Drivers;
use sim::sweep::{self, RunSpec};

use crate::config::PaperConfig;
use crate::experiment::{Experiment, units_of};
use crate::options::{RunOptions, WallLog};
use crate::registration::Registration;
use crate::results::Results;
use crate::{PaperError, page};

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
    let registration = Registration::load(&opts.registered_in)?;
    if let Some(r) = &registration {
        r.check_rules(&opts.registered_in)?;
    }
    if !opts.report_only {
        same_backend(cfg, opts, &units)?;
        let existing = Results::load(cfg, &opts.out, &units_of(&Experiment::ALL, cfg))?;
        if let Some(r) = &registration {
            let here = sim::output::provenance::build_id();
            let builds = existing.provenance(|p| &p.build);
            r.check_builds(&opts.registered_in, builds.iter().chain([&here]))?;
        }
        if !opts.mixed_builds {
            same_build(
                &existing.provenance(|p| &p.build),
                &sim::output::provenance::build_id(),
                &opts.out,
            )?;
        }
        let cpus = existing.cpus();
        if let Some(note) = other_cpus(&cpus, sim::output::provenance::cpu_model().as_deref()) {
            eprintln!("paper: {note}");
        }
        // Logged as each run finishes, so a kill loses only the runs in flight.
        let clock = std::sync::Mutex::new(WallClock::start());
        let mut plans = Vec::new();
        for u in &units {
            let dir = u.dir(cfg, &opts.out);
            let plan = u.plan(cfg, &opts.out)?;
            dir.prepare(&plan)?;
            plans.push((u, dir, plan));
        }
        let planned: usize = plans.iter().map(|(_, _, p)| p.runs.len()).sum();
        let left = plans
            .iter()
            .map(|(_, dir, p)| p.runs.iter().filter(|s| !dir.is_done(s)).count())
            .sum();
        eprintln!(
            "paper: {}",
            plan_line(planned, left, &WallLog::read(&opts.out))
        );
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
                    |spec, written| {
                        let mut c = clock.lock().unwrap_or_else(|e| e.into_inner());
                        if let Err(e) = c.log(opts, usize::from(written)) {
                            c.error.get_or_insert(e);
                        }
                        drop(c);
                        progress.run_done(spec);
                    },
                );
                if let Some(e) = clock.lock().unwrap_or_else(|e| e.into_inner()).error.take() {
                    return Err(e);
                }
                outcome.finished += o.finished;
                for (key, why) in o.failed {
                    outcome.failed.push((u.id(cfg), key, why));
                }
                if o.finished > 0 {
                    // The page follows the runs, so a run cut short leaves it current.
                    report(cfg, opts)?;
                }
            }
        }
    }
    outcome.written = report(cfg, opts)?;
    Ok(outcome)
}

/// Seconds a run of the paper takes on 2 cores, two at a time, when no run has been
/// timed in the folder yet: the registration's bound for the whole plan, at most
/// 32.7 h for its 2,808 runs (docs/paper/registration.md, "Budget": measured on the
/// bar of issue 48, whose policies finish their routes), 41.9 s a run.
pub const DEFAULT_RUN_S: f64 = 32.7 * 3600.0 / 2808.0;

/// "N runs in the plan, D done, L left: about H h at S s a run (...)": the rest
/// at the folder's own wall time per run ([`WallLog`]), else [`DEFAULT_RUN_S`].
pub fn plan_line(planned: usize, left: usize, wall: &WallLog) -> String {
    let (per_run, from) = if wall.runs > 0 {
        (
            wall.sweep_s / wall.runs as f64,
            format!("this folder's {} runs so far", wall.runs),
        )
    } else {
        (DEFAULT_RUN_S, "the registration's estimate".to_string())
    };
    format!(
        "{planned} runs in the plan, {} done, {left} left: about {:.1} h at {per_run:.1} s a run \
         ({from})",
        planned - left.min(planned),
        left as f64 * per_run / 3600.0
    )
}

/// A note when runs in the folder were made on CPUs other than `here` (a policy's run
/// is not bit-identical across CPU makers: README, "Determinism"), else `None`.
fn other_cpus(
    cpus: &std::collections::BTreeMap<String, usize>,
    here: Option<&str>,
) -> Option<String> {
    let here = here.unwrap_or("an unnamed CPU");
    let others: Vec<String> = cpus
        .iter()
        .filter(|(cpu, _)| cpu.as_str() != here)
        .map(|(cpu, n)| match cpu.as_str() {
            "not recorded" => format!("CPUs their records do not name ({n} runs)"),
            _ => format!("{cpu} ({n} runs)"),
        })
        .collect();
    (!others.is_empty()).then(|| {
        format!(
            "this machine's CPU is {here}; runs already here were made on {}. A policy's run \
             made on another CPU maker can differ by a few ticks: the seeds stay independent \
             samples, but a rerun here is not a check of a run made there.",
            others.join(", ")
        )
    })
}

/// Refuses to add runs to a folder holding runs of another build than `here`
/// (the study's provenance rule: one build for every record of the page).
fn same_build(
    builds: &std::collections::BTreeSet<String>,
    here: &str,
    out: &std::path::Path,
) -> Result<(), PaperError> {
    match builds.iter().find(|b| *b != here) {
        None => Ok(()),
        Some(other) => Err(PaperError::Build {
            out: out.to_path_buf(),
            existing: other.clone(),
            here: here.to_string(),
        }),
    }
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
    /// The first failure to write the log, reported once the sweep is done.
    error: Option<PaperError>,
}

impl WallClock {
    fn start() -> Self {
        WallClock {
            last: Instant::now(),
            counted: false,
            error: None,
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

/// Rewrites the tables, figures and page sections from the runs that exist:
/// of the experiments asked for, and of any other whose runs are all here, so
/// `--only` adds to the page without dropping what is complete (an experiment
/// neither asked for nor complete gets a line saying it was not run here).
/// A registered folder's page takes only records of builds that descend from
/// the registering commit ([`Registration::check_builds`]).
fn report(cfg: &PaperConfig, opts: &RunOptions) -> Result<Vec<PathBuf>, PaperError> {
    let results = Results::load(cfg, &opts.out, &units_of(&Experiment::ALL, cfg))?;
    let registration = Registration::load(&opts.registered_in)?;
    if let Some(r) = &registration {
        r.check_rules(&opts.registered_in)?;
        r.check_builds(&opts.registered_in, &results.provenance(|p| &p.build))?;
    }
    page::write_all(cfg, opts, &results, registration.as_ref())
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_note_names_the_other_cpus_only() {
        let cpus: std::collections::BTreeMap<String, usize> =
            [("AMD EPYC".to_string(), 3), ("not recorded".to_string(), 5)].into();
        let note = super::other_cpus(&cpus, Some("AMD EPYC")).unwrap();
        assert!(note.contains("do not name (5 runs)"), "{note}");
        assert!(!note.contains("EPYC (3 runs)"), "{note}");
        let only_here = [("AMD EPYC".to_string(), 3)].into();
        assert_eq!(super::other_cpus(&only_here, Some("AMD EPYC")), None);
        assert!(
            super::other_cpus(&only_here, None)
                .unwrap()
                .contains("AMD EPYC (3 runs)")
        );
    }

    use super::*;

    #[test]
    fn runs_of_another_build_are_refused_with_the_way_out() {
        let out = std::path::Path::new("docs/paper");
        let here = "mrdrive 0.1.0 (abc)";
        let set = |b: &[&str]| b.iter().map(|s| s.to_string()).collect();
        assert!(same_build(&set(&[]), here, out).is_ok());
        assert!(same_build(&set(&[here]), here, out).is_ok());
        let e = same_build(&set(&[here, "mrdrive 0.1.0 (def)"]), here, out)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("docs/paper") && e.contains("(def)") && e.contains("--mixed-builds"),
            "{e}"
        );
    }

    #[test]
    fn the_plan_line_sizes_the_rest_at_the_folders_own_pace() {
        let fresh = plan_line(2808, 2808, &WallLog::default());
        assert_eq!(
            fresh,
            "2808 runs in the plan, 0 done, 2808 left: about 32.7 h at 41.9 s a run (the \
             registration's estimate)"
        );
        let timed = WallLog {
            sweep_s: 3600.0,
            runs: 300,
            invocations: 1,
            jobs: 2,
        };
        assert_eq!(
            plan_line(2088, 1788, &timed),
            "2088 runs in the plan, 300 done, 1788 left: about 6.0 h at 12.0 s a run (this \
             folder's 300 runs so far)"
        );
    }

    #[test]
    fn the_wall_log_grows_run_by_run_across_invocations() {
        let tmp = tempfile::tempdir().unwrap();
        let opts = RunOptions {
            out: tmp.path().to_path_buf(),
            jobs: 2,
            experiments: Vec::new(),
            report_only: false,
            mixed_builds: false,
            label: "quick".into(),
            seeds: None,
            registered_in: tmp.path().to_path_buf(),
        };
        // One invocation: two runs finish, one fails (time, no run).
        let mut clock = WallClock::start();
        std::thread::sleep(std::time::Duration::from_millis(20));
        clock.log(&opts, 1).unwrap();
        let after_one = WallLog::read(&opts.out);
        assert_eq!((after_one.runs, after_one.invocations), (1, 1));
        assert!(after_one.sweep_s >= 0.02, "{after_one:?}");
        clock.log(&opts, 1).unwrap();
        clock.log(&opts, 0).unwrap();
        // A second invocation (a resume after a kill) adds to it.
        WallClock::start().log(&opts, 1).unwrap();
        let log = WallLog::read(&opts.out);
        assert_eq!((log.runs, log.invocations, log.jobs), (3, 2, 2));
        assert!(log.sweep_s >= after_one.sweep_s);
        // Written whole: no temporary file is left beside it.
        assert!(!opts.out.join("wall.json.tmp").exists());
    }
}
