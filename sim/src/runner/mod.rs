//! The closed loop: one scenario driven from start to result record.
//!
//! Each 40 Hz tick (docs/protocol.md §1, DESIGN's data flow):
//!
//! 1. At a control boundary, the resolution selector picks the input scale
//!    (and with it the latency in force), the camera renders the rig at that
//!    scale if the driver needs it, the driver computes a control, and the
//!    control enters the zero-order-hold [`DelayLine`].
//! 2. The control in force for this step is latched onto the ego.
//! 3. NPCs and pedestrians decide, physics moves everything, contacts are
//!    collected (under the light states of this tick).
//! 4. The monitors look at the step; the recorder writes what was asked.
//! 5. The lights advance.
//!
//! The run ends when the route is driven (>= 99 % and within 10 m of its
//! end), when a terminating event happens (deviation, stuck, low speed, route
//! timeout), or at the tick limit.
//!
//! | file | what |
//! | --- | --- |
//! | `mod.rs` | [`run`]: the loop above, and the result record it ends with |
//! | `setup.rs` | the scenario's town and route ([`Prepared`]), its traffic, the ego's start, the world the loop steps |
//! | `timing.rs` | the delay and period in force (`max(D, Lexec)`, written once), the latency's jitter, the controls in force |
//! | `boundary.rs` | a control boundary: the selector's input, the observation, the driver's control, in line or beside the loop |
//!
//! What a run gives, the record, its log, its picture, is in [`crate::output`].

use std::path::Path;
use std::time::Instant;

use world::rules::{RouteStops, route_s_at};
use world::{ActorSnapshot, Vec2};

use crate::camera::Camera;
use crate::driver::{Driver, RgbImage, VehicleControl};
use crate::monitors::score::driving_score;
use crate::monitors::{EgoContact, EgoPose, EgoTick, Infraction, InfractionKind, Monitors};
use crate::observe::{RunObserver, TickView, TimedCamera};
use crate::overlap::Overlap;
use crate::record::{
    Provenance, RealisedTraffic, RunPerf, RunRecord, RunResult, RunSettings, count_by_kind,
};
use crate::scenario::{LatencyModel, Scenario};
use crate::selector::ResolutionSelector;

/// Seconds of route timeout per metre of route, plus a fixed allowance
/// (leaderboard-style: generous enough for waits at every light).
const TIMEOUT_S_PER_M: f64 = 0.8;
const TIMEOUT_EXTRA_S: f64 = 30.0;
/// How far ahead along the route the expert looks for actors (metres).
pub const AHEAD_RANGE_M: f32 = 40.0;
/// Half-width of the corridor around the route for "ahead" (metres).
pub const AHEAD_CORRIDOR_M: f32 = 1.4;

pub use crate::error::RunError;

mod boundary;
mod setup;
mod timing;

pub use setup::{Prepared, ego_start, prepare, traffic_config};
pub use timing::timing_at;

use crate::output::provenance::{build_id, cpu_model};
use boundary::{Boundary, Now};
use setup::World;
use timing::Controls;

/// Everything a run is given besides the scenario.
pub struct RunInputs<'a> {
    /// The loaded town and planned route.
    pub prepared: &'a Prepared,
    /// Who drives.
    pub driver: &'a mut dyn Driver,
    /// Who picks the scale.
    pub selector: &'a mut dyn ResolutionSelector,
    /// The camera, if the driver or an observer needs images.
    pub camera: Option<&'a mut dyn Camera>,
    /// Everything that watches the run (recorder, progress, moments, data
    /// collection), called in this order after each tick's monitors.
    pub observers: Vec<&'a mut dyn RunObserver>,
    /// Stop after this many ticks at the latest (for short tests).
    pub max_ticks: Option<u64>,
}

