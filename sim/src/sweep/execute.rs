//! Running the runs of a sweep that are not done yet, in parallel.

use std::fmt::Display;
use std::path::Path;

use rayon::prelude::*;

use super::{RunSpec, SweepDir};
use crate::build::{self, BuildError, Drivers, RunRequest, ScenarioRun};
use crate::record;
use crate::recorder::RecordOptions;

/// What a sweep did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SweepOutcome {
    /// Runs that were already done and skipped.
    pub skipped: usize,
    /// Runs finished now.
    pub finished: usize,
    /// Runs that failed: their key and why.
    pub failed: Vec<(String, String)>,
}

/// Runs one run of a sweep: its scenario with the spec's overrides, built
/// by `drivers`; with `log_dir`, it also records an MCAP log there, named
/// after the run's key.
pub fn run_spec(
    spec: &RunSpec,
    drivers: &Drivers,
    log_dir: Option<&Path>,
) -> Result<ScenarioRun, BuildError> {
    let overrides = spec.overrides();
    let log = log_dir.map(|d| d.join(format!("{}.mcap", spec.key())));
    let request = RunRequest {
        scale: spec.scale,
        record: log.as_deref().map(|p| (p, RecordOptions::default())),
        ..RunRequest::new(&spec.scenario, &overrides)
    };
    build::run_scenario(&request, drivers, &mut |_| {})
}

/// Runs the shard's runs that are not done yet, `jobs` at a time, writing
/// each record as soon as it is finished. `run` turns a spec into a record;
/// `on_done` is called after each with whether its record was written (for a
/// progress bar, a wall-time log). A failing run is
/// reported (with its error and causes) and the others go on.
pub fn execute<E: Display>(
    dir: &SweepDir,
    runs: &[&RunSpec],
    jobs: usize,
    run: impl Fn(&RunSpec) -> Result<record::RunRecord, E> + Sync,
    on_done: impl Fn(&RunSpec, bool) + Sync,
) -> SweepOutcome {
    let todo: Vec<&RunSpec> = runs.iter().copied().filter(|s| !dir.is_done(s)).collect();
    let skipped = runs.len() - todo.len();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.max(1))
        .build()
        .expect("a thread pool");
    let results: Vec<(String, Result<(), String>)> = pool.install(|| {
        todo.par_iter()
            .with_max_len(1)
            .map(|spec| {
                let path = dir.record_path(spec);
                let outcome = run(spec).map_err(|e| e.to_string()).and_then(|rec| {
                    record::write_atomically(&path, &rec)
                        .map_err(|e| format!("cannot write {}: {e}", path.display()))
                });
                on_done(spec, outcome.is_ok());
                (spec.key(), outcome)
            })
            .collect()
    });
    let mut outcome = SweepOutcome {
        skipped,
        ..Default::default()
    };
    for (key, result) in results {
        match result {
            Ok(()) => outcome.finished += 1,
            Err(why) => outcome.failed.push((key, why)),
        }
    }
    outcome
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use super::super::fixtures::{fake_record, plan};
    use super::super::read_records;
    use super::*;

    #[test]
    fn an_interrupted_sweep_resumes_without_redoing_or_losing_runs() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = SweepDir {
            root: tmp.path().join("sweep"),
        };
        let p = plan();
        dir.prepare(&p).unwrap();
        let all: Vec<&RunSpec> = p.runs.iter().collect();
        // First attempt: the machine "dies" after 10 runs (the rest fail).
        let calls = Mutex::new(0usize);
        let first = execute(
            &dir,
            &all,
            1,
            |spec| {
                let mut n = calls.lock().unwrap();
                *n += 1;
                if *n > 10 {
                    Err("killed")
                } else {
                    Ok(fake_record(spec))
                }
            },
            |_, _| {},
        );
        assert_eq!(first.finished, 10);
        assert_eq!(first.failed.len(), p.runs.len() - 10);
        assert_eq!(first.failed[0].1, "killed");
        let done_first: Vec<String> = p
            .runs
            .iter()
            .filter(|s| dir.is_done(s))
            .map(RunSpec::key)
            .collect();
        let bytes_before: Vec<Vec<u8>> = p
            .runs
            .iter()
            .filter(|s| dir.is_done(s))
            .map(|s| std::fs::read(dir.record_path(s)).unwrap())
            .collect();
        // Resume: only the missing runs are run, the finished ones untouched.
        let ran = Mutex::new(Vec::new());
        let second = execute(
            &dir,
            &all,
            2,
            |spec| {
                ran.lock().unwrap().push(spec.key());
                Ok::<_, String>(fake_record(spec))
            },
            |_, _| {},
        );
        assert_eq!(second.skipped, 10);
        assert_eq!(second.finished, p.runs.len() - 10);
        assert!(ran.lock().unwrap().iter().all(|k| !done_first.contains(k)));
        let bytes_after: Vec<Vec<u8>> = p
            .runs
            .iter()
            .filter(|s| done_first.contains(&s.key()))
            .map(|s| std::fs::read(dir.record_path(s)).unwrap())
            .collect();
        assert_eq!(bytes_before, bytes_after);
        assert_eq!(read_records(&dir).unwrap().len(), p.runs.len());
    }
}
