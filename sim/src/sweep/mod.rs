//! Sweeps: the cross product of scenarios, delays, scales, densities and
//! seeds, run in parallel, one record file per run, and the tables that
//! aggregate them.
//!
//! A sweep folder holds `plan.json` (every run of the sweep, in a fixed
//! order) and `runs/KEY.json` (one record per finished run, written
//! atomically). Running a sweep again into the same folder skips every run
//! whose record exists, so a killed sweep resumes without redoing or losing a
//! finished run. `--shard i/n` runs every n-th run of the plan, starting at
//! i, so n machines (a Slurm array, a Kubernetes Indexed Job) share one
//! sweep; [`merge`] joins their folders and checks that no run is missing.
//!
//! - [`plan`]: the runs ([`RunSpec`], [`SweepPlan`]), shards, and the seed and
//!   density lists of the command line.
//! - [`folder`]: the folder layout ([`SweepDir`]) and reading its records.
//! - [`execute`]: running the runs that are not done yet.
//! - [`merge`]: joining shard folders.
//! - [`tables`]: grouping records by a typed [`GroupKey`] and the statistics
//!   of each group, as Markdown and CSV.
//! - [`error`]: what can go wrong ([`SweepError`]).

pub mod cluster;
pub mod error;
pub mod exact;
pub mod execute;
pub mod folder;
pub mod merge;
pub mod paired_binary;
pub mod plan;
pub mod stats;
pub mod tables;

pub use error::SweepError;
pub use execute::{SweepOutcome, execute, run_spec};
pub use folder::{SweepDir, read_records};
pub use merge::merge;
pub use plan::{RunSpec, SweepPlan, parse_density, parse_seeds, parse_shard};
pub use tables::{GroupKey, SummaryRow, Tables, mean_sd, summarise, write_tables};

#[cfg(test)]
pub(crate) mod fixtures {
    //! Records that stand in for runs in the sweep tests.

    use std::collections::BTreeMap;

    use super::{RunSpec, SweepPlan};
    use crate::monitors::{Infraction, InfractionKind};
    use crate::record::*;

    /// A record whose counts are a function of the spec, standing in for a run.
    pub fn fake_record(spec: &RunSpec) -> RunRecord {
        let mut infractions = Vec::new();
        for _ in 0..(spec.delay_ms.unwrap_or(0.0) as u64 / 50) {
            infractions.push(Infraction {
                tick: 1,
                time_s: 0.025,
                kind: InfractionKind::RedLight,
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
                    render_fingerprint: None,
                    cpu: None,
                    checkpoint: None,
                    trigger: None,
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
                    walkers_sent: 0,
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
                collisions: Default::default(),
                contacts: Vec::new(),
                trace: Vec::new(),
            },
            perf: RunPerf::default(),
        }
    }

    /// 2 scenarios x 2 delays x 2 scales x 2 densities x 2 seeds.
    pub fn plan() -> SweepPlan {
        SweepPlan::cross(
            &["a.toml".into(), "b.toml".into()],
            &[Some(0.0), Some(100.0)],
            &[Some(0.75), Some(1.0)],
            &[Some((0, 0)), Some((5, 10))],
            &[1, 2],
        )
    }
}
