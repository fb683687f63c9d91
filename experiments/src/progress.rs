//! How far the training pipeline is and how long the rest will take
//! (`mrdrive train --all` prints it before each step).
//!
//! Each step of the plan says what it does in the units its time goes with ([`Work`]):
//! episodes collected, episodes labelled, samples trained, runs driven. What is
//! left of a step is read from the cache (the episodes and labels in the
//! dataset's folder, the run's `state/progress.json`, the records in the sweep's
//! folder), so a step a lost job had finished counts nothing. The rest's time is
//! what is left of each kind times its rate ([`Rates`]): measured in this job
//! once a step of that kind has done some work, else the rate measured on a
//! 2-core AMD EPYC (docs/training.md).

use std::path::{Path, PathBuf};

/// What a step does, in the units its time is counted in.
#[derive(Debug, Clone, PartialEq)]
pub enum Work {
    /// Collect dataset `dir`'s episodes after the first `from`, up to `end`
    /// (`episode-NNNNN.safetensors`).
    Collect {
        /// The dataset's folder.
        dir: PathBuf,
        /// Episodes before this step's (the slices before).
        from: u32,
        /// Episodes in all once it is done.
        end: u32,
    },
    /// Label dataset `dir`'s episodes after the first `from`, up to `end`
    /// (`labels-NNNNN.safetensors`).
    Label {
        /// The dataset's folder.
        dir: PathBuf,
        /// Episodes before this step's.
        from: u32,
        /// Labelled episodes in all once it is done.
        end: u32,
    },
    /// Train the run in folder `run` (its `state/progress.json`) to `steps` steps,
    /// each of `samples_per_step` samples (the batch, times the scales a step trains).
    Train {
        /// The run folder.
        run: PathBuf,
        /// Steps in all once it is done.
        steps: u64,
        /// Samples (forward and backward passes at one scale) per step.
        samples_per_step: u64,
    },
    /// Drive `runs` closed-loop runs into sweep folder `out` (`out/runs/*.json`).
    Drive {
        /// The sweep's folder.
        out: PathBuf,
        /// Runs in all.
        runs: u32,
    },
    /// Seconds (a table, a summary).
    Small,
}

/// The units [`Work`] is counted in, one kind each.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Episodes collected.
    Collect,
    /// Episodes labelled.
    Label,
    /// Samples trained.
    Train,
    /// Runs driven.
    Drive,
    /// Nothing worth counting.
    Small,
}

/// Seconds per unit of each [`Kind`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rates {
    /// Seconds to collect one episode (90 s of driving at most).
    pub collect_s: f64,
    /// Seconds to label one episode.
    pub label_s: f64,
    /// Seconds to train one sample.
    pub train_s: f64,
    /// Seconds to drive one closed-loop run (two at a time).
    pub drive_s: f64,
}

impl Default for Rates {
    /// Measured in the training chain on a 2-core AMD EPYC with foreground work
    /// beside it (builds, soaks), as the chain runs (docs/training.md): slice 4
    /// (40 episodes) collected in 287 s and labelled in 486.3 s (2026-12-06, at
    /// 05:51-08:40), round 4 trained at 23.2 samples/s and its 12 runs driven in
    /// 824 s (09:01-09:47). A quiet machine is faster (35.2 samples/s).
    fn default() -> Self {
        Rates {
            collect_s: 287.0 / 40.0,
            label_s: 486.3 / 40.0,
            train_s: 1.0 / 23.2,
            drive_s: 824.0 / 12.0,
        }
    }
}

impl Rates {
    /// The rate of a kind (seconds per unit; 0 for [`Kind::Small`]).
    pub fn of(&self, kind: Kind) -> f64 {
        match kind {
            Kind::Collect => self.collect_s,
            Kind::Label => self.label_s,
            Kind::Train => self.train_s,
            Kind::Drive => self.drive_s,
            Kind::Small => 0.0,
        }
    }
}

/// The rates of a job: the measured default of each kind until a step of that
/// kind has done some work in this job, then what this job's steps of that kind
/// took per unit.
#[derive(Debug, Clone, Default)]
pub struct JobRates {
    defaults: Rates,
    /// Per kind (collect, label, train, drive): units done and seconds spent.
    done: [(f64, f64); 4],
}

impl JobRates {
    /// A job's rates, starting from `defaults`.
    pub fn new(defaults: Rates) -> Self {
        JobRates {
            defaults,
            done: [(0.0, 0.0); 4],
        }
    }

    fn slot(kind: Kind) -> Option<usize> {
        match kind {
            Kind::Collect => Some(0),
            Kind::Label => Some(1),
            Kind::Train => Some(2),
            Kind::Drive => Some(3),
            Kind::Small => None,
        }
    }

