//! The result record of one run: everything a table or a plot needs, and
//! where it came from.
//!
//! A record has a deterministic part ([`RunResult`]: counts, completion,
//! the scenario and build it came from), identical for two runs of the same
//! scenario, seed, build and render backend, and a [`RunPerf`] part with
//! wall-clock timings, which is not.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::monitors::contacts::Touch;
use crate::monitors::counting::{CollisionCounts, CountingRule, collision_kind};
use crate::monitors::{Infraction, InfractionKind};

/// One run's record, as written by `mrdrive run --json` and by sweeps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRecord {
    /// What happened (deterministic).
    pub result: RunResult,
    /// How long it took (wall clock; differs run to run).
    pub perf: RunPerf,
}

/// The deterministic outcome of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunResult {
    /// Where the run came from.
    pub provenance: Provenance,
    /// The run's settings after command-line overrides.
    pub settings: RunSettings,
    /// Realised traffic.
    pub traffic: RealisedTraffic,
    /// Route completion (percent).
    pub completion_pct: f64,
    /// >= 99 % completion and within 10 m of the final route point.
    pub success: bool,
    /// Leaderboard-1.0 driving score (percent), its collisions counted by
    /// leaderboard 1.0's rule.
    pub driving_score: f64,
    /// Share of the route progress made outside the driving lanes or against them
    /// (percent; the leaderboard's `OutsideRouteLanesTest`, `monitors::outside_lane`).
    pub outside_lane_pct: f64,
    /// Number of infractions of each kind (every kind listed, zeros included);
    /// collisions as the paper's scorer counts them (`monitors::counting::paper`).
    pub counts: BTreeMap<InfractionKind, u32>,
    /// What ended the run early, if anything.
    pub termination: Option<InfractionKind>,
    /// Route length (metres).
    pub route_length_m: f64,
    /// Simulated time (seconds).
    pub sim_time_s: f64,
    /// Ticks simulated.
    pub ticks: u64,
    /// Share of control boundaries at each input scale, keyed like "0.75".
    pub scale_share: BTreeMap<String, f64>,
    /// The largest latency in force during the run (milliseconds).
    pub max_latency_ms: f64,
    /// Every infraction, in order (collisions under the `paper` rule).
    pub infractions: Vec<Infraction>,
    /// Collisions under each named counting rule (`paper`, `leaderboard-1.0`;
    /// `monitors::counting`). Empty (and left out of the JSON) in records made
    /// before it.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub collisions: BTreeMap<String, CollisionCounts>,
    /// Every contact of the ego, kerbs included (`monitors::contacts`): any
    /// counting rule can be applied to them afterwards. Left out of the JSON
    /// when there was none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub contacts: Vec<Touch>,
    /// Where the ego was, every [`TRACE_EVERY_S`] of simulated time and at the end:
    /// `[time (s), x (m), y (m), input scale in force]`, positions to the centimetre.
    /// What a picture of the run draws (`sim::picture`). Empty (and left out of the
    /// JSON) in records made before it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub trace: Vec<[f64; 4]>,
}

/// The collisions of a run's touches under every named rule, keyed by the rule's name.
pub fn collisions_by_rule(touches: &[Touch]) -> BTreeMap<String, CollisionCounts> {
    CountingRule::ALL
        .into_iter()
        .map(|r| (r.name().to_string(), r.count(touches)))
        .collect()
}

/// The kinds of a run's infractions with its collisions counted by leaderboard
/// 1.0's rule instead of the paper's: what leaderboard 1.0's driving score reads.
pub fn leaderboard_kinds<'a>(
    infractions: &'a [Infraction],
    touches: &'a [Touch],
) -> impl Iterator<Item = InfractionKind> + 'a {
    let collisions = CountingRule::Leaderboard1
        .counted(touches)
        .into_iter()
        .map(|i| collision_kind(&touches[i]));
    infractions
        .iter()
        .map(|i| i.kind)
        .filter(|k| !k.is_collision())
        .chain(collisions)
}

/// Simulated seconds between two points of a record's trace ([`RunResult::trace`]).
pub const TRACE_EVERY_S: f64 = 0.5;

/// A trace point: time (s), position to the centimetre (m), scale.
pub fn trace_point(time_s: f64, position: [f32; 2], scale: f64) -> [f64; 4] {
    let cm = |v: f32| (f64::from(v) * 100.0).round() / 100.0;
    [time_s, cm(position[0]), cm(position[1]), scale]
}

