//! The expert: a privileged autopilot, the data source for training and the
//! upper bound in every table.
//!
//! It reads the simulator's exact state ([`Privileged`]) and drives the dense
//! route:
//!
//! - **Lateral**: pure pursuit on the route from the rear axle, looking
//!   [`rules::pursuit_lookahead_m`] ahead, converted to a steer value through
//!   the vehicle model's inverse (`VehicleParams::steer_for_curvature`).
//! - **Speed**: 6 m/s on turns (a LEFT/RIGHT command within 10 m), 6.5 m/s
//!   otherwise, never above the lane's limit (docs/protocol.md §5's target speeds).
//! - **Stops**: for a light it must stop for ([`rules::must_stop`]: red, or
//!   yellow when it can still stop at `stop_decel_mps2`), at a stop line of
//!   the route within 40 m ([`rules::RouteStops`], given in the privileged
//!   view; every one in that range, not only the nearest) that its crossing
//!   point has not passed ([`rules::crossing`]), it brakes to stand 1 m
//!   before the line; for the nearest
//!   vehicle or pedestrian ahead on its route (the same "ahead" query the
//!   NPCs use: a corridor around the route) it keeps a gap of 4 m: it stops
//!   behind a standing one and follows a moving one with a braking profile
//!   `v = sqrt(2 a d)` plus the leader's speed.
//! - **Junctions without lights**: while another vehicle holds a connecting
//!   lane that conflicts with its own ([`rules::junction_yield`], the table
//!   the NPCs' reservations use), it stops 1 m before the junction, as for a
//!   stop line; once its front is inside, it goes on.
//! - **Lane changes**: the route's `ChangeLaneLeft`/`ChangeLaneRight` points
//!   move it across by pursuit; while the lane it moves into has no room
//!   ([`rules::lane_change_clear`]: 5 m ahead, 2 s of the follower's speed
//!   behind) it waits before the change.
//! - **Pedals**: a proportional speed controller asks for an acceleration,
//!   which the vehicle model's inverse turns into throttle or brake; standing
//!   at a stop it holds the brake. It drives on by itself once the light turns
//!   green or the way is free.

use world::Command;
use world::rules;

use crate::driver::{Driver, DriverNeeds, Observation, Privileged, VehicleControl};

/// Where a car driving `route` must wait, as the runner hands it to the
/// expert: before a junction without lights while `held(lane)` says another
/// vehicle holds a lane conflicting with the route's (or, where the map
/// gives a lane priority over the route's, is about to take it)
/// ([`Privileged::junction_yield_s`]), and before a lane change while the
/// target lane has no room among `actors` ([`Privileged::lane_change_wait_s`]);
/// `ego` is the car, `route_index` the route point it has reached.
pub fn waits(
    town: &world::Town,
    route: &world::route::DenseRoute,
    route_index: usize,
    ego: &world::ActorSnapshot,
    held: impl Fn(world::LaneIdx) -> bool,
    actors: &[rules::ActorView],
) -> (Option<f32>, Option<f32>) {
    let position = ego.position.truncate();
    let half_length = ego.extent.x / 2.0;
    let front_s = rules::route_s_at(route, route_index, position) + half_length;
    (
        rules::junction_yield(town, route, front_s, rules::YIELD_RANGE_M, held),
        rules::lane_change_wait(town, route, front_s, half_length, ego.id, actors),
    )
}

/// The expert's tuning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExpertParams {
    /// Cruise speed (metres per second).
    pub cruise_mps: f32,
    /// Speed on turns (metres per second).
    pub turn_mps: f32,
    /// A turn command within this distance ahead slows to `turn_mps` (metres).
    pub turn_lookahead_m: f32,
    /// Deceleration used to plan stops (metres per second squared).
    pub stop_decel_mps2: f32,
    /// Where the front bumper stops before a stop line (metres).
    pub stop_margin_m: f32,
    /// Gap kept to the actor ahead (metres, bumper to footprint).
    pub gap_m: f32,
    /// Proportional gain from speed error to acceleration (1 / second).
    pub speed_gain_per_s: f32,
    /// Largest acceleration asked for (metres per second squared).
    pub max_accel_mps2: f32,
}

