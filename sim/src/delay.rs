//! The zero-order-hold delay line between the driver and the ego's actuators.
//!
//! This reproduces the timeline of the paper's experiment code (TimeParam's
//! run loop, docs/protocol.md §1) on a 40 Hz tick:
//!
//! - Controls are computed at *control boundaries*, every `period_ticks`
//!   ticks, from the observation at that tick.
//! - A control computed at tick `t` lands at tick `t + latency_ticks` and is
//!   held (zero-order hold) until a newer control lands.
//! - The control in force during the step `t -> t + 1` is the newest one that
//!   has landed by tick `t`; before the first one lands, the ego gets a no-op
//!   control (no steer, no throttle, no brake).
//!
//! TimeParam ties the two numbers to one latency `L`: with `L >= 50 ms`,
//! `latency_ticks = period_ticks = round(L / dt)`, so every command lands one
//! period late and is held for the whole period; with `L = 0` the policy runs
//! every 2 ticks and its control is in force from the tick it was computed on.
//! [`DelayTiming::time_param`] builds exactly that; the general form also
//! covers a latency shorter than the control period.
//!
//! A resolution switcher may change the timing at a boundary
//! ([`DelayLine::set_timing`]): the new latency applies to the control computed
//! at that boundary, the new period to the distance to the next boundary.

use crate::driver::VehicleControl;

/// When controls are computed and how late they land, in simulation ticks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DelayTiming {
    /// Ticks between two control boundaries (at least 1).
    pub period_ticks: u32,
    /// Ticks from a control's computation to the tick it is in force from.
    pub latency_ticks: u32,
}

impl DelayTiming {
    /// TimeParam's timing for a latency `latency_ms` on a `tick_s` tick: a
    /// 50 ms period with no delay below 50 ms, else period = latency =
    /// `round(L / dt)` ticks.
    pub fn time_param(latency_ms: f64, tick_s: f64) -> Self {
        let latency_s = latency_ms / 1000.0;
        if latency_s >= 0.05 - 1e-9 {
            let ticks = ((latency_s / tick_s).round() as u32).max(1);
            Self {
                period_ticks: ticks,
                latency_ticks: ticks,
            }
        } else {
            let period = ((0.05 / tick_s).round() as u32).max(1);
            Self {
                period_ticks: period,
                latency_ticks: 0,
            }
        }
    }

    /// The general form: a control period `Tc` and a latency `L` (both in
    /// milliseconds). The loop period is `max(Tc, L)` (a compute-bound
    /// controller cannot run faster than it computes) and each control lands
    /// `L` after its observation.
    pub fn from_period_and_latency(control_period_ms: f64, latency_ms: f64, tick_s: f64) -> Self {
        let to_ticks = |ms: f64| (ms / 1000.0 / tick_s).round() as u32;
        let latency_ticks = to_ticks(latency_ms);
        let period_ticks = to_ticks(control_period_ms.max(latency_ms)).max(1);
        Self {
            period_ticks,
            latency_ticks,
        }
    }
}

/// The queue of computed controls waiting to land, and the one in force.
#[derive(Debug, Clone)]
pub struct DelayLine {
    timing: DelayTiming,
    /// The next tick at which a control is computed.
    next_boundary: u64,
    /// Controls computed but not yet landed: (landing tick, control), in
    /// order of computation. At most a few entries: no allocation after the
    /// first ticks.
    in_flight: Vec<(u64, VehicleControl)>,
    /// The control in force now (the last one that landed).
    applied: VehicleControl,
}

impl DelayLine {
    /// A delay line whose first boundary is tick 0.
    pub fn new(timing: DelayTiming) -> Self {
        Self {
            timing,
            next_boundary: 0,
            in_flight: Vec::with_capacity(4),
            applied: VehicleControl::default(),
        }
    }

    /// The timing in force.
    pub fn timing(&self) -> DelayTiming {
        self.timing
    }

    /// Whether tick `tick` is a control boundary: the driver must be asked
    /// for a control from the observation at this tick, and given to
    /// [`DelayLine::submit`].
    pub fn is_boundary(&self, tick: u64) -> bool {
        tick >= self.next_boundary
    }

