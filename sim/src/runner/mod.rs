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

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
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
use crate::monitors::score::driving_score;
use crate::monitors::{
    ContactKind, EgoContact, EgoPose, EgoTick, Infraction, InfractionKind, Monitors,
};
use crate::observe::{RunObserver, TickView, TimedCamera};
use crate::overlap::{Overlap, Seen};
use crate::record::{
    Provenance, RealisedTraffic, RunPerf, RunRecord, RunResult, RunSettings, count_by_kind,
};
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

pub use crate::error::RunError;

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
    /// Who drives, over the scenario's `[driver]` (paths relative to the working folder).
    pub driver: Option<crate::scenario::DriverSpec>,
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
        if let Some(d) = &self.driver {
            s.driver = d.clone();
        }
        s
    }
}

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

/// The git commit and version this binary was built from.
pub fn build_id() -> String {
    format!(
        "mrdrive {} ({})",
        env!("CARGO_PKG_VERSION"),
        option_env!("MRDRIVE_GIT_COMMIT").unwrap_or("unknown commit")
    )
}

/// The CPU's model name (the first `model name` of `/proc/cpuinfo`), or `None` where
/// the OS does not say. Run records carry it ([`Provenance::cpu`]).
pub fn cpu_model() -> Option<String> {
    cpuinfo_field(
        &std::fs::read_to_string("/proc/cpuinfo").ok()?,
        "model name",
    )
}

/// The first value of `key` in a `/proc/cpuinfo` text (`key<tabs>: value`), trimmed;
/// `None` if absent or blank.
fn cpuinfo_field(cpuinfo: &str, key: &str) -> Option<String> {
    cpuinfo
        .lines()
        .find_map(|l| l.strip_prefix(key)?.trim_start().strip_prefix(':'))
        .map(|value| value.trim().to_string())
        .filter(|value| !value.is_empty())
}

/// The timing in force at `scale`: the delay is `max(D, Lexec(scale))`, the
/// period `max(Tc, delay)` (docs/protocol.md §1). With `latency = "measured"` the
/// loop replaces `Lexec` by the driver's real compute time at each boundary.
pub fn timing_at(scenario: &Scenario, scale: f64) -> (DelayTiming, f64) {
    timing_for(scenario, scenario.latency_ms_at(scale))
}

/// The one rule of the achieved loop (docs/protocol.md §1): an execution latency of
/// `exec_ms` puts `max(D, exec_ms)` in force as the delay, with the period
/// `max(Tc, delay)`. Returns the timing and the delay (milliseconds).
fn timing_for(scenario: &Scenario, exec_ms: f64) -> (DelayTiming, f64) {
    let t = &scenario.timing;
    let latency_ms = t.delay_ms.max(exec_ms);
    (
        DelayTiming::from_period_and_latency(t.control_period_ms, latency_ms, t.tick_s),
        latency_ms,
    )
}

/// The NPC traffic a scenario spawns: its densities and seed, on its tick.
pub fn traffic_config(scenario: &Scenario) -> TrafficConfig {
    let defaults = TrafficConfig::default();
    TrafficConfig {
        vehicles: scenario.traffic.vehicles as usize,
        pedestrians: scenario.traffic.pedestrians as usize,
        seed: scenario.traffic.seed,
        tick_s: scenario.timing.tick_s as f32,
        pedestrian: PedestrianParams {
            cross_factor: scenario.traffic.cross_factor,
            ego_crossings_per_min: scenario.traffic.ego_crossings_per_min,
            ..defaults.pedestrian
        },
        ..defaults
    }
}

