//! Timeouts that end a run (PROTOCOL §3): stuck (standing still while
//! pressing the throttle, or after a collision), low speed for too long, and
//! the route timeout.

use super::{EgoTick, Infraction, InfractionKind, Monitor};

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
        }
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
        self.standing_for_s = if standing {
            self.standing_for_s + tick_s
        } else {
            0.0
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