impl Default for ExpertParams {
    fn default() -> Self {
        Self {
            cruise_mps: 6.5,
            turn_mps: 6.0,
            turn_lookahead_m: 10.0,
            stop_decel_mps2: 3.0,
            stop_margin_m: 1.0,
            gap_m: 4.0,
            speed_gain_per_s: 1.5,
            max_accel_mps2: 2.5,
        }
    }
}

/// The privileged autopilot.
#[derive(Debug, Clone)]
pub struct Expert {
    /// Its tuning.
    pub params: ExpertParams,
}

impl Expert {
    /// An expert with this tuning; it reads its route and the stop lines on
    /// it from the privileged view.
    pub fn new(params: ExpertParams) -> Self {
        Self { params }
    }

    /// The speed it wants now (metres per second), and the distance from its
    /// front bumper to where it must stand, if it must stop (metres).
    fn desired_speed(&self, p: &Privileged<'_>, ego_s: f32) -> (f32, Option<f32>) {
        let prm = &self.params;
        let v = p.ego.speed_mps.max(0.0);
        let i = p.route_index.min(p.route.points.len().saturating_sub(1));
        let command = p.route.command_ahead(i, prm.turn_lookahead_m);
        let here = p.route.points.get(i).map(|q| q.command);
        let turning = matches!(command, Command::Left | Command::Right)
            || matches!(here, Some(Command::Left | Command::Right));
        let mut want = if turning {
            prm.turn_mps
        } else {
            prm.cruise_mps
        };
        if let Some(q) = p.route.points.get(i) {
            want = want.min(p.town.lane(q.lane).speed_limit_mps.max(1.0));
        }
        let mut stop_at: Option<f32> = None;
        let half_length = p.ego.extent.x / 2.0;
        let front_s = ego_s + half_length;
        // Lights: the stop lines within 40 m the car has not yet passed (its
        // crossing point, the red-light monitor's, is not over the line, so a
        // car whose nose overshot a stop line on red waits there instead of
        // driving on), nearest first: the first it must stop for holds it.
        // Two lit junctions closer than that (Town03's road 77) are judged
        // both, as the NPCs do.
        let tail_s = ego_s - rules::crossing_offset_m(p.ego.extent.x);
        for stop in p.stops.after(tail_s) {
            let to_line = stop.route_s - front_s;
            let d = to_line - prm.stop_margin_m;
            if d >= 40.0 {
                break;
            }
            let state = rules::light_state(p.lights, stop.light);
            if rules::must_stop(state, to_line, v, prm.stop_decel_mps2) {
                stop_at = Some(d);
                break;
            }
        }
        // A junction without lights whose conflicting lanes another vehicle
        // holds: wait before it, as for a stop line.
        // And before a lane change whose target lane has no room.
        for wait_s in [p.junction_yield_s, p.lane_change_wait_s]
            .into_iter()
            .flatten()
        {
            let d = wait_s - front_s - prm.stop_margin_m;
            stop_at = Some(stop_at.map_or(d, |s| s.min(d)));
        }
        // Actors on the route ahead.
        if let Some(a) = p.ahead {
            let gap = a.distance_m - half_length - prm.gap_m;
            if a.speed_along_mps < 0.5 {
                stop_at = Some(stop_at.map_or(gap, |d| d.min(gap)));
            } else {
                let follow = (2.0 * prm.stop_decel_mps2 * gap.max(0.0)).sqrt() + a.speed_along_mps;
                want = want.min(if gap <= 0.0 { 0.0 } else { follow });
            }
        }
        if let Some(d) = stop_at {
            want = want.min((2.0 * prm.stop_decel_mps2 * d.max(0.0)).sqrt());
            if d < 0.3 {
                want = 0.0;
            }
        }
        (want, stop_at)
    }

