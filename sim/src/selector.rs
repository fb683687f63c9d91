//! Resolution selectors: which input scale the policy sees at the next control boundary.
//!
//! The loop calls a selector at each control boundary with the distance along
//! the route to the stop line of the next traffic light ahead (and, if it
//! knows it, how far the ego is past the last stop line it crossed). The scale
//! returned applies from that boundary: the next observation is rendered at
//! it, and the latency in force is the one the [`LatencyTable`] gives for it
//! (docs/protocol.md §1 and §7, Table III).

/// What a selector sees at a control boundary.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SelectorInput {
    /// Distance along the route to the stop line of the next light ahead (metres), if any.
    pub light_ahead_m: Option<f32>,
    /// Distance along the route past the last stop line crossed (metres), if known.
    pub light_behind_m: Option<f32>,
    /// Ego speed (metres per second).
    pub speed_mps: f32,
    /// The driver's estimate, from its last observation, of the probability
    /// that the high scale is needed (a learned trigger, see [`Learned`]);
    /// `None` for a driver without one.
    pub driver_hint: Option<f32>,
}

impl SelectorInput {
    /// Distance to the nearest stop line, ahead or behind (metres).
    pub fn nearest_m(&self) -> Option<f32> {
        match (self.light_ahead_m, self.light_behind_m) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }
}

/// Chooses the input scale at each control boundary.
pub trait ResolutionSelector {
    /// The selector with every parameter that changes what it selects, for
    /// result records and sweep tables ("fixed-0.75",
    /// "oracle-0.75/1-5/15m", ...): two selectors that may select
    /// differently never share a name.
    fn name(&self) -> String;
    /// The scale to use from this boundary on.
    fn select(&mut self, input: &SelectorInput) -> f32;
    /// Forgets any state (start of a run).
    fn reset(&mut self) {}
}

/// The compute latency of each scale (milliseconds), for the delay the loop injects.
#[derive(Debug, Clone, PartialEq)]
pub struct LatencyTable {
    /// `(scale, latency_ms)`, ascending by scale.
    entries: Vec<(f32, f64)>,
}

/// Why a latency table cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LatencyTableError {
    /// A scale or latency is not usable.
    #[error(
        "latency table entry {index} (scale {scale}, latency {latency_ms} ms): {problem}; fix: give positive scales, each once, with finite latencies >= 0 ms"
    )]
    Entry {
        /// Position in the list given.
        index: usize,
        /// The scale.
        scale: f32,
        /// The latency (milliseconds).
        latency_ms: f64,
        /// What is wrong.
        problem: &'static str,
    },
    /// No entries.
    #[error("latency table is empty; fix: give at least one `scale = latency_ms` entry")]
    Empty,
}

impl LatencyTable {
    /// A table from `(scale, latency_ms)` pairs in any order.
    pub fn new(pairs: &[(f32, f64)]) -> Result<Self, LatencyTableError> {
        if pairs.is_empty() {
            return Err(LatencyTableError::Empty);
        }
        for (index, &(scale, latency_ms)) in pairs.iter().enumerate() {
            let problem = if !(scale > 0.0 && scale.is_finite()) {
                Some("scale not positive")
            } else if !(latency_ms >= 0.0 && latency_ms.is_finite()) {
                Some("latency not a finite number >= 0")
            } else if pairs[..index].iter().any(|(s, _)| (s - scale).abs() < 1e-4) {
                Some("scale listed twice")
            } else {
                None
            };
            if let Some(problem) = problem {
                return Err(LatencyTableError::Entry {
                    index,
                    scale,
                    latency_ms,
                    problem,
                });
            }
        }
        let mut entries = pairs.to_vec();
        entries.sort_by(|a, b| a.0.total_cmp(&b.0));
        Ok(LatencyTable { entries })
    }

    /// The latency of `scale` (milliseconds), if the table has it.
    pub fn latency_ms(&self, scale: f32) -> Option<f64> {
        self.entries
            .iter()
            .find(|(s, _)| (s - scale).abs() < 1e-4)
            .map(|e| e.1)
    }

    /// The scales, ascending.
    pub fn scales(&self) -> Vec<f32> {
        self.entries.iter().map(|e| e.0).collect()
    }