/// Where the ego starts: the route's first point.
pub fn ego_start(route: &DenseRoute) -> Result<EgoStart, RunError> {
    EgoStart::at_start_of(route)
        .ok_or_else(|| RunError::Setup(format!("route {} has no points", route.id)))
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
            static_name: None,
        },
        Party::Actor { id, .. } => EgoContact {
            other: id,
            kind: ContactKind::Vehicle,
            static_name: None,
        },
        // Statics carry no per-object id: each kind counts as one "actor".
        Party::Static(kind) => EgoContact {
            other: 1_000_000 + kind as u32,
            kind: ContactKind::Static,
            static_name: Some(kind.name()),
        },
    })
}

/// What the selector sees: the distances along the route from the ego's
/// centre to the next stop line ahead and from the last one passed (metres).
/// TimeParam's oracle measures a straight line to the light's trigger volume
/// (the stop line of the approach lane); on an approach the two agree.
/// With the driver's own hint ([`Driver::scale_hint`]) for a learned selector.
fn selector_input(
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

/// The log-normal spread of the execution latency (`timing.latency_jitter`):
/// a factor with mean 1 drawn at each control boundary from its own seeded
/// generator, so jitter never changes the traffic's random draws.
struct Jitter {
    sigma: f64,
    rng: ChaCha8Rng,
}

impl Jitter {
    fn new(scenario: &Scenario) -> Option<Jitter> {
        let sigma = scenario.timing.latency_jitter;
        (sigma > 0.0).then(|| Jitter {
            sigma,
            rng: ChaCha8Rng::seed_from_u64(scenario.traffic.seed ^ 0x6a69_7474_6572),
        })
    }

    /// The next factor: exp(sigma z - sigma^2 / 2), z standard normal (Box-Muller).
    fn factor(&mut self) -> f64 {
        let u1: f64 = 1.0 - self.rng.random::<f64>();
        let u2: f64 = self.rng.random::<f64>();
        let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        (self.sigma * z - self.sigma * self.sigma / 2.0).exp()
    }
}

/// The control side of the loop: the scale in force, the delay line and
/// the latencies seen.
struct Controls {
    scale: f64,
    latency_ms: f64,
    max_latency_ms: f64,
    delay: DelayLine,
    /// Boundaries at each scale (keyed by the scale's bits).
    scale_counts: BTreeMap<u64, u64>,
    jitter: Option<Jitter>,
}

impl Controls {
    fn new(scenario: &Scenario, selector: &mut dyn ResolutionSelector) -> Controls {
        selector.reset();
        let scale = f64::from(selector.select(&SelectorInput::default()));
        let (timing, latency_ms) = timing_at(scenario, scale);
        Controls {
            scale,
            latency_ms,
            max_latency_ms: latency_ms,
            delay: DelayLine::new(timing),
            scale_counts: BTreeMap::new(),
            jitter: Jitter::new(scenario),
        }
    }

    /// At a boundary: a new scale's latency, or with jitter a new draw of
    /// the current one, put in force from this boundary on.
    fn retime(&mut self, scenario: &Scenario, new_scale: f64) {
        let changed = new_scale != self.scale;
        self.scale = new_scale;
        if let Some(j) = self.jitter.as_mut() {
            let (timing, l) = timing_for(scenario, scenario.latency_ms_at(new_scale) * j.factor());
            self.set_latency(timing, l);
        } else if changed {
            let (t, l) = timing_at(scenario, new_scale);
            self.set_latency(t, l);
        }
    }

    /// Puts `latency_ms` in force (from the next boundary on).
    fn set_latency(&mut self, timing: DelayTiming, latency_ms: f64) {
        self.delay.set_timing(timing);
        self.latency_ms = latency_ms;
        self.max_latency_ms = self.max_latency_ms.max(latency_ms);
    }

    /// The share of the boundaries at each scale.
    fn scale_share(&self) -> BTreeMap<String, f64> {
        let total: u64 = self.scale_counts.values().sum();
        self.scale_counts
            .iter()
            .map(|(bits, n)| {
                (
                    format!("{}", f64::from_bits(*bits)),
                    *n as f64 / total.max(1) as f64,
                )
            })
            .collect()
    }
}

/// The world of a run: traffic with the ego, and the lights.
struct World {
    traffic: Traffic,
    lights: LightController,
    /// Every light's state during the coming step.
    light_states: Vec<LightState>,
}

impl World {
    fn new(scenario: &Scenario, prepared: &Prepared) -> Result<World, RunError> {
        let seed = scenario.traffic.seed;
        let cfg = traffic_config(scenario);
        let town = prepared.town.clone();
        let traffic = Traffic::new(town.clone(), cfg, Some(ego_start(&prepared.route)?));
        let lights = LightController::new(&town, LightTiming::default(), seed ^ 0x6c69_6768_7473);
        let mut world = World {
            traffic,
            lights,
            light_states: vec![LightState::Red; town.lights.len()],
        };
        world.read_lights();
        Ok(world)
    }

    fn read_lights(&mut self) {
        for (i, s) in self.light_states.iter_mut().enumerate() {
            *s = self.lights.state(LightIdx(i as u32));
        }
    }

    /// NPCs, pedestrians and physics for one tick; the ego's contacts.
    fn step(&mut self, contacts: &mut Vec<EgoContact>) {
        let events = self.traffic.step(&self.light_states);
        contacts.clear();
        contacts.extend(events.iter().filter_map(|e| ego_contact(e.a, e.b)));
    }

    /// The lights advance by one tick.
    fn step_lights(&mut self, tick_s: f64) {
        self.lights.step(tick_s);
        self.read_lights();
    }
}

/// One tick as a control boundary sees it.
struct Now<'t> {
    /// The tick.
    tick: u64,
    /// The world before the step.
    world: &'t World,
    /// The ego's snapshot.
    ego: &'t ActorSnapshot,
    /// Every actor's snapshot, the ego first.
    actors: &'t [ActorSnapshot],
    /// The ego's index on the dense route.
    route_index: usize,
}

