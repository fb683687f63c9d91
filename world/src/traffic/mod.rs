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
//! seed and its id, so the same seed gives the same run bit for bit.

pub mod light_controller;
pub mod soak;

pub use light_controller::{LightController, LightTiming};
pub use soak::{MeanSd, SoakReport, TableOneRow, soak, table_one};

use crate::agents::actor::{ActorKind, ActorSnapshot};
use crate::agents::npc::{self, Npc, NpcParams, Reservations, Scratch};
use crate::agents::pedestrian::{Pedestrian, PedestrianParams, WalkGraph};
use crate::agents::vehicle::{VehicleControl, VehicleParams, VehicleState};
use crate::map::town::{LaneIdx, LightState, Town};
use crate::physics::{
    ContactEvent, DT_S, PEDESTRIAN_HEIGHT_M, PEDESTRIAN_RADIUS_M, Party, Physics,
};
use crate::road::lane_path::LanePath;
use crate::rules::ahead::{ActorView, Ahead, nearest_ahead};
use crate::rules::{self, RuleBook};
use glam::{Vec2, Vec3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;

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

/// An NPC stopped this long counts as a deadlock (seconds).
const DEADLOCK_S: f32 = 60.0;
/// A walker held up by a vehicle this long turns back (seconds).
const WALKER_PATIENCE_S: f32 = 0.5;

/// Counters the soak and the reports read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TrafficStats {
    /// Ticks stepped.
    pub ticks: u64,
    /// NPC respawns (stuck for more than `stuck_ticks`, or off their path).
    pub respawns: u64,
    /// Stop lines crossed by an NPC's front bumper while the light was red.
    pub npc_red_runs: u64,
    /// Contacts started between two NPC vehicles.
    pub npc_npc_collisions: u64,
    /// Contacts started by an NPC vehicle driving into a pedestrian.
    pub npc_pedestrian_collisions: u64,
    /// Contacts started by a pedestrian walking into a vehicle (NPC or ego).
    pub pedestrian_vehicle_bumps: u64,
    /// Contacts started between an NPC vehicle and a static collider.
    pub npc_static_collisions: u64,
    /// Times an NPC had been stopped for more than 60 s.
    pub deadlocks: u64,
}

/// The ego vehicle.
#[derive(Debug, Clone)]
pub struct Ego {
    /// Pose, speed, actuators.
    pub state: VehicleState,
    /// Ground height (metres).
    pub z: f32,
    /// The control in force.
    pub control: VehicleControl,
    /// The lane it is on (lane, arc length), if any.
    pub lane: Option<(LaneIdx, f32)>,
}

/// Ego, NPC vehicles and pedestrians in one physics world (see the module docs).
pub struct Traffic {
    town: Arc<Town>,
    cfg: TrafficConfig,
    /// The physics world.
    pub physics: Physics,
    rules: Arc<RuleBook>,
    reservations: Reservations,
    walk: WalkGraph,
    ego: Option<Ego>,
    /// The NPC vehicles, by id.
    pub npcs: Vec<Npc>,
    /// The pedestrians, by id.
    pub pedestrians: Vec<Pedestrian>,
    views: Vec<ActorView>,
    events: Vec<ContactEvent>,
    stats: TrafficStats,
    scratch: Scratch,
    spawn_lanes: Vec<LaneIdx>,
}

fn actor_rng(seed: u64, id: u32) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed ^ 0x7261_6666_6963_0000);
    r.set_stream(id as u64 + 1);
    r
}

impl Traffic {
    /// Builds the world and spawns the ego (if given), then the NPCs and pedestrians from the seed.
    pub fn new(town: Arc<Town>, cfg: TrafficConfig, ego: Option<EgoStart>) -> Traffic {
        let physics = Physics::new(&town, cfg.tick_s);
        let rules = Arc::new(RuleBook::new(&town));
        let reservations = Reservations::new(town.lanes.len());
        let walk = WalkGraph::new(&town, &cfg.pedestrian);
        let min_len = cfg.vehicle.length_m + 4.0;
        let spawn_lanes = (0..town.lanes.len())
            .filter(|&i| {
                town.lanes[i].junction.is_none()
                    && town.lanes[i].length_m() > min_len
                    && !town.lanes[i].successors.is_empty()
            })
            .map(|i| LaneIdx(i as u32))
            .collect();
        let mut t = Traffic {
            town,
            cfg,
            physics,
            rules,
            reservations,
            walk,
            ego: None,
            npcs: Vec::new(),
            pedestrians: Vec::new(),
            views: Vec::new(),
            events: Vec::new(),
            stats: TrafficStats::default(),
            scratch: Scratch::default(),
            spawn_lanes,
        };
        if let Some(e) = ego {
            t.teleport_ego(e);
        }
        t.spawn_vehicles();
        t.spawn_pedestrians();
        t.refresh_views();
        t
    }

    fn vehicle_size(&self) -> Vec3 {
        let v = &self.cfg.vehicle;
        Vec3::new(v.length_m, v.width_m, v.height_m)
    }