    /// The control for a privileged view.
    pub fn control(&self, p: &Privileged<'_>) -> VehicleControl {
        let prm = &self.params;
        let v = p.ego.speed_mps.max(0.0);
        let ego_s = rules::route_s_at(p.route, p.route_index, p.ego.position.truncate());
        // Lateral: pure pursuit from the rear axle, so the rear wheels follow
        // the lane through tight turns instead of cutting across the curb.
        let rear_wb = p.vehicle.rear_wb_m;
        let forward = world::Vec2::from_angle(p.ego.heading);
        let rear = p.ego.position.truncate() - forward * rear_wb;
        let lookahead = rules::pursuit_lookahead_m(v);
        let target = rules::route_point_at(p.route, p.route_index, ego_s - rear_wb + lookahead)
            .unwrap_or(p.ego.position.truncate());
        let rel = target - rear;
        let (dx, dy) = (rel.dot(forward), rel.dot(forward.perp()));
        let d2 = (dx * dx + dy * dy).max(1e-3);
        let steer = p.vehicle.steer_for_curvature(2.0 * dy / d2);
        // Longitudinal: a speed controller, with a braking feed-forward when
        // a stop is near (the deceleration that stands the car exactly there).
        let (want, stop_at) = self.desired_speed(p, ego_s);
        if want < 0.05 && v < 0.3 {
            return VehicleControl {
                steer,
                ..VehicleControl::BRAKE
            };
        }
        let mut accel = (prm.speed_gain_per_s * (want - v))
            .clamp(-p.vehicle.brake_decel_mps2, prm.max_accel_mps2);
        if let Some(d) = stop_at {
            let needed = v * v / (2.0 * d.max(0.05));
            if needed > 0.5 * prm.stop_decel_mps2 {
                accel = accel.min(-needed);
            }
        }
        let (throttle, brake) = p.vehicle.pedals_for_accel(accel, v);
        VehicleControl {
            steer,
            throttle,
            brake,
        }
    }
}

impl Driver for Expert {
    fn name(&self) -> String {
        "expert".into()
    }

    fn needs(&self) -> DriverNeeds {
        DriverNeeds {
            camera: false,
            privileged: true,
            labels: false,
        }
    }

    fn act(&mut self, obs: &Observation<'_>) -> VehicleControl {
        match obs.privileged {
            Some(p) => self.control(p),
            // The loop gives privileged state to drivers that ask for it; if
            // it ever did not, standing still is the safe answer.
            None => VehicleControl::BRAKE,
        }
    }
}

#[cfg(test)]
mod tests {
    //! Scripted situations on the grid test town, the ego driven by the
    //! vehicle model from the expert's controls at every 40 Hz tick.
    use super::*;
    use crate::runner::{AHEAD_CORRIDOR_M, AHEAD_RANGE_M};
    use world::agents::{VehicleParams, VehicleState};
    use world::map::testtown::{grid, planned_route};
    use world::route::DenseRoute;
    use world::rules::{ActorView, nearest_ahead, walker_horizon_s};
    use world::rules::{RouteStops, StopLines};
    use world::{ActorKind, ActorSnapshot, LightState, Town, Vec2, Vec3};

    const DT: f32 = 0.025;

    /// A situation: the grid town, a planned route, its stops, the lights
    /// and the other actors (moved by `script` each tick).
    struct Scene {
        town: Town,
        route: DenseRoute,
        stops: RouteStops,
        lights: Vec<LightState>,
        actors: Vec<ActorView>,
        /// Until when (seconds of the drive) another vehicle holds every lane
        /// that conflicts with the ego's at a junction without lights.
        held_until_s: f32,
    }

    /// What happened at one tick.
    #[derive(Debug, Clone, Copy)]
    struct Tick {
        state: VehicleState,
        control: VehicleControl,
        ahead: Option<world::rules::Ahead>,
    }

