//! Collisions as they happen: every contact recorded as a touch
//! ([`super::contacts`]) and counted under the paper's rule
//! ([`super::counting::paper`], docs/protocol.md §3). The record counts the
//! same touches under every rule at the run's end.

use super::contacts::{ContactLog, Touch};
use super::counting::{CountingRule, collision_kind};
use super::{EgoTick, Infraction, Monitor};

/// Records the ego's touches and reports the collisions the paper's rule counts.
#[derive(Debug, Clone, Default)]
pub struct CollisionMonitor {
    log: ContactLog,
}

impl CollisionMonitor {
    /// Every touch so far.
    pub fn touches(&self) -> &[Touch] {
        self.log.touches()
    }

    /// Takes the touches out (at the run's end).
    pub fn into_touches(self) -> Vec<Touch> {
        self.log.into_touches()
    }
}

impl Monitor for CollisionMonitor {
    /// Records this tick's touches; pushes the collisions that count.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        let added = self.log.observe(tick, tick.kerbs);
        if added == 0 {
            return;
        }
        let touches = self.log.touches();
        let first_new = touches.len() - added;
        for i in CountingRule::Paper.counted(touches) {
            if i < first_new {
                continue;
            }
            let t = &touches[i];
            let detail = match t.actor {
                Some(id) => format!("actor {id}"),
                None => format!("a {}", t.what),
            };
            out.push(Infraction::at(tick, collision_kind(t), detail));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::scripted::{self, CAR, TREE, WALKER, WALL};
    use super::super::{EgoContact, InfractionKind};
    use super::*;

    /// Drives 100 ticks at `speed`, touching `contact_at(tick)`.
    fn count(speed: f32, contact_at: impl Fn(u64) -> Vec<EgoContact>) -> Vec<InfractionKind> {
        let mut monitor = CollisionMonitor::default();
        let mut out = Vec::new();
        scripted::touching(speed, 100, contact_at, |t| monitor.observe(t, &mut out));
        out.into_iter().map(|i| i.kind).collect()
    }

    #[test]
    fn a_long_contact_with_one_car_counts_once() {
        assert_eq!(
            count(5.0, |t| if (10..40).contains(&t) {
                vec![CAR]
            } else {
                vec![]
            }),
            vec![InfractionKind::CollisionVehicle]
        );
    }

    #[test]
    fn the_same_actor_never_counts_twice() {
        let got = count(5.0, |t| {
            if t == 10 || t == 80 {
                vec![CAR]
            } else {
                vec![]
            }
        });
        assert_eq!(got, vec![InfractionKind::CollisionVehicle]);
    }

    #[test]
    fn each_actor_counts_once_and_the_map_is_one_actor() {
        let got = count(5.0, |t| match t {
            10 => vec![CAR],
            11 => vec![WALKER], // right after another: counted (no cooldown across actors)
            30 => vec![WALL],
            90 => vec![TREE], // more map geometry: the same actor
            _ => vec![],
        });
        assert_eq!(
            got,
            vec![
                InfractionKind::CollisionVehicle,
                InfractionKind::CollisionPedestrian,
                InfractionKind::CollisionStatic
            ]
        );
    }

    #[test]
    fn contacts_while_standing_still_count() {
        assert_eq!(
            count(0.0, |_| vec![CAR]),
            vec![InfractionKind::CollisionVehicle]
        );
    }

    /// A car steered off its lane in the grid town climbs the sidewalk's 0.15 m
    /// kerb: both axles are recorded, and the mount is one static collision for
    /// the paper and none for leaderboard 1.0.
    #[test]
    fn a_kerb_mount_in_a_hand_made_town_is_recorded_and_counted_by_each_rule() {
        use crate::monitors::contacts::TouchWith;
        use std::sync::Arc;
        use world::agents::VehicleControl;
        use world::map::testtown::grid;
        use world::traffic::{EgoStart, Traffic, TrafficConfig};
        use world::{LightState, Vec2};

        let town = Arc::new(grid(3, 1, 100.0));
        let start = EgoStart {
            position: Vec2::new(30.0, -1.75),
            z: 0.0,
            yaw: -0.25,
        };
        let cfg = TrafficConfig {
            vehicles: 0,
            pedestrians: 0,
            ..Default::default()
        };
        let mut tr = Traffic::new(town.clone(), cfg, Some(start));
        tr.set_ego_control(VehicleControl {
            steer: 0.0,
            throttle: 0.6,
            brake: 0.0,
        });
        let lights = vec![LightState::Green; town.lights.len()];
        let pose = |tr: &Traffic| {
            let e = tr.ego().unwrap();
            world::EgoPose {
                position: e.state.position.extend(e.z),
                heading: e.state.yaw,
            }
        };
        let mut monitor = CollisionMonitor::default();
        let mut out = Vec::new();
        for tick in 1..=400u64 {
            let prev = pose(&tr);
            tr.step(&lights);
            let e = tr.ego().unwrap();
            let t = EgoTick {
                tick,
                time_s: tick as f64 * 0.025,
                prev,
                now: pose(&tr),
                speed_mps: e.state.speed_mps,
                size_m: (4.79, 2.16),
                throttle: 0.6,
                contacts: &[],
                kerbs: &e.kerbs,
                route_progress_m: 0.0,
                lights: &lights,
                dt_s: 0.025,
            };
            monitor.observe(&t, &mut out);
            if monitor.touches().len() >= 2 {
                break;
            }
        }
        let touches = monitor.touches();
        assert_eq!(touches.len(), 2, "{touches:?}");
        for (t, front) in touches.iter().zip([true, false]) {
            let k = t.kerb.expect("a kerb touch");
            assert_eq!((t.with, t.what.as_str()), (TouchWith::Kerb, "kerb up"));
            assert_eq!(k.front_axle, front);
            assert!((k.height_m - 0.15).abs() < 1e-4);
            assert!(k.speed_mps.1 < k.speed_mps.0, "{k:?}");
        }
        let kinds: Vec<InfractionKind> = out.iter().map(|i| i.kind).collect();
        assert_eq!(kinds, [InfractionKind::CollisionStatic]);
        assert_eq!(CountingRule::Paper.count(touches).static_, 1);
        assert_eq!(CountingRule::Leaderboard1.count(touches).total(), 0);
    }
}
