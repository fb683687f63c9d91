//! The moving part of the world: ego, NPC vehicles and pedestrians in one physics world.
//!
//! [`Traffic`] owns the [`Physics`], the NPC vehicles and the pedestrians.
//! It spawns the requested counts from a seed (reporting what it realised),
//! and [`Traffic::step`] advances everything one tick of
//! [`TrafficConfig::tick_s`] (the scenario's, 40 Hz by default) given the
//! light states (indexed by `LightIdx`). Within a tick the order is fixed:
//! everyone decides from the start-of-tick state; junction reservations are
//! granted; the ego, then the NPCs (by id), then the pedestrians (by id) are
//! moved through the physics; NPC paths advance; stuck NPCs are respawned;
//! contact events are collected. Ids: the ego is 0, NPC vehicles are
//! `1..=n_vehicles`, pedestrians follow.
//!
//! Random streams: every actor has its own `ChaCha8Rng` derived from the
//! seed and its id (`spawn.rs`), so the same seed gives the same run bit for
//! bit.
//!
//! | file | what |
//! | --- | --- |
//! | `mod.rs` | [`Traffic`], its configuration and accessors |
//! | `spawn.rs` | seeded spawning, the ego's start, placing and respawning NPCs |
//! | [`reservations`] | junction reservations and how they are granted |
//! | `step.rs` | one tick |
//! | `stats.rs` | the counters ([`TrafficStats`]) |
//! | [`incidents`] | the incidents counted, listed (the first 50 of each kind): who, where, how fast |
//! | `views.rs` | actor views, snapshots, what is ahead of the ego |
//! | [`soak`] | soak runs and the realised-count table (Table I) |
//! | [`crossings`] | walkers sent across the road ahead of the ego (a collection aid) |
//! | [`light_controller`] | the traffic-light controllers |
//! | `tests.rs`, `tests_gen03.rs` | tests through the API; on gen03: giving way at the roundabout, reservations round a ring, gridlocks, lane changes |

pub mod crossings;
pub mod incidents;
pub mod light_controller;
pub mod removal;
pub mod reservations;
pub mod soak;
mod spawn;
mod stats;
mod step;
mod views;

pub use incidents::{Incident, IncidentActor, IncidentKind, IncidentLane, RespawnCause};
pub use light_controller::{LightController, LightTiming};
pub use reservations::Reservations;
pub use soak::{
    MeanSd, SoakReport, TableOneRow, soak, table_one, table_one_text, table_per_route_text,
};
pub use stats::TrafficStats;

use std::sync::Arc;

use glam::Vec2;

use crate::agents::npc::{Npc, NpcParams, Scratch};
use crate::agents::pedestrian::{Pedestrian, PedestrianParams, WalkGraph};
use crate::agents::{VehicleControl, VehicleParams, VehicleState};
use crate::map::{LaneIdx, Town};
use crate::physics::{ContactEvent, DT_S, Physics};
use crate::rules::{ActorView, RuleBook};

/// An NPC farther than this from the point of its lane it follows is respawned (metres).
pub const OFF_PATH_M: f32 = 4.0;

/// What to put in the town, and the step it moves by.
#[derive(Debug, Clone, PartialEq)]
pub struct TrafficConfig {
    /// NPC vehicles requested.
    pub vehicles: usize,
    /// Pedestrians requested.
    pub pedestrians: usize,
    /// The traffic seed (derived from the scenario's).
    pub seed: u64,
    /// The vehicle model (ego and NPCs).
    pub vehicle: VehicleParams,
    /// The NPC driver.
    pub npc: NpcParams,
    /// The walkers.
    pub pedestrian: PedestrianParams,
    /// The simulation step: each [`Traffic::step`] advances this much
    /// (seconds; the scenario's `timing.tick_s`, [`DT_S`] by default).
    pub tick_s: f32,
}

impl Default for TrafficConfig {
    fn default() -> Self {
        TrafficConfig {
            vehicles: 0,
            pedestrians: 0,
            seed: 0,
            vehicle: VehicleParams::default(),
            npc: NpcParams::default(),
            pedestrian: PedestrianParams::default(),
            tick_s: DT_S,
        }
    }
}