    /// The highest scale whose latency is at most `budget_ms`, else the cheapest scale.
    pub fn best_within(&self, budget_ms: f64) -> f32 {
        self.entries
            .iter()
            .rev()
            .find(|(_, l)| *l <= budget_ms)
            .or_else(|| self.entries.iter().min_by(|a, b| a.1.total_cmp(&b.1)))
            .map(|e| e.0)
            .expect("a latency table is never empty")
    }
}

/// Always the same scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Fixed {
    /// The scale.
    pub scale: f32,
}

impl ResolutionSelector for Fixed {
    fn name(&self) -> String {
        format!("fixed-{}", self.scale)
    }
    fn select(&mut self, _: &SelectorInput) -> f32 {
        self.scale
    }
}

/// The paper's oracle switcher (TimeParam `test_wor_switching.py`).
///
/// Low scale by default; the high scale once a light's stop line is within
/// `enter_m` (5 m) ahead; it stays high while that stop line is within
/// `exit_m` (5 + 10 = 15 m), ahead or behind; then low again. TimeParam
/// measures a straight-line distance to the trigger-volume centre; we measure
/// along the route, which is the same on an approach lane.
#[derive(Debug, Clone, PartialEq)]
pub struct Oracle {
    /// Default scale (0.75).
    pub low: f32,
    /// Scale near lights (1.0).
    pub high: f32,
    /// Switch up within this distance ahead of a stop line (metres).
    pub enter_m: f32,
    /// Stay up while the stop line is within this distance (metres).
    pub exit_m: f32,
    /// Whether the high scale is in force.
    pub active: bool,
}

impl Default for Oracle {
    fn default() -> Self {
        Oracle {
            low: 0.75,
            high: 1.0,
            enter_m: 5.0,
            exit_m: 15.0,
            active: false,
        }
    }
}

/// The hysteresis both distance-based selectors share.
fn hysteresis(active: bool, input: &SelectorInput, enter_m: f32, exit_m: f32) -> bool {
    let entering = input.light_ahead_m.is_some_and(|d| d <= enter_m);
    let staying = active && input.nearest_m().is_some_and(|d| d <= exit_m);
    entering || staying
}

impl ResolutionSelector for Oracle {
    fn name(&self) -> String {
        format!(
            "oracle-{}/{}-{}/{}m",
            self.low, self.high, self.enter_m, self.exit_m
        )
    }
    fn select(&mut self, input: &SelectorInput) -> f32 {
        self.active = hysteresis(self.active, input, self.enter_m, self.exit_m);
        if self.active { self.high } else { self.low }
    }
    fn reset(&mut self) {
        self.active = false;
    }
}

/// Map-based lookahead: like the oracle, but switches up early enough that a
/// high-resolution control is already in force `enter_m` before the stop line.
///
/// A switch decided at a boundary first shows in the observation of the next
/// boundary (one low-scale period away) and its control lands one high-scale
/// latency later, so it switches at `enter_m + speed * cover_s` with
/// `cover_s = L(low) + L(high)` ([`Lookahead::covering`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Lookahead {
    /// Default scale.
    pub low: f32,
    /// Scale near lights.
    pub high: f32,
    /// Distance before the stop line by which the high scale must act (metres).
    pub enter_m: f32,
    /// Stay up while the stop line is within this distance (metres).
    pub exit_m: f32,
    /// Time the switch needs to take effect (seconds).
    pub cover_s: f32,
    /// With a deceleration (m/s^2), the switch also covers the distance to
    /// stop from the current speed: the high scale then decides whether to
    /// brake for the line ([`Lookahead::braking`]). `None`: the paper's 5 m
    /// plus the switch's own delay only.
    pub brake_mps2: Option<f32>,
    /// Whether the high scale is in force.
    pub active: bool,
}

impl Lookahead {
    /// A lookahead whose lead time covers the latencies of `low` then `high` in `table`.
    pub fn covering(low: f32, high: f32, table: &LatencyTable) -> Option<Self> {
        let cover_ms = table.latency_ms(low)? + table.latency_ms(high)?;
        Some(Lookahead {
            low,
            high,
            enter_m: 5.0,
            exit_m: 15.0,
            cover_s: (cover_ms / 1000.0) as f32,
            brake_mps2: None,
            active: false,
        })
    }