    impl Scene {
        /// The 3 x 3 grid town (junctions 60 m apart; the one at (60, 0) is
        /// lit, its west stop line at x = 46 on lane y = -1.75) and a route
        /// through `waypoints` (x, y, heading).
        fn new(waypoints: &[(f32, f32, f32)], light: LightState) -> Scene {
            let town = grid(3, 3, 60.0);
            let lights = vec![light; town.lights.len()];
            Scene::on(town, waypoints, lights)
        }

        /// [`Scene::new`] in the grid town without its lights.
        fn unlit(waypoints: &[(f32, f32, f32)]) -> Scene {
            let mut town = grid(3, 3, 60.0);
            town.lights.clear();
            Scene::on(town, waypoints, Vec::new())
        }

        /// A route through `waypoints` (x, y, heading) in `town`, its lights in `lights`.
        fn on(town: Town, waypoints: &[(f32, f32, f32)], lights: Vec<LightState>) -> Scene {
            let route = planned_route(&town, waypoints).unwrap();
            let stops = StopLines::new(&town).on_route(&route);
            Scene {
                town,
                route,
                stops,
                lights,
                actors: Vec::new(),
                held_until_s: 0.0,
            }
        }

        /// Drives the ego from the route's start, at rest, for `seconds`;
        /// `script(t, actors)` moves the other actors before each tick.
        fn drive(
            &mut self,
            seconds: f32,
            mut script: impl FnMut(f32, &mut Vec<ActorView>),
        ) -> Vec<Tick> {
            let vp = VehicleParams::default();
            let expert = Expert::new(ExpertParams::default());
            let start = self.route.points[0];
            let mut state = VehicleState::at_rest(start.position.truncate(), start.heading);
            let mut index = 0;
            let mut path = Vec::new();
            let mut out = Vec::new();
            for k in 0..(seconds / DT).round() as usize {
                let t = k as f32 * DT;
                script(t, &mut self.actors);
                index = rules::nearest_route_point(&self.route, state.position, index, 40)
                    .map_or(index, |(i, _)| i);
                rules::route_ahead(&self.route, index, state.position, AHEAD_RANGE_M, &mut path);
                let ahead = nearest_ahead(
                    &path,
                    &self.actors,
                    Some(0),
                    AHEAD_CORRIDOR_M,
                    AHEAD_RANGE_M,
                    walker_horizon_s(state.speed_mps),
                );
                let ego = ActorSnapshot {
                    id: 0,
                    kind: ActorKind::Ego,
                    position: state.position.extend(0.0),
                    heading: state.yaw,
                    extent: Vec3::new(vp.length_m, vp.width_m, vp.height_m),
                    speed_mps: state.speed_mps,
                    color: 0,
                };
                let held = t < self.held_until_s;
                let (junction_yield_s, lane_change_wait_s) =
                    waits(&self.town, &self.route, index, &ego, |_| held, &self.actors);
                let p = Privileged {
                    town: &self.town,
                    route: &self.route,
                    route_index: index,
                    ego,
                    lights: &self.lights,
                    stops: &self.stops,
                    ahead,
                    junction_yield_s,
                    lane_change_wait_s,
                    vehicle: &vp,
                };
                let control = expert.control(&p);
                state.step(&vp, control, DT);
                out.push(Tick {
                    state,
                    control,
                    ahead,
                });
            }
            out
        }
    }

    fn front_x(t: &Tick) -> f32 {
        t.state.position.x + VehicleParams::default().length_m / 2.0
    }

    /// East along y = -1.75 from x = 15 through the junction at (60, 0) to x = 100.
    const EAST: [(f32, f32, f32); 2] = [(15.0, -1.75, 0.0), (100.0, -1.75, 0.0)];

