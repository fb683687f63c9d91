//! Putting actors into the traffic world: the seeded spawn of NPC vehicles
//! and pedestrians, the ego's start, placing an NPC on a lane path, and the
//! respawn of stuck NPCs (which goes through the same placement).
//!
//! Random streams: every actor has its own `ChaCha8Rng` derived from the
//! seed and its id, so the same seed gives the same run bit for bit.

use std::sync::Arc;

use glam::{Vec2, Vec3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use std::cmp::Reverse;

use super::incidents::{IncidentKind, RespawnCause};
use super::removal;
use super::reservations::Reservations;
use super::{Ego, EgoStart, OFF_PATH_M, Traffic, TrafficConfig, TrafficStats};
use crate::agents::npc::{self, Npc, Scratch};
use crate::agents::pedestrian::{Pedestrian, WalkGraph};
use crate::agents::{ActorKind, VehicleControl, VehicleState};
use crate::map::LightState;
use crate::map::props::place_props;
use crate::map::{LaneIdx, Town};
use crate::physics::Physics;
use crate::road::LanePath;
use crate::rules::{self, RuleBook};

fn actor_rng(seed: u64, id: u32) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed ^ 0x7261_6666_6963_0000);
    r.set_stream(id as u64 + 1);
    r
}

impl Traffic {
    /// Builds the world and spawns the ego (if given), then the NPCs and pedestrians from the seed.
    pub fn new(town: Arc<Town>, cfg: TrafficConfig, ego: Option<EgoStart>) -> Traffic {
        let mut physics = Physics::new(&town);
        physics.add_props(&place_props(&town, cfg.seed), town.ground_z());
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
        let crossing_edges = super::crossings::crossing_edges(&walk.edges);
        let crossing_rng = actor_rng(cfg.seed, u32::MAX);
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
            incidents: Vec::new(),
            scratch: Scratch::default(),
            spawn_lanes,
            crossing_edges,
            crossing_rng,
            last_removal_tick: 0,
        };
        if let Some(e) = ego {
            t.teleport_ego(e);
        }
        t.spawn_vehicles();
        t.spawn_pedestrians();
        t.refresh_views();
        t
    }

    pub(super) fn vehicle_size(&self) -> Vec3 {
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
            let mut change = None;
            npc::extend_path_planning(&self.town, &mut path, &mut rng, 80.0, &mut change);
            self.physics
                .add_vehicle(id, ActorKind::Vehicle, self.vehicle_size(), p, z, yaw);
            self.npcs.push(Npc {
                id,
                state: VehicleState::at_rest(p, yaw),
                ground_z: z,
                path,
                reservation: None,
                leaving: None,
                request: None,
                change,
                idle_ticks: 0,
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

    /// Puts NPC number `index` (in [`Traffic::npcs`]) at rest at the start
    /// of `path`, extended with random successors from its own stream; drops
    /// its reservation and request and clears its stuck counters. Respawns
    /// go through here; tests and scripted scenes call it directly (the
    /// caller checks that the spot is free).
    pub fn place_npc(&mut self, index: usize, path: LanePath) {
        let n = &mut self.npcs[index];
        let id = n.id;
        for r in [n.reservation.take(), n.leaving.take()]
            .into_iter()
            .flatten()
        {
            self.reservations.release(r, id);
        }
        let (p, yaw, z) = self.town.lane(path.lane()).pose_at(path.s_m);
        n.state = VehicleState::at_rest(p, yaw);
        n.ground_z = z;
        n.path = path;
        n.request = None;
        n.change = None;
        n.idle_ticks = 0;
        n.stopped_ticks = 0;
        npc::extend_path_planning(&self.town, &mut n.path, &mut n.rng, 80.0, &mut n.change);
        self.physics.teleport(id, p, yaw);
        self.physics.set_ground_z(id, z);
        self.refresh_views();
    }

    /// Moves the ego to a pose at rest (no sweep; for scenario starts).
    pub fn teleport_ego(&mut self, start: EgoStart) {
        let size = self.vehicle_size();
        self.physics
            .add_vehicle(0, ActorKind::Ego, size, start.position, start.z, start.yaw);
        self.ego = Some(Ego {
            state: VehicleState::at_rest(start.position, start.yaw),
            z: start.z,
            road_z: start.z,
            control: VehicleControl::BRAKE,
            lane: self
                .rules
                .lanes
                .lane_under(&self.town, start.position, start.yaw)
                .map(|lp| (lp.lane, lp.s)),
            kerbs: Vec::new(),
        });
        self.refresh_views();
    }

    /// Respawns an NPC as CARLA's Traffic Manager removes one (`removal`): the
    /// NPC that has stood longest, once it has stood 90 s (180 s while the light
    /// of its next stop line is red), at most one every 10 s; and any NPC pushed
    /// off its path.
    pub(super) fn respawn_stuck(&mut self, lights: &[LightState]) {
        let dt = self.cfg.tick_s;
        let since_last = self.stats.ticks.saturating_sub(self.last_removal_tick) as f32 * dt;
        if since_last > removal::BETWEEN_REMOVALS_S
            && let Some(i) =
                (0..self.npcs.len()).max_by_key(|&i| (self.npcs[i].idle_ticks, Reverse(i)))
        {
            let n = &self.npcs[i];
            let at_red = self
                .light_stop(n, lights)
                .is_some_and(|(_, _, l)| rules::light_state(lights, l) == LightState::Red);
            let idle_s = n.idle_ticks as f32 * dt;
            if let Some(cause) = removal::cause(idle_s, at_red) {
                self.last_removal_tick = self.stats.ticks;
                self.respawn(i, cause);
            }
        }
        for i in 0..self.npcs.len() {
            let n = &self.npcs[i];
            let (lp, _, _) = self.town.lane(n.path.lane()).pose_at(n.path.s_m);
            if (lp - n.state.position).length() > OFF_PATH_M {
                self.respawn(i, RespawnCause::OffPath);
            }
        }
    }

    /// Moves NPC `i` to a free spot on a random lane ([`Traffic::place_npc`]); it stays where it is if none is found.
    fn respawn(&mut self, i: usize, cause: RespawnCause) {
        let id = self.npcs[i].id;
        let mut rng = self.npcs[i].rng.clone();
        let spot = self.free_spot(&mut rng, 20, Some(id));
        self.npcs[i].rng = rng;
        if let Some((lane, s, ..)) = spot {
            self.note_npc(IncidentKind::Respawn(cause), id);
            self.place_npc(i, LanePath::new(lane, s));
            match cause {
                RespawnCause::Blocked => self.stats.respawns_blocked += 1,
                RespawnCause::BlockedAtRed => self.stats.respawns_blocked_at_red += 1,
                RespawnCause::OffPath => self.stats.respawns_off_path += 1,
            }
        }
    }
}