    /// Like [`Lookahead::covering`], and up before the braking point: the
    /// stopping distance at the rule book's deceleration
    /// ([`world::rules::ahead::STOPPING_DECEL_MPS2`], 3 m/s^2) is added to the
    /// trigger, so the stop for a red light is decided at the high scale.
    /// The oracle and the plain lookahead switch up 5-7 m before the line,
    /// inside the 6-7 m a car at 6 m/s needs to stop, where the low scale may
    /// already have decided (`docs/paper-2026-12-05/discussion.md` has what the runs
    /// showed).
    pub fn braking(low: f32, high: f32, table: &LatencyTable) -> Option<Self> {
        Some(Lookahead {
            brake_mps2: Some(world::rules::ahead::STOPPING_DECEL_MPS2),
            ..Lookahead::covering(low, high, table)?
        })
    }

    /// The distance ahead of the stop line at which it switches up at
    /// `speed_mps` (metres): `enter_m + v cover_s`, plus `v^2 / (2 a)` with a
    /// braking deceleration `a`.
    pub fn trigger_m(&self, speed_mps: f32) -> f32 {
        let v = speed_mps.max(0.0);
        let stopping = self.brake_mps2.map_or(0.0, |a| v * v / (2.0 * a));
        self.enter_m + v * self.cover_s + stopping
    }
}

impl ResolutionSelector for Lookahead {
    fn name(&self) -> String {
        let brake = self
            .brake_mps2
            .map_or(String::new(), |a| format!("-brake{a}"));
        format!(
            "lookahead-{}/{}-{}/{}m-cover{}s{brake}",
            self.low, self.high, self.enter_m, self.exit_m, self.cover_s
        )
    }
    fn select(&mut self, input: &SelectorInput) -> f32 {
        let enter = self.trigger_m(input.speed_mps);
        self.active = hysteresis(self.active, input, enter, self.exit_m.max(enter));
        if self.active { self.high } else { self.low }
    }
    fn reset(&mut self) {
        self.active = false;
    }
}

/// A learned trigger: the high scale while the driver's own estimate
/// ([`SelectorInput::driver_hint`], a small head on the policy's pooled
/// features, `mrdrive policy trigger`) says it is needed, and for
/// `hold_steps` boundaries after it last said so. No map is read.
///
/// The hint comes from the previous observation, so a switch shows one
/// control period after the frame that asked for it, as the oracle's does.
/// Without a hint (a driver that has no trigger) it keeps the high scale:
/// the safe choice.
#[derive(Debug, Clone, PartialEq)]
pub struct Learned {
    /// Default scale.
    pub low: f32,
    /// Scale when the trigger fires.
    pub high: f32,
    /// The trigger fires when the hint is at least this probability.
    pub threshold: f32,
    /// Boundaries the high scale is held after the trigger last fired.
    pub hold_steps: u32,
    /// Boundaries left to hold the high scale.
    pub left: u32,
}

impl ResolutionSelector for Learned {
    fn name(&self) -> String {
        format!(
            "learned-{}/{}-p{}-hold{}",
            self.low, self.high, self.threshold, self.hold_steps
        )
    }
    fn select(&mut self, input: &SelectorInput) -> f32 {
        let Some(p) = input.driver_hint else {
            return self.high;
        };
        if p >= self.threshold {
            self.left = self.hold_steps;
            self.high
        } else if self.left > 0 {
            self.left -= 1;
            self.high
        } else {
            self.low
        }
    }
    fn reset(&mut self) {
        self.left = 0;
    }
}

/// The highest scale whose latency fits a budget (the cheapest if none fits).
#[derive(Debug, Clone, PartialEq)]
pub struct LatencyBudget {
    /// Latency per scale.
    pub table: LatencyTable,
    /// The budget (milliseconds).
    pub budget_ms: f64,
}

