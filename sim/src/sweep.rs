//! Sweeps: the cross product of scenarios, delays, scales, densities and
//! seeds, run in parallel, one record file per run.
//!
//! A sweep folder holds `plan.json` (every run of the sweep, in a fixed
//! order) and `runs/KEY.json` (one record per finished run, written
//! atomically). Running a sweep again into the same folder skips every run
//! whose record exists, so a killed sweep resumes without redoing or losing a
//! finished run. `--shard i/n` runs every n-th run of the plan, starting at
//! i, so n machines (a Slurm array, a Kubernetes Indexed Job) share one
//! sweep; [`merge`] joins their folders and checks that no run is missing.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::record::{self, RunRecord};

/// One run of a sweep: a scenario file and the settings that override it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSpec {
    /// The scenario file.
    pub scenario: PathBuf,
    /// Injected delay (milliseconds); `None` keeps the scenario's.
    pub delay_ms: Option<f64>,
    /// Input scale (fraction of S0); `None` keeps the scenario's selector.
    pub scale: Option<f64>,
    /// Target (vehicles, pedestrians); `None` keeps the scenario's.
    pub density: Option<(u32, u32)>,
    /// Traffic seed.
    pub seed: u64,
}

impl RunSpec {
    /// A file-name-safe key, unique within a sweep.
    pub fn key(&self) -> String {
        let stem = self
            .scenario
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let scale = self.scale.map_or("sel".to_string(), |s| format!("{s:.3}"));
        let delay = self
            .delay_ms
            .map_or("sc".to_string(), |d| format!("{:03}", d.round() as u64));
        let density = self
            .density
            .map_or("sc".to_string(), |(v, p)| format!("v{v}p{p}"));
        format!("{stem}__d{delay}_s{scale}_{density}_seed{}", self.seed)
    }
}

/// The axes of a sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepPlan {
    /// Every run, in a fixed order.
    pub runs: Vec<RunSpec>,
}

impl SweepPlan {
    /// The cross product, scenarios outermost, seeds innermost.
    pub fn cross(
        scenarios: &[PathBuf],
        delays_ms: &[Option<f64>],
        scales: &[Option<f64>],
        densities: &[Option<(u32, u32)>],
        seeds: &[u64],
    ) -> Self {
        let mut runs = Vec::new();
        for scenario in scenarios {
            for &delay_ms in delays_ms {
                for &scale in scales {
                    for &density in densities {
                        for &seed in seeds {
                            runs.push(RunSpec {
                                scenario: scenario.clone(),
                                delay_ms,
                                scale,
                                density,
                                seed,
                            });
                        }
                    }
                }
            }
        }
        Self { runs }
    }

    /// The runs of shard `index` of `count` (every `count`-th run from `index`).
    pub fn shard(&self, index: usize, count: usize) -> Vec<&RunSpec> {
        self.runs
            .iter()
            .enumerate()
            .filter(|(i, _)| i % count.max(1) == index)
            .map(|(_, r)| r)
            .collect()
    }
}

/// Parses `i/n` for `--shard`.
pub fn parse_shard(text: &str) -> Result<(usize, usize), String> {
    let (i, n) = text
        .split_once('/')
        .ok_or_else(|| format!("--shard {text}: write it as INDEX/COUNT, e.g. 0/4"))?;
    let (i, n): (usize, usize) = (
        i.trim()
            .parse()
            .map_err(|_| format!("--shard {text}: INDEX must be a number"))?,
        n.trim()
            .parse()
            .map_err(|_| format!("--shard {text}: COUNT must be a number"))?,
    );
    if n == 0 || i >= n {
        return Err(format!("--shard {text}: need 0 <= INDEX < COUNT"));
    }
    Ok((i, n))
}

/// The folder layout of a sweep.
#[derive(Debug, Clone)]
pub struct SweepDir {
    /// The sweep's folder.
    pub root: PathBuf,
}

impl SweepDir {
    /// The plan file.
    pub fn plan_path(&self) -> PathBuf {
        self.root.join("plan.json")
    }

    /// The folder of records.
    pub fn runs_dir(&self) -> PathBuf {
        self.root.join("runs")
    }

    /// The record file of a run.
    pub fn record_path(&self, spec: &RunSpec) -> PathBuf {
        self.runs_dir().join(format!("{}.json", spec.key()))
    }

