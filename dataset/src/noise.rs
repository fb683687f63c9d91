//! The expert with noise: the driver of data collection.
//!
//! Left alone, the expert keeps to the lane centre at its target speed, so a
//! policy that learned only from it would never see how to come back. So, as
//! in DAgger-style collection, perturbations are injected at random moments:
//! with a mean gap of `mean_gap_s` seconds, a perturbation lasts 0.25-1.0 s
//! (uniform) and is one of
//!
//! - a steering offset of ±(0.15-0.5) added to the expert's steer (70 %),
//! - coasting: no throttle, no brake (15 %),
//! - a throttle burst at 0.6-1.0 with no brake (15 %).
//!
//! Between perturbations the expert drives, so the data holds the recovery.
//! Everything is drawn from one ChaCha8 stream per episode: the same seed gives
//! the same perturbations.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::driver::{Driver, DriverNeeds, Observation, VehicleControl as Control};

/// The noise model's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseParams {
    /// Mean time between the starts of two perturbations (seconds); 0 turns noise off.
    pub mean_gap_s: f64,
    /// Shortest and longest perturbation (seconds).
    pub duration_s: (f64, f64),
    /// Smallest and largest steering offset (steer units).
    pub steer_offset: (f32, f32),
}

impl Default for NoiseParams {
    fn default() -> Self {
        NoiseParams {
            mean_gap_s: 4.0,
            duration_s: (0.25, 1.0),
            steer_offset: (0.15, 0.5),
        }
    }
}

/// What a perturbation does to the expert's control.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Perturbation {
    Steer(f32),
    Coast,
    Throttle(f32),
}

/// The expert (or any driver) with perturbations.
pub struct NoisyDriver<D> {
    inner: D,
    params: NoiseParams,
    rng: ChaCha8Rng,
    next_start_s: f64,
    active: Option<(Perturbation, f64)>,
    /// Control boundaries at which a perturbation was in force.
    pub perturbed: u64,
}

impl<D: Driver> NoisyDriver<D> {
    /// Wraps `inner`; `seed` fixes every perturbation.
    pub fn new(inner: D, params: NoiseParams, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let next_start_s = Self::gap(&mut rng, &params);
        NoisyDriver {
            inner,
            params,
            rng,
            next_start_s,
            active: None,
            perturbed: 0,
        }
    }

    fn gap(rng: &mut ChaCha8Rng, params: &NoiseParams) -> f64 {
        if params.mean_gap_s <= 0.0 {
            return f64::INFINITY;
        }
        // Exponential waiting time: memoryless starts.
        let u: f64 = rng.random_range(1e-9..1.0);
        -params.mean_gap_s * u.ln()
    }
}

impl<D: Driver> Driver for NoisyDriver<D> {
    fn name(&self) -> String {
        format!(
            "{} + noise (gap {} s)",
            self.inner.name(),
            self.params.mean_gap_s
        )
    }

    fn needs(&self) -> DriverNeeds {
        self.inner.needs()
    }

    fn act(&mut self, obs: &Observation<'_>) -> Control {
        let control = self.inner.act(obs);
        let t = obs.time_s;
        if self.active.is_some_and(|(_, end)| t >= end) {
            self.active = None;
        }
        if self.active.is_none() && t >= self.next_start_s {
            let p = &self.params;
            let duration = self.rng.random_range(p.duration_s.0..=p.duration_s.1);
            let kind: f32 = self.rng.random_range(0.0..1.0);
            let perturbation = if kind < 0.7 {
                let size = self.rng.random_range(p.steer_offset.0..=p.steer_offset.1);
                let sign = if self.rng.random_range(0..2) == 0 {
                    -1.0
                } else {
                    1.0
                };
                Perturbation::Steer(sign * size)
            } else if kind < 0.85 {
                Perturbation::Coast
            } else {
                Perturbation::Throttle(self.rng.random_range(0.6..=1.0))
            };
            self.active = Some((perturbation, t + duration));
            self.next_start_s = t + duration + Self::gap(&mut self.rng, p);
        }
        let Some((perturbation, _)) = self.active else {
            return control;
        };
        self.perturbed += 1;
        match perturbation {
            Perturbation::Steer(offset) => Control {
                steer: (control.steer + offset).clamp(-1.0, 1.0),
                ..control
            },
            Perturbation::Coast => Control {
                throttle: 0.0,
                brake: 0.0,
                ..control
            },
            Perturbation::Throttle(throttle) => Control {
                throttle,
                brake: 0.0,
                ..control
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use world::Command;

    struct Steady;
    impl Driver for Steady {
        fn name(&self) -> String {
            "steady".into()
        }
        fn needs(&self) -> DriverNeeds {
            DriverNeeds::default()
        }
        fn act(&mut self, _: &Observation<'_>) -> Control {
            Control {
                steer: 0.0,
                throttle: 0.3,
                brake: 0.0,
            }
        }
    }

    fn drive(seed: u64, params: NoiseParams) -> Vec<Control> {
        let mut d = NoisyDriver::new(Steady, params, seed);
        (0..2000)
            .map(|i| {
                d.act(&Observation {
                    time_s: i as f64 * 0.05,
                    speed_mps: 5.0,
                    command: Command::LaneFollow,
                    scale: 1.0,
                    image: None,
                    labels: None,
                    privileged: None,
                })
            })
            .collect()
    }

    #[test]
    fn noise_is_seeded_and_perturbs_a_share_of_the_time() {
        let a = drive(3, NoiseParams::default());
        assert_eq!(a, drive(3, NoiseParams::default()));
        assert_ne!(a, drive(4, NoiseParams::default()));
        let changed = a
            .iter()
            .filter(|c| c.steer != 0.0 || c.throttle != 0.3)
            .count();
        // Mean gap 4 s, mean length 0.625 s: about 13.5 % of 100 s.
        let share = changed as f64 / a.len() as f64;
        assert!((0.05..0.3).contains(&share), "share {share}");
        assert!(a.iter().all(|c| (-1.0..=1.0).contains(&c.steer)));
        let quiet = drive(
            3,
            NoiseParams {
                mean_gap_s: 0.0,
                ..NoiseParams::default()
            },
        );
        assert!(quiet.iter().all(|c| c.steer == 0.0 && c.throttle == 0.3));
    }
}