impl ResolutionSelector for LatencyBudget {
    fn name(&self) -> String {
        format!("budget-{}ms", self.budget_ms)
    }
    fn select(&mut self, _: &SelectorInput) -> f32 {
        self.table.best_within(self.budget_ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scripted drive: the ego approaches a stop line from 30 m at `speed` m/s,
    /// crosses it, drives on to 30 m past, with a control boundary every `period_s`.
    /// Returns (signed distance to the line: + ahead / - past, scale) at each boundary.
    fn drive(sel: &mut dyn ResolutionSelector, speed: f32, period_s: f32) -> Vec<(f32, f32)> {
        let mut out = vec![];
        let mut d = 30.0f32;
        while d >= -30.0 {
            let input = SelectorInput {
                light_ahead_m: (d >= 0.0).then_some(d),
                light_behind_m: (d < 0.0).then_some(-d),
                speed_mps: speed,
                driver_hint: None,
            };
            out.push((d, sel.select(&input)));
            d -= speed * period_s;
        }
        out
    }

    fn switches(trace: &[(f32, f32)]) -> Vec<(f32, f32)> {
        trace
            .windows(2)
            .filter(|w| w[0].1 != w[1].1)
            .map(|w| (w[1].0, w[1].1))
            .collect()
    }

    #[test]
    fn oracle_switches_at_5_m_ahead_and_back_past_15_m() {
        // 5 m/s, 0.1 s period: boundaries every 0.5 m, so the thresholds fall on boundaries.
        let trace = drive(&mut Oracle::default(), 5.0, 0.1);
        assert_eq!(switches(&trace), vec![(5.0, 1.0), (-15.5, 0.75)]);
        assert_eq!(trace[0].1, 0.75);
    }

    #[test]
    fn oracle_without_distance_behind_drops_when_the_light_is_passed() {
        let mut o = Oracle::default();
        let at = |ahead| SelectorInput {
            light_ahead_m: ahead,
            ..Default::default()
        };
        assert_eq!(o.select(&at(Some(6.0))), 0.75);
        assert_eq!(o.select(&at(Some(4.0))), 1.0);
        assert_eq!(o.select(&at(Some(0.5))), 1.0);
        // Past the line the next light is 120 m away: back to low at once.
        assert_eq!(o.select(&at(Some(120.0))), 0.75);
        assert_eq!(o.select(&at(None)), 0.75);
        o.select(&at(Some(3.0)));
        o.reset();
        assert!(!o.active);
    }

    #[test]
    fn lookahead_switches_early_by_the_latency_it_covers() {
        let table = LatencyTable::new(&[(1.0, 100.0), (0.75, 50.0)]).unwrap();
        let mut la = Lookahead::covering(0.75, 1.0, &table).unwrap();
        assert!((la.cover_s - 0.15).abs() < 1e-6);
        // 10 m/s: trigger at 5 + 10 * 0.15 = 6.5 m; boundaries every 0.5 m.
        assert!((la.trigger_m(10.0) - 6.5).abs() < 1e-5);
        let trace = drive(&mut la, 10.0, 0.05);
        assert_eq!(switches(&trace), vec![(6.5, 1.0), (-15.5, 0.75)]);
    }

    #[test]
    fn braking_lookahead_switches_before_the_stopping_distance() {
        let table = LatencyTable::new(&[(1.0, 100.0), (0.75, 50.0)]).unwrap();
        let mut la = Lookahead::braking(0.75, 1.0, &table).unwrap();
        assert_eq!(la.brake_mps2, Some(3.0));
        // 6 m/s: 5 + 6 * 0.15 + 36 / 6 = 11.9 m, against the plain lookahead's 5.9 m.
        assert!((la.trigger_m(6.0) - 11.9).abs() < 1e-5);
        let plain = Lookahead::covering(0.75, 1.0, &table).unwrap();
        assert!((plain.trigger_m(6.0) - 5.9).abs() < 1e-5);
        // Standing, both wait for the paper's 5 m.
        assert_eq!(la.trigger_m(0.0), 5.0);
        // 10 m/s, boundaries every 0.5 m: 5 + 1.5 + 100 / 6 = 23.17 m, so up at
        // the boundary at 23.0 m, and the exit follows the trigger (at least
        // 15 m): down once the line is more than 23.17 m behind.
        let trace = drive(&mut la, 10.0, 0.05);
        assert_eq!(switches(&trace), vec![(23.0, 1.0), (-23.5, 0.75)]);
        assert!(la.name().ends_with("-brake3"), "{}", la.name());
        assert!(!plain.name().contains("brake"), "{}", plain.name());
    }

    #[test]
    fn learned_follows_the_hint_and_holds_the_high_scale() {
        let mut l = Learned {
            low: 0.75,
            high: 1.0,
            threshold: 0.5,
            hold_steps: 2,
            left: 0,
        };
        let hint = |p: Option<f32>| SelectorInput {
            driver_hint: p,
            ..Default::default()
        };
        // No hint (a driver without a trigger): the safe high scale.
        assert_eq!(l.select(&hint(None)), 1.0);
        let trace: Vec<f32> = [0.1, 0.49, 0.5, 0.2, 0.1, 0.0, 0.9, 0.0]
            .iter()
            .map(|&p| l.select(&hint(Some(p))))
            .collect();
        // Fires at 0.5 and holds two more boundaries; fires again at 0.9.
        assert_eq!(trace, vec![0.75, 0.75, 1.0, 1.0, 1.0, 0.75, 1.0, 1.0]);
        l.reset();
        assert_eq!(l.select(&hint(Some(0.0))), 0.75);
        assert_eq!(l.name(), "learned-0.75/1-p0.5-hold2");
    }

    #[test]
    fn budget_picks_the_highest_scale_that_fits() {
        let table = LatencyTable::new(&[(1.0, 100.0), (0.5, 30.0), (0.75, 50.0)]).unwrap();
        assert_eq!(table.scales(), vec![0.5, 0.75, 1.0]);
        let mut b = LatencyBudget {
            table: table.clone(),
            budget_ms: 60.0,
        };
        assert_eq!(b.select(&SelectorInput::default()), 0.75);
        b.budget_ms = 100.0;
        assert_eq!(b.select(&SelectorInput::default()), 1.0);
        b.budget_ms = 10.0;
        assert_eq!(b.select(&SelectorInput::default()), 0.5);
        assert_eq!(table.latency_ms(0.75), Some(50.0));
        assert_eq!(table.latency_ms(0.6), None);
    }

    #[test]
    fn bad_latency_tables_are_refused() {
        assert_eq!(LatencyTable::new(&[]), Err(LatencyTableError::Empty));
        let e = LatencyTable::new(&[(1.0, 10.0), (1.0, 20.0)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("entry 1") && e.contains("twice"), "{e}");
        assert!(LatencyTable::new(&[(0.75, f64::NAN)]).is_err());
    }

    #[test]
    fn names_carry_every_parameter() {
        let o = Oracle::default();
        assert_eq!(o.name(), "oracle-0.75/1-5/15m");
        let names: std::collections::BTreeSet<String> = [
            o.clone(),
            Oracle {
                low: 0.5,
                ..o.clone()
            },
            Oracle {
                high: 0.9,
                ..o.clone()
            },
            Oracle {
                enter_m: 8.0,
                ..o.clone()
            },
            Oracle {
                exit_m: 20.0,
                ..o.clone()
            },
        ]
        .iter()
        .map(ResolutionSelector::name)
        .collect();
        assert_eq!(names.len(), 5, "{names:?}");
        let table = LatencyTable::new(&[(1.0, 100.0), (0.75, 50.0)]).unwrap();
        let la = Lookahead::covering(0.75, 1.0, &table).unwrap();
        assert_eq!(la.name(), "lookahead-0.75/1-5/15m-cover0.15s");
        let slower = Lookahead {
            cover_s: 0.3,
            ..la.clone()
        };
        assert_ne!(la.name(), slower.name());
        assert_ne!(Fixed { scale: 0.75 }.name(), Fixed { scale: 1.0 }.name());
    }

    #[test]
    fn fixed_is_fixed() {
        let trace = drive(&mut Fixed { scale: 0.75 }, 5.0, 0.1);
        assert!(trace.iter().all(|(_, s)| *s == 0.75));
    }
}
