//! Red-light infractions (docs/protocol.md §3, CARLA's `RunningRedLightTest`): the
//! ego crosses, in its driving direction, the stop line of a light that is
//! red, faster than 0.3 m/s. The point that must cross is the rule book's
//! crossing point ([`world::rules::crossing`]: 0.8 half-lengths behind the
//! centre), so a car that stops with its nose over the line has not run the
//! light; each crossing of a stop line is one passage, so one infraction.
//! The stop lines are the rule book's table ([`world::rules::StopLines`]).

use std::sync::Arc;

use world::LightState;
use world::road::geometry::crosses_stop_line;
use world::rules::{RuleBook, crossing_point};

use super::{EgoTick, Infraction, InfractionKind, Monitor};

/// Counts red-light infractions.
#[derive(Debug, Clone)]
pub struct RedLightMonitor {
    /// Only crossings faster than this count (metres per second).
    pub min_speed_mps: f32,
    /// The town's rule tables (its stop lines).
    rules: Arc<RuleBook>,
}

impl RedLightMonitor {
    /// Watches the stop lines of a town's rule book.
    pub fn new(rules: Arc<RuleBook>) -> Self {
        Self {
            min_speed_mps: 0.3,
            rules,
        }
    }
}

impl Monitor for RedLightMonitor {
    /// Pushes an infraction if the ego ran a red light during this tick.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        if tick.speed_mps <= self.min_speed_mps {
            return;
        }
        let length_m = tick.size_m.0;
        let from = crossing_point(tick.prev.ground(), tick.prev.heading, length_m);
        let to = crossing_point(tick.now.ground(), tick.now.heading, length_m);
        for line in self.rules.stop_lines.all() {
            let red = tick.lights.get(line.light.0 as usize).copied() == Some(LightState::Red);
            if red && crosses_stop_line(from, to, line.ends) {
                out.push(Infraction::at(
                    tick,
                    InfractionKind::RedLight,
                    format!("light {}", line.light.0),
                ));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{EgoPose, scripted};
    use super::*;
    use world::{LaneIdx, StopLine, Town, TrafficLight, Vec2, Vec3};

    /// One light with a stop line across the lane y in [-3.5, 0] at x = 50,
    /// for traffic heading +x.
    fn town_with_light() -> Town {
        Town {
            lights: vec![TrafficLight {
                od_id: "1".into(),
                position: Vec3::new(52.0, -5.0, 0.0),
                heading: std::f32::consts::PI,
                head_height_m: 5.0,
                junction: None,
                group: 0,
                stop_lines: vec![StopLine {
                    lane: LaneIdx(0),
                    s: 50.0,
                    ends: [Vec3::new(50.0, 0.0, 0.0), Vec3::new(50.0, -3.5, 0.0)],
                }],
            }],
            bounds: (Vec2::new(0.0, -5.0), Vec2::new(100.0, 5.0)),
            ..Town::empty("light")
        }
    }

    fn count(poses: &[EgoPose], speed: f32, state: LightState) -> usize {
        let mut monitor = RedLightMonitor::new(Arc::new(RuleBook::new(&town_with_light())));
        let mut out = Vec::new();
        scripted::drive(poses, speed, &[state], |t| monitor.observe(t, &mut out));
        out.len()
    }

    #[test]
    fn driving_through_a_red_light_counts_exactly_one() {
        let poses = scripted::straight(20.0, -1.75, 6.0, 400); // 20 m -> 80 m
        assert_eq!(count(&poses, 6.0, LightState::Red), 1);
    }

    #[test]
    fn driving_through_on_green_or_yellow_counts_none() {
        let poses = scripted::straight(20.0, -1.75, 6.0, 400);
        assert_eq!(count(&poses, 6.0, LightState::Green), 0);
        assert_eq!(count(&poses, 6.0, LightState::Yellow), 0);
    }

    #[test]
    fn standing_in_front_of_a_red_light_counts_none() {
        // Stopped with the nose 0.5 m past the line: the tail has not crossed.
        let mut poses = scripted::straight(20.0, -1.75, 6.0, 187); // centre at x = 48.05
        poses.extend(std::iter::repeat_n(*poses.last().unwrap(), 200));
        assert_eq!(count(&poses, 6.0, LightState::Red), 0);
        assert_eq!(count(&poses, 0.0, LightState::Red), 0);
    }

    #[test]
    fn the_opposite_lane_and_reversing_do_not_count() {
        let beside: Vec<EgoPose> = scripted::straight(20.0, 1.75, 6.0, 400);
        assert_eq!(count(&beside, 6.0, LightState::Red), 0);
        let mut back = scripted::straight(20.0, -1.75, 6.0, 400);
        back.reverse();
        assert_eq!(count(&back, 6.0, LightState::Red), 0);
    }
}