    /// A step of `kind` did `units` in `secs` seconds.
    pub fn observe(&mut self, kind: Kind, units: f64, secs: f64) {
        if let Some(k) = Self::slot(kind)
            && units > 0.0
        {
            self.done[k].0 += units;
            self.done[k].1 += secs;
        }
    }

    /// Seconds per unit of `kind` now.
    pub fn of(&self, kind: Kind) -> f64 {
        match Self::slot(kind) {
            Some(k) if self.done[k].0 > 0.0 => self.done[k].1 / self.done[k].0,
            _ => self.defaults.of(kind),
        }
    }

    /// Whether `kind`'s rate was measured in this job.
    pub fn measured(&self, kind: Kind) -> bool {
        Self::slot(kind).is_some_and(|k| self.done[k].0 > 0.0)
    }
}

/// Files in `dir` whose names start with `prefix` and end with `suffix`.
fn count_files(dir: &Path, prefix: &str, suffix: &str) -> u32 {
    std::fs::read_dir(dir).map_or(0, |entries| {
        entries
            .filter_map(Result::ok)
            .filter(|e| {
                let name = e.file_name();
                let name = name.to_string_lossy();
                name.starts_with(prefix) && name.ends_with(suffix)
            })
            .count() as u32
    })
}

/// Episodes of the slice after the first `from`, up to `end`, whose files
/// (`PREFIX-NNNNN.safetensors`) dataset folder `dir` does not hold yet.
fn slice_left(dir: &Path, prefix: &str, from: u32, end: u32) -> f64 {
    let have = count_files(dir, prefix, ".safetensors");
    f64::from(end - have.clamp(from.min(end), end))
}

/// The step a run folder's state has reached (0 without one).
fn run_step(run: &Path) -> u64 {
    let text = std::fs::read_to_string(run.join("state/progress.json")).unwrap_or_default();
    serde_json::from_str::<serde_json::Value>(&text)
        .ok()
        .and_then(|v| v.get("step")?.as_u64())
        .unwrap_or(0)
}

impl Work {
    /// What is left of it (its kind and units), read from the files under `dir`
    /// (the plan's working directory; absolute paths are left as they are).
    pub fn left(&self, dir: &Path) -> (Kind, f64) {
        match self {
            Work::Collect { dir: d, from, end } => (
                Kind::Collect,
                slice_left(&dir.join(d), "episode-", *from, *end),
            ),
            Work::Label { dir: d, from, end } => (
                Kind::Label,
                slice_left(&dir.join(d), "labels-", *from, *end),
            ),
            Work::Train {
                run,
                steps,
                samples_per_step,
            } => {
                let at = run_step(&dir.join(run));
                (
                    Kind::Train,
                    (steps.saturating_sub(at) * samples_per_step) as f64,
                )
            }
            Work::Drive { out, runs } => {
                let have = count_files(&dir.join(out).join("runs"), "", ".json");
                (Kind::Drive, f64::from(runs.saturating_sub(have)))
            }
            Work::Small => (Kind::Small, 0.0),
        }
    }
}

/// What is left of a plan: units of each kind and the seconds they will take.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Left {
    /// Episodes to collect.
    pub collect: f64,
    /// Episodes to label.
    pub label: f64,
    /// Samples to train.
    pub train: f64,
    /// Runs to drive.
    pub drive: f64,
    /// Seconds it will take, lanes that run at once counted by the longest.
    pub secs: f64,
}

impl Left {
    /// Adds what is left of `work` (read under `dir`) and returns the seconds it
    /// will take at `rates`.
    pub fn add(&mut self, work: &Work, dir: &Path, rates: &JobRates) -> f64 {
        let (kind, units) = work.left(dir);
        match kind {
            Kind::Collect => self.collect += units,
            Kind::Label => self.label += units,
            Kind::Train => self.train += units,
            Kind::Drive => self.drive += units,
            Kind::Small => {}
        }
        units * rates.of(kind)
    }
}

/// "41 h 05 min", "12 min", "under a minute".
pub fn duration(secs: f64) -> String {
    let min = (secs / 60.0).round() as u64;
    match min {
        0 => "under a minute".into(),
        m if m < 60 => format!("{m} min"),
        m => format!("{} h {:02} min", m / 60, m % 60),
    }
}