    /// A free spot on a random lane: (lane, s, position, yaw, z); None after `tries` failures.
    fn free_spot(
        &self,
        rng: &mut ChaCha8Rng,
        tries: usize,
        ignore: Option<u32>,
    ) -> Option<(LaneIdx, f32, Vec2, f32, f32)> {
        if self.spawn_lanes.is_empty() {
            return None;
        }
        let half = self.cfg.vehicle.length_m * 0.5;
        for _ in 0..tries {
            let lane = self.spawn_lanes[rng.random_range(0..self.spawn_lanes.len())];
            let l = self.town.lane(lane);
            let s = rng.random_range(half + 1.0..l.length_m() - half - 1.0);
            let (p, yaw, z) = l.pose_at(s);
            if self.physics.vehicle_fits(
                self.vehicle_size(),
                p,
                z,
                yaw,
                self.cfg.npc.min_gap_m,
                ignore,
            ) {
                return Some((lane, s, p, yaw, z));
            }
        }
        None
    }

    fn spawn_vehicles(&mut self) {
        for k in 0..self.cfg.vehicles {
            let id = self.npcs.len() as u32 + 1;
            let mut rng = actor_rng(self.cfg.seed, id);
            // A requested vehicle that finds no free spot in 50 tries is not spawned.
            let Some((lane, s, p, yaw, z)) = self.free_spot(&mut rng, 50, None) else {
                continue;
            };
            let mut path = LanePath::new(lane, s);
            npc::extend_path(&self.town, &mut path, &mut rng, 80.0);
            self.physics
                .add_vehicle(id, ActorKind::Vehicle, self.vehicle_size(), p, z, yaw);
            self.npcs.push(Npc {
                id,
                state: VehicleState::at_rest(p, yaw),
                ground_z: z,
                path,
                reservation: None,
                request: None,
                stuck_ticks: 0,
                stopped_ticks: 0,
                control: VehicleControl::BRAKE,
                color: (k % 8) as u8,
                rng,
            });
        }
    }

    fn spawn_pedestrians(&mut self) {
        let first = self.cfg.vehicles as u32 + 1;
        let n_nodes = self.walk.nodes.len();
        for k in 0..self.cfg.pedestrians {
            let id = first + k as u32;
            let mut rng = actor_rng(self.cfg.seed, id);
            if n_nodes == 0 {
                break;
            }
            // One try per requested walker, like a batch spawn: an unsafe spot is refused.
            let node = rng.random_range(0..n_nodes) as u32;
            let n = self.walk.nodes[node as usize];
            if !self
                .physics
                .pedestrian_fits(n.position, self.cfg.pedestrian.spawn_clearance_m)
            {
                continue;
            }
            let p = &self.cfg.pedestrian;
            let speed = rng.random_range(p.min_speed_mps..=p.max_speed_mps);
            let jaywalker = rng.random::<f32>() < p.cross_factor;
            self.physics.add_pedestrian(id, n.position, n.z);
            self.pedestrians
                .push(Pedestrian::new(id, &self.walk, node, speed, jaywalker, rng));
        }
    }

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