    #[test]
    fn it_stops_before_a_red_light_and_goes_on_green() {
        let mut scene = Scene::new(&EAST, LightState::Red);
        assert_eq!(scene.stops.all().len(), 1);
        let line_x = 46.0;
        let ticks = scene.drive(20.0, |_, _| {});
        let last = ticks.last().unwrap();
        assert!(last.state.speed_mps < 0.05, "{:?}", last.state);
        assert!(
            last.control.brake > 0.5,
            "holds the brake: {:?}",
            last.control
        );
        // It reached cruising speed on the way, braked, and stands about
        // `stop_margin_m` before the line, its front never over it.
        let top = ticks.iter().map(|t| t.state.speed_mps).fold(0.0, f32::max);
        assert!(top > 5.0, "top speed {top}");
        let max_front = ticks.iter().map(front_x).fold(f32::MIN, f32::max);
        assert!(max_front < line_x, "front reached x = {max_front}");
        assert!(
            front_x(last) > line_x - 2.0,
            "stopped at {} m before the line",
            line_x - front_x(last)
        );
        // Green: it drives through.
        scene.lights.fill(LightState::Green);
        let ticks = scene.drive(20.0, |_, _| {});
        assert!(ticks.iter().any(|t| t.state.position.x > 80.0));
    }

    #[test]
    fn it_stops_for_a_red_line_just_past_a_green_one() {
        // Two lights' lines 6 m apart on the route (two lit junctions that
        // close): the nearer green, the farther red. It stops before the red
        // one; looking at the nearer line alone, it would see the red one only
        // once past the green one, 3 m before it at cruise speed.
        let mut scene = Scene::new(&EAST, LightState::Red);
        let line_x = 46.0;
        let (red, line) = scene
            .town
            .lights
            .iter()
            .enumerate()
            .find_map(|(i, l)| {
                let sl = l
                    .stop_lines
                    .iter()
                    .find(|sl| (sl.ends[0].x - line_x).abs() < 0.5)?;
                Some((i, sl.clone()))
            })
            .expect("the west stop line at x = 46");
        let green = (red + 1) % scene.town.lights.len();
        let shift = Vec3::new(-6.0, 0.0, 0.0);
        scene.town.lights[green].stop_lines.push(world::StopLine {
            lane: line.lane,
            s: line.s - 6.0,
            ends: [line.ends[0] + shift, line.ends[1] + shift],
        });
        scene.stops = StopLines::new(&scene.town).on_route(&scene.route);
        assert_eq!(scene.stops.all().len(), 2);
        scene.lights.fill(LightState::Green);
        scene.lights[red] = LightState::Red;
        let ticks = scene.drive(20.0, |_, _| {});
        let max_front = ticks.iter().map(front_x).fold(f32::MIN, f32::max);
        assert!(max_front < line_x, "front reached x = {max_front}");
        assert!(ticks.last().unwrap().state.speed_mps < 0.05);
    }

    #[test]
    fn it_waits_before_a_junction_without_lights_until_the_conflict_clears() {
        let mut scene = Scene::unlit(&EAST);
        assert!(scene.stops.all().is_empty());
        let entry_x = scene
            .route
            .points
            .iter()
            .find(|p| scene.town.lane(p.lane).junction.is_some())
            .unwrap()
            .position
            .x;
        // Held for 12 s: it stops before the junction, its front outside it.
        scene.held_until_s = 12.0;
        let ticks = scene.drive(24.0, |_, _| {});
        let waiting: Vec<&Tick> = ticks[..(12.0 / DT) as usize].iter().collect();
        let max_front = waiting.iter().map(|t| front_x(t)).fold(f32::MIN, f32::max);
        assert!(
            max_front < entry_x,
            "front reached x = {max_front} (entry {entry_x})"
        );
        let stood = waiting.last().unwrap();
        assert!(stood.state.speed_mps < 0.05, "{:?}", stood.state);
        assert!(
            front_x(stood) > entry_x - 2.5,
            "stopped {} m short",
            entry_x - front_x(stood)
        );
        // Free: it drives through.
        assert!(ticks.iter().any(|t| t.state.position.x > 80.0));
        // Never held: it does not stop at all.
        scene.held_until_s = 0.0;
        let ticks = scene.drive(15.0, |_, _| {});
        let slowest_in_junction = ticks
            .iter()
            .filter(|t| (entry_x - 5.0..entry_x + 5.0).contains(&front_x(t)))
            .map(|t| t.state.speed_mps)
            .fold(f32::MAX, f32::min);
        assert!(slowest_in_junction > 3.0, "{slowest_in_junction}");
    }

