//! The expert: a privileged autopilot, the data source for training and the
//! upper bound in every table.
//!
//! It reads the simulator's exact state ([`Privileged`]) and drives the dense
//! route:
//!
//! - **Lateral**: pure pursuit on the route from the rear axle, looking
//!   `2 + 0.5 v` metres ahead (3.5-10 m), converted to a steer value through
//!   the vehicle model's inverse (`VehicleParams::steer_for_curvature`).
//! - **Speed**: 6 m/s on turns (a LEFT/RIGHT command within 10 m), 6.5 m/s
//!   otherwise, never above the lane's limit (PROTOCOL §5's target speeds).
//! - **Stops**: for a red light, and for a yellow one it can still stop for
//!   comfortably, it brakes to stand 1 m before the stop line; for the nearest
//!   vehicle or pedestrian ahead on its route (the same "ahead" query the
//!   NPCs use: a corridor around the route) it keeps a gap of 4 m: it stops
//!   behind a standing one and follows a moving one with a braking profile
//!   `v = sqrt(2 a d)` plus the leader's speed.
//! - **Pedals**: a proportional speed controller asks for an acceleration,
//!   which the vehicle model's inverse turns into throttle or brake; standing
//!   at a stop it holds the brake. It drives on by itself once the light turns
//!   green or the way is free.

use world::{Command, LightState};

use crate::driver::{Control, Driver, DriverNeeds, Observation, Privileged};

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

/// A stop line on the route: where it is along the route and whose it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RouteStop {
    /// Distance along the route (metres).
    pub route_s: f32,
    /// The light (index into `Town::lights`).
    pub light: usize,
}

/// The stop lines the route crosses, in route order: a stop line is on the
/// route where a route point's lane is the stop line's lane and the route
/// passes its arc length.
pub fn stops_on_route(town: &world::Town, route: &world::planner::DenseRoute) -> Vec<RouteStop> {
    let mut stops = Vec::new();
    for w in route.points.windows(2) {
        let (a, b) = (w[0], w[1]);
        for (li, light) in town.lights.iter().enumerate() {
            for stop in &light.stop_lines {
                let on_a =
                    stop.lane == a.lane && a.s <= stop.s && (b.lane != a.lane || stop.s < b.s);
                if on_a {
                    let route_s = a.route_s + (stop.s - a.s);
                    if stops.last().is_none_or(|last: &RouteStop| {
                        (last.route_s - route_s).abs() > 0.5 || last.light != li
                    }) {
                        stops.push(RouteStop { route_s, light: li });
                    }
                }
            }
        }
    }
    stops.sort_by(|a, b| a.route_s.total_cmp(&b.route_s));
    stops
}

/// The privileged autopilot.
#[derive(Debug, Clone)]
pub struct Expert {
    /// Its tuning.
    pub params: ExpertParams,
    stops: Vec<RouteStop>,
}

impl Expert {
    /// An expert for this route.
    pub fn new(
        town: &world::Town,
        route: &world::planner::DenseRoute,
        params: ExpertParams,
    ) -> Self {
        Self {
            params,
            stops: stops_on_route(town, route),
        }
    }

    /// The stop lines on its route.
    pub fn stops(&self) -> &[RouteStop] {
        &self.stops
    }

    /// The route distance of the ego's centre: the reached point's distance
    /// plus the ego's offset along the route there.
    fn ego_route_s(p: &Privileged<'_>) -> f32 {
        let pts = &p.route.points;
        let Some(pt) = pts.get(p.route_index) else {
            return p.route.length_m;
        };
        let forward = world::Vec2::from_angle(pt.heading);
        pt.route_s + (p.ego.position.truncate() - pt.position.truncate()).dot(forward)
    }

    /// The route point at distance `s` along the route (clamped), from `from`.
    fn point_at(p: &Privileged<'_>, from: usize, s: f32) -> world::Vec2 {
        let pts = &p.route.points;
        let mut i = from.min(pts.len().saturating_sub(1));
        while i + 1 < pts.len() && pts[i + 1].route_s < s {
            i += 1;
        }
        if i + 1 >= pts.len() {
            return pts
                .last()
                .map_or(p.ego.position.truncate(), |q| q.position.truncate());
        }
        let (a, b) = (pts[i], pts[i + 1]);
        let t = ((s - a.route_s) / (b.route_s - a.route_s).max(1e-3)).clamp(0.0, 1.0);
        a.position.truncate().lerp(b.position.truncate(), t)
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
        // Lights: the first stop line the car has not yet passed. "Passed"
        // is the red-light monitor's definition (the point 0.8 half-lengths
        // behind the centre crossed it), so a car whose nose overshot a stop
        // line on red waits there instead of driving on.
        let tail_s = ego_s - 0.8 * half_length;
        if let Some(stop) = self.stops.iter().find(|st| st.route_s > tail_s) {
            let state = p
                .lights
                .get(stop.light)
                .copied()
                .unwrap_or(LightState::Green);
            let d = stop.route_s - front_s - prm.stop_margin_m;
            let comfortable = d >= v * v / (2.0 * prm.stop_decel_mps2);
            let must_stop = match state {
                LightState::Red => true,
                LightState::Yellow => comfortable,
                LightState::Green => false,
            };
            if must_stop && d < 40.0 {
                stop_at = Some(d);
            }
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
    pub fn control(&self, p: &Privileged<'_>) -> Control {
        let prm = &self.params;
        let v = p.ego.speed_mps.max(0.0);
        let ego_s = Self::ego_route_s(p);
        // Lateral: pure pursuit from the rear axle, so the rear wheels follow
        // the lane through tight turns instead of cutting across the curb.
        let rear_wb = p.vehicle.rear_wb_m;
        let forward = world::Vec2::from_angle(p.ego.heading);
        let rear = p.ego.position.truncate() - forward * rear_wb;
        let lookahead = (2.0 + 0.5 * v).clamp(3.5, 10.0);
        let target = Self::point_at(p, p.route_index, ego_s - rear_wb + lookahead);
        let rel = target - rear;
        let (dx, dy) = (rel.dot(forward), rel.dot(forward.perp()));
        let d2 = (dx * dx + dy * dy).max(1e-3);
        let steer = p.vehicle.steer_for_curvature(2.0 * dy / d2);
        // Longitudinal: a speed controller, with a braking feed-forward when
        // a stop is near (the deceleration that stands the car exactly there).
        let (want, stop_at) = self.desired_speed(p, ego_s);
        if want < 0.05 && v < 0.3 {
            return Control {
                steer,
                throttle: 0.0,
                brake: 1.0,
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
        Control {
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
        }
    }

    fn act(&mut self, obs: &Observation<'_>) -> Control {
        match obs.privileged {
            Some(p) => self.control(p),
            // The loop gives privileged state to drivers that ask for it; if
            // it ever did not, standing still is the safe answer.
            None => Control {
                steer: 0.0,
                throttle: 0.0,
                brake: 1.0,
            },
        }
    }
}