/// Where a record came from: enough to rerun it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The scenario's name.
    pub scenario: String,
    /// The scenario file as given.
    pub scenario_file: String,
    /// The map file.
    pub map: String,
    /// The route file and id.
    pub route: String,
    /// The driver's name (and checkpoint for a policy).
    pub driver: String,
    /// mrdrive's version and git commit.
    pub build: String,
    /// The render backend and adapter, or "none" if nothing was rendered.
    pub render_backend: String,
    /// The CPU that made the run: its model name as the OS reports it. `None` where the
    /// OS does not say, and in records made before the field existed (then left out of
    /// the JSON).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cpu: Option<String>,
    /// For a run that rendered, what this machine's renderer draws: the first 16 hex
    /// digits of `mrdrive render fingerprint`'s digest (fixed frames, rendered once per
    /// process). Records with different fingerprints were drawn differently and are
    /// never merged into one sweep. `None` for runs that drew nothing and in records
    /// from before the field existed (then left out of the JSON).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub render_fingerprint: Option<String>,
    /// A policy's checkpoint file and the digest of its bytes, so that a
    /// resumed sweep never mixes the runs of two checkpoints saved under one
    /// name; `None` for the expert (and left out of the JSON).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint: Option<CheckpointId>,
    /// A policy's learned trigger (the `learned` selector's head) and the
    /// digest of its file, for the same reason; `None` without one (and
    /// left out of the JSON).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trigger: Option<CheckpointId>,
}

impl Provenance {
    /// The model files that drove the run, each with its digest: the
    /// checkpoint, then the trigger.
    pub fn model_files(&self) -> impl Iterator<Item = &CheckpointId> {
        self.checkpoint.iter().chain(&self.trigger)
    }
}

/// A model file that drove a run (a checkpoint, or a learned trigger): the
/// file as the driver opened it and the SHA-256 of its bytes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CheckpointId {
    /// The file (`.safetensors` weights, or a `.trigger.json`) as the driver opened it.
    pub file: String,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub sha256: String,
}

impl CheckpointId {
    /// Reads and digests a checkpoint file.
    pub fn of(file: &Path) -> std::io::Result<Self> {
        Ok(Self::of_bytes(file, &std::fs::read(file)?))
    }

    /// The id of `file` whose bytes are `bytes` (already read by the caller).
    pub fn of_bytes(file: &Path, bytes: &[u8]) -> Self {
        Self {
            file: file.display().to_string(),
            sha256: sha256_hex(bytes),
        }
    }

    /// The first 12 hex digits, for pages and messages.
    pub fn short(&self) -> &str {
        &self.sha256[..self.sha256.len().min(12)]
    }
}

/// SHA-256 of some bytes, lower-case hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The settings a run used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSettings {
    /// The traffic seed.
    pub seed: u64,
    /// Injected delay D (milliseconds).
    pub delay_ms: f64,
    /// Control period Tc (milliseconds).
    pub control_period_ms: f64,
    /// The selector with its parameters ([`crate::selector::ResolutionSelector::name`]:
    /// "fixed-1", "oracle-0.75/1-5/15m", ...).
    pub resolution: String,
    /// Target NPC vehicles.
    pub vehicles: u32,
    /// Target pedestrians.
    pub pedestrians: u32,
}

/// The traffic a run actually had.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RealisedTraffic {
    /// NPC vehicles spawned.
    pub vehicles: u32,
    /// Pedestrians spawned.
    pub pedestrians: u32,
    /// Walkers sent across the road ahead of the ego
    /// (`traffic.ego_crossings_per_min`; left out of the JSON when 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub walkers_sent: u32,
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

/// Wall-clock figures of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct RunPerf {
    /// Whole run (seconds).
    pub wall_s: f64,
    /// Simulated seconds per wall second.
    pub real_time_factor: f64,
    /// Time in NPC and pedestrian behaviours and physics (seconds).
    pub traffic_s: f64,
    /// Time rendering the camera (seconds).
    pub render_s: f64,
    /// Time in the driver (seconds).
    pub driver_s: f64,
    /// Time in lights, monitors and recording (seconds).
    pub other_s: f64,
}

