//! Waiting in a queue at a red light: the moments of a run at which the ego
//! stands behind a stopped vehicle while the next light on its route says stop.
//! Issue 33 found every shipped policy running into such queues on Town02; the
//! closed-loop check of issue 48 asks the retrained RA to wait in them.
//!
//! Each part is the rule `mrdrive data info` counts its frames with, so a run's
//! moments and a dataset's counts mean the same: the ego stands below
//! [`STOPPED_MPS`]; a vehicle stands in its corridor straight ahead
//! ([`stopped_vehicle_ahead`]); the next stop line on its route within
//! [`crate::info::RED_LIGHT_RANGE_M`] has a light that says stop
//! ([`crate::info::approaching_red`]).

use sim::camera::Camera;
use sim::error::RunError;
use sim::observe::{RunObserver, TickView};
use world::rules::{RouteStops, StopLines};

use crate::format::{ActorRow, EgoRow, STOPPED_MPS, light_code, stopped_vehicle_ahead};
use crate::info::approaching_red;

/// One tick at which the ego waited in a queue at a red light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QueueMoment {
    /// The tick.
    pub tick: u64,
    /// Simulated time at its end (seconds).
    pub time_s: f64,
    /// The gap to the stopped vehicle ahead (metres, from the ego's centre to its
    /// near edge).
    pub gap_m: f32,
}

/// The gap to the stopped vehicle the ego waits behind (metres), when it stands
/// (below [`STOPPED_MPS`]) behind one and `at_red` (the next light on its route
/// says stop); `None` otherwise.
pub fn waiting_behind(ego: &EgoRow, actors: &[ActorRow], at_red: bool) -> Option<f32> {
    if !at_red || ego.speed.abs() >= STOPPED_MPS {
        return None;
    }
    stopped_vehicle_ahead(ego, actors)
}

/// Watches a run for [`QueueMoment`]s (hand it to `sim::build::run_scenario_with`).
#[derive(Debug, Default)]
pub struct QueueWatch {
    /// The route's stop lines, found at the first tick.
    stops: Option<RouteStops>,
    /// Every tick at which the ego waited in a queue at a red light, in order.
    pub moments: Vec<QueueMoment>,
    /// The tick's light codes and other actors, kept between ticks (no allocation a tick).
    lights: Vec<u8>,
    actors: Vec<ActorRow>,
}

impl QueueWatch {
    /// The separate waits: each run of consecutive waiting ticks as its first
    /// tick's time and its length (seconds, first to last tick), in order.
    pub fn waits(&self) -> Vec<(f64, f64)> {
        let mut out: Vec<(f64, f64)> = Vec::new();
        let mut last_tick = None;
        for m in &self.moments {
            match out.last_mut() {
                Some((start, len)) if last_tick == Some(m.tick - 1) => *len = m.time_s - *start,
                _ => out.push((m.time_s, 0.0)),
            }
            last_tick = Some(m.tick);
        }
        out
    }
}

impl RunObserver for QueueWatch {
    fn on_tick(
        &mut self,
        view: &TickView<'_>,
        _camera: Option<&mut dyn Camera>,
    ) -> Result<(), RunError> {
        let stops = self
            .stops
            .get_or_insert_with(|| StopLines::new(view.town).on_route(view.route));
        self.lights.clear();
        self.lights
            .extend(view.lights.iter().map(|&s| light_code(s)));
        let at_red = approaching_red(stops, view.route_s, &self.lights);
        let ego = EgoRow::of(view.ego());
        self.actors.clear();
        self.actors
            .extend(view.actors[1..].iter().map(ActorRow::of));
        if let Some(gap_m) = waiting_behind(&ego, &self.actors, at_red) {
            self.moments.push(QueueMoment {
                tick: view.tick,
                time_s: view.time_s,
                gap_m,
            });
        }
        Ok(())
    }

    /// It reads the world, not the controls: the run may overlap its driver.
    fn reads_computed(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ego(speed: f32) -> EgoRow {
        EgoRow {
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
            speed,
        }
    }

    fn car(x: f32, speed: f32) -> ActorRow {
        ActorRow {
            kind: ActorRow::VEHICLE,
            id: 3,
            x,
            y: 0.0,
            yaw: 0.0,
            length: 4.5,
            width: 1.9,
            speed,
        }
    }

    #[test]
    fn the_ego_waits_when_it_stands_behind_a_stopped_car_at_a_red_light() {
        let gap = waiting_behind(&ego(0.0), &[car(7.0, 0.0)], true).expect("a queue");
        assert!((4.0..5.0).contains(&gap), "{gap} m to the car's rear");
        assert_eq!(
            waiting_behind(&ego(0.0), &[car(7.0, 0.0)], false),
            None,
            "green"
        );
        assert_eq!(
            waiting_behind(&ego(2.0), &[car(7.0, 0.0)], true),
            None,
            "the ego still rolls"
        );
        assert_eq!(
            waiting_behind(&ego(0.0), &[car(7.0, 3.0)], true),
            None,
            "the car ahead drives"
        );
        assert_eq!(waiting_behind(&ego(0.0), &[], true), None, "no car");
    }

    #[test]
    fn consecutive_ticks_make_one_wait() {
        let at = |tick: u64| QueueMoment {
            tick,
            time_s: tick as f64 * 0.025,
            gap_m: 4.0,
        };
        let watch = QueueWatch {
            moments: [10, 11, 12, 20, 30, 31].into_iter().map(at).collect(),
            ..QueueWatch::default()
        };
        let waits = watch.waits();
        let rounded: Vec<(f64, f64)> = waits
            .iter()
            .map(|&(s, l)| ((s * 1000.0).round() / 1000.0, (l * 1000.0).round() / 1000.0))
            .collect();
        assert_eq!(rounded, vec![(0.25, 0.05), (0.5, 0.0), (0.75, 0.025)]);
        assert!(QueueWatch::default().waits().is_empty());
    }
}
