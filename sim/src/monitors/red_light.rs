//! Red-light infractions as the paper's scorer counts them (TimeParam
//! `wor_common.py` `_check_red_light`, docs/protocol.md §3; docs/rule-book.md
//! says where CARLA's trigger volumes make ours differ). Each tick, unless the
//! ego is slower than 0.3 m/s: a red light's stop line is run when the ego's
//! tail segment (from its crossing point, 0.8 half-lengths behind the centre,
//! to 1.5 m behind the rear) lies across the line widened to 0.6 lane widths
//! each way, the ego facing the lane's direction and its tail on the line's
//! lane ([`world::rules::StopLineEntry::under_tail`]). One infraction per tick
//! at most, and the light counted last is not counted again until it is no
//! longer red. A car that stops with its nose over the line has not run it.

use std::sync::Arc;

use world::rules::{RuleBook, light_state};
use world::{LightIdx, LightState, Town};

use super::{EgoTick, Infraction, InfractionKind, Monitor};

/// Counts red-light infractions.
#[derive(Debug, Clone)]
pub struct RedLightMonitor {
    /// Ticks slower than this count nothing (metres per second; TimeParam's 0.3).
    pub min_speed_mps: f32,
    /// The town (its lanes, for the tail's lane).
    town: Arc<Town>,
    /// The town's rule tables (its stop lines).
    rules: Arc<RuleBook>,
    /// The light counted last, while it stays red (TimeParam `_last_red_light_id`).
    last: Option<LightIdx>,
}

impl RedLightMonitor {
    /// Watches the stop lines of a town's rule book.
    pub fn new(town: Arc<Town>, rules: Arc<RuleBook>) -> Self {
        Self {
            min_speed_mps: 0.3,
            town,
            rules,
            last: None,
        }
    }
}