/// Step 1 of the tick (docs/protocol.md §1): at a control boundary the selector picks
/// the scale (and with it the latency in force), the camera renders the
/// observation, the driver acts and its control enters the delay line. Holds
/// what every boundary of a run reads, and the buffers it reuses.
struct Boundary<'r> {
    scenario: &'r Scenario,
    town: &'r Town,
    route: &'r DenseRoute,
    stops: &'r RouteStops,
    vehicle: &'r world::agents::VehicleParams,
    needs: crate::driver::DriverNeeds,
    /// The class image of a driver that asks for it.
    labels_image: RgbImage,
    /// The route ahead of the ego, for the privileged "actor ahead".
    ahead_path: Vec<Vec2>,
}

impl Boundary<'_> {
    /// The selector's scale at `now` (given the driver's `hint`), put in force with its
    /// latency and counted.
    fn select(
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
    fn act_beside<'scope, 'd: 'scope>(
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
    fn act(
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

#[cfg(test)]
mod tests {
    use super::cpuinfo_field;

    #[test]
    fn a_cpuinfo_field_is_its_first_value() {
        let info = "processor\t: 0\nvendor_id\t: AuthenticAMD\nmodel\t\t: 17\n\
                    model name\t: AMD EPYC 9R14\nprocessor\t: 1\nmodel name\t: other\n";
        let field = |key| cpuinfo_field(info, key);
        assert_eq!(field("model name").as_deref(), Some("AMD EPYC 9R14"));
        assert_eq!(field("vendor_id").as_deref(), Some("AuthenticAMD"));
        // `model` is its own key, not the start of `model name`.
        let named_first = "model name\t: AMD EPYC 9R14\nmodel\t\t: 17\n";
        assert_eq!(cpuinfo_field(named_first, "model").as_deref(), Some("17"));
        // A blank value or none at all says nothing.
        assert_eq!(cpuinfo_field("model name\t:   \n", "model name"), None);
        assert_eq!(cpuinfo_field("", "vendor_id"), None);
    }
}