    /// Writes the plan, or checks that it matches the one already there (a
    /// resumed sweep must be the same sweep).
    pub fn prepare(&self, plan: &SweepPlan) -> Result<(), String> {
        std::fs::create_dir_all(self.runs_dir())
            .map_err(|e| format!("cannot create {}: {e}", self.runs_dir().display()))?;
        let path = self.plan_path();
        if path.exists() {
            let old = self.read_plan()?;
            if old != *plan {
                return Err(format!(
                    "{} holds a different sweep: resume it with the same arguments, or give another --out folder",
                    self.root.display()
                ));
            }
            return Ok(());
        }
        let text = serde_json::to_string_pretty(plan).map_err(|e| e.to_string())?;
        std::fs::write(&path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))
    }

    /// Reads the plan.
    pub fn read_plan(&self) -> Result<SweepPlan, String> {
        let path = self.plan_path();
        let text = std::fs::read_to_string(&path)
            .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        serde_json::from_str(&text)
            .map_err(|e| format!("{} is not a sweep plan: {e}", path.display()))
    }

    /// Whether a run's record is there and readable.
    pub fn is_done(&self, spec: &RunSpec) -> bool {
        record::read(&self.record_path(spec)).is_ok()
    }
}

/// What a sweep did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SweepOutcome {
    /// Runs that were already done and skipped.
    pub skipped: usize,
    /// Runs finished now.
    pub finished: usize,
    /// Runs that failed, with why.
    pub failed: Vec<(String, String)>,
}

/// Runs the shard's runs that are not done yet, `jobs` at a time, writing
/// each record as soon as it is finished. `run` turns a spec into a record;
/// `on_done` is called after each (for a progress bar). A failing run is
/// reported and the others go on.
pub fn execute(
    dir: &SweepDir,
    runs: &[&RunSpec],
    jobs: usize,
    run: impl Fn(&RunSpec) -> Result<RunRecord, String> + Sync,
    on_done: impl Fn(&RunSpec) + Sync,
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
                let outcome = run(spec).and_then(|rec| {
                    record::write_atomically(&dir.record_path(spec), &rec).map_err(|e| {
                        format!("cannot write {}: {e}", dir.record_path(spec).display())
                    })
                });
                on_done(spec);
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

/// Joins shard folders into `out`: copies every record, then checks against
/// the plan that no run is missing. Returns the missing keys (empty: whole).
pub fn merge(shards: &[PathBuf], out: &Path) -> Result<Vec<String>, String> {
    let out_dir = SweepDir {
        root: out.to_path_buf(),
    };
    let mut plan: Option<SweepPlan> = None;
    for shard in shards {
        let dir = SweepDir {
            root: shard.clone(),
        };
        let p = dir.read_plan()?;
        match &plan {
            None => plan = Some(p),
            Some(first) if *first != p => {
                return Err(format!(
                    "{} belongs to another sweep (its plan.json differs)",
                    shard.display()
                ));
            }
            Some(_) => {}
        }
    }
    let plan = plan.ok_or("give at least one shard folder to merge")?;
    out_dir.prepare(&plan)?;
    for shard in shards {
        let dir = SweepDir {
            root: shard.clone(),
        };
        for spec in &plan.runs {
            let from = dir.record_path(spec);
            let to = out_dir.record_path(spec);
            if from.exists() && !to.exists() {
                let rec = record::read(&from)?;
                record::write_atomically(&to, &rec)
                    .map_err(|e| format!("cannot write {}: {e}", to.display()))?;
            }
        }
    }
    Ok(plan
        .runs
        .iter()
        .filter(|s| !out_dir.is_done(s))
        .map(RunSpec::key)
        .collect())
}

/// One row of a sweep's aggregate table: the runs that share a configuration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SummaryRow {
    /// The configuration: scenario group, delay, scale/selector, density.
    pub config: String,
    /// Runs in the group.
    pub runs: usize,
    /// Share of runs that succeeded (percent).
    pub success_pct: f64,
    /// Share of runs with at least one collision (percent).
    pub collision_pct: f64,
    /// Route completion, mean and sd (percent).
    pub completion: (f64, f64),
    /// Driving score, mean and sd (percent).
    pub driving_score: (f64, f64),
    /// Lane crossings per run, mean and sd.
    pub lane_crossings: (f64, f64),
    /// Red lights per run, mean and sd.
    pub red_lights: (f64, f64),
    /// Red lights, total over the group.
    pub red_lights_total: u32,
    /// Collisions per run, mean and sd.
    pub collisions: (f64, f64),
}