impl RunRecord {
    /// The run's result as a small table, one line a figure (`mrdrive run`):
    /// scenario, driver, delay, traffic, result, infractions and the time split.
    pub fn table(&self) -> String {
        use std::fmt::Write;
        let r = &self.result;
        let p = &self.perf;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "scenario      {} ({})",
            r.provenance.scenario, r.provenance.route
        );
        let _ = writeln!(
            out,
            "driver        {}   resolution {}",
            r.provenance.driver, r.settings.resolution
        );
        if r.provenance.render_backend != "none" {
            let _ = writeln!(out, "camera        {}", r.provenance.render_backend);
        }
        let _ = writeln!(
            out,
            "delay         {} ms (max latency in force {} ms)",
            r.settings.delay_ms, r.max_latency_ms
        );
        let _ = writeln!(
            out,
            "traffic       {} vehicles, {} pedestrians (asked {}, {}), seed {}",
            r.traffic.vehicles,
            r.traffic.pedestrians,
            r.settings.vehicles,
            r.settings.pedestrians,
            r.settings.seed
        );
        let _ = writeln!(
            out,
            "result        {}  completion {:.1} % of {:.0} m  driving score {:.1}",
            if r.success { "SUCCESS" } else { "FAILURE" },
            r.completion_pct,
            r.route_length_m,
            r.driving_score
        );
        let _ = writeln!(
            out,
            "outside lanes {:.1} % of the route (on a sidewalk or against the lane)",
            r.outside_lane_pct
        );
        if let Some(t) = r.termination {
            let _ = writeln!(out, "ended by      {}", t.name());
        }
        let _ = writeln!(
            out,
            "infractions   (collisions as the paper's scorer counts them)"
        );
        for (kind, n) in &r.counts {
            if !kind.terminates() || *n > 0 {
                let _ = writeln!(out, "  {:<22} {n}", kind.name());
            }
        }
        if !r.collisions.is_empty() {
            let _ = writeln!(
                out,
                "collisions    by rule (pedestrian / vehicle / static), from {} contacts recorded",
                r.contacts.len()
            );
            for (rule, c) in &r.collisions {
                let _ = writeln!(
                    out,
                    "  {rule:<22} {} / {} / {}",
                    c.pedestrian, c.vehicle, c.static_
                );
            }
        }
        let _ = writeln!(
            out,
            "time          {:.1} s simulated in {:.2} s wall ({:.0}x real time): traffic {:.2} s, render {:.2} s, driver {:.2} s, other {:.2} s",
            r.sim_time_s,
            p.wall_s,
            p.real_time_factor,
            p.traffic_s,
            p.render_s,
            p.driver_s,
            p.other_s
        );
        out
    }
}

impl RunResult {
    /// The count of one infraction kind.
    pub fn count(&self, kind: InfractionKind) -> u32 {
        self.counts.get(&kind).copied().unwrap_or(0)
    }

    /// All collisions, whatever the other actor.
    pub fn collisions(&self) -> u32 {
        self.count(InfractionKind::CollisionVehicle)
            + self.count(InfractionKind::CollisionPedestrian)
            + self.count(InfractionKind::CollisionStatic)
    }

    /// This result with its collision counts ([`RunResult::counts`], which
    /// `collisions()` sums) as `rule` counts them, taken from the record's own
    /// per-rule counts (its `collisions` field); everything else, the
    /// infraction list included, as it was. `None` for a record made before
    /// records counted by rule.
    pub fn counted_by(&self, rule: CountingRule) -> Option<RunResult> {
        let c = self.collisions.get(rule.name())?;
        let mut r = self.clone();
        r.counts.insert(InfractionKind::CollisionVehicle, c.vehicle);
        r.counts
            .insert(InfractionKind::CollisionPedestrian, c.pedestrian);
        r.counts.insert(InfractionKind::CollisionStatic, c.static_);
        Some(r)
    }
}

/// Counts infractions by kind, listing every kind (zeros included).
pub fn count_by_kind(infractions: &[Infraction]) -> BTreeMap<InfractionKind, u32> {
    let mut counts: BTreeMap<InfractionKind, u32> =
        InfractionKind::ALL.into_iter().map(|k| (k, 0)).collect();
    for i in infractions {
        *counts.entry(i.kind).or_default() += 1;
    }
    counts
}

/// Writes `record` as pretty JSON to `path` atomically: a reader (or a
/// resumed sweep) sees either the whole record or none.
pub fn write_atomically(path: &Path, record: &RunRecord) -> std::io::Result<()> {
    let text = serde_json::to_string_pretty(record).map_err(std::io::Error::other)?;
    let tmp = path.with_extension("json.partial");
    std::fs::write(&tmp, text + "\n")?;
    std::fs::rename(&tmp, path)
}

