//! Traffic soak runs and the realised-count table (the paper's Table I).
//!
//! [`soak`] runs a town with NPCs and pedestrians (no ego, no camera) for a
//! number of simulated minutes and reports what the issue asks: collisions
//! among NPCs, red lights run by NPCs, deadlocks (an NPC stopped for more
//! than 60 s), pedestrians alive and the tick rate of physics plus
//! behaviours. [`table_one`] spawns each density for several seeds and
//! reports the realised counts as mean and standard deviation.

use crate::map::town::{LightState, Town};
use crate::traffic::{EgoStart, Incident, Traffic, TrafficConfig, TrafficStats};
use std::sync::Arc;
use std::time::Instant;

/// What a soak run measured.
#[derive(Debug, Clone, PartialEq)]
pub struct SoakReport {
    /// NPC vehicles requested and realised.
    pub vehicles: (usize, usize),
    /// Pedestrians requested and realised.
    pub pedestrians: (usize, usize),
    /// Pedestrians present at the end (they never despawn; reported as the issue asks).
    pub pedestrians_alive: usize,
    /// Ticks simulated.
    pub ticks: u64,
    /// Simulated time (seconds).
    pub sim_s: f64,
    /// Wall time spent in `Traffic::step` (seconds).
    pub step_wall_s: f64,
    /// Ticks per wall second of `Traffic::step` (physics + behaviours).
    pub ticks_per_s: f64,
    /// CPU time of the stepping thread over the run (seconds; Linux only, None elsewhere).
    pub cpu_s: Option<f64>,
    /// The counters (collisions, red runs, deadlocks, respawns).
    pub stats: TrafficStats,
    /// The first incidents of each kind ([`crate::traffic::incidents`]).
    pub incidents: Vec<Incident>,
    /// The process's resident memory after the first simulated minute and at
    /// the end (KiB; Linux only, None elsewhere): flat when nothing grows.
    pub rss_kib: Option<(u64, u64)>,
}

impl SoakReport {
    /// The report as `mrdrive traffic soak` prints it, one figure a line;
    /// with `incidents`, the incidents listed after it.
    pub fn text(&self, incidents: bool) -> String {
        use std::fmt::Write;
        let mut out = String::new();
        let s = &self.stats;
        let lines: [(&str, String); 14] = [
            (
                "realised vehicles",
                format!("{} / {}", self.vehicles.1, self.vehicles.0),
            ),
            (
                "realised pedestrians",
                format!("{} / {}", self.pedestrians.1, self.pedestrians.0),
            ),
            (
                "simulated",
                format!("{:.0} s ({} ticks)", self.sim_s, self.ticks),
            ),
            ("NPC-NPC collisions", s.npc_npc_collisions.to_string()),
            ("red lights run by NPCs", s.npc_red_runs.to_string()),
            ("deadlocks (stuck > 60s)", s.deadlocks.to_string()),
            ("pedestrians alive", self.pedestrians_alive.to_string()),
            (
                "NPCs into pedestrians",
                s.npc_pedestrian_collisions.to_string(),
            ),
            (
                "pedestrians into cars",
                s.pedestrian_vehicle_bumps.to_string(),
            ),
            ("NPC-static contacts", s.npc_static_collisions.to_string()),
            (
                "NPC respawns",
                format!(
                    "{} ({} stopped 90 s, {} stopped 180 s at a red light, {} off their path)",
                    s.respawns(),
                    s.respawns_blocked,
                    s.respawns_blocked_at_red,
                    s.respawns_off_path
                ),
            ),
            (
                "gridlock moves",
                format!("{} cars let move", s.gridlocks_broken),
            ),
            (
                "NPC lane changes",
                format!(
                    "{} made, {} given up",
                    s.lane_changes, s.lane_changes_given_up
                ),
            ),
            ("step wall time", format!("{:.2} s", self.step_wall_s)),
        ];
        for (name, value) in lines {
            let _ = writeln!(out, "{name:<23} {value}");
        }
        let _ = writeln!(
            out,
            "ticks/s                 {:.0} per wall second of stepping (physics + behaviours, one thread)",
            self.ticks_per_s
        );
        if let Some((first, last)) = self.rss_kib {
            let _ = writeln!(
                out,
                "resident memory         {:.1} MiB after the first minute, {:.1} MiB at the end",
                first as f64 / 1024.0,
                last as f64 / 1024.0
            );
        }
        if let Some(cpu) = self.cpu_s.filter(|&c| c > 0.0) {
            let _ = writeln!(
                out,
                "ticks per CPU second    {:.0} ({cpu:.2} s of CPU for the soak loop; differs from wall when cores are shared)",
                self.ticks as f64 / cpu
            );
        }
        if incidents {
            let _ = writeln!(
                out,
                "incidents               {} listed",
                self.incidents.len()
            );
            for i in &self.incidents {
                let _ = writeln!(out, "  {i}");
            }
        }
        out
    }
}

