//! Timeouts that end a run (docs/protocol.md §3): stuck (standing still while
//! pressing the throttle, or after a collision), low speed for too long, and
//! the route timeout.
//!
//! Time spent standing where a red (or yellow) light holds the ego
//! ([`world::rules::StopLines::holding`]: before its stop line, or queued
//! up to [`LIGHT_QUEUE_M`] behind it) does not count toward the low-speed
//! timeout. In CARLA's Town01 and Town02, where the paper measured, a light
//! is never red for 40 s (a junction has at most three groups: 30 s of red);
//! a four-way junction of our generated towns is red for up to 50 s, and a
//! driver that stops for it correctly would otherwise be ended.

use std::sync::Arc;

use world::rules::RuleBook;

use super::{EgoTick, Infraction, InfractionKind, Monitor};

/// How far before a stop line a standing ego still counts as waiting for
/// its light (metres from the front bumper): a queue of two or three cars.
pub const LIGHT_QUEUE_M: f32 = 20.0;

/// Below this speed the ego counts as standing (metres per second).
const STANDING_MPS: f32 = 0.2;
/// Above this throttle a standing ego is trying to move.
const PRESSING_THROTTLE: f32 = 0.3;

/// Watches for the ego standing still too long, and for the route timeout.
#[derive(Debug, Clone)]
pub struct BlockedMonitor {
    /// Stuck limit (seconds).
    pub stuck_s: f64,
    /// Low-speed limit (seconds).
    pub low_speed_s: f64,
    /// Route timeout (seconds).
    pub timeout_s: f64,
    stuck_for_s: f64,
    standing_for_s: f64,
    after_collision: bool,
    fired: bool,
    /// The town's stop lines, for time held by a light.
    rules: Option<Arc<RuleBook>>,
}

impl BlockedMonitor {
    /// A monitor with these limits (seconds).
    pub fn new(stuck_s: f64, low_speed_s: f64, timeout_s: f64) -> Self {
        Self {
            stuck_s,
            low_speed_s,
            timeout_s,
            stuck_for_s: 0.0,
            standing_for_s: 0.0,
            after_collision: false,
            fired: false,
            rules: None,
        }
    }

    /// Does not count the time a light of this town holds the ego.
    pub fn waiting_at_lights_of(mut self, rules: Arc<RuleBook>) -> Self {
        self.rules = Some(rules);
        self
    }

    /// Whether a red or yellow light holds the ego standing in this tick.
    fn held_by_light(&self, tick: &EgoTick<'_>) -> bool {
        self.rules.as_ref().is_some_and(|r| {
            r.stop_lines
                .holding(
                    tick.now.ground(),
                    tick.now.heading,
                    tick.size_m.0,
                    tick.lights,
                    LIGHT_QUEUE_M,
                )
                .is_some()
        })
    }
}