/// A record file could not be read back.
#[derive(Debug, thiserror::Error)]
pub enum ReadRecordError {
    /// The file could not be read.
    #[error("cannot read {path}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a record of this version.
    #[error("{path} is not a run record; fix: delete it and run again to redo that run")]
    Json {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        #[source]
        source: serde_json::Error,
    },
}

/// Reads a record written by [`write_atomically`].
pub fn read(path: &Path) -> Result<RunRecord, ReadRecordError> {
    let text = std::fs::read_to_string(path).map_err(|source| ReadRecordError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    serde_json::from_str(&text).map_err(|source| ReadRecordError::Json {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_digest_is_sha256() {
        // FIPS 180-2's test vector for "abc".
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        let id = CheckpointId {
            file: "m.safetensors".into(),
            sha256: sha256_hex(b"abc"),
        };
        assert_eq!(id.short(), "ba7816bf8f01");
    }

    #[test]
    fn the_table_lists_the_result_and_every_non_terminating_kind() {
        let spec = crate::sweep::RunSpec {
            scenario: "a.toml".into(),
            delay_ms: Some(100.0),
            scale: None,
            density: None,
            seed: 0,
            driver: None,
        };
        let table = crate::sweep::fixtures::fake_record(&spec).table();
        assert!(table.starts_with("scenario      a__d100"), "{table}");
        assert!(
            table.contains("result        SUCCESS  completion 100.0 % of 100 m"),
            "{table}"
        );
        assert!(table.contains("  red_light              2\n"), "{table}");
        assert!(!table.contains("ended by"), "{table}");
        assert!(table.ends_with("other 0.00 s\n"), "{table}");
        // A kerb mount: a static collision for the paper, none for leaderboard 1.0.
        let mut record = crate::sweep::fixtures::fake_record(&spec);
        record.result.contacts = vec![Touch {
            tick: 10,
            time_s: 0.25,
            with: crate::monitors::contacts::TouchWith::Kerb,
            actor: None,
            what: "kerb up".into(),
            position: [1.0, 2.0],
            speed_mps: 3.0,
            repeat: false,
            kerb: None,
            left_tick: None,
        }];
        record.result.collisions = collisions_by_rule(&record.result.contacts);
        let table = record.table();
        assert!(table.contains("from 1 contacts recorded\n"), "{table}");
        assert!(
            table.contains("  paper                  0 / 0 / 1\n"),
            "{table}"
        );
        assert!(
            table.contains("  leaderboard-1.0        0 / 0 / 0\n"),
            "{table}"
        );
    }

    #[test]
    fn a_result_counted_by_a_rule_takes_that_rules_collisions() {
        let spec = crate::sweep::RunSpec {
            scenario: "a.toml".into(),
            delay_ms: None,
            scale: None,
            density: None,
            seed: 0,
            driver: None,
        };
        let mut result = crate::sweep::fixtures::fake_record(&spec).result;
        // A record from before the counting rules: no rule can count it again.
        result.collisions.clear();
        assert_eq!(result.counted_by(CountingRule::Leaderboard1), None);
        // A kerb mount and a car: the paper counts both, leaderboard 1.0 the car.
        use crate::monitors::contacts::TouchWith;
        let touch = |with, what: &str, tick| Touch {
            tick,
            time_s: tick as f64 / 20.0,
            with,
            actor: (with == TouchWith::Vehicle).then_some(7),
            what: what.into(),
            position: [tick as f32 * 10.0, 0.0],
            speed_mps: 3.0,
            repeat: false,
            kerb: None,
            left_tick: None,
        };
        result.contacts = vec![
            touch(TouchWith::Kerb, "kerb up", 10),
            touch(TouchWith::Vehicle, "vehicle", 100),
        ];
        result.collisions = collisions_by_rule(&result.contacts);
        let paper = result.counted_by(CountingRule::Paper).unwrap();
        let lb = result.counted_by(CountingRule::Leaderboard1).unwrap();
        assert_eq!((paper.collisions(), lb.collisions()), (2, 1));
        assert_eq!(paper.count(InfractionKind::CollisionStatic), 1);
        assert_eq!(lb.count(InfractionKind::CollisionStatic), 0);
        assert_eq!(lb.count(InfractionKind::CollisionVehicle), 1);
        // Nothing else moves.
        assert_eq!(
            lb.count(InfractionKind::RedLight),
            result.count(InfractionKind::RedLight)
        );
        assert_eq!(
            (lb.success, &lb.infractions),
            (result.success, &result.infractions)
        );
    }
}
