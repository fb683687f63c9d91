//! The closed loop: one scenario driven from start to result record.
//!
//! Each 40 Hz tick (PROTOCOL §1, DESIGN's data flow):
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

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use world::agents::pedestrian::PedestrianParams;
use world::map::{LoadOptions, UnsignalledJunctions, load_xodr_file};
use world::physics::Party;
use world::route::RouteFile;
use world::route::{DenseRoute, PlannerConfig, plan_route};
use world::rules::Ahead;
use world::rules::{RouteStops, route_ahead, route_s_at};
use world::traffic::{EgoStart, Traffic, TrafficConfig};
use world::traffic::{LightController, LightTiming};
use world::{ActorKind, ActorSnapshot, LightIdx, LightState, Town, Vec2};

use crate::camera::{Camera, CameraFrame};
use crate::delay::{DelayLine, DelayTiming};
use crate::driver::{Driver, Observation, Privileged, RgbImage, VehicleControl};
use crate::monitors::blocked::BlockedMonitor;
use crate::monitors::collision::CollisionMonitor;
use crate::monitors::lane_crossing::LaneCrossingMonitor;
use crate::monitors::outside_lane::OutsideLaneMonitor;
use crate::monitors::red_light::RedLightMonitor;
use crate::monitors::route::RouteMonitor;
use crate::monitors::score::driving_score;
use crate::monitors::{ContactKind, EgoContact, EgoPose, EgoTick, Infraction, InfractionKind};
use crate::record::{
    Provenance, RealisedTraffic, RunPerf, RunRecord, RunResult, RunSettings, count_by_kind,
};
use crate::recorder::{BEV_EXTENT_M, BEV_SIZE_PX, Recorder, tick_ns};
use crate::scenario::{LatencyModel, Scenario};
use crate::selector::{ResolutionSelector, SelectorInput};

/// Seconds of route timeout per metre of route, plus a fixed allowance
/// (leaderboard-style: generous enough for waits at every light).
const TIMEOUT_S_PER_M: f64 = 0.8;
const TIMEOUT_EXTRA_S: f64 = 30.0;
/// How far ahead along the route the expert looks for actors (metres).
pub const AHEAD_RANGE_M: f32 = 40.0;
/// Half-width of the corridor around the route for "ahead" (metres).
pub const AHEAD_CORRIDOR_M: f32 = 1.4;

/// A run could not be set up or carried out.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The map could not be loaded.
    #[error(transparent)]
    Map(#[from] world::MapError),
    /// The route could not be read or planned.
    #[error(transparent)]
    Route(#[from] world::RouteError),
    /// The camera failed.
    #[error("camera: {0}")]
    Camera(String),
    /// The recorder failed.
    #[error(transparent)]
    Record(#[from] crate::recorder::RecordError),
    /// Something about the set-up is inconsistent.
    #[error("{0}")]
    Setup(String),
}

/// The town and the planned route of a scenario: loaded once, shared by runs.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The town.
    pub town: Arc<Town>,
    /// The dense route.
    pub route: DenseRoute,
    /// The route file.
    pub route_file: PathBuf,
}

/// Loads the scenario's map and plans its route.
pub fn prepare(scenario: &Scenario) -> Result<Prepared, RunError> {
    let opts = LoadOptions {
        unsignalled: if scenario.map.generate_lights {
            UnsignalledJunctions::GenerateLights
        } else {
            UnsignalledJunctions::NoLights
        },
    };
    let (town, _report) = load_xodr_file(&scenario.map.file, &opts)?;
    let routes = RouteFile::load(&scenario.route.file)?;
    let route = routes.route(&scenario.route.id)?;
    let dense = plan_route(&town, route, &PlannerConfig::default())?;
    Ok(Prepared {
        town: Arc::new(town),
        route: dense,
        route_file: scenario.route.file.clone(),
    })
}

/// Settings given on the command line over the scenario's.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// Injected delay (milliseconds).
    pub delay_ms: Option<f64>,
    /// Traffic seed.
    pub seed: Option<u64>,
    /// Target vehicles.
    pub vehicles: Option<u32>,
    /// Target pedestrians.
    pub pedestrians: Option<u32>,
}