impl Monitor for BlockedMonitor {
    /// Pushes at most one terminating event over the whole run. A collision
    /// the collision monitor pushed for this tick (it observes first) makes
    /// standing still afterwards count as stuck.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        let collided = out.iter().any(|i| {
            i.tick == tick.tick
                && matches!(
                    i.kind,
                    InfractionKind::CollisionVehicle
                        | InfractionKind::CollisionPedestrian
                        | InfractionKind::CollisionStatic
                )
        });
        if collided {
            self.after_collision = true;
        }
        if self.fired {
            return;
        }
        let tick_s = tick.dt_s;
        let standing = tick.speed_mps < STANDING_MPS;
        if !standing {
            self.after_collision = false;
        }
        self.standing_for_s = if !standing {
            0.0
        } else if self.held_by_light(tick) {
            self.standing_for_s
        } else {
            self.standing_for_s + tick_s
        };
        let trying = standing && (tick.throttle > PRESSING_THROTTLE || self.after_collision);
        self.stuck_for_s = if trying {
            self.stuck_for_s + tick_s
        } else {
            0.0
        };
        let event = if self.stuck_for_s >= self.stuck_s - 1e-9 {
            Some((
                InfractionKind::Stuck,
                format!("{:.1} s without moving", self.stuck_for_s),
            ))
        } else if self.standing_for_s >= self.low_speed_s - 1e-9 {
            Some((
                InfractionKind::LowSpeedTimeout,
                format!("{:.1} s below {STANDING_MPS} m/s", self.standing_for_s),
            ))
        } else if tick.time_s >= self.timeout_s - 1e-9 {
            Some((
                InfractionKind::RouteTimeout,
                format!("{:.1} s", tick.time_s),
            ))
        } else {
            None
        };
        if let Some((kind, detail)) = event {
            self.fired = true;
            out.push(Infraction::at(tick, kind, detail));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::scripted;
    use super::*;

    fn run(
        monitor: &mut BlockedMonitor,
        ticks: usize,
        speed: f32,
        throttle: f32,
    ) -> Vec<Infraction> {
        let mut out = Vec::new();
        let poses = scripted::straight(0.0, 0.0, speed, ticks);
        scripted::drive(&poses, speed, &[], |t| {
            let tick = EgoTick { throttle, ..*t };
            monitor.observe(&tick, &mut out);
        });
        out
    }

    #[test]
    fn pressing_the_throttle_against_a_wall_is_stuck_after_eight_seconds() {
        let mut m = BlockedMonitor::new(8.0, 40.0, 1000.0);
        let out = run(&mut m, 400, 0.0, 1.0);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].kind, InfractionKind::Stuck);
        assert_eq!(out[0].tick, 320); // 8 s at 40 Hz
    }

    #[test]
    fn waiting_at_a_light_is_not_stuck_but_times_out_after_forty_seconds() {
        let mut m = BlockedMonitor::new(8.0, 40.0, 1000.0);
        assert!(run(&mut m, 1000, 0.0, 0.0).is_empty());
        let mut m = BlockedMonitor::new(8.0, 40.0, 1000.0);
        let out = run(&mut m, 1700, 0.0, 0.0);
        assert_eq!(
            out.iter().map(|i| (i.kind, i.tick)).collect::<Vec<_>>(),
            vec![(InfractionKind::LowSpeedTimeout, 1600)]
        );
    }

    #[test]
    fn time_held_by_a_red_light_does_not_count_toward_the_low_speed_timeout() {
        // A light whose stop line crosses the ego's lane 1 m ahead of its front.
        let town = world::map::testtown::grid(3, 3, 60.0);
        let rules = Arc::new(RuleBook::new(&town));
        let line = *rules.stop_lines.on_lane(world::LaneIdx(0)).next().unwrap();
        let (x, y) = (line.position.x, line.position.y);
        let mut states = vec![world::LightState::Green; town.lights.len()];
        states[line.light.0 as usize] = world::LightState::Red;
        let green = vec![world::LightState::Green; town.lights.len()];
        // Stands with its front about 1 m before the line for `ticks` ticks under `lights`.
        let stand = |m: &mut BlockedMonitor, lights: &[world::LightState], ticks: usize| {
            let mut out = Vec::new();
            let poses = scripted::straight(x - 3.5, y, 0.0, ticks);
            scripted::drive(&poses, 0.0, lights, |t| {
                m.observe(
                    &EgoTick {
                        throttle: 0.0,
                        ..*t
                    },
                    &mut out,
                );
            });
            out
        };
        // 20 s on green, 30 s on red, then green again: the clock paused on
        // red and ends the run 20 s into the second green (40 s not held).
        let mut held = BlockedMonitor::new(8.0, 40.0, 1000.0).waiting_at_lights_of(rules.clone());
        assert!(stand(&mut held, &green, 800).is_empty());
        assert!(stand(&mut held, &states, 1200).is_empty());
        let out = stand(&mut held, &green, 1700);
        assert_eq!(
            out.iter().map(|i| (i.kind, i.tick)).collect::<Vec<_>>(),
            vec![(InfractionKind::LowSpeedTimeout, 800)]
        );
        // Without the rule book, the same red light times out at 40 s.
        let mut plain = BlockedMonitor::new(8.0, 40.0, 1000.0);
        let out = stand(&mut plain, &states, 1700);
        assert_eq!(
            out.iter().map(|i| (i.kind, i.tick)).collect::<Vec<_>>(),
            vec![(InfractionKind::LowSpeedTimeout, 1600)]
        );
    }

    #[test]
    fn driving_past_the_timeout_ends_the_run() {
        let mut m = BlockedMonitor::new(8.0, 40.0, 5.0);
        let out = run(&mut m, 400, 5.0, 0.5);
        assert_eq!(
            out.iter().map(|i| (i.kind, i.tick)).collect::<Vec<_>>(),
            vec![(InfractionKind::RouteTimeout, 200)]
        );
    }
}

#[cfg(test)]
mod collision_tests {
    use super::super::scripted;
    use super::*;

    #[test]
    fn standing_after_a_collision_counted_this_tick_is_stuck() {
        let mut m = BlockedMonitor::new(8.0, 40.0, 1000.0);
        let mut out = Vec::new();
        let poses = scripted::straight(0.0, 0.0, 0.0, 400);
        scripted::drive(&poses, 0.0, &[], |t| {
            let tick = EgoTick {
                throttle: 0.0,
                ..*t
            };
            if t.tick == 1 {
                out.push(Infraction::at(
                    &tick,
                    InfractionKind::CollisionVehicle,
                    "npc 3".into(),
                ));
            }
            m.observe(&tick, &mut out);
        });
        let stuck: Vec<u64> = out
            .iter()
            .filter(|i| i.kind == InfractionKind::Stuck)
            .map(|i| i.tick)
            .collect();
        assert_eq!(stuck, vec![320], "{out:?}");
    }
}