/// The ego's starting pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoStart {
    /// Position of the body centre (metres, ground plane).
    pub position: Vec2,
    /// Ground height (metres).
    pub z: f32,
    /// Heading (radians).
    pub yaw: f32,
}

impl EgoStart {
    /// At the first point of a route, facing along it (`None` for a route without points).
    pub fn at_start_of(route: &crate::route::DenseRoute) -> Option<EgoStart> {
        let p = route.points.first()?;
        Some(EgoStart {
            position: p.position.truncate(),
            z: p.position.z,
            yaw: p.heading,
        })
    }
}

/// The ego vehicle.
#[derive(Debug, Clone)]
pub struct Ego {
    /// Pose, speed, actuators.
    pub state: VehicleState,
    /// Ground height (metres): the road's under it, raised by the kerb its
    /// wheels stand on.
    pub z: f32,
    /// The height of the road under it (metres): its lane's (bridges and
    /// ramps included), the last lane's while it is off the lanes. Its
    /// physics body stands on it.
    pub road_z: f32,
    /// The control in force.
    pub control: VehicleControl,
    /// The lane it is on (lane, arc length), if any.
    pub lane: Option<(LaneIdx, f32)>,
    /// The kerbs its axles went up or down during the last tick, front axle first.
    pub kerbs: Vec<crate::agents::kerb::KerbCrossing>,
}

/// Ego, NPC vehicles and pedestrians in one physics world (see the module docs).
pub struct Traffic {
    town: Arc<Town>,
    cfg: TrafficConfig,
    physics: Physics,
    rules: Arc<RuleBook>,
    reservations: Reservations,
    walk: WalkGraph,
    ego: Option<Ego>,
    npcs: Vec<Npc>,
    pedestrians: Vec<Pedestrian>,
    views: Vec<ActorView>,
    events: Vec<ContactEvent>,
    stats: TrafficStats,
    incidents: Vec<Incident>,
    scratch: Scratch,
    spawn_lanes: Vec<LaneIdx>,
    crossing_edges: Vec<(u32, u32)>,
    crossing_rng: rand_chacha::ChaCha8Rng,
    /// The tick of the last removal by the Traffic Manager's rule (`removal`; 0 before any).
    last_removal_tick: u64,
}

impl Traffic {
    /// The town.
    pub fn town(&self) -> &Town {
        &self.town
    }

    /// The configuration.
    pub fn config(&self) -> &TrafficConfig {
        &self.cfg
    }

    /// NPC vehicles actually spawned.
    pub fn realised_vehicles(&self) -> usize {
        self.npcs.len()
    }

    /// Pedestrians actually spawned.
    pub fn realised_pedestrians(&self) -> usize {
        self.pedestrians.len()
    }

    /// The counters so far.
    pub fn stats(&self) -> TrafficStats {
        self.stats
    }

    /// The NPC vehicles, by id.
    pub fn npcs(&self) -> &[Npc] {
        &self.npcs
    }

    /// The pedestrians, by id.
    pub fn pedestrians(&self) -> &[Pedestrian] {
        &self.pedestrians
    }

    /// The physics world (read only: actors move through [`Traffic::step`],
    /// [`Traffic::place_npc`] and [`Traffic::teleport_ego`]).
    pub fn physics(&self) -> &Physics {
        &self.physics
    }

    /// The junction reservations in force.
    pub fn reservations(&self) -> &Reservations {
        &self.reservations
    }

    /// The town's rule tables (stop lines, junction conflicts, the lane
    /// grid), built once by [`Traffic::new`]; share them rather than build
    /// them again.
    pub fn rules(&self) -> &Arc<RuleBook> {
        &self.rules
    }

    /// The walk graph.
    pub fn walk_graph(&self) -> &WalkGraph {
        &self.walk
    }

    /// The ego, if there is one.
    pub fn ego(&self) -> Option<&Ego> {
        self.ego.as_ref()
    }

    /// Sets the ego's control; it stays in force until changed.
    pub fn set_ego_control(&mut self, control: VehicleControl) {
        if let Some(e) = &mut self.ego {
            e.control = control.clamped();
        }
    }

    /// The contact events of the last tick.
    pub fn contacts(&self) -> &[ContactEvent] {
        &self.events
    }
}

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_gen03;