    #[test]
    fn it_changes_lanes_only_into_a_gap() {
        // 100 m in the right lane of a straight two-lane road, then into the left one.
        let mut scene = Scene::on(
            world::map::testtown::two_lane_road(300.0),
            &[(10.0, -1.75, 0.0), (100.0, -1.75, 0.0), (290.0, 1.75, 0.0)],
            Vec::new(),
        );
        let start_x = scene
            .route
            .points
            .iter()
            .find(|p| p.command == Command::ChangeLaneLeft)
            .unwrap()
            .position
            .x;
        let vp = VehicleParams::default();
        let blocker = ActorView {
            id: 1,
            kind: ActorKind::Vehicle,
            position: Vec2::new(start_x - 2.0, 1.75),
            yaw: 0.0,
            speed_mps: 0.0,
            half_length_m: vp.length_m / 2.0,
            half_width_m: vp.width_m / 2.0,
        };
        // A car stands in the target lane where the change starts, for the first 30 s.
        let ticks = scene.drive(60.0, |t, actors| {
            actors.clear();
            if t < 30.0 {
                actors.push(blocker);
            }
        });
        let before: Vec<&Tick> = ticks[..(30.0 / DT) as usize].iter().collect();
        // While it stands there, the ego stays in its lane, before the change.
        let max_front = before.iter().map(|t| front_x(t)).fold(f32::MIN, f32::max);
        assert!(
            max_front < start_x,
            "front reached x = {max_front} (change at {start_x})"
        );
        assert!(before.iter().all(|t| t.state.position.y < -1.0));
        // Once it has gone, the ego moves across and drives on in the left lane.
        let last = ticks.last().unwrap();
        assert!(last.state.position.x > start_x + 30.0, "{:?}", last.state);
        assert!(
            (last.state.position.y - 1.75).abs() < 0.5,
            "{:?}",
            last.state
        );
    }

    #[test]
    fn it_stops_behind_a_standing_car_with_a_gap() {
        let mut scene = Scene::new(&EAST, LightState::Green);
        // A car standing on the lane at x = 40 (its rear at 37.6).
        let vp = VehicleParams::default();
        scene.actors.push(ActorView {
            id: 1,
            kind: ActorKind::Vehicle,
            position: Vec2::new(40.0, -1.75),
            yaw: 0.0,
            speed_mps: 0.0,
            half_length_m: vp.length_m / 2.0,
            half_width_m: vp.width_m / 2.0,
        });
        let rear_x = 40.0 - vp.length_m / 2.0;
        let ticks = scene.drive(15.0, |_, _| {});
        let last = ticks.last().unwrap();
        assert!(last.state.speed_mps < 0.05, "{:?}", last.state);
        assert_eq!(last.ahead.map(|a| a.id), Some(1));
        let gaps: Vec<f32> = ticks.iter().map(|t| rear_x - front_x(t)).collect();
        let min_gap = gaps.iter().copied().fold(f32::MAX, f32::min);
        assert!(min_gap > 3.0, "came within {min_gap} m");
        let gap = rear_x - front_x(last);
        assert!(
            (3.0..5.0).contains(&gap),
            "stands {gap} m behind (gap_m = 4)"
        );
    }