/// Mean and sample standard deviation (0 for fewer than two values).
pub fn mean_sd(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let sd = if values.len() < 2 {
        0.0
    } else {
        (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    };
    (mean, sd)
}

/// Groups records by configuration (all but the seed and the route) and
/// aggregates each group. `group_of` names a record's group.
pub fn summarise(
    records: &[RunRecord],
    group_of: impl Fn(&RunRecord) -> String,
) -> Vec<SummaryRow> {
    let mut groups: BTreeMap<String, Vec<&RunRecord>> = BTreeMap::new();
    for r in records {
        groups.entry(group_of(r)).or_default().push(r);
    }
    groups
        .into_iter()
        .map(|(config, recs)| {
            let n = recs.len();
            let of = |f: &dyn Fn(&RunRecord) -> f64| {
                mean_sd(&recs.iter().map(|r| f(r)).collect::<Vec<_>>())
            };
            let pct = |f: &dyn Fn(&RunRecord) -> bool| {
                100.0 * recs.iter().filter(|r| f(r)).count() as f64 / n as f64
            };
            use crate::monitors::InfractionKind::{LaneCrossing, RedLight};
            SummaryRow {
                config,
                runs: n,
                success_pct: pct(&|r| r.result.success),
                collision_pct: pct(&|r| r.result.collisions() > 0),
                completion: of(&|r| r.result.completion_pct),
                driving_score: of(&|r| r.result.driving_score),
                lane_crossings: of(&|r| f64::from(r.result.count(LaneCrossing))),
                red_lights: of(&|r| f64::from(r.result.count(RedLight))),
                red_lights_total: recs.iter().map(|r| r.result.count(RedLight)).sum(),
                collisions: of(&|r| f64::from(r.result.collisions())),
            }
        })
        .collect()
}

/// The aggregate table in Markdown.
pub fn summary_markdown(rows: &[SummaryRow]) -> String {
    let mut s = String::from(
        "| configuration | runs | success % | collision % | completion % | driving score | lane crossings | red lights | red lights (total) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    let pm = |(m, sd): (f64, f64)| format!("{m:.2} ± {sd:.2}");
    for r in rows {
        s += &format!(
            "| {} | {} | {:.2} | {:.2} | {} | {} | {} | {} | {} |\n",
            r.config,
            r.runs,
            r.success_pct,
            r.collision_pct,
            pm(r.completion),
            pm(r.driving_score),
            pm(r.lane_crossings),
            pm(r.red_lights),
            r.red_lights_total
        );
    }
    s
}

/// The aggregate table as CSV.
pub fn summary_csv(rows: &[SummaryRow]) -> Result<String, String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "configuration",
        "runs",
        "success_pct",
        "collision_pct",
        "completion_mean",
        "completion_sd",
        "driving_score_mean",
        "driving_score_sd",
        "lane_crossings_mean",
        "lane_crossings_sd",
        "red_lights_mean",
        "red_lights_sd",
        "red_lights_total",
        "collisions_mean",
        "collisions_sd",
    ])
    .map_err(|e| e.to_string())?;
    for r in rows {
        let f = |v: f64| format!("{v:.4}");
        w.write_record([
            r.config.clone(),
            r.runs.to_string(),
            f(r.success_pct),
            f(r.collision_pct),
            f(r.completion.0),
            f(r.completion.1),
            f(r.driving_score.0),
            f(r.driving_score.1),
            f(r.lane_crossings.0),
            f(r.lane_crossings.1),
            f(r.red_lights.0),
            f(r.red_lights.1),
            r.red_lights_total.to_string(),
            f(r.collisions.0),
            f(r.collisions.1),
        ])
        .map_err(|e| e.to_string())?;
    }
    String::from_utf8(w.into_inner().map_err(|e| e.to_string())?).map_err(|e| e.to_string())
}