impl Overrides {
    /// The scenario with the overrides applied.
    pub fn apply(&self, scenario: &Scenario) -> Scenario {
        let mut s = scenario.clone();
        if let Some(d) = self.delay_ms {
            s.timing.delay_ms = d;
        }
        if let Some(seed) = self.seed {
            s.traffic.seed = seed;
        }
        if let Some(v) = self.vehicles {
            s.traffic.vehicles = v;
        }
        if let Some(p) = self.pedestrians {
            s.traffic.pedestrians = p;
        }
        s
    }
}

/// A callback given every tick: the tick, every actor (ego first) and the
/// light states.
pub type TickObserver<'a> = dyn FnMut(u64, &[ActorSnapshot], &[LightState]) + 'a;

/// Everything a run is given besides the scenario.
pub struct RunInputs<'a> {
    /// The loaded town and planned route.
    pub prepared: &'a Prepared,
    /// Who drives.
    pub driver: &'a mut dyn Driver,
    /// Who picks the scale.
    pub selector: &'a mut dyn ResolutionSelector,
    /// The camera, if anything needs images.
    pub camera: Option<&'a mut dyn Camera>,
    /// The log, if recording.
    pub recorder: Option<&'a mut Recorder>,
    /// Called now and then with the route completion (percent).
    pub progress: &'a mut dyn FnMut(f64),
    /// Stop after this many ticks at the latest (for short tests).
    pub max_ticks: Option<u64>,
    /// Called after every tick with the tick, every actor (ego first) and
    /// the light states: for data collection and snapshots.
    pub observer: Option<&'a mut TickObserver<'a>>,
    /// Render the rig at every camera tick even when nothing consumes it
    /// (what data collection costs; for timing).
    pub render_every_frame: bool,
}

/// The git commit and version this binary was built from.
pub fn build_id() -> String {
    format!(
        "mrdrive {} ({})",
        env!("CARGO_PKG_VERSION"),
        option_env!("MRDRIVE_GIT_COMMIT").unwrap_or("unknown commit")
    )
}

/// The timing in force at `scale`: the delay is `max(D, Lexec(scale))`, the
/// period `max(Tc, delay)` (PROTOCOL §1). With `latency = "measured"` the
/// loop replaces `Lexec` by the driver's real compute time at each boundary.
pub fn timing_at(scenario: &Scenario, scale: f64) -> (DelayTiming, f64) {
    let t = &scenario.timing;
    let latency_ms = t.delay_ms.max(scenario.latency_ms_at(scale));
    (
        DelayTiming::from_period_and_latency(t.control_period_ms, latency_ms, t.tick_s),
        latency_ms,
    )
}

/// Where the ego starts: the route's first point.
fn ego_start(route: &DenseRoute) -> Result<EgoStart, RunError> {
    let p = route
        .points
        .first()
        .ok_or_else(|| RunError::Setup(format!("route {} has no points", route.id)))?;
    Ok(EgoStart {
        position: p.position.truncate(),
        z: p.position.z,
        yaw: p.heading,
    })
}

/// The contact's other party as the collision monitor counts it.
fn ego_contact(a: Party, b: Party) -> Option<EgoContact> {
    let other = match (a, b) {
        (Party::Actor { id: 0, .. }, other) | (other, Party::Actor { id: 0, .. }) => other,
        _ => return None,
    };
    Some(match other {
        Party::Actor {
            id,
            kind: ActorKind::Pedestrian,
        } => EgoContact {
            other: id,
            kind: ContactKind::Pedestrian,
        },
        Party::Actor { id, .. } => EgoContact {
            other: id,
            kind: ContactKind::Vehicle,
        },
        // Statics carry no per-object id: each kind counts as one "actor".
        Party::Static(kind) => EgoContact {
            other: 1_000_000 + kind as u32,
            kind: ContactKind::Static,
        },
    })
}

/// What the selector sees: the distances along the route from the ego's
/// centre to the next stop line ahead and from the last one passed (metres).
/// TimeParam's oracle measures a straight line to the light's trigger volume
/// (the stop line of the approach lane); on an approach the two agree.
fn selector_input(
    route: &DenseRoute,
    index: usize,
    ego: &ActorSnapshot,
    stops: &RouteStops,
) -> SelectorInput {
    let ego_s = route_s_at(route, index, ego.position.truncate());
    SelectorInput {
        light_ahead_m: stops.next_after(ego_s).map(|s| s.route_s - ego_s),
        light_behind_m: stops.last_up_to(ego_s).map(|s| ego_s - s.route_s),
        speed_mps: ego.speed_mps,
    }
}