    #[test]
    fn it_brakes_for_a_pedestrian_stepping_out() {
        // A walker on the sidewalk at x = 45 (y = -7) steps out at 2 s and
        // walks north at 1.5 m/s to the lane's centre, where it stays: it
        // enters the ego's corridor at about 4.4 s, when the ego, cruising,
        // is some 10 m away.
        let walker = |t: f32, actors: &mut Vec<ActorView>| {
            let y = (-7.0 + 1.5 * (t - 2.0).max(0.0)).min(-1.75);
            actors.clear();
            actors.push(ActorView {
                id: 7,
                kind: ActorKind::Pedestrian,
                position: Vec2::new(45.0, y),
                yaw: std::f32::consts::FRAC_PI_2,
                speed_mps: if t > 2.0 && y < -1.75 { 1.5 } else { 0.0 },
                half_length_m: 0.3,
                half_width_m: 0.3,
            });
        };
        let mut free = Scene::new(&EAST, LightState::Green);
        let alone = free.drive(9.0, |_, _| {});
        // Without the walker it passes x = 45 at speed.
        assert!(
            alone
                .iter()
                .any(|t| t.state.position.x > 46.0 && t.state.speed_mps > 5.0)
        );
        let mut scene = Scene::new(&EAST, LightState::Green);
        let ticks = scene.drive(12.0, walker);
        let first_seen = ticks
            .iter()
            .position(|t| t.ahead.is_some_and(|a| a.id == 7))
            .expect("the walker is seen ahead");
        assert!(
            ticks[first_seen].state.speed_mps > 4.0,
            "it was cruising when the walker stepped out"
        );
        // The rule book predicts a walking pedestrian's path, so the walker
        // is ahead before its footprint reaches the corridor (1.4 m around
        // the lane's centre, y = -1.75), at 2 + (7 - 3.45) / 1.5 = 4.37 s.
        let enters = ((2.0 + (7.0 - 3.45) / 1.5) / DT).round() as usize;
        assert!(
            first_seen < enters,
            "seen at tick {first_seen}, enters at {enters}"
        );
        // It brakes no later than half a second after the walker enters the
        // corridor and stops at least 2 m short of it (the walker's near edge
        // is at x = 44.7).
        assert!(
            ticks[first_seen..enters + 20]
                .iter()
                .any(|t| t.control.brake > 0.0),
            "no brake after seeing the walker"
        );
        let last = ticks.last().unwrap();
        assert!(last.state.speed_mps < 0.05, "{:?}", last.state);
        let max_front = ticks.iter().map(front_x).fold(f32::MIN, f32::max);
        assert!(
            max_front < 45.0 - 0.3 - 2.0,
            "front reached x = {max_front}"
        );
    }

    #[test]
    fn it_steers_left_through_a_left_turn() {
        // East on y = -1.75, left at the junction (60, 0), north on x = 61.75.
        let mut scene = Scene::new(
            &[
                (15.0, -1.75, 0.0),
                (61.75, 40.0, std::f32::consts::FRAC_PI_2),
            ],
            LightState::Green,
        );
        assert!(
            scene
                .route
                .points
                .iter()
                .any(|p| p.command == Command::Left)
        );
        let ticks = scene.drive(25.0, |_, _| {});
        // In the junction it steers left: negative steer (positive turns right, as CARLA).
        let in_junction: Vec<&Tick> = ticks
            .iter()
            .filter(|t| (52.0..68.0).contains(&t.state.position.x) && t.state.position.y > -1.0)
            .collect();
        assert!(!in_junction.is_empty());
        let mean_steer =
            in_junction.iter().map(|t| t.control.steer).sum::<f32>() / in_junction.len() as f32;
        assert!(mean_steer < -0.1, "mean steer {mean_steer} in the turn");
        // It comes out heading north on the exit lane.
        let out = ticks
            .iter()
            .find(|t| t.state.position.y > 25.0)
            .expect("it drove out of the junction northwards");
        assert!(
            (out.state.yaw - std::f32::consts::FRAC_PI_2).abs() < 0.1,
            "yaw {}",
            out.state.yaw
        );
        assert!(
            (out.state.position.x - 61.75).abs() < 0.5,
            "x {}",
            out.state.position.x
        );
    }
}