    /// Puts NPC number `index` (in [`Traffic::npcs`]) at rest at the start
    /// of `path`, extended with random successors from its own stream; drops
    /// its reservation and request and clears its stuck counters. Respawns
    /// go through here; tests and scripted scenes call it directly (the
    /// caller checks that the spot is free).
    pub fn place_npc(&mut self, index: usize, path: LanePath) {
        let n = &mut self.npcs[index];
        let id = n.id;
        if let Some(r) = n.reservation.take() {
            self.reservations.release(r, id);
        }
        let (p, yaw, z) = self.town.lane(path.lane()).pose_at(path.s_m);
        n.state = VehicleState::at_rest(p, yaw);
        n.ground_z = z;
        n.path = path;
        n.request = None;
        n.stuck_ticks = 0;
        n.stopped_ticks = 0;
        npc::extend_path(&self.town, &mut n.path, &mut n.rng, 80.0);
        self.physics.teleport(id, p, yaw);
        self.refresh_views();
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

    /// Moves the ego to a pose at rest (no sweep; for scenario starts).
    pub fn teleport_ego(&mut self, start: EgoStart) {
        let size = self.vehicle_size();
        self.physics
            .add_vehicle(0, ActorKind::Ego, size, start.position, start.z, start.yaw);
        self.ego = Some(Ego {
            state: VehicleState::at_rest(start.position, start.yaw),
            z: start.z,
            control: VehicleControl::BRAKE,
            lane: self
                .rules
                .lanes
                .lane_under(&self.town, start.position, start.yaw)
                .map(|lp| (lp.lane, lp.s)),
        });
        self.refresh_views();
    }

    /// Every actor as the behaviours see it (start of the next tick).
    pub fn actor_views(&self) -> &[ActorView] {
        &self.views
    }

    /// The nearest actor other than the ego ahead along a path (points ~1 m apart from the ego's centre): see [`crate::rules::ahead`].
    pub fn nearest_ahead_of_ego(
        &self,
        path: &[Vec2],
        corridor_half_m: f32,
        max_m: f32,
    ) -> Option<Ahead> {
        nearest_ahead(path, &self.views, Some(0), corridor_half_m, max_m)
    }

    /// The contact events of the last tick.
    pub fn contacts(&self) -> &[ContactEvent] {
        &self.events
    }

    fn refresh_views(&mut self) {
        self.views.clear();
        let (hl, hw) = (
            self.cfg.vehicle.length_m * 0.5,
            self.cfg.vehicle.width_m * 0.5,
        );
        if let Some(e) = &self.ego {
            self.views.push(ActorView {
                id: 0,
                kind: ActorKind::Ego,
                position: e.state.position,
                yaw: e.state.yaw,
                speed_mps: e.state.speed_mps,
                half_length_m: hl,
                half_width_m: hw,
            });
        }
        for n in &self.npcs {
            self.views.push(ActorView {
                id: n.id,
                kind: ActorKind::Vehicle,
                position: n.state.position,
                yaw: n.state.yaw,
                speed_mps: n.state.speed_mps,
                half_length_m: hl,
                half_width_m: hw,
            });
        }
        for p in &self.pedestrians {
            self.views.push(ActorView {
                id: p.id,
                kind: ActorKind::Pedestrian,
                position: p.position,
                yaw: p.yaw,
                speed_mps: p.current_speed_mps,
                half_length_m: PEDESTRIAN_RADIUS_M,
                half_width_m: PEDESTRIAN_RADIUS_M,
            });
        }
    }

    /// Snapshots of every actor for the camera, monitors and logs (ego first, then by id).
    pub fn snapshots(&self, out: &mut Vec<ActorSnapshot>) {
        out.clear();
        let size = self.vehicle_size();
        if let Some(e) = &self.ego {
            out.push(ActorSnapshot {
                id: 0,
                kind: ActorKind::Ego,
                position: e.state.position.extend(e.z),
                heading: e.state.yaw,
                extent: size,
                speed_mps: e.state.speed_mps,
                color: 0,
            });
        }
        for n in &self.npcs {
            out.push(ActorSnapshot {
                id: n.id,
                kind: ActorKind::Vehicle,
                position: n.state.position.extend(n.ground_z),
                heading: n.state.yaw,
                extent: size,
                speed_mps: n.state.speed_mps,
                color: n.color,
            });
        }
        for p in &self.pedestrians {
            out.push(ActorSnapshot {
                id: p.id,
                kind: ActorKind::Pedestrian,
                position: p.position.extend(p.z),
                heading: p.yaw,
                extent: Vec3::new(
                    2.0 * PEDESTRIAN_RADIUS_M,
                    2.0 * PEDESTRIAN_RADIUS_M,
                    PEDESTRIAN_HEIGHT_M,
                ),
                speed_mps: p.current_speed_mps,
                color: (p.id % 8) as u8,
            });
        }
    }

    /// Whether an NPC must stop for the light ahead: (must stop, distance from its front to the stop line).
    fn light_stop(
        &self,
        n: &Npc,
        lights: &[LightState],
    ) -> Option<(bool, f32, crate::map::town::LightIdx)> {
        let v = n.state.speed_mps;
        npc::next_stop_line(&self.town, &self.rules, n, &self.cfg.vehicle, 80.0).map(
            |(d, light)| {
                let stop = rules::must_stop(
                    rules::light_state(lights, light),
                    d,
                    v,
                    self.cfg.npc.comfort_decel_mps2,
                );
                (stop, d, light)
            },
        )
    }

    /// Where each vehicle's rear is on the lane graph (for the box check).
    fn occupants(&self) -> Vec<(LaneIdx, f32)> {
        let half = self.cfg.vehicle.length_m * 0.5;
        let mut occ: Vec<(LaneIdx, f32)> = self
            .npcs
            .iter()
            .map(|n| (n.path.lane(), n.path.s_m - half))
            .collect();
        if let Some((l, s)) = self.ego.as_ref().and_then(|e| e.lane) {
            occ.push((l, s - half));
        }
        occ
    }

    fn update_reservations(&mut self, lights: &[LightState]) {
        let tick = self.stats.ticks;
        let vp = self.cfg.vehicle;
        let half = vp.length_m * 0.5;
        // Release: left the junction, or now stopping for a light before it.
        for i in 0..self.npcs.len() {
            let n = &self.npcs[i];
            let Some(res) = n.reservation else { continue };
            let inside_or_ahead = n.path.lanes.contains(&res);
            let left = !inside_or_ahead && n.path.s_m > half + 1.0;
            let lost =
                !inside_or_ahead && !left && n.path.lanes[0] != town_successor_of(&self.town, res);
            let before = inside_or_ahead && n.path.lane() != res;
            let entry = npc::next_junction_lane(&self.town, n, &vp)
                .filter(|(l, _)| *l == res)
                .map(|(_, d)| d);
            let stop_for_light = before
                && entry.is_some_and(|d_entry| {
                    self.light_stop(n, lights)
                        .is_some_and(|(stop, d, _)| stop && d > -0.3 && d <= d_entry + 0.1)
                });
            if left || lost || stop_for_light {
                let id = n.id;
                self.reservations.release(res, id);
                self.npcs[i].reservation = None;
            }
        }
        // Requests.
        let occ = self.occupants();
        let mut requests: Vec<(u64, u32, usize, LaneIdx)> = Vec::new();
        for (i, n) in self.npcs.iter_mut().enumerate() {
            let Some((lane, d)) = npc::next_junction_lane(&self.town, n, &vp) else {
                n.request = None;
                continue;
            };
            if n.reservation.is_some() {
                // One reservation at a time: the next is asked for once the last is released.
                n.request = None;
                continue;
            }
            let v = n.state.speed_mps;
            let near = d < v * v / (2.0 * self.cfg.npc.comfort_decel_mps2) + 10.0;
            if !near {
                n.request = None;
                continue;
            }
            let since = match n.request {
                Some((l, t)) if l == lane => t,
                _ => tick,
            };
            n.request = Some((lane, since));
            requests.push((since, n.id, i, lane));
        }
        requests.sort();
        let min_room = vp.length_m + self.cfg.npc.min_gap_m;
        let mut waiting: Vec<LaneIdx> = Vec::new();
        // The ego reserves nothing, but while it is on a connecting lane NPCs treat that lane as held.
        let ego_junction_lane = self
            .ego
            .as_ref()
            .and_then(|e| e.lane)
            .map(|(l, _)| l)
            .filter(|l| self.town.lanes[l.0 as usize].junction.is_some());
        if let Some(l) = ego_junction_lane {
            self.reservations.grant(l, 0);
        }
        for (_, id, i, lane) in requests {
            let n = &self.npcs[i];
            // A red (or stoppable yellow) light before this junction's entry: wait for it.
            let d_entry =
                npc::next_junction_lane(&self.town, n, &vp).map_or(f32::INFINITY, |(_, d)| d);
            if self
                .light_stop(n, lights)
                .is_some_and(|(stop, d, _)| stop && d > -0.3 && d <= d_entry + 0.1)
            {
                continue;
            }
            // An older request that is waiting for a conflicting lane goes first: no overtaking it.
            let queued_behind = waiting
                .iter()
                .any(|&w: &LaneIdx| w == lane || self.rules.conflicts.of(lane).contains(&w));
            if queued_behind || !self.reservations.free_for(&self.rules.conflicts, lane, id) {
                waiting.push(lane);
                continue;
            }
            // Only the first vehicle of its lane may reserve: one behind it could not enter anyway
            // and would block the lanes the first one needs.
            let (my_lane, my_rear) = occ[i];
            if occ
                .iter()
                .enumerate()
                .any(|(k, &(l, rear))| k != i && l == my_lane && rear > my_rear)
            {
                continue;
            }
            // Don't block the box: the exit lane needs room for this car.
            let exit = town_successor_of(&self.town, lane);
            let exit_on_path = n
                .path
                .lanes
                .iter()
                .skip_while(|&&l| l != lane)
                .nth(1)
                .copied()
                .unwrap_or(exit);
            let room = occ.iter().enumerate().all(|(k, &(l, rear))| {
                let other = if k < self.npcs.len() {
                    self.npcs[k].id
                } else {
                    0
                };
                other == id || l != exit_on_path || rear >= min_room
            });
            if !room {
                continue;
            }
            self.reservations.grant(lane, id);
            let n = &mut self.npcs[i];
            n.reservation = Some(lane);
            n.request = None;
        }
        if let Some(l) = ego_junction_lane {
            self.reservations.release(l, 0);
        }
    }

    /// Advances the world one tick of [`TrafficConfig::tick_s`]; `lights` are the light states by `LightIdx` (a light beyond the slice's end counts as green). Returns the tick's contacts.
    pub fn step(&mut self, lights: &[LightState]) -> &[ContactEvent] {
        let vp = self.cfg.vehicle;
        let dt = self.cfg.tick_s;
        self.update_reservations(lights);
        // Decide.
        let mut decisions = Vec::with_capacity(self.npcs.len());
        for n in &self.npcs {
            decisions.push(npc::decide(
                &self.town,
                &self.rules,
                &self.cfg.npc,
                &vp,
                n,
                &self.views,
                lights,
                &mut self.scratch,
            ));
        }
        let mut ped_targets = Vec::with_capacity(self.pedestrians.len());
        for p in &mut self.pedestrians {
            ped_targets.push(p.decide(&self.walk, &self.cfg.pedestrian, &self.views, dt));
        }
        // Move: ego, NPCs, pedestrians.
        if let Some(e) = &mut self.ego {
            let mut s = e.state;
            s.step(&vp, e.control, dt);
            let out = self.physics.move_actor(0, s.position, s.yaw);
            s.position = out.position;
            s.yaw = out.yaw;
            if out.hit.is_some() {
                s.speed_mps *= out.fraction;
            }
            e.state = s;
        }
        for (n, d) in self.npcs.iter_mut().zip(&decisions) {
            let stop_before = npc::next_stop_line(&self.town, &self.rules, n, &vp, 20.0);
            n.control = d.control;
            let mut s = n.state;
            s.step(&vp, d.control, dt);
            let out = self.physics.move_actor(n.id, s.position, s.yaw);
            s.position = out.position;
            s.yaw = out.yaw;
            if out.hit.is_some() {
                s.speed_mps *= out.fraction;
            }
            n.state = s;
            let travelled = n.path.advance_to(&self.town, s.position);
            if let Some((dist, light)) = stop_before
                && dist >= 0.0
                && travelled > dist
                && lights.get(light.0 as usize) == Some(&LightState::Red)
            {
                self.stats.npc_red_runs += 1;
            }
            npc::extend_path(&self.town, &mut n.path, &mut n.rng, 80.0);
            // Stuck / stopped bookkeeping.
            if s.speed_mps < 0.1 {
                n.stopped_ticks += 1;
                if n.stopped_ticks == (DEADLOCK_S / dt) as u32 + 1 {
                    self.stats.deadlocks += 1;
                }
                if d.accel_mps2 > 0.3 {
                    n.stuck_ticks += 1;
                } else {
                    n.stuck_ticks = 0;
                }
            } else {
                n.stopped_ticks = 0;
                n.stuck_ticks = 0;
            }
        }
        for (p, (target, z)) in self.pedestrians.iter_mut().zip(ped_targets) {
            let out = self.physics.move_actor(p.id, target, p.yaw);
            let z = if out.fraction >= 1.0 { z } else { p.z };
            p.arrive(&self.walk, out.position, z, dt);
            // A walker held up by a vehicle for half a second turns back (cars wait for walkers
            // in front of them; this keeps the two from waiting for each other).
            p.note_blocked(
                &self.walk,
                p.held_by_vehicle || (out.hit.is_some() && out.fraction < 0.5),
                (WALKER_PATIENCE_S / dt).round() as u32,
            );
        }
        // Respawn NPCs stuck too long or pushed off their path.
        for i in 0..self.npcs.len() {
            let n = &self.npcs[i];
            let (lp, _, _) = self.town.lane(n.path.lane()).pose_at(n.path.s_m);
            let off_path = (lp - n.state.position).length() > 4.0;
            if n.stuck_ticks > self.cfg.npc.stuck_ticks || off_path {
                self.respawn(i);
            }
        }
        if let Some(e) = &mut self.ego {
            e.lane = self
                .rules
                .lanes
                .lane_under(&self.town, e.state.position, e.state.yaw)
                .map(|lp| (lp.lane, lp.s));
        }
        self.events.clear();
        self.events.extend_from_slice(self.physics.end_tick());
        for ev in &self.events {
            if !ev.started {
                continue;
            }
            let kind = |p: Party| match p {
                Party::Actor { kind, .. } => Some(kind),
                Party::Static(_) => None,
            };
            match (kind(ev.a), kind(ev.b)) {
                (Some(ActorKind::Vehicle), Some(ActorKind::Vehicle)) => {
                    self.stats.npc_npc_collisions += 1
                }
                (Some(ActorKind::Vehicle), Some(ActorKind::Pedestrian)) => {
                    self.stats.npc_pedestrian_collisions += 1
                }
                (Some(ActorKind::Vehicle), None) => self.stats.npc_static_collisions += 1,
                (Some(ActorKind::Pedestrian), Some(_)) => self.stats.pedestrian_vehicle_bumps += 1,
                _ => {}
            }
        }
        self.stats.ticks += 1;
        self.refresh_views();
        &self.events
    }

    /// Moves NPC `i` to a free spot on a random lane ([`Traffic::place_npc`]); it stays where it is if none is found.
    fn respawn(&mut self, i: usize) {
        let id = self.npcs[i].id;
        let mut rng = self.npcs[i].rng.clone();
        let spot = self.free_spot(&mut rng, 20, Some(id));
        self.npcs[i].rng = rng;
        if let Some((lane, s, ..)) = spot {
            self.place_npc(i, LanePath::new(lane, s));
            self.stats.respawns += 1;
        }
    }
}

fn town_successor_of(town: &Town, lane: LaneIdx) -> LaneIdx {
    town.lanes[lane.0 as usize]
        .successors
        .first()
        .copied()
        .unwrap_or(lane)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown::{FixtureLights, grid};

    fn town() -> Arc<Town> {
        Arc::new(grid(3, 3, 60.0))
    }

    fn cfg(v: usize, p: usize, seed: u64) -> TrafficConfig {
        TrafficConfig {
            vehicles: v,
            pedestrians: p,
            seed,
            ..Default::default()
        }
    }

    fn trace(seed: u64, ticks: u64) -> Vec<u32> {
        let t = town();
        let lights = FixtureLights::new(&t);
        let ego = EgoStart {
            position: Vec2::new(30.0, -1.75),
            z: 0.0,
            yaw: 0.0,
        };
        let mut tr = Traffic::new(t, cfg(10, 20, seed), Some(ego));
        tr.set_ego_control(VehicleControl {
            steer: 0.0,
            throttle: 0.5,
            brake: 0.0,
        });
        let mut states = Vec::new();
        let mut snaps = Vec::new();
        let mut bits = Vec::new();
        for tick in 0..ticks {
            lights.states_at(tick, &mut states);
            tr.step(&states);
            tr.snapshots(&mut snaps);
            for s in &snaps {
                bits.extend([
                    s.id,
                    s.position.x.to_bits(),
                    s.position.y.to_bits(),
                    s.position.z.to_bits(),
                    s.heading.to_bits(),
                    s.speed_mps.to_bits(),
                ]);
            }
        }
        bits
    }

    #[test]
    fn same_seed_gives_identical_trajectories_bit_for_bit() {
        let a = trace(11, 600);
        let b = trace(11, 600);
        assert_eq!(a.len(), b.len());
        assert!(a == b, "trajectories differ");
        let c = trace(12, 600);
        assert!(a != c, "a different seed should give a different run");
    }

    /// The ego's x after `seconds` at full throttle from rest on a straight
    /// road, stepping `tick_s`.
    fn ego_x_after(tick_s: f32, seconds: f32) -> f32 {
        let t = Arc::new(grid(4, 1, 200.0));
        let ego = EgoStart {
            position: Vec2::new(20.0, -1.75),
            z: 0.0,
            yaw: 0.0,
        };
        let c = TrafficConfig {
            tick_s,
            ..cfg(0, 0, 1)
        };
        let mut tr = Traffic::new(t, c, Some(ego));
        tr.set_ego_control(VehicleControl {
            steer: 0.0,
            throttle: 1.0,
            brake: 0.0,
        });
        for _ in 0..(seconds / tick_s).round() as usize {
            tr.step(&[]);
        }
        tr.ego().unwrap().state.position.x
    }

    #[test]
    fn a_tick_of_another_length_moves_the_ego_that_much_farther() {
        // 3 s at full throttle: the vehicle model's own integration at the
        // step, and the same distance (to the integration error) at 40 Hz.
        let vp = VehicleParams::default();
        let mut model = VehicleState::at_rest(Vec2::new(20.0, -1.75), 0.0);
        let full = VehicleControl {
            steer: 0.0,
            throttle: 1.0,
            brake: 0.0,
        };
        for _ in 0..30 {
            model.step(&vp, full, 0.1);
        }
        let (x40, x10) = (ego_x_after(DT_S, 3.0), ego_x_after(0.1, 3.0));
        assert_eq!(x10, model.position.x, "stepped by the configured tick");
        let (d40, d10) = (x40 - 20.0, x10 - 20.0);
        assert!(d40 > 10.0, "{d40}");
        assert!(
            (d10 - d40).abs() < 0.05 * d40,
            "{d10} m at 10 Hz vs {d40} m at 40 Hz"
        );
    }

    #[test]
    fn spawns_do_not_overlap_each_other_or_the_ego() {
        let t = town();
        let ego = EgoStart {
            position: Vec2::new(30.0, -1.75),
            z: 0.0,
            yaw: 0.0,
        };
        let tr = Traffic::new(t, cfg(20, 40, 5), Some(ego));
        assert_eq!(tr.realised_vehicles(), 20);
        assert!(tr.realised_pedestrians() > 30 && tr.realised_pedestrians() <= 40);
        let ids: Vec<u32> = std::iter::once(0)
            .chain(tr.npcs.iter().map(|n| n.id))
            .collect();
        for &a in &ids {
            for &b in &ids {
                if a < b {
                    let d = tr.physics.distance(a, b).unwrap();
                    assert!(
                        d > tr.config().npc.min_gap_m,
                        "{a} and {b} spawned {d} m apart"
                    );
                }
            }
        }
    }

    #[test]
    fn npcs_stop_at_red_lights_at_the_stop_line() {
        let t = town();
        let mut tr = Traffic::new(t.clone(), cfg(16, 0, 3), None);
        let red = vec![LightState::Red; t.lights.len()];
        let vp = tr.config().vehicle;
        let half = vp.length_m * 0.5;
        let lines: Vec<[Vec2; 2]> = t
            .lights
            .iter()
            .flat_map(|l| &l.stop_lines)
            .map(|sl| [sl.ends[0].truncate(), sl.ends[1].truncate()])
            .collect();
        let front = |n: &Npc| n.state.position + Vec2::from_angle(n.state.yaw) * half;
        // Every front bumper, tick by tick: none crosses a stop line (all are red).
        let mut fronts: Vec<Vec2> = tr.npcs.iter().map(front).collect();
        for _ in 0..(40 * 90) {
            let respawns = tr.stats().respawns;
            tr.step(&red);
            // (A respawned NPC jumps: its old and new fronts are no drive.)
            let jumped = tr.stats().respawns != respawns;
            for (n, prev) in tr.npcs.iter().zip(&mut fronts) {
                let now = front(n);
                for ends in &lines {
                    assert!(
                        jumped || !crate::road::geometry::crosses_stop_line(*prev, now, *ends),
                        "NPC {} crossed a red stop line at {now}",
                        n.id
                    );
                }
                *prev = now;
            }
        }
        assert_eq!(tr.stats().npc_red_runs, 0);
        // NPCs whose front bumper is within 2 m before a stop line of their lane stand still.
        let mut waiting_at_line = 0;
        for n in &tr.npcs {
            let before_line = t.lights.iter().flat_map(|l| &l.stop_lines).any(|sl| {
                let d = sl.s - (n.path.s_m + half);
                sl.lane == n.path.lane() && (-0.3..2.0).contains(&d)
            });
            if before_line {
                assert!(
                    n.state.speed_mps < 0.1,
                    "NPC {} at the line moving {}",
                    n.id,
                    n.state.speed_mps
                );
                waiting_at_line += 1;
            }
        }
        assert!(
            waiting_at_line >= 4,
            "only {waiting_at_line} NPCs wait at a stop line"
        );
        assert_eq!(tr.stats().npc_npc_collisions, 0);
        // Queues keep about 3.0 m bumper to bumper (IDM minimum gap).
        let mut gaps = Vec::new();
        for a in &tr.npcs {
            for b in &tr.npcs {
                if a.id != b.id && a.path.lane() == b.path.lane() && b.path.s_m > a.path.s_m {
                    let gap = b.path.s_m - a.path.s_m - vp.length_m;
                    if gap < 8.0 {
                        gaps.push(gap);
                    }
                }
            }
        }
        assert!(gaps.len() >= 3, "no queues formed: {gaps:?}");
        for g in &gaps {
            assert!(*g > 2.7 && *g < 4.0, "queue gap {g} m: {gaps:?}");
        }
    }

    #[test]
    fn no_npc_npc_collisions_in_normal_flow() {
        let t = town();
        let lights = FixtureLights::new(&t);
        let mut tr = Traffic::new(t, cfg(20, 20, 7), None);
        let mut states = Vec::new();
        let start: Vec<Vec2> = tr.npcs.iter().map(|n| n.state.position).collect();
        for tick in 0..(40 * 120) {
            lights.states_at(tick, &mut states);
            tr.step(&states);
        }
        let s = tr.stats();
        assert_eq!(s.npc_npc_collisions, 0, "{s:?}");
        assert_eq!(s.npc_red_runs, 0, "{s:?}");
        assert_eq!(s.deadlocks, 0, "{s:?}");
        // They did drive.
        let moved = tr
            .npcs
            .iter()
            .zip(&start)
            .filter(|(n, p)| (n.state.position - **p).length() > 20.0)
            .count();
        assert!(moved >= 15, "only {moved} NPCs moved: {s:?}");
    }

    #[test]
    fn ego_drives_from_controls_and_its_contacts_name_both_actors() {
        let t = town();
        // Park an NPC 20 m ahead of the ego on its lane by spawning none and placing the ego behind a wall of NPC... use a single NPC.
        let ego = EgoStart {
            position: Vec2::new(20.0, -1.75),
            z: 0.0,
            yaw: 0.0,
        };
        let mut tr = Traffic::new(t.clone(), cfg(1, 0, 1), Some(ego));
        // The NPC 18 m ahead of the ego on its lane (x = 38); red lights keep it there.
        let id = tr.npcs[0].id;
        tr.place_npc(0, LanePath::new(LaneIdx(0), 28.0));
        assert_eq!(tr.npcs[0].state.position, Vec2::new(38.0, -1.75));
        tr.set_ego_control(VehicleControl {
            steer: 0.0,
            throttle: 1.0,
            brake: 0.0,
        });
        let red = vec![LightState::Red; t.lights.len()];
        let mut hit = None;
        for _ in 0..200 {
            let ev = tr.step(&red).to_vec();
            if let Some(e) = ev.iter().find(|e| {
                e.started
                    && e.a
                        == Party::Actor {
                            id: 0,
                            kind: ActorKind::Ego,
                        }
            }) {
                hit = Some(*e);
                break;
            }
        }
        let e = hit.expect("the ego hit the NPC");
        assert!(matches!(
            e.b,
            Party::Actor {
                kind: ActorKind::Vehicle,
                ..
            }
        ));
        assert!(!tr.physics.overlapping(0, id));
        // The query sees the NPC ahead of the ego.
        let path: Vec<Vec2> = (0..30)
            .map(|i| Vec2::new(tr.ego().unwrap().state.position.x + i as f32, -1.75))
            .collect();
        let a = tr
            .nearest_ahead_of_ego(&path, 1.5, 40.0)
            .expect("something ahead");
        assert!(
            a.kind == ActorKind::Vehicle && a.distance_m < 2.4 + 0.3,
            "{a:?}"
        );
    }

    #[test]
    fn a_stuck_npc_is_respawned_after_40_ticks() {
        let t = town();
        let mut tr = Traffic::new(t.clone(), cfg(1, 0, 2), None);
        // Put the NPC on lane 0 (at x = 20) and a box it cannot see (not an actor) 10 m ahead of it.
        tr.place_npc(0, LanePath::new(LaneIdx(0), 10.0));
        assert_eq!(tr.npcs[0].state.position, Vec2::new(20.0, -1.75));
        tr.physics.add_static_box(
            Vec2::new(30.0, -1.75),
            0.0,
            Vec3::new(1.0, 3.0, 1.0),
            0.0,
            crate::physics::StaticKind::Pole,
        );
        let green = vec![LightState::Green; t.lights.len()];
        let mut hit_tick = None;
        let mut respawn_tick = None;
        for tick in 0..400u32 {
            let ev = tr.step(&green).to_vec();
            if hit_tick.is_none()
                && ev
                    .iter()
                    .any(|e| e.started && matches!(e.b, Party::Static(_)))
            {
                hit_tick = Some(tick);
            }
            if tr.stats().respawns > 0 {
                respawn_tick = Some(tick);
                break;
            }
        }
        let (h, r) = (
            hit_tick.expect("hit the box"),
            respawn_tick.expect("respawned"),
        );
        // Respawned once stuck for more than 40 ticks (it needs a few ticks to come to a stop).
        assert!(r > h + 40 && r < h + 60, "hit at {h}, respawned at {r}");
        assert!((tr.npcs[0].state.position - Vec2::new(27.0, -1.75)).length() > 3.0);
        assert_eq!(tr.stats().npc_static_collisions, 1);
    }

    #[test]
    fn the_cross_factor_decides_who_crosses_between_crosswalks() {
        let t = town();
        let legs = |cross: f32| {
            let mut c = cfg(0, 40, 9);
            c.pedestrian.cross_factor = cross;
            let mut tr = Traffic::new(t.clone(), c, None);
            let lights = vec![LightState::Red; t.lights.len()];
            for _ in 0..(40 * 120) {
                tr.step(&lights);
            }
            let cw: u32 = tr.pedestrians.iter().map(|p| p.crosswalk_legs).sum();
            let jw: u32 = tr.pedestrians.iter().map(|p| p.jaywalk_legs).sum();
            let jaywalkers = tr.pedestrians.iter().filter(|p| p.jaywalker).count();
            assert!(tr.pedestrians.iter().all(|p| p.jaywalker == (cross >= 1.0)));
            (cw, jw, jaywalkers)
        };
        let (cw0, jw0, j0) = legs(0.0);
        assert!(cw0 > 5, "{cw0} crosswalk legs");
        assert_eq!((jw0, j0), (0, 0));
        let (_, jw1, j1) = legs(1.0);
        assert!(j1 > 30, "{j1} jaywalkers");
        assert!(jw1 > 5, "{jw1} jaywalk legs");
    }

    #[test]
    fn npcs_do_not_enter_a_junction_across_the_ego() {
        let t = town();
        let rules = RuleBook::new(&t);
        let dir_of = |l: usize| {
            let c = &t.lanes[l].centerline;
            (c[c.len() - 1] - c[0]).truncate().normalize()
        };
        let in_j4 = |l: usize| t.lanes[l].junction == Some(crate::map::town::JunctionIdx(4));
        // The ego stands in the centre junction on the straight northbound lane.
        let ego_lane = (0..t.lanes.len())
            .find(|&l| in_j4(l) && dir_of(l).y > 0.99)
            .unwrap();
        let l = &t.lanes[ego_lane];
        let (p, yaw, _) = l.pose_at(l.length_m() * 0.5);
        let mut tr = Traffic::new(
            t.clone(),
            cfg(1, 0, 4),
            Some(EgoStart {
                position: p,
                z: 0.0,
                yaw,
            }),
        );
        // One NPC approaches from the west and wants to go straight east, across the ego.
        let approach = (0..t.lanes.len())
            .find(|&l| {
                t.lanes[l].junction.is_none()
                    && dir_of(l).x > 0.99
                    && t.lanes[l].successors.iter().any(|s| in_j4(s.0 as usize))
            })
            .unwrap();
        let straight = *t.lanes[approach]
            .successors
            .iter()
            .find(|s| dir_of(s.0 as usize).x > 0.99)
            .unwrap();
        assert!(
            rules
                .conflicts
                .of(LaneIdx(ego_lane as u32))
                .contains(&straight)
        );
        let entry_x = t.lanes[straight.0 as usize].centerline[0].x;
        let mut path = LanePath::new(LaneIdx(approach as u32), 5.0);
        path.lanes.push_back(straight);
        tr.place_npc(0, path);
        let green = vec![LightState::Green; t.lights.len()];
        let half = tr.config().vehicle.length_m * 0.5;
        for _ in 0..(40 * 20) {
            tr.step(&green);
            let front = tr.npcs[0].state.position.x + half;
            assert!(
                front < entry_x + 0.1,
                "NPC entered the junction across the ego (front at {front})"
            );
            assert_ne!(tr.npcs[0].reservation, Some(straight));
        }
        // It waits at the entry, and goes once the ego has left.
        assert!(tr.npcs[0].state.position.x + half > entry_x - 2.0);
        tr.teleport_ego(EgoStart {
            position: Vec2::new(-100.0, -100.0),
            z: 0.0,
            yaw: 0.0,
        });
        for _ in 0..(40 * 10) {
            tr.step(&green);
        }
        assert!(
            tr.npcs[0].state.position.x > entry_x + 10.0,
            "NPC did not go after the ego left"
        );
    }

    #[test]
    fn an_npc_stopping_for_a_red_at_the_line_gives_its_reservation_back() {
        let t = town();
        let mut tr = Traffic::new(t.clone(), cfg(1, 0, 6), None);
        let sl = t.lights[0].stop_lines[0].clone();
        let half = tr.config().vehicle.length_m * 0.5;
        let turn = t.lanes[sl.lane.0 as usize].successors[0];
        // Front bumper 0.2 m before the stop line, at rest, going into the junction.
        let mut path = LanePath::new(sl.lane, sl.s - half - 0.2);
        path.lanes.push_back(turn);
        tr.place_npc(0, path);
        let id = tr.npcs[0].id;
        tr.step(&vec![LightState::Green; t.lights.len()]);
        assert_eq!(tr.npcs[0].reservation, Some(turn), "granted on green");
        // The light turns red before it has crossed the line: it stops there and
        // must not keep the junction from the crossing traffic meanwhile.
        let red = vec![LightState::Red; t.lights.len()];
        for _ in 0..(40 * 5) {
            tr.step(&red);
        }
        // Still on the approach lane with its front bumper at most 0.3 m over the line.
        let n = &tr.npcs[0];
        assert_eq!(n.path.lane(), sl.lane, "left the approach lane");
        let over = n.path.s_m + half - sl.s;
        assert!(over < 0.3, "crossed the red line by {over} m");
        assert_eq!(tr.npcs[0].reservation, None);
        assert!(!tr.reservations().holders(turn).contains(&id));
        assert_eq!(tr.stats().npc_red_runs, 0);
    }

    #[test]
    fn a_free_npc_drives_at_the_speed_limit() {
        // A straight road through unlit junctions: 4 x 1 junctions 200 m apart.
        let t = Arc::new(grid(4, 1, 200.0));
        let mut tr = Traffic::new(t.clone(), cfg(1, 0, 8), None);
        tr.place_npc(0, LanePath::new(LaneIdx(0), 1.0));
        let green = vec![LightState::Green; t.lights.len()];
        let limit = t.lanes[0].speed_limit_mps;
        let mut top = 0.0f32;
        for _ in 0..(40 * 15) {
            tr.step(&green);
            top = top.max(tr.npcs[0].state.speed_mps);
        }
        assert!(
            top > 0.95 * limit && top < 1.02 * limit,
            "top speed {top} vs limit {limit}"
        );
        // Tracking: it stays near its lane's centre.
        let (lp, _, _) = t.lane(tr.npcs[0].path.lane()).pose_at(tr.npcs[0].path.s_m);
        assert!((lp - tr.npcs[0].state.position).length() < 0.3);
    }
}
