//! A sweep's tables: records grouped by a typed [`GroupKey`], each group's
//! statistics, as Markdown and CSV.

use std::cmp::Ordering;
use std::collections::BTreeMap;
use std::fmt;

use serde::Serialize;

use super::stats::{Z95, wilson};
use super::{SweepDir, SweepError, read_records};
use crate::monitors::InfractionKind::{LaneCrossing, RedLight};
use crate::record::RunRecord;

/// What the runs of one table row share: everything but the seed (and, in
/// the summary table, the scenario). Two runs that differ in driver or
/// checkpoint, selector or any selector parameter, delay, control period or
/// traffic density never share a row.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupKey {
    /// The scenario's name; `None` groups across scenarios.
    pub scenario: Option<String>,
    /// The driver's name (a policy's names its checkpoint and engine).
    pub driver: String,
    /// The resolution selector with its parameters ("oracle-0.75/1-5/15m").
    pub selector: String,
    /// Injected delay D (milliseconds).
    pub delay_ms: f64,
    /// Control period Tc (milliseconds).
    pub control_period_ms: f64,
    /// Target NPC vehicles.
    pub vehicles: u32,
    /// Target pedestrians.
    pub pedestrians: u32,
}

impl GroupKey {
    /// The key of a record across scenarios (the summary table's rows).
    pub fn of(record: &RunRecord) -> Self {
        let r = &record.result;
        GroupKey {
            scenario: None,
            driver: r.provenance.driver.clone(),
            selector: r.settings.resolution.clone(),
            delay_ms: r.settings.delay_ms,
            control_period_ms: r.settings.control_period_ms,
            vehicles: r.settings.vehicles,
            pedestrians: r.settings.pedestrians,
        }
    }

    /// The key of a record within its scenario (the detail table's rows).
    pub fn with_scenario(record: &RunRecord) -> Self {
        GroupKey {
            scenario: Some(record.result.provenance.scenario.clone()),
            ..GroupKey::of(record)
        }
    }
}

impl Eq for GroupKey {}

impl Ord for GroupKey {
    fn cmp(&self, other: &Self) -> Ordering {
        self.scenario
            .cmp(&other.scenario)
            .then_with(|| self.driver.cmp(&other.driver))
            .then_with(|| self.selector.cmp(&other.selector))
            .then_with(|| self.delay_ms.total_cmp(&other.delay_ms))
            .then_with(|| self.control_period_ms.total_cmp(&other.control_period_ms))
            .then_with(|| self.vehicles.cmp(&other.vehicles))
            .then_with(|| self.pedestrians.cmp(&other.pedestrians))
    }
}

impl PartialOrd for GroupKey {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl fmt::Display for GroupKey {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(s) = &self.scenario {
            write!(f, "{s}, ")?;
        }
        write!(
            f,
            "{}, {}, D={} ms, Tc={} ms, traffic {}:{}",
            self.driver,
            self.selector,
            self.delay_ms,
            self.control_period_ms,
            self.vehicles,
            self.pedestrians
        )
    }
}

/// One row of a sweep's aggregate table: the runs that share a [`GroupKey`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SummaryRow {
    /// What the runs share.
    pub key: GroupKey,
    /// Runs in the group.
    pub runs: usize,
    /// Share of runs that succeeded (percent).
    pub success_pct: f64,
    /// Its Wilson 95 % interval (percent).
    pub success_ci: (f64, f64),
    /// Share of runs with at least one collision (percent).
    pub collision_pct: f64,
    /// Its Wilson 95 % interval (percent).
    pub collision_ci: (f64, f64),
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

