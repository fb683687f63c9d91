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
    for tick in 0..ticks {
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
    }
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
}
