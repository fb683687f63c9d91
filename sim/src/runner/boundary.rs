//! A control boundary: what the selector sees, the scale it picks, the camera's
//! observation and the driver's control, in line or beside the loop.

use std::time::Instant;

use world::route::DenseRoute;
use world::rules::Ahead;
use world::rules::{RouteStops, route_ahead, route_s_at};
use world::{ActorSnapshot, Town, Vec2};

use super::setup::World;
use super::timing::Controls;
use super::timing::timing_for;
use super::{AHEAD_CORRIDOR_M, AHEAD_RANGE_M, RunError};
use crate::camera::{Camera, CameraFrame};
use crate::driver::{Driver, Observation, Privileged, RgbImage, VehicleControl};
use crate::observe::TimedCamera;
use crate::overlap::{Overlap, Seen};
use crate::scenario::{LatencyModel, Scenario};
use crate::selector::{ResolutionSelector, SelectorInput};

/// What the selector sees: the distances along the route from the ego's
/// centre to the next stop line ahead and from the last one passed (metres).
/// TimeParam's oracle measures a straight line to the light's trigger volume
/// (the stop line of the approach lane); on an approach the two agree.
/// With the driver's own hint ([`Driver::scale_hint`]) for a learned selector.
pub(super) fn selector_input(
    route: &DenseRoute,
    index: usize,
    ego: &ActorSnapshot,
    stops: &RouteStops,
    driver_hint: Option<f32>,
) -> SelectorInput {
    let ego_s = route_s_at(route, index, ego.position.truncate());
    SelectorInput {
        light_ahead_m: stops.light_ahead(ego_s, f32::INFINITY).map(|(_, d)| d),
        light_behind_m: stops.last_up_to(ego_s).map(|s| ego_s - s.route_s),
        speed_mps: ego.speed_mps,
        driver_hint,
    }
}

/// One tick as a control boundary sees it.
pub(super) struct Now<'t> {
    /// The tick.
    pub(super) tick: u64,
    /// The world before the step.
    pub(super) world: &'t World,
    /// The ego's snapshot.
    pub(super) ego: &'t ActorSnapshot,
    /// Every actor's snapshot, the ego first.
    pub(super) actors: &'t [ActorSnapshot],
    /// The ego's index on the dense route.
    pub(super) route_index: usize,
}

/// Step 1 of the tick (docs/protocol.md §1): at a control boundary the selector picks
/// the scale (and with it the latency in force), the camera renders the
/// observation, the driver acts and its control enters the delay line. Holds
/// what every boundary of a run reads, and the buffers it reuses.
pub(super) struct Boundary<'r> {
    pub(super) scenario: &'r Scenario,
    pub(super) town: &'r Town,
    pub(super) route: &'r DenseRoute,
    pub(super) stops: &'r RouteStops,
    pub(super) vehicle: &'r world::agents::VehicleParams,
    pub(super) needs: crate::driver::DriverNeeds,
    /// The class image of a driver that asks for it.
    pub(super) labels_image: RgbImage,
    /// The route ahead of the ego, for the privileged "actor ahead".
    pub(super) ahead_path: Vec<Vec2>,
}