/// Runs `minutes` of simulated time; `lights(tick, out)` fills the light states for a tick.
pub fn soak(
    town: Arc<Town>,
    cfg: TrafficConfig,
    minutes: f64,
    lights: &mut dyn FnMut(u64, &mut Vec<LightState>),
) -> SoakReport {
    let mut traffic = Traffic::new(town, cfg.clone(), None);
    let tick_s = f64::from(cfg.tick_s);
    let ticks = (minutes * 60.0 / tick_s).round() as u64;
    let mut states = Vec::new();
    let mut wall = 0.0f64;
    let cpu0 = thread_cpu_s();
    let first_minute = (60.0 / tick_s).round() as u64;
    let mut rss_first = None;
    for tick in 0..ticks {
        if tick == first_minute.min(ticks.saturating_sub(1)) {
            rss_first = resident_kib();
        }
        lights(tick, &mut states);
        let t0 = Instant::now();
        traffic.step(&states);
        wall += t0.elapsed().as_secs_f64();
    }
    let cpu_s = thread_cpu_s().zip(cpu0).map(|(b, a)| b - a);
    SoakReport {
        vehicles: (cfg.vehicles, traffic.realised_vehicles()),
        pedestrians: (cfg.pedestrians, traffic.realised_pedestrians()),
        pedestrians_alive: traffic.pedestrians().len(),
        ticks,
        sim_s: ticks as f64 * tick_s,
        step_wall_s: wall,
        ticks_per_s: if wall > 0.0 { ticks as f64 / wall } else { 0.0 },
        cpu_s,
        stats: traffic.stats(),
        incidents: traffic.incidents().to_vec(),
        rss_kib: rss_first.zip(resident_kib()),
    }
}

/// The process's resident memory (KiB), from Linux's `/proc/self/status`.
fn resident_kib() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = text.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// CPU time this thread has run (seconds), from Linux's `/proc/thread-self/schedstat`.
fn thread_cpu_s() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

/// A mean and a (sample) standard deviation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanSd {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (0 for fewer than two samples).
    pub sd: f64,
}

impl MeanSd {
    /// Mean and sample standard deviation of some values.
    pub fn of(xs: &[f64]) -> MeanSd {
        let n = xs.len() as f64;
        if xs.is_empty() {
            return MeanSd { mean: 0.0, sd: 0.0 };
        }
        let mean = xs.iter().sum::<f64>() / n;
        let sd = if xs.len() < 2 {
            0.0
        } else {
            (xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0)).sqrt()
        };
        MeanSd { mean, sd }
    }
}

/// One row of Table I: a requested density and what was realised over the seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct TableOneRow {
    /// (vehicles, pedestrians) requested.
    pub requested: (usize, usize),
    /// Realised vehicles over the seeds.
    pub vehicles: MeanSd,
    /// Realised pedestrians over the seeds.
    pub pedestrians: MeanSd,
    /// Number of seeds (resets).
    pub resets: usize,
}