    /// Changes the timing from this boundary on (a resolution switch). Call
    /// it at a boundary, before [`DelayLine::submit`].
    pub fn set_timing(&mut self, timing: DelayTiming) {
        self.timing = timing;
    }

    /// Hands in the control computed at boundary `tick`.
    pub fn submit(&mut self, tick: u64, control: VehicleControl) {
        let landing = self.defer(tick);
        self.fulfil(landing, control);
    }

    /// Passes boundary `tick` whose control is still being computed: the next
    /// boundary is set, and the tick at which the control will land is returned, for
    /// [`DelayLine::fulfil`]. [`DelayLine::submit`] is the two at once.
    pub fn defer(&mut self, tick: u64) -> u64 {
        let period = u64::from(self.timing.period_ticks.max(1));
        self.next_boundary = tick + period;
        tick + u64::from(self.timing.latency_ticks)
    }

    /// Hands in a deferred control, landing at `landing` ([`DelayLine::defer`]'s
    /// answer). Deferred controls are handed in in the order of their boundaries, each
    /// before [`DelayLine::control_for_step`] of its landing tick.
    pub fn fulfil(&mut self, landing: u64, control: VehicleControl) {
        self.in_flight.push((landing, control));
    }

    /// The control in force during the step `tick -> tick + 1`. Call once per
    /// tick, after any [`DelayLine::submit`] for this tick.
    pub fn control_for_step(&mut self, tick: u64) -> VehicleControl {
        // The newest computed control that has landed wins; older ones still
        // in flight can no longer matter.
        if let Some(newest_landed) = self.in_flight.iter().rposition(|(land, _)| *land <= tick) {
            self.applied = self.in_flight[newest_landed].1;
            self.in_flight.drain(..=newest_landed);
        }
        self.applied
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 0.025;

    /// A control that records the tick it was computed at (in `throttle`).
    fn stamped(tick: u64) -> VehicleControl {
        VehicleControl {
            steer: 0.0,
            throttle: tick as f32,
            brake: 0.0,
        }
    }

    /// Runs `ticks` ticks and returns, for each step `t -> t + 1`, the tick
    /// the control in force was computed at, or `None` for the initial no-op
    /// (computed controls carry a brake mark to tell them from it).
    fn timeline(
        timing: DelayTiming,
        ticks: u64,
        switch: impl FnMut(u64) -> Option<DelayTiming>,
    ) -> Vec<Option<u64>> {
        let mut line = DelayLine::new(timing);
        let mut switch = switch;
        (0..ticks)
            .map(|t| {
                if line.is_boundary(t) {
                    if let Some(timing) = switch(t) {
                        line.set_timing(timing);
                    }
                    line.submit(
                        t,
                        VehicleControl {
                            brake: 1.0,
                            ..stamped(t)
                        },
                    );
                }
                let c = line.control_for_step(t);
                (c.brake == 1.0).then_some(c.throttle as u64)
            })
            .collect()
    }

    /// A control handed in late, after its boundary was passed with `defer` but before
    /// its landing tick, gives the timeline of `submit` at the boundary (what the loop
    /// relies on when the policy computes beside it).
    #[test]
    fn a_deferred_control_fulfilled_before_it_lands_is_a_submitted_one() {
        for delay_ms in [25.0, 50.0, 100.0, 150.0] {
            let timing = DelayTiming::time_param(delay_ms, DT);
            let mut submitted = DelayLine::new(timing);
            let mut deferred = DelayLine::new(timing);
            let mut owed: Option<(u64, VehicleControl)> = None;
            for t in 0..40 {
                let c = VehicleControl {
                    brake: 1.0,
                    ..stamped(t)
                };
                if submitted.is_boundary(t) {
                    submitted.submit(t, c);
                }
                if deferred.is_boundary(t) {
                    if let Some((landing, c)) = owed.take() {
                        deferred.fulfil(landing, c);
                    }
                    owed = Some((deferred.defer(t), c));
                }
                if let Some((landing, c)) = owed.filter(|(landing, _)| *landing <= t) {
                    deferred.fulfil(landing, c);
                    owed = None;
                }
                assert_eq!(
                    submitted.control_for_step(t),
                    deferred.control_for_step(t),
                    "D = {delay_ms} ms, tick {t}"
                );
            }
        }
    }

    #[test]
    fn time_param_timing_matches_the_protocol() {
        assert_eq!(
            DelayTiming::time_param(0.0, DT),
            DelayTiming {
                period_ticks: 2,
                latency_ticks: 0
            }
        );
        assert_eq!(
            DelayTiming::time_param(50.0, DT),
            DelayTiming {
                period_ticks: 2,
                latency_ticks: 2
            }
        );
        assert_eq!(
            DelayTiming::time_param(100.0, DT),
            DelayTiming {
                period_ticks: 4,
                latency_ticks: 4
            }
        );
        assert_eq!(
            DelayTiming::time_param(150.0, DT),
            DelayTiming {
                period_ticks: 6,
                latency_ticks: 6
            }
        );
        assert_eq!(
            DelayTiming::time_param(200.0, DT),
            DelayTiming {
                period_ticks: 8,
                latency_ticks: 8
            }
        );
        assert_eq!(
            DelayTiming::from_period_and_latency(50.0, 120.0, DT),
            DelayTiming {
                period_ticks: 5,
                latency_ticks: 5
            }
        );
        assert_eq!(
            DelayTiming::from_period_and_latency(100.0, 50.0, DT),
            DelayTiming {
                period_ticks: 4,
                latency_ticks: 2
            }
        );
    }

    #[test]
    fn no_delay_applies_each_control_from_its_own_tick_for_two_steps() {
        // docs/protocol.md §1: with D = 0 the command from the observation at t = 2 is
        // in force over the steps 2->3 and 3->4.
        let got = timeline(DelayTiming::time_param(0.0, DT), 8, |_| None);
        assert_eq!(
            got,
            vec![
                Some(0),
                Some(0),
                Some(2),
                Some(2),
                Some(4),
                Some(4),
                Some(6),
                Some(6)
            ]
        );
    }

    #[test]
    fn fifty_ms_delay_lands_one_period_late_and_holds() {
        // docs/protocol.md §1: with D = 50 ms the command from t = 0 is in force over
        // 2->3 and 3->4, the one from t = 2 over 4->5 and 5->6; a no-op before.
        let got = timeline(DelayTiming::time_param(50.0, DT), 8, |_| None);
        assert_eq!(
            got,
            vec![
                None,
                None,
                Some(0),
                Some(0),
                Some(2),
                Some(2),
                Some(4),
                Some(4)
            ]
        );
    }

    #[test]
    fn hundred_ms_delay_holds_for_four_ticks() {
        let got = timeline(DelayTiming::time_param(100.0, DT), 13, |_| None);
        let mut want = vec![None; 4];
        want.extend([Some(0); 4]);
        want.extend([Some(4); 4]);
        want.push(Some(8));
        assert_eq!(got, want);
    }

    #[test]
    fn switch_takes_effect_at_the_boundary_it_is_made() {
        // 100 ms (period 4) until tick 8, then 50 ms (period 2): the control
        // computed at 8 lands at 10 and the next boundary is 10.
        let fast = DelayTiming::time_param(50.0, DT);
        let got = timeline(DelayTiming::time_param(100.0, DT), 14, |t| {
            (t == 8).then_some(fast)
        });
        let want = vec![
            None,
            None,
            None,
            None, // 0..4: no-op
            Some(0),
            Some(0),
            Some(0),
            Some(0), // 4..8: from 0
            Some(4),
            Some(4), // 8..10: from 4 (lands at 8)
            Some(8),
            Some(8), // 10..12: from 8 (new latency 2)
            Some(10),
            Some(10), // 12..14
        ];
        assert_eq!(got, want);
    }

    #[test]
    fn latency_shorter_than_period_lands_mid_period() {
        // Tc = 100 ms, L = 50 ms: computed every 4 ticks, each lands 2 later.
        let got = timeline(
            DelayTiming::from_period_and_latency(100.0, 50.0, DT),
            10,
            |_| None,
        );
        assert_eq!(
            got,
            vec![
                None,
                None,
                Some(0),
                Some(0),
                Some(0),
                Some(0),
                Some(4),
                Some(4),
                Some(4),
                Some(4)
            ]
        );
    }
}