impl Left {
    /// One line: how long, and what is left of each kind.
    pub fn line(&self, rates: &JobRates) -> String {
        let mut parts = Vec::new();
        let mut part = |units: f64, what: &str, kind: Kind| {
            if units > 0.0 {
                let units = what.replace('#', &format!("{units:.0}"));
                parts.push(if rates.measured(kind) {
                    format!("{units} (at this job's rate)")
                } else {
                    units
                });
            }
        };
        part(self.collect, "collect # episodes", Kind::Collect);
        part(self.label, "label # episodes", Kind::Label);
        if self.train >= 10_000.0 {
            part(self.train / 1000.0, "train #k samples", Kind::Train);
        } else {
            part(self.train, "train # samples", Kind::Train);
        }
        part(self.drive, "drive # runs", Kind::Drive);
        if parts.is_empty() {
            return "nothing left".into();
        }
        format!(
            "about {} left on a 2-core machine: {}",
            duration(self.secs),
            parts.join(", ")
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn touch(dir: &Path, names: impl IntoIterator<Item = String>) {
        std::fs::create_dir_all(dir).unwrap();
        for n in names {
            std::fs::write(dir.join(n), b"").unwrap();
        }
    }

    #[test]
    fn what_is_left_is_read_from_the_cache() {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path();
        // 43 episodes collected, 40 labelled.
        touch(
            &root.join("data"),
            (0..43).map(|i| format!("episode-{i:05}.safetensors")),
        );
        touch(
            &root.join("data"),
            (0..40).map(|i| format!("labels-{i:05}.safetensors")),
        );
        let slice = |from, end| {
            (
                Work::Collect {
                    dir: "data".into(),
                    from,
                    end,
                }
                .left(root),
                Work::Label {
                    dir: "data".into(),
                    from,
                    end,
                }
                .left(root),
            )
        };
        // The first slice is done, the second is 3 episodes in, the third untouched.
        assert_eq!(slice(0, 40), ((Kind::Collect, 0.0), (Kind::Label, 0.0)));
        assert_eq!(slice(40, 80), ((Kind::Collect, 37.0), (Kind::Label, 40.0)));
        assert_eq!(slice(80, 120), ((Kind::Collect, 40.0), (Kind::Label, 40.0)));
        // A run at step 250 of 1000, batches of 32; one with no state yet.
        std::fs::create_dir_all(root.join("runs/a/state")).unwrap();
        std::fs::write(
            root.join("runs/a/state/progress.json"),
            r#"{"step": 250, "wall_s": 300.0}"#,
        )
        .unwrap();
        let train = |run: &str| Work::Train {
            run: run.into(),
            steps: 1000,
            samples_per_step: 32,
        };
        assert_eq!(train("runs/a").left(root), (Kind::Train, 24_000.0));
        assert_eq!(train("runs/b").left(root), (Kind::Train, 32_000.0));
        // 4 of 12 runs recorded.
        touch(
            &root.join("sweep/runs"),
            (0..4).map(|i| format!("run-{i}.json")),
        );
        let drive = Work::Drive {
            out: "sweep".into(),
            runs: 12,
        };
        assert_eq!(drive.left(root), (Kind::Drive, 8.0));
        assert_eq!(Work::Small.left(root), (Kind::Small, 0.0));
    }

    #[test]
    fn a_job_counts_at_its_own_rate_once_it_has_measured_one() {
        let mut r = JobRates::new(Rates::default());
        assert_eq!(r.of(Kind::Label), Rates::default().label_s);
        assert!(!r.measured(Kind::Label));
        // A step that found its work done measures nothing.
        r.observe(Kind::Label, 0.0, 5.0);
        assert!(!r.measured(Kind::Label));
        r.observe(Kind::Label, 10.0, 100.0);
        r.observe(Kind::Label, 30.0, 500.0);
        assert_eq!(r.of(Kind::Label), 15.0);
        assert_eq!(r.of(Kind::Collect), Rates::default().collect_s);
        assert_eq!(r.of(Kind::Small), 0.0);
    }

    #[test]
    fn a_few_samples_are_not_rounded_to_thousands() {
        let rates = JobRates::default();
        let few = Left {
            train: 32.0,
            ..Left::default()
        };
        assert!(
            few.line(&rates).ends_with("train 32 samples"),
            "{}",
            few.line(&rates)
        );
        let many = Left {
            train: 32_000.0,
            ..Left::default()
        };
        assert!(
            many.line(&rates).ends_with("train 32k samples"),
            "{}",
            many.line(&rates)
        );
    }

    #[test]
    fn durations_read_as_hours_and_minutes() {
        assert_eq!(duration(20.0), "under a minute");
        assert_eq!(duration(12.0 * 60.0), "12 min");
        assert_eq!(duration(41.0 * 3600.0 + 5.0 * 60.0), "41 h 05 min");
    }
}