/// Groups records by `key_of` ([`GroupKey::of`] or
/// [`GroupKey::with_scenario`]) and aggregates each group, in key order.
pub fn summarise(
    records: &[RunRecord],
    key_of: impl Fn(&RunRecord) -> GroupKey,
) -> Vec<SummaryRow> {
    let mut groups: BTreeMap<GroupKey, Vec<&RunRecord>> = BTreeMap::new();
    for r in records {
        groups.entry(key_of(r)).or_default().push(r);
    }
    groups
        .into_iter()
        .map(|(key, recs)| {
            let n = recs.len();
            let of = |f: &dyn Fn(&RunRecord) -> f64| {
                mean_sd(&recs.iter().map(|r| f(r)).collect::<Vec<_>>())
            };
            let count = |f: &dyn Fn(&RunRecord) -> bool| recs.iter().filter(|r| f(r)).count();
            let pct = |k: usize| 100.0 * k as f64 / n as f64;
            let ci = |k: usize| {
                let (lo, hi) = wilson(k, n, Z95);
                (100.0 * lo, 100.0 * hi)
            };
            let success = count(&|r| r.result.success);
            let collided = count(&|r| r.result.collisions() > 0);
            SummaryRow {
                key,
                runs: n,
                success_pct: pct(success),
                success_ci: ci(success),
                collision_pct: pct(collided),
                collision_ci: ci(collided),
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

/// The aggregate table in Markdown, one column per key field.
pub fn summary_markdown(rows: &[SummaryRow]) -> String {
    let mut s = String::from(
        "| scenario | driver | selector | D (ms) | Tc (ms) | vehicles:pedestrians | runs | success % [95 % CI] | collision % [95 % CI] | completion % | driving score | lane crossings | red lights | red lights (total) |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    let pm = |(m, sd): (f64, f64)| format!("{m:.2} ± {sd:.2}");
    for r in rows {
        let k = &r.key;
        s += &format!(
            "| {} | {} | {} | {} | {} | {}:{} | {} | {:.2} [{:.0}, {:.0}] | {:.2} [{:.0}, {:.0}] | {} | {} | {} | {} | {} |\n",
            k.scenario.as_deref().unwrap_or("all"),
            k.driver,
            k.selector,
            k.delay_ms,
            k.control_period_ms,
            k.vehicles,
            k.pedestrians,
            r.runs,
            r.success_pct,
            r.success_ci.0,
            r.success_ci.1,
            r.collision_pct,
            r.collision_ci.0,
            r.collision_ci.1,
            pm(r.completion),
            pm(r.driving_score),
            pm(r.lane_crossings),
            pm(r.red_lights),
            r.red_lights_total
        );
    }
    s
}

/// The aggregate table as CSV, one column per key field.
pub fn summary_csv(rows: &[SummaryRow]) -> Result<String, SweepError> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "scenario",
        "driver",
        "selector",
        "delay_ms",
        "control_period_ms",
        "vehicles",
        "pedestrians",
        "runs",
        "success_pct",
        "success_ci_low",
        "success_ci_high",
        "collision_pct",
        "collision_ci_low",
        "collision_ci_high",
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
    ])?;
    for r in rows {
        let f = |v: f64| format!("{v:.4}");
        let k = &r.key;
        w.write_record([
            k.scenario.clone().unwrap_or_default(),
            k.driver.clone(),
            k.selector.clone(),
            k.delay_ms.to_string(),
            k.control_period_ms.to_string(),
            k.vehicles.to_string(),
            k.pedestrians.to_string(),
            r.runs.to_string(),
            f(r.success_pct),
            f(r.success_ci.0),
            f(r.success_ci.1),
            f(r.collision_pct),
            f(r.collision_ci.0),
            f(r.collision_ci.1),
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
        ])?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| SweepError::Csv(e.into_error().into()))?;
    Ok(String::from_utf8(bytes).expect("CSV of UTF-8 fields is UTF-8"))
}

/// A sweep folder's tables.
#[derive(Debug, Clone, PartialEq)]
pub struct Tables {
    /// Records read.
    pub records: usize,
    /// Rows across scenarios ([`GroupKey::of`]).
    pub summary: Vec<SummaryRow>,
    /// Rows per scenario ([`GroupKey::with_scenario`]).
    pub detail: Vec<SummaryRow>,
}

/// Reads a sweep folder's records and writes its tables beside them:
/// `summary.md` (both tables), `summary.csv` and `detail.csv`.
pub fn write_tables(dir: &SweepDir) -> Result<Tables, SweepError> {
    let records = read_records(dir)?;
    let tables = Tables {
        records: records.len(),
        summary: summarise(&records, GroupKey::of),
        detail: summarise(&records, GroupKey::with_scenario),
    };
    let md = format!(
        "# Sweep summary ({} runs)\n\n## Across scenarios\n\n{}\n## By scenario\n\n{}",
        tables.records,
        summary_markdown(&tables.summary),
        summary_markdown(&tables.detail)
    );
    let write = |name: &str, text: &str| {
        let path = dir.root.join(name);
        std::fs::write(&path, text).map_err(|e| SweepError::io("write", path, e))
    };
    write("summary.md", &md)?;
    write("summary.csv", &summary_csv(&tables.summary)?)?;
    write("detail.csv", &summary_csv(&tables.detail)?)?;
    Ok(tables)
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{fake_record, plan};
    use super::*;
    use crate::selector::{Oracle, ResolutionSelector};

    #[test]
    fn summary_aggregates_groups() {
        let p = plan();
        let records: Vec<RunRecord> = p.runs.iter().map(fake_record).collect();
        let rows = summarise(&records, GroupKey::of);
        // Delay x scale x density; scenarios and seeds merge.
        assert_eq!(rows.len(), 8);
        let d100 = rows
            .iter()
            .find(|r| {
                r.key.delay_ms == 100.0 && r.key.vehicles == 5 && r.key.selector == "Some(1.0)"
            })
            .unwrap();
        assert_eq!(d100.runs, 4);
        assert_eq!(d100.red_lights, (2.0, 0.0));
        assert_eq!(d100.red_lights_total, 8);
        assert_eq!(d100.success_pct, 50.0);
        // 2 of 4: Wilson's 95 % interval, [15.0, 85.0] %.
        assert!((d100.success_ci.0 - 15.0).abs() < 0.1 && (d100.success_ci.1 - 85.0).abs() < 0.1);
        let md = summary_markdown(&rows);
        assert!(
            md.contains("| all | expert | Some(1.0) | 100 | 50 | 5:10 | 4 | 50.00 [15, 85] |"),
            "{md}"
        );
        let csv = summary_csv(&rows).unwrap();
        assert_eq!(csv.lines().count(), 9);
        assert!(csv.lines().nth(1).unwrap().starts_with(",expert,"), "{csv}");
        assert_eq!(mean_sd(&[1.0, 2.0, 3.0]), (2.0, 1.0));
        // Per scenario, the fake records' scenario names are their keys: one row each seed pair.
        let detail = summarise(&records, GroupKey::with_scenario);
        assert_eq!(detail.len(), records.len());
    }

    #[test]
    fn drivers_selector_parameters_and_periods_get_rows_of_their_own() {
        let base = fake_record(&plan().runs[0]);
        let with = |f: &dyn Fn(&mut RunRecord)| {
            let mut r = base.clone();
            f(&mut r);
            r
        };
        let oracle = |enter_m: f32| {
            Oracle {
                enter_m,
                ..Oracle::default()
            }
            .name()
        };
        let records = vec![
            with(&|r| r.result.settings.resolution = oracle(5.0)),
            with(&|r| r.result.settings.resolution = oracle(5.0)),
            with(&|r| r.result.settings.resolution = oracle(8.0)),
            with(&|r| {
                r.result.settings.resolution = oracle(5.0);
                r.result.provenance.driver = "policy:models/a.safetensors (cpu, fused)".into();
            }),
            with(&|r| {
                r.result.settings.resolution = oracle(5.0);
                r.result.settings.control_period_ms = 100.0;
            }),
        ];
        let rows = summarise(&records, GroupKey::of);
        let runs: Vec<(String, String, f64, usize)> = rows
            .iter()
            .map(|r| {
                (
                    r.key.driver.clone(),
                    r.key.selector.clone(),
                    r.key.control_period_ms,
                    r.runs,
                )
            })
            .collect();
        assert_eq!(
            runs,
            vec![
                ("expert".into(), oracle(5.0), 50.0, 2),
                ("expert".into(), oracle(5.0), 100.0, 1),
                ("expert".into(), oracle(8.0), 50.0, 1),
                (
                    "policy:models/a.safetensors (cpu, fused)".into(),
                    oracle(5.0),
                    50.0,
                    1
                ),
            ]
        );
    }

    #[test]
    fn tables_are_written_beside_the_records() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = SweepDir {
            root: tmp.path().to_path_buf(),
        };
        let p = plan();
        dir.prepare(&p).unwrap();
        let all: Vec<_> = p.runs.iter().collect();
        super::super::execute(
            &dir,
            &all[..4],
            1,
            |s| Ok::<_, String>(fake_record(s)),
            |_, _| {},
        );
        let t = write_tables(&dir).unwrap();
        assert_eq!(t.records, 4);
        let md = std::fs::read_to_string(tmp.path().join("summary.md")).unwrap();
        assert!(md.starts_with("# Sweep summary (4 runs)"), "{md}");
        for f in ["summary.csv", "detail.csv"] {
            assert!(tmp.path().join(f).is_file(), "{f}");
        }
    }
}