/// Drives one scenario; returns its record.
///
/// Each tick reads as DESIGN.md's data flow: at a control boundary the
/// selector picks the scale, the camera renders, the driver acts and its
/// control enters the zero-order hold; the latched control drives the ego;
/// NPCs, pedestrians and physics step; the monitors count; the observers
/// watch; the lights advance.
pub fn run(
    scenario: &Scenario,
    scenario_file: &Path,
    inputs: RunInputs<'_>,
) -> Result<RunRecord, RunError> {
    let RunInputs {
        prepared,
        driver,
        selector,
        camera,
        mut observers,
        max_ticks,
    } = inputs;
    let wall = Instant::now();
    let mut perf = RunPerf::default();
    let town = prepared.town.clone();
    let route = &prepared.route;
    let needs = driver.needs();
    if needs.camera && camera.is_none() {
        return Err(RunError::Setup(format!(
            "driver {} needs the camera, but no camera was given",
            driver.name()
        )));
    }
    let mut camera = camera.map(TimedCamera::new);
    let tick_s = scenario.timing.tick_s;
    let ticks_per_frame = u64::from(scenario.ticks_per_frame());

    let mut world = World::new(scenario, prepared)?;
    let vehicle = world.traffic.config().vehicle;
    let rules = world.traffic.rules().clone();
    let stops: RouteStops = rules.stop_lines.on_route(route);
    let timeout_s = scenario
        .termination
        .timeout_s
        .unwrap_or(f64::from(route.length_m) * TIMEOUT_S_PER_M + TIMEOUT_EXTRA_S);
    let t = &scenario.termination;
    let mut monitors = Monitors::new(
        &town,
        rules,
        route,
        t.deviation_m as f32,
        (t.stuck_s, t.low_speed_s, timeout_s),
    );
    let mut controls = Controls::new(scenario, selector);

    let mut infractions: Vec<Infraction> = Vec::new();
    let mut new_infractions: Vec<Infraction> = Vec::new();
    let mut snapshots: Vec<ActorSnapshot> = Vec::new();
    let mut boundary = Boundary {
        scenario,
        town: &town,
        route,
        stops: &stops,
        vehicle: &vehicle,
        needs,
        labels_image: RgbImage::default(),
        ahead_path: Vec::with_capacity(64),
    };
    let mut contacts: Vec<EgoContact> = Vec::new();
    let max_ticks = max_ticks
        .unwrap_or(u64::MAX)
        .min((timeout_s / tick_s).ceil() as u64 + 1);
    let mut termination: Option<InfractionKind> = None;
    let mut tick: u64 = 0;
    let trace_every = ((crate::record::TRACE_EVERY_S / tick_s).round() as u64).max(1);
    let mut trace: Vec<[f64; 4]> = Vec::new();
    // The driver acts beside the loop where nothing waits for its answer (crate::overlap).
    let beside = needs
        == (crate::driver::DriverNeeds {
            camera: true,
            privileged: false,
            labels: false,
        })
        && driver.trigger().is_none()
        && scenario.timing.latency == LatencyModel::Fixed
        && observers.iter().all(|o| !o.reads_computed());

    std::thread::scope(|scope| -> Result<(), RunError> {
        let mut lanes = Overlap::new(scope, &mut *driver);
        while tick < max_ticks {
            world.traffic.snapshots(&mut snapshots);
            let ego = *snapshots
                .first()
                .ok_or_else(|| RunError::Setup("the ego was not spawned".into()))?;
            let route_index = monitors.route.index();

            // 1. A control boundary: the scale, the observation, the control.
            let computed = if controls.delay.is_boundary(tick) {
                let now = Now {
                    tick,
                    world: &world,
                    ego: &ego,
                    actors: &snapshots,
                    route_index,
                };
                match (beside, camera.as_mut()) {
                    (true, Some(camera)) => {
                        boundary.act_beside(
                            &now,
                            &mut *selector,
                            camera,
                            &mut lanes,
                            &mut controls,
                            &mut perf.driver_s,
                        )?;
                        None
                    }
                    _ => {
                        let driver = lanes.driver(&mut controls.delay, &mut perf.driver_s);
                        Some(boundary.act(
                            &now,
                            &mut *selector,
                            camera.as_mut(),
                            driver,
                            &mut controls,
                            &mut perf.driver_s,
                        )?)
                    }
                }
            } else {
                None
            };
            lanes.settle(tick, &mut controls.delay, &mut perf.driver_s);

            // 2. The control in force for this step drives the ego.
            let control: VehicleControl = controls.delay.control_for_step(tick);
            world.traffic.set_ego_control(control);

            // 3. NPCs, pedestrians and physics.
            let prev = EgoPose::from(&ego);
            let started = Instant::now();
            world.step(&mut contacts);
            perf.traffic_s += started.elapsed().as_secs_f64();
            tick += 1;

            // 4. The monitors count.
            let started = Instant::now();
            let render_before = camera.as_ref().map_or(0.0, |c| c.spent_s);
            let e = world
                .traffic
                .ego()
                .ok_or_else(|| RunError::Setup("the ego vanished".into()))?;
            let now = EgoPose {
                position: e.state.position.extend(e.z),
                heading: e.state.yaw,
            };
            let ego_tick = EgoTick {
                tick,
                time_s: tick as f64 * tick_s,
                prev,
                now,
                speed_mps: e.state.speed_mps,
                size_m: (vehicle.length_m, vehicle.width_m),
                throttle: control.throttle,
                contacts: &contacts,
                kerbs: &e.kerbs,
                route_progress_m: 0.0,
                lights: &world.light_states,
                dt_s: tick_s,
            };
            if tick.is_multiple_of(trace_every) {
                trace.push(crate::record::trace_point(
                    ego_tick.time_s,
                    now.ground().to_array(),
                    controls.scale,
                ));
            }
            new_infractions.clear();
            let touches_before = monitors.collisions.touches().len();
            monitors.observe(&ego_tick, &mut new_infractions);
            if let Some(end) = new_infractions.iter().find(|i| i.kind.terminates()) {
                termination = Some(end.kind);
            }

            // 5. The observers watch.
            if !observers.is_empty() {
                world.traffic.snapshots(&mut snapshots);
                let route_index = monitors.route.index();
                let view = TickView {
                    tick,
                    time_s: tick as f64 * tick_s,
                    camera_frame: tick.is_multiple_of(ticks_per_frame),
                    town: &town,
                    route,
                    route_index,
                    route_s: route_s_at(route, route_index, now.ground()),
                    command: route.command_ahead(route_index, 0.0),
                    completion_pct: monitors.route.completion_pct(),
                    actors: &snapshots,
                    lights: &world.light_states,
                    scale: controls.scale,
                    latency_ms: controls.latency_ms,
                    control,
                    computed,
                    infractions: &new_infractions,
                    touches: &monitors.collisions.touches()[touches_before..],
                };
                for o in observers.iter_mut() {
                    o.on_tick(&view, camera.as_mut().map(|c| c as &mut dyn Camera))?;
                }
            }
            infractions.append(&mut new_infractions);
            let render_in_observers = camera.as_ref().map_or(0.0, |c| c.spent_s) - render_before;
            perf.other_s += started.elapsed().as_secs_f64() - render_in_observers;

            // 6. The lights advance.
            world.step_lights(tick_s);

            if termination.is_some() || monitors.route.succeeded(now.ground()) {
                break;
            }
        }
        lanes.join(&mut controls.delay, &mut perf.driver_s);
        Ok(())
    })?;

    monitors.finish(&mut infractions);
    let final_position = world.traffic.ego().map_or(Vec2::ZERO, |e| e.state.position);
    if !tick.is_multiple_of(trace_every) {
        trace.push(crate::record::trace_point(
            tick as f64 * tick_s,
            final_position.to_array(),
            controls.scale,
        ));
    }
    let completion_pct = monitors.route.completion_pct();
    let success = monitors.route.succeeded(final_position) && termination.is_none();
    let outside_lane_pct = monitors.outside_lane.outside_pct();
    let contacts = monitors.collisions.into_touches();
    let collisions = crate::record::collisions_by_rule(&contacts);
    perf.render_s = camera.as_ref().map_or(0.0, |c| c.spent_s);
    let result = RunResult {
        provenance: Provenance {
            scenario: scenario.name.clone(),
            scenario_file: scenario_file.display().to_string(),
            map: scenario.map.file.display().to_string(),
            route: format!("{} id {}", prepared.route_file.display(), route.id),
            driver: driver.name(),
            build: build_id(),
            render_backend: camera.as_ref().map_or("none".to_string(), |c| c.backend()),
            render_fingerprint: camera
                .as_ref()
                .and_then(|_| crate::render::fingerprint::this_process()),
            cpu: cpu_model(),
            checkpoint: driver.checkpoint(),
            trigger: driver.trigger(),
        },
        settings: RunSettings {
            seed: scenario.traffic.seed,
            delay_ms: scenario.timing.delay_ms,
            control_period_ms: scenario.timing.control_period_ms,
            resolution: selector.name(),
            vehicles: scenario.traffic.vehicles,
            pedestrians: scenario.traffic.pedestrians,
        },
        traffic: RealisedTraffic {
            vehicles: world.traffic.realised_vehicles() as u32,
            pedestrians: world.traffic.realised_pedestrians() as u32,
            walkers_sent: world.traffic.stats().walkers_sent as u32,
        },
        completion_pct,
        success,
        driving_score: driving_score(
            completion_pct,
            crate::record::leaderboard_kinds(&infractions, &contacts),
            outside_lane_pct,
        ),
        outside_lane_pct,
        counts: count_by_kind(&infractions),
        termination,
        route_length_m: f64::from(route.length_m),
        sim_time_s: tick as f64 * tick_s,
        ticks: tick,
        scale_share: controls.scale_share(),
        max_latency_ms: controls.max_latency_ms,
        infractions,
        collisions,
        contacts,
        trace,
    };
    perf.wall_s = wall.elapsed().as_secs_f64();
    perf.real_time_factor = result.sim_time_s / perf.wall_s.max(1e-9);
    Ok(RunRecord { result, perf })
}