/// Spawns each density once per seed (with the ego at `ego`, if given) and summarises the realised counts.
pub fn table_one(
    town: Arc<Town>,
    base: &TrafficConfig,
    ego: Option<EgoStart>,
    densities: &[(usize, usize)],
    seeds: &[u64],
) -> Vec<TableOneRow> {
    densities
        .iter()
        .map(|&(v, p)| {
            let mut vs = Vec::new();
            let mut ps = Vec::new();
            for &seed in seeds {
                let cfg = TrafficConfig {
                    vehicles: v,
                    pedestrians: p,
                    seed,
                    ..base.clone()
                };
                let t = Traffic::new(town.clone(), cfg, ego);
                vs.push(t.realised_vehicles() as f64);
                ps.push(t.realised_pedestrians() as f64);
            }
            TableOneRow {
                requested: (v, p),
                vehicles: MeanSd::of(&vs),
                pedestrians: MeanSd::of(&ps),
                resets: seeds.len(),
            }
        })
        .collect()
}

/// Table I as text: a row per density, realised counts as mean +- sd.
pub fn table_one_text(town: &str, resets: usize, rows: &[TableOneRow]) -> String {
    use std::fmt::Write;
    let mut out = format!("Table I on {town} ({resets} resets per density)\n");
    let _ = writeln!(
        out,
        "{:>12} {:>16} {:>16}",
        "requested", "vehicles", "pedestrians"
    );
    for r in rows {
        let _ = writeln!(
            out,
            "{:>12} {:>9.1} +- {:<4.1} {:>9.1} +- {:<4.1}",
            format!("({}, {})", r.requested.0, r.requested.1),
            r.vehicles.mean,
            r.vehicles.sd,
            r.pedestrians.mean,
            r.pedestrians.sd
        );
    }
    out
}

/// Table I as the paper lays it out: a column per route (`columns[k]` is
/// route `ids[k]`'s rows, the ego at its start), a row per density.
pub fn table_per_route_text(
    town: &str,
    resets: usize,
    ids: &[String],
    columns: &[Vec<TableOneRow>],
) -> String {
    use std::fmt::Write;
    let mut out =
        format!("Table I on {town} ({resets} resets per density; vehicles, pedestrians)\n");
    let _ = write!(out, "{:>10}", "target");
    for id in ids {
        let _ = write!(out, " | route {id:<22}");
    }
    out.push('\n');
    for (row, first) in columns.first().into_iter().flatten().enumerate() {
        let _ = write!(
            out,
            "{:>10}",
            format!("({}, {})", first.requested.0, first.requested.1)
        );
        for col in columns {
            let r = &col[row];
            let _ = write!(
                out,
                " | {:>4.1} +- {:<3.1}  {:>4.1} +- {:<3.1}",
                r.vehicles.mean, r.vehicles.sd, r.pedestrians.mean, r.pedestrians.sd
            );
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_sd_matches_hand_computation() {
        let m = MeanSd::of(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]);
        assert!((m.mean - 5.0).abs() < 1e-12);
        assert!((m.sd - (32.0f64 / 7.0).sqrt()).abs() < 1e-12);
        assert_eq!(MeanSd::of(&[3.0]).sd, 0.0);
    }

    #[test]
    fn the_tables_have_a_row_per_density() {
        let row = |v: usize, mean: f64| TableOneRow {
            requested: (v, 2 * v),
            vehicles: MeanSd { mean, sd: 0.5 },
            pedestrians: MeanSd {
                mean: 2.0 * mean,
                sd: 1.0,
            },
            resets: 3,
        };
        let rows = vec![row(0, 0.0), row(5, 4.5)];
        let one = table_one_text("T", 3, &rows);
        assert_eq!(
            one.lines().nth(3).unwrap(),
            "     (5, 10)       4.5 +- 0.5        9.0 +- 1.0 "
        );
        let per = table_per_route_text("T", 3, &["0".into(), "1".into()], &[rows.clone(), rows]);
        let lines: Vec<&str> = per.lines().collect();
        assert_eq!(lines.len(), 4, "{per}");
        assert!(
            lines[1].ends_with("| route 1                     "),
            "{per}"
        );
        assert_eq!(lines[3].matches("4.5 +- 0.5").count(), 2, "{per}");
    }
}