impl Boundary<'_> {
    /// The selector's scale at `now` (given the driver's `hint`), put in force with its
    /// latency and counted.
    pub(super) fn select(
        &self,
        now: &Now<'_>,
        selector: &mut dyn ResolutionSelector,
        hint: Option<f32>,
        controls: &mut Controls,
    ) -> f64 {
        let input = selector_input(self.route, now.route_index, now.ego, self.stops, hint);
        let new_scale = f64::from(selector.select(&input));
        controls.retime(self.scenario, new_scale);
        *controls
            .scale_counts
            .entry(controls.scale.to_bits())
            .or_default() += 1;
        controls.scale
    }

    /// Runs the boundary at `now` for a driver that needs only the camera, the control
    /// computed beside the loop where it lands later (`crate::overlap`): the same
    /// scale, image and control as [`Boundary::act`].
    pub(super) fn act_beside<'scope, 'd: 'scope>(
        &mut self,
        now: &Now<'_>,
        selector: &mut dyn ResolutionSelector,
        camera: &mut TimedCamera<'_>,
        lanes: &mut Overlap<'scope, '_, 'd>,
        controls: &mut Controls,
        driver_s: &mut f64,
    ) -> Result<(), RunError> {
        let scale = self.select(now, selector, None, controls);
        let frame = CameraFrame {
            ego: now.ego,
            actors: now.actors,
            lights: &now.world.light_states,
        };
        let image = camera.render(&frame, scale).map_err(RunError::Camera)?;
        let seen = Seen {
            time_s: now.tick as f64 * self.scenario.timing.tick_s,
            speed_mps: now.ego.speed_mps,
            command: self.route.command_ahead(now.route_index, 0.0),
            scale: scale as f32,
        };
        lanes.act(now.tick, image, seen, &mut controls.delay, driver_s);
        Ok(())
    }

    /// Runs the boundary at `now`; returns the control computed (it lands
    /// after the latency in force) and adds the driver's time to `driver_s`.
    pub(super) fn act(
        &mut self,
        now: &Now<'_>,
        selector: &mut dyn ResolutionSelector,
        camera: Option<&mut TimedCamera<'_>>,
        driver: &mut dyn Driver,
        controls: &mut Controls,
        driver_s: &mut f64,
    ) -> Result<VehicleControl, RunError> {
        let scale = self.select(now, selector, driver.scale_hint(), controls);
        let mut labelled = false;
        let image = match camera {
            Some(cam) if self.needs.camera => {
                let frame = CameraFrame {
                    ego: now.ego,
                    actors: now.actors,
                    lights: &now.world.light_states,
                };
                // Borrowed from the camera until the driver has acted: no copy.
                let with_labels = self
                    .needs
                    .labels
                    .then(|| cam.render_labelled(&frame, scale, &mut self.labels_image))
                    .flatten();
                match with_labels {
                    Some(rendered) => {
                        labelled = true;
                        Some(rendered.map_err(RunError::Camera)?)
                    }
                    None => Some(cam.render(&frame, scale).map_err(RunError::Camera)?),
                }
            }
            _ => None,
        };
        let ahead: Option<Ahead> = self
            .needs
            .privileged
            .then(|| {
                route_ahead(
                    self.route,
                    now.route_index,
                    now.ego.position.truncate(),
                    AHEAD_RANGE_M,
                    &mut self.ahead_path,
                );
                now.world.traffic.nearest_ahead_of_ego(
                    &self.ahead_path,
                    AHEAD_CORRIDOR_M,
                    AHEAD_RANGE_M,
                )
            })
            .flatten();
        let (junction_yield_s, lane_change_wait_s) = if self.needs.privileged {
            let traffic = &now.world.traffic;
            crate::expert::waits(
                self.town,
                self.route,
                now.route_index,
                now.ego,
                |lane| traffic.ego_must_wait_for(lane),
                traffic.actor_views(),
            )
        } else {
            (None, None)
        };
        let privileged = Privileged {
            town: self.town,
            route: self.route,
            route_index: now.route_index,
            ego: *now.ego,
            lights: &now.world.light_states,
            stops: self.stops,
            ahead,
            junction_yield_s,
            lane_change_wait_s,
            vehicle: self.vehicle,
        };
        let obs = Observation {
            time_s: now.tick as f64 * self.scenario.timing.tick_s,
            speed_mps: now.ego.speed_mps,
            command: self.route.command_ahead(now.route_index, 0.0),
            scale: scale as f32,
            image,
            labels: labelled.then_some(&self.labels_image),
            privileged: self.needs.privileged.then_some(&privileged),
        };
        let started = Instant::now();
        let control = driver.act(&obs);
        let compute_s = started.elapsed().as_secs_f64();
        *driver_s += compute_s;
        if self.scenario.timing.latency == LatencyModel::Measured {
            // The control lands after the time it really took (at least D).
            let (t, l) = timing_for(self.scenario, compute_s * 1000.0);
            controls.set_latency(t, l);
        }
        controls.delay.submit(now.tick, control);
        Ok(control)
    }
}