/// Reads every record of a sweep folder that its plan names.
pub fn read_records(dir: &SweepDir) -> Result<Vec<RunRecord>, String> {
    let plan = dir.read_plan()?;
    plan.runs
        .iter()
        .filter(|s| dir.record_path(s).exists())
        .map(|s| record::read(&dir.record_path(s)))
        .collect()
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use super::*;
    use crate::record::*;

    /// A record whose counts are a function of the spec, standing in for a run.
    fn fake_record(spec: &RunSpec) -> RunRecord {
        let mut infractions = Vec::new();
        for _ in 0..(spec.delay_ms.unwrap_or(0.0) as u64 / 50) {
            infractions.push(crate::monitors::Infraction {
                tick: 1,
                time_s: 0.025,
                kind: crate::monitors::InfractionKind::RedLight,
                position: [0.0, 0.0],
                detail: String::new(),
            });
        }
        RunRecord {
            result: RunResult {
                provenance: Provenance {
                    scenario: spec.key(),
                    scenario_file: spec.scenario.display().to_string(),
                    map: "m".into(),
                    route: "r".into(),
                    driver: "expert".into(),
                    build: "test".into(),
                    render_backend: "none".into(),
                },
                settings: RunSettings {
                    seed: spec.seed,
                    delay_ms: spec.delay_ms.unwrap_or(0.0),
                    control_period_ms: 50.0,
                    resolution: format!("{:?}", spec.scale),
                    vehicles: spec.density.unwrap_or((0, 0)).0,
                    pedestrians: spec.density.unwrap_or((0, 0)).1,
                },
                traffic: RealisedTraffic {
                    vehicles: spec.density.unwrap_or((0, 0)).0,
                    pedestrians: spec.density.unwrap_or((0, 0)).1,
                },
                completion_pct: 100.0,
                success: spec.seed.is_multiple_of(2),
                driving_score: 100.0,
                outside_lane_pct: 0.0,
                counts: count_by_kind(&infractions),
                termination: None,
                route_length_m: 100.0,
                sim_time_s: 20.0,
                ticks: 800,
                scale_share: BTreeMap::new(),
                max_latency_ms: 0.0,
                infractions,
            },
            perf: RunPerf::default(),
        }
    }

    fn plan() -> SweepPlan {
        SweepPlan::cross(
            &["a.toml".into(), "b.toml".into()],
            &[Some(0.0), Some(100.0)],
            &[Some(0.75), Some(1.0)],
            &[Some((0, 0)), Some((5, 10))],
            &[1, 2],
        )
    }

    #[test]
    fn cross_product_has_every_combination_with_unique_keys() {
        let p = plan();
        assert_eq!(p.runs.len(), 2 * 2 * 2 * 2 * 2);
        let keys: std::collections::BTreeSet<String> = p.runs.iter().map(RunSpec::key).collect();
        assert_eq!(keys.len(), p.runs.len());
    }

    #[test]
    fn shards_partition_the_plan() {
        let p = plan();
        let mut all: Vec<String> = (0..3)
            .flat_map(|i| p.shard(i, 3))
            .map(RunSpec::key)
            .collect();
        all.sort();
        let mut want: Vec<String> = p.runs.iter().map(RunSpec::key).collect();
        want.sort();
        assert_eq!(all, want);
        assert_eq!(parse_shard("1/4"), Ok((1, 4)));
        assert!(parse_shard("4/4").is_err());
        assert!(parse_shard("x").is_err());
    }

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
                    Err("killed".into())
                } else {
                    Ok(fake_record(spec))
                }
            },
            |_| {},
        );
        assert_eq!(first.finished, 10);
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
                Ok(fake_record(spec))
            },
            |_| {},
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

    #[test]
    fn a_folder_of_another_sweep_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = SweepDir {
            root: tmp.path().to_path_buf(),
        };
        dir.prepare(&plan()).unwrap();
        let other = SweepPlan::cross(&["a.toml".into()], &[Some(0.0)], &[None], &[None], &[1]);
        assert!(dir.prepare(&other).unwrap_err().contains("different sweep"));
    }

    #[test]
    fn merge_joins_shards_and_reports_missing_runs() {
        let tmp = tempfile::tempdir().unwrap();
        let p = plan();
        let shards: Vec<PathBuf> = (0..2)
            .map(|i| tmp.path().join(format!("shard{i}")))
            .collect();
        for (i, root) in shards.iter().enumerate() {
            let dir = SweepDir { root: root.clone() };
            dir.prepare(&p).unwrap();
            let mine = p.shard(i, 2);
            // Shard 1 loses its last run.
            let mine = if i == 1 {
                &mine[..mine.len() - 1]
            } else {
                &mine[..]
            };
            execute(&dir, mine, 1, |s| Ok(fake_record(s)), |_| {});
        }
        let out = tmp.path().join("merged");
        let missing = merge(&shards, &out).unwrap();
        assert_eq!(missing, vec![p.shard(1, 2).last().unwrap().key()]);
        assert_eq!(
            read_records(&SweepDir { root: out }).unwrap().len(),
            p.runs.len() - 1
        );
    }

    #[test]
    fn summary_aggregates_groups() {
        let p = plan();
        let records: Vec<RunRecord> = p.runs.iter().map(fake_record).collect();
        let rows = summarise(&records, |r| format!("d{}", r.result.settings.delay_ms));
        assert_eq!(rows.len(), 2);
        let d100 = rows.iter().find(|r| r.config == "d100").unwrap();
        assert_eq!(d100.runs, 16);
        assert_eq!(d100.red_lights, (2.0, 0.0));
        assert_eq!(d100.red_lights_total, 32);
        assert_eq!(d100.success_pct, 50.0);
        let md = summary_markdown(&rows);
        assert!(md.contains("| d100 | 16 | 50.00 |"), "{md}");
        let csv = summary_csv(&rows).unwrap();
        assert_eq!(csv.lines().count(), 3);
        assert_eq!(mean_sd(&[1.0, 2.0, 3.0]), (2.0, 1.0));
    }
}