impl Monitor for RedLightMonitor {
    /// Pushes an infraction if the ego runs a red light at this tick.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        if self
            .last
            .is_some_and(|l| light_state(tick.lights, l) != LightState::Red)
        {
            self.last = None;
        }
        if tick.speed_mps < self.min_speed_mps {
            return;
        }
        let (position, heading) = (tick.now.ground(), tick.now.heading);
        let length_m = tick.size_m.0;
        for line in self.rules.stop_lines.all() {
            if Some(line.light) == self.last
                || light_state(tick.lights, line.light) != LightState::Red
            {
                continue;
            }
            if line.under_tail(&self.town, position, heading, length_m) {
                out.push(Infraction::at(
                    tick,
                    InfractionKind::RedLight,
                    format!("light {}", line.light.0),
                ));
                self.last = Some(line.light);
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{EgoPose, scripted};
    use super::*;
    use world::{DriveLane, LaneIdx, StopLine, Town, TrafficLight, Vec2, Vec3};

    /// One light with a stop line across the lane y in [-3.5, 0] at x = 50,
    /// for traffic heading +x on the lane (road "1", lane -1) along y = -1.75,
    /// and the lane of road "1" beside it heading -x.
    fn town_with_light() -> Town {
        let lane = |y: f32, dir: f32, od_lane: i32| {
            let xs: Vec<f32> = (0..=100)
                .map(|i| {
                    if dir > 0.0 {
                        i as f32
                    } else {
                        100.0 - i as f32
                    }
                })
                .collect();
            DriveLane {
                road_id: "1".into(),
                od_lane,
                centerline: xs.iter().map(|&x| Vec3::new(x, y, 0.0)).collect(),
                s: (0..=100).map(|i| i as f32).collect(),
                width: vec![3.5; 101],
                speed_limit_mps: 8.0,
                junction: None,
                successors: Vec::new(),
                predecessors: Vec::new(),
                left: None,
                right: None,
            }
        };
        Town {
            lanes: vec![lane(-1.75, 1.0, -1), lane(1.75, -1.0, 1)],
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
        count_with(poses, speed, |_| state)
    }

    /// Counts with the light's state a function of the tick.
    fn count_with(poses: &[EgoPose], speed: f32, state: impl Fn(u64) -> LightState) -> usize {
        let town = Arc::new(town_with_light());
        let mut monitor = RedLightMonitor::new(town.clone(), Arc::new(RuleBook::new(&town)));
        let mut out = Vec::new();
        scripted::drive(poses, speed, &[LightState::Green], |t| {
            let lights = [state(t.tick)];
            let tick = EgoTick {
                lights: &lights,
                ..*t
            };
            monitor.observe(&tick, &mut out)
        });
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
    fn the_opposite_lane_does_not_count_and_reversing_forwards_facing_does_once() {
        let beside: Vec<EgoPose> = scripted::straight(20.0, 1.75, 6.0, 400);
        assert_eq!(count(&beside, 6.0, LightState::Red), 0);
        // TimeParam tests the heading, not the motion: backing over the line counts.
        let mut back = scripted::straight(20.0, -1.75, 6.0, 400);
        back.reverse();
        assert_eq!(count(&back, 6.0, LightState::Red), 1);
        // Facing the other way (the oncoming lane's direction) counts nothing.
        let turned: Vec<EgoPose> = back
            .iter()
            .map(|p| EgoPose {
                heading: std::f32::consts::PI,
                ..*p
            })
            .collect();
        assert_eq!(count(&turned, 6.0, LightState::Red), 0);
    }

    #[test]
    fn a_light_that_turns_red_over_the_tail_counts() {
        // 2 m/s: the tail segment (1.98 m long) is over the line for about 40 ticks.
        let poses = scripted::straight(40.0, -1.75, 2.0, 400);
        let over = (0..400u64).find(|&t| {
            let p = poses[t as usize];
            world::rules::StopLineEntry {
                light: LightIdx(0),
                lane: LaneIdx(0),
                s: 50.0,
                position: Vec2::new(50.0, -1.75),
                heading: 0.0,
                ends: [Vec2::new(50.0, 0.0), Vec2::new(50.0, -3.5)],
            }
            .under_tail(&town_with_light(), p.ground(), 0.0, 4.79)
        });
        let first = over.expect("the tail crosses the line");
        // Red from a few ticks after the crossing point passed: still counted.
        assert_eq!(
            count_with(&poses, 2.0, |t| if t > first + 5 {
                LightState::Red
            } else {
                LightState::Green
            }),
            1
        );
        // Red only once the tail's far end is past: not.
        assert_eq!(
            count_with(&poses, 2.0, |t| if t > first + 60 {
                LightState::Red
            } else {
                LightState::Green
            }),
            0
        );
    }

    #[test]
    fn the_line_is_six_tenths_of_a_lane_wide_each_way_on_its_own_lane() {
        // The lane's centre is y = -1.75, the line y in [-3.5, 0]: 0.6 lane widths
        // (2.1 m) reach y = 0.35 and y = -3.85.
        let at = |y: f32| count(&scripted::straight(20.0, y, 6.0, 400), 6.0, LightState::Red);
        assert_eq!(at(-3.7), 1);
        assert_eq!(at(-4.0), 0);
        // Within the widened line but nearer the oncoming lane: the tail's lane is not
        // the line's (TimeParam compares road and lane ids).
        assert_eq!(at(0.2), 0);
    }

    #[test]
    fn the_same_red_counts_once_and_a_new_red_again() {
        // Over the line, back, over again on the same red: once.
        let mut poses = scripted::straight(20.0, -1.75, 6.0, 400);
        let mut back = poses.clone();
        back.reverse();
        poses.extend(back.iter().map(|p| EgoPose {
            heading: std::f32::consts::PI,
            ..*p
        }));
        poses.extend(scripted::straight(20.0, -1.75, 6.0, 400));
        assert_eq!(count(&poses, 6.0, LightState::Red), 1);
        // A green while turned round: the next passage is a new red.
        let green_between = |t: u64| {
            if (500..700).contains(&t) {
                LightState::Green
            } else {
                LightState::Red
            }
        };
        assert_eq!(count_with(&poses, 6.0, green_between), 2);
    }

    #[test]
    fn creeping_over_below_the_speed_gate_counts_none() {
        let poses = scripted::straight(20.0, -1.75, 6.0, 400);
        assert_eq!(count(&poses, 0.29, LightState::Red), 0);
        assert_eq!(count(&poses, 0.3, LightState::Red), 1);
    }
}