/// Drives one scenario; returns its record.
pub fn run(
    scenario: &Scenario,
    scenario_file: &Path,
    inputs: RunInputs<'_>,
) -> Result<RunRecord, RunError> {
    let RunInputs {
        prepared,
        driver,
        selector,
        mut camera,
        mut recorder,
        progress,
        max_ticks,
        mut observer,
        render_every_frame,
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
    let tick_s = scenario.timing.tick_s;
    let ticks_per_frame = u64::from(scenario.ticks_per_frame());
    let seed = scenario.traffic.seed;

    // The world.
    let defaults = TrafficConfig::default();
    let cfg = TrafficConfig {
        vehicles: scenario.traffic.vehicles as usize,
        pedestrians: scenario.traffic.pedestrians as usize,
        seed,
        tick_s: tick_s as f32,
        pedestrian: PedestrianParams {
            cross_factor: scenario.traffic.cross_factor,
            ..defaults.pedestrian
        },
        ..defaults
    };
    let vehicle = cfg.vehicle;
    let mut traffic = Traffic::new(town.clone(), cfg, Some(ego_start(route)?));
    let mut lights = LightController::new(&town, LightTiming::default(), seed ^ 0x6c69_6768_7473);
    let mut light_states: Vec<LightState> = vec![LightState::Red; town.lights.len()];
    let fill_states = |lc: &LightController, out: &mut Vec<LightState>| {
        for (i, s) in out.iter_mut().enumerate() {
            *s = lc.state(LightIdx(i as u32));
        }
    };
    fill_states(&lights, &mut light_states);

    // The monitors.
    let mut route_monitor = RouteMonitor::new(route, scenario.termination.deviation_m as f32);
    let mut collisions = CollisionMonitor::default();
    let mut lane_crossings = LaneCrossingMonitor::new(&town);
    let mut red_lights = RedLightMonitor::new(traffic.rules().clone());
    let mut outside_lane = OutsideLaneMonitor::default();
    let timeout_s = scenario
        .termination
        .timeout_s
        .unwrap_or(f64::from(route.length_m) * TIMEOUT_S_PER_M + TIMEOUT_EXTRA_S);
    let mut blocked = BlockedMonitor::new(
        scenario.termination.stuck_s,
        scenario.termination.low_speed_s,
        timeout_s,
    );
    let stops: RouteStops = traffic.rules().stop_lines.on_route(route);
    let mut infractions: Vec<Infraction> = Vec::new();
    let mut new_infractions: Vec<Infraction> = Vec::new();

    // Timing.
    selector.reset();
    let mut scale = f64::from(selector.select(&SelectorInput::default()));
    let (timing, mut latency_ms) = timing_at(scenario, scale);
    let mut delay = DelayLine::new(timing);
    let mut max_latency_ms = latency_ms;
    let mut scale_counts: std::collections::BTreeMap<u64, u64> = Default::default();

    let mut snapshots: Vec<ActorSnapshot> = Vec::new();
    let mut ahead_path: Vec<Vec2> = Vec::with_capacity(64);
    let mut contacts: Vec<EgoContact> = Vec::new();
    let mut label_image = RgbImage::default();
    let max_ticks = max_ticks
        .unwrap_or(u64::MAX)
        .min((timeout_s / tick_s).ceil() as u64 + 1);
    let mut termination: Option<InfractionKind> = None;
    let mut tick: u64 = 0;
    let mut last_progress = -1.0;

    while tick < max_ticks {
        traffic.snapshots(&mut snapshots);
        let ego = *snapshots
            .first()
            .ok_or_else(|| RunError::Setup("the ego was not spawned".into()))?;

        // 1. A control boundary.
        let mut computed = None;
        if delay.is_boundary(tick) {
            let input = selector_input(route, route_monitor.index(), &ego, &stops);
            let new_scale = f64::from(selector.select(&input));
            if new_scale != scale {
                scale = new_scale;
                let (t, l) = timing_at(scenario, scale);
                delay.set_timing(t);
                latency_ms = l;
                max_latency_ms = max_latency_ms.max(l);
            }
            *scale_counts.entry(scale.to_bits()).or_default() += 1;
            let image = if needs.camera {
                let started = Instant::now();
                let frame = CameraFrame {
                    ego: &ego,
                    actors: &snapshots,
                    lights: &light_states,
                };
                let cam = camera.as_deref_mut().expect("checked above");
                // Borrowed from the camera until the driver has acted: no copy.
                let image = cam.render(&frame, scale).map_err(RunError::Camera)?;
                perf.render_s += started.elapsed().as_secs_f64();
                Some(image)
            } else {
                None
            };
            let ahead: Option<Ahead> = if needs.privileged {
                route_ahead(
                    route,
                    route_monitor.index(),
                    ego.position.truncate(),
                    AHEAD_RANGE_M,
                    &mut ahead_path,
                );
                traffic.nearest_ahead_of_ego(&ahead_path, AHEAD_CORRIDOR_M, AHEAD_RANGE_M)
            } else {
                None
            };
            let privileged = Privileged {
                town: &town,
                route,
                route_index: route_monitor.index(),
                ego,
                lights: &light_states,
                stops: &stops,
                ahead,
                vehicle: &vehicle,
            };
            let command = route.command_ahead(route_monitor.index(), 0.0);
            let obs = Observation {
                time_s: tick as f64 * tick_s,
                speed_mps: ego.speed_mps,
                command,
                scale: scale as f32,
                image,
                privileged: needs.privileged.then_some(&privileged),
            };
            let started = Instant::now();
            let control = driver.act(&obs);
            let compute_s = started.elapsed().as_secs_f64();
            perf.driver_s += compute_s;
            if scenario.timing.latency == LatencyModel::Measured {
                // The control lands after the time it really took (at least D).
                let l = scenario.timing.delay_ms.max(compute_s * 1000.0);
                delay.set_timing(DelayTiming::from_period_and_latency(
                    scenario.timing.control_period_ms,
                    l,
                    tick_s,
                ));
                latency_ms = l;
                max_latency_ms = max_latency_ms.max(l);
            }
            delay.submit(tick, control);
            computed = Some(control);
        }

        // 2. Latch the control in force.
        let control: VehicleControl = delay.control_for_step(tick);
        traffic.set_ego_control(control);

        // 3. Traffic and physics.
        let prev = EgoPose::from(&ego);
        let started = Instant::now();
        let events = traffic.step(&light_states);
        contacts.clear();
        contacts.extend(events.iter().filter_map(|e| ego_contact(e.a, e.b)));
        perf.traffic_s += started.elapsed().as_secs_f64();
        tick += 1;

        // 4. Monitors.
        let started = Instant::now();
        let render_before = perf.render_s;
        let e = traffic
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
            lights: &light_states,
        };
        new_infractions.clear();
        route_monitor.observe(&ego_tick, &mut new_infractions);
        let before = new_infractions.len();
        collisions.observe(&ego_tick, &mut new_infractions);
        if new_infractions.len() > before {
            blocked.collided();
        }
        lane_crossings.observe(&ego_tick, &mut new_infractions);
        red_lights.observe(&ego_tick, &mut new_infractions);
        outside_lane.observe(&ego_tick, e.lane.is_some());
        blocked.observe(&ego_tick, tick_s, &mut new_infractions);

        if let Some(rec) = recorder.as_deref_mut() {
            let t_ns = tick_ns(tick, tick_s);
            for i in &new_infractions {
                rec.infraction(t_ns, i)?;
            }
            rec.control(t_ns, computed, control)?;
            if tick.is_multiple_of(ticks_per_frame) {
                traffic.snapshots(&mut snapshots);
                let ego_now = snapshots[0];
                rec.ego_transform(t_ns, &ego_now)?;
                rec.actors(t_ns, &snapshots, &town, &light_states)?;
                let command = route.command_ahead(route_monitor.index(), 0.0);
                rec.ego_state(t_ns, &ego_now, command, scale, latency_ms)?;
                if let Some(cam) = camera.as_deref_mut() {
                    // Rendering counts as render time; encoding and writing
                    // the images as other time.
                    let frame = CameraFrame {
                        ego: &ego_now,
                        actors: &snapshots,
                        lights: &light_states,
                    };
                    let opts = rec.options();
                    let started = Instant::now();
                    let labelled = if opts.labels {
                        cam.render_labelled(&frame, scale, &mut label_image)
                    } else {
                        None
                    };
                    if let Some(image) = labelled {
                        let image = image.map_err(RunError::Camera)?;
                        perf.render_s += started.elapsed().as_secs_f64();
                        rec.camera(t_ns, image)?;
                        rec.labels(t_ns, &label_image)?;
                    } else if opts.camera {
                        let image = cam.render(&frame, scale).map_err(RunError::Camera)?;
                        perf.render_s += started.elapsed().as_secs_f64();
                        rec.camera(t_ns, image)?;
                    }
                    let started = Instant::now();
                    if opts.bev
                        && let Some(image) =
                            cam.render_bev(&frame, BEV_SIZE_PX, BEV_SIZE_PX, BEV_EXTENT_M)
                    {
                        let image = image.map_err(RunError::Camera)?;
                        perf.render_s += started.elapsed().as_secs_f64();
                        rec.bev(t_ns, image)?;
                    }
                }
            }
        }
        if let Some(end) = new_infractions.iter().find(|i| i.kind.terminates()) {
            termination = Some(end.kind);
        }
        infractions.append(&mut new_infractions);
        perf.other_s += started.elapsed().as_secs_f64() - (perf.render_s - render_before);

        if render_every_frame
            && recorder.is_none()
            && tick.is_multiple_of(ticks_per_frame)
            && let Some(cam) = camera.as_deref_mut()
        {
            traffic.snapshots(&mut snapshots);
            let started = Instant::now();
            let frame = CameraFrame {
                ego: &snapshots[0],
                actors: &snapshots,
                lights: &light_states,
            };
            cam.render(&frame, scale).map_err(RunError::Camera)?;
            perf.render_s += started.elapsed().as_secs_f64();
        }
        if let Some(obs) = observer.as_deref_mut() {
            traffic.snapshots(&mut snapshots);
            obs(tick, &snapshots, &light_states);
        }

        // 5. Lights.
        lights.step(tick_s);
        fill_states(&lights, &mut light_states);

        let completion = route_monitor.completion_pct();
        if completion - last_progress >= 1.0 {
            progress(completion);
            last_progress = completion;
        }
        if termination.is_some() || route_monitor.succeeded(now.ground()) {
            break;
        }
    }

    let final_position = traffic.ego().map_or(Vec2::ZERO, |e| e.state.position);
    let completion_pct = route_monitor.completion_pct();
    let success = route_monitor.succeeded(final_position) && termination.is_none();
    let total_boundaries: u64 = scale_counts.values().sum();
    let scale_share = scale_counts
        .into_iter()
        .map(|(bits, n)| {
            (
                format!("{}", f64::from_bits(bits)),
                n as f64 / total_boundaries.max(1) as f64,
            )
        })
        .collect();
    let result = RunResult {
        provenance: Provenance {
            scenario: scenario.name.clone(),
            scenario_file: scenario_file.display().to_string(),
            map: scenario.map.file.display().to_string(),
            route: format!("{} id {}", prepared.route_file.display(), route.id),
            driver: driver.name(),
            build: build_id(),
            render_backend: camera.as_ref().map_or("none".to_string(), |c| c.backend()),
        },
        settings: RunSettings {
            seed,
            delay_ms: scenario.timing.delay_ms,
            control_period_ms: scenario.timing.control_period_ms,
            resolution: selector.name(),
            vehicles: scenario.traffic.vehicles,
            pedestrians: scenario.traffic.pedestrians,
        },
        traffic: RealisedTraffic {
            vehicles: traffic.realised_vehicles() as u32,
            pedestrians: traffic.realised_pedestrians() as u32,
        },
        completion_pct,
        success,
        driving_score: driving_score(completion_pct, infractions.iter().map(|i| i.kind)),
        outside_lane_pct: outside_lane.outside_pct(),
        counts: count_by_kind(&infractions),
        termination,
        route_length_m: f64::from(route.length_m),
        sim_time_s: tick as f64 * tick_s,
        ticks: tick,
        scale_share,
        max_latency_ms,
        infractions,
    };
    perf.wall_s = wall.elapsed().as_secs_f64();
    perf.real_time_factor = result.sim_time_s / perf.wall_s.max(1e-9);
    progress(completion_pct);
    Ok(RunRecord { result, perf })
}
