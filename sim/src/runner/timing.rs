//! The timing of the loop: the delay and period in force at each scale, written
//! once ([`timing_for`]: `max(D, Lexec)`, docs/protocol.md §1), the jittered latency
//! draw, and the controls: the delay line and the scale in force.

use std::collections::BTreeMap;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::delay::{DelayLine, DelayTiming};
use crate::scenario::Scenario;
use crate::selector::{ResolutionSelector, SelectorInput};

/// The timing in force at `scale`: the delay is `max(D, Lexec(scale))`, the
/// period `max(Tc, delay)` (docs/protocol.md §1). With `latency = "measured"` the
/// loop replaces `Lexec` by the driver's real compute time at each boundary.
pub fn timing_at(scenario: &Scenario, scale: f64) -> (DelayTiming, f64) {
    timing_for(scenario, scenario.latency_ms_at(scale))
}

/// The one rule of the achieved loop (docs/protocol.md §1): an execution latency of
/// `exec_ms` puts `max(D, exec_ms)` in force as the delay, with the period
/// `max(Tc, delay)`. Returns the timing and the delay (milliseconds).
pub(super) fn timing_for(scenario: &Scenario, exec_ms: f64) -> (DelayTiming, f64) {
    let t = &scenario.timing;
    let latency_ms = t.delay_ms.max(exec_ms);
    (
        DelayTiming::from_period_and_latency(t.control_period_ms, latency_ms, t.tick_s),
        latency_ms,
    )
}

/// The log-normal spread of the execution latency (`timing.latency_jitter`):
/// a factor with mean 1 drawn at each control boundary from its own seeded
/// generator, so jitter never changes the traffic's random draws.
pub(super) struct Jitter {
    pub(super) sigma: f64,
    pub(super) rng: ChaCha8Rng,
}

impl Jitter {
    pub(super) fn new(scenario: &Scenario) -> Option<Jitter> {
        let sigma = scenario.timing.latency_jitter;
        (sigma > 0.0).then(|| Jitter {
            sigma,
            rng: ChaCha8Rng::seed_from_u64(scenario.traffic.seed ^ 0x6a69_7474_6572),
        })
    }

    /// The next factor: exp(sigma z - sigma^2 / 2), z standard normal (Box-Muller).
    pub(super) fn factor(&mut self) -> f64 {
        let u1: f64 = 1.0 - self.rng.random::<f64>();
        let u2: f64 = self.rng.random::<f64>();
        let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        (self.sigma * z - self.sigma * self.sigma / 2.0).exp()
    }
}

/// The control side of the loop: the scale in force, the delay line and
/// the latencies seen.
pub(super) struct Controls {
    pub(super) scale: f64,
    pub(super) latency_ms: f64,
    pub(super) max_latency_ms: f64,
    pub(super) delay: DelayLine,
    /// Boundaries at each scale (keyed by the scale's bits).
    pub(super) scale_counts: BTreeMap<u64, u64>,
    pub(super) jitter: Option<Jitter>,
}

impl Controls {
    pub(super) fn new(scenario: &Scenario, selector: &mut dyn ResolutionSelector) -> Controls {
        selector.reset();
        let scale = f64::from(selector.select(&SelectorInput::default()));
        let (timing, latency_ms) = timing_at(scenario, scale);
        Controls {
            scale,
            latency_ms,
            max_latency_ms: latency_ms,
            delay: DelayLine::new(timing),
            scale_counts: BTreeMap::new(),
            jitter: Jitter::new(scenario),
        }
    }

    /// At a boundary: a new scale's latency, or with jitter a new draw of
    /// the current one, put in force from this boundary on.
    pub(super) fn retime(&mut self, scenario: &Scenario, new_scale: f64) {
        let changed = new_scale != self.scale;
        self.scale = new_scale;
        if let Some(j) = self.jitter.as_mut() {
            let (timing, l) = timing_for(scenario, scenario.latency_ms_at(new_scale) * j.factor());
            self.set_latency(timing, l);
        } else if changed {
            let (t, l) = timing_at(scenario, new_scale);
            self.set_latency(t, l);
        }
    }

    /// Puts `latency_ms` in force (from the next boundary on).
    pub(super) fn set_latency(&mut self, timing: DelayTiming, latency_ms: f64) {
        self.delay.set_timing(timing);
        self.latency_ms = latency_ms;
        self.max_latency_ms = self.max_latency_ms.max(latency_ms);
    }

    /// The share of the boundaries at each scale.
    pub(super) fn scale_share(&self) -> BTreeMap<String, f64> {
        let total: u64 = self.scale_counts.values().sum();
        self.scale_counts
            .iter()
            .map(|(bits, n)| {
                (
                    format!("{}", f64::from_bits(*bits)),
                    *n as f64 / total.max(1) as f64,
                )
            })
            .collect()
    }
}
