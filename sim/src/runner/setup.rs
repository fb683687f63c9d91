//! A run's setup: the scenario's town and route loaded once ([`Prepared`]), its
//! traffic and the ego's start, and the world the loop steps (traffic, lights, the
//! ego's contacts).

use std::path::PathBuf;
use std::sync::Arc;

use world::agents::pedestrian::PedestrianParams;
use world::map::{LoadOptions, UnsignalledJunctions, load_xodr_file};
use world::route::RouteFile;
use world::route::{DenseRoute, PlannerConfig, plan_route};
use world::traffic::{EgoStart, Traffic, TrafficConfig};
use world::traffic::{LightController, LightTiming};
use world::{LightIdx, LightState, Town};

use super::RunError;
use crate::monitors::EgoContact;
use crate::scenario::Scenario;

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
        unsignalled: if scenario.map.generates_lights() {
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

/// The world of a run: traffic with the ego, and the lights.
pub(super) struct World {
    pub(super) traffic: Traffic,
    pub(super) lights: LightController,
    /// Every light's state during the coming step.
    pub(super) light_states: Vec<LightState>,
}

impl World {
    pub(super) fn new(scenario: &Scenario, prepared: &Prepared) -> Result<World, RunError> {
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

    pub(super) fn read_lights(&mut self) {
        for (i, s) in self.light_states.iter_mut().enumerate() {
            *s = self.lights.state(LightIdx(i as u32));
        }
    }

    /// NPCs, pedestrians and physics for one tick; the ego's contacts.
    pub(super) fn step(&mut self, contacts: &mut Vec<EgoContact>) {
        let events = self.traffic.step(&self.light_states);
        contacts.clear();
        contacts.extend(events.iter().filter_map(|e| EgoContact::between(e.a, e.b)));
    }

    /// The lights advance by one tick.
    pub(super) fn step_lights(&mut self, tick_s: f64) {
        self.lights.step(tick_s);
        self.read_lights();
    }
}
