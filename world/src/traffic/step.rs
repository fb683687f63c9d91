//! One tick of the traffic world: decide, move through the physics, keep
//! the books.
//!
//! Everyone decides from the start-of-tick state; junction reservations are
//! granted ([`super::reservations`]); the ego, then the NPCs (by id), then
//! the pedestrians (by id) are moved through the physics; NPC paths advance;
//! stuck NPCs are respawned (`spawn.rs`); contact events are counted
//! ([`super::TrafficStats`]).

use super::Traffic;
use super::incidents::IncidentKind;
use super::removal;
use super::views::npc_view;
use crate::agents::{kerb, npc};
use crate::map::LightState;
use crate::physics::ContactEvent;
use crate::rules;
use crate::rules::ActorView;

/// An NPC stopped this long counts as a deadlock (seconds).
const DEADLOCK_S: f32 = 60.0;
/// A walker held up by a vehicle this long turns back (seconds).
const WALKER_PATIENCE_S: f32 = 0.5;

impl Traffic {
    /// Makes the lane changes NPCs planned ([`npc::PlannedChange`]) where
    /// the target lane has room ([`rules::lane_change_clear`], the rule the
    /// expert changes lanes by), and gives up those that ran out of road.
    /// Decided from the start-of-tick views, NPCs in id order.
    fn change_lanes(&mut self) {
        let half = self.cfg.vehicle.length_m * 0.5;
        let decel = self.cfg.npc.comfort_decel_mps2;
        for i in 0..self.npcs.len() {
            let n = &self.npcs[i];
            let Some(c) = n.change else { continue };
            if n.path.lane() != c.from {
                if !n.path.lanes.contains(&c.from) {
                    self.npcs[i].change = None; // not on its way there any more
                }
                continue;
            }
            let v = n.state.speed_mps;
            let left = self.town.lane(c.from).length_m() - n.path.s_m - half;
            // Room beside is looked for among the cars on the target lane and among
            // those already changing into it, each counted where its path puts it
            // on the lane (its body is not "on" the lane until half-way over: two
            // cars changing into one middle lane from either side at one tick met
            // there, Town06's road 39).
            let target = self.town.lane(c.to);
            let clear_of_changers = self.npcs.iter().filter(|o| o.path.lane() == c.to).all(|o| {
                let (position, yaw, _) = target.pose_at(o.path.s_m);
                let placed = ActorView {
                    position,
                    yaw,
                    ..npc_view(o, &self.cfg.vehicle)
                };
                rules::lane_change_clear(
                    &self.town,
                    c.to,
                    n.state.position,
                    half,
                    n.id,
                    std::slice::from_ref(&placed),
                )
            });
            let n = &mut self.npcs[i];
            // A lane that leads nowhere has no way on to give the change up for.
            let optional = !npc::leads_nowhere(&self.town, c.from);
            if optional && left < v * v / (2.0 * decel) + npc::CHANGE_GIVE_UP_M {
                n.change = None;
                npc::extend_path(&self.town, &mut n.path, &mut n.rng, 80.0);
                self.stats.lane_changes_given_up += 1;
                continue;
            }
            // Wholly on the lane (out of the junction behind), and room beside.
            if n.path.s_m < 2.0 * half
                || !clear_of_changers
                || !rules::lane_change_clear(
                    &self.town,
                    c.to,
                    n.state.position,
                    half,
                    n.id,
                    &self.views,
                )
            {
                continue;
            }
            let s = target
                .project_near(n.state.position, n.path.s_m, 5.0)
                .unwrap_or(n.path.s_m)
                .min(target.length_m());
            n.path = crate::road::LanePath::new(c.to, s);
            n.path.lanes.push_back(c.then);
            n.change = None;
            npc::extend_path_planning(&self.town, &mut n.path, &mut n.rng, 80.0, &mut n.change);
            self.stats.lane_changes += 1;
        }
    }

    /// Advances the world one tick of [`TrafficConfig::tick_s`]; `lights` are the light states by `LightIdx` (a light beyond the slice's end counts as green). Returns the tick's contacts.
    pub fn step(&mut self, lights: &[LightState]) -> &[ContactEvent] {
        let vp = self.cfg.vehicle;
        let dt = self.cfg.tick_s;
        if self.maybe_send_walker() {
            self.refresh_views();
        }
        self.change_lanes();
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
        let mut deadlocked: Vec<u32> = Vec::new();
        let mut ran_red: Vec<u32> = Vec::new();
        for p in &mut self.pedestrians {
            ped_targets.push(p.decide(&self.walk, &self.cfg.pedestrian, &self.views, dt));
        }
        // Move: ego, NPCs, pedestrians. A vehicle's wheels climb the kerbs it meets.
        let sidewalks = &self.rules.sidewalks;
        if let Some(e) = &mut self.ego {
            let mut s = e.state;
            let before = (s.position, s.yaw);
            s.step(&vp, e.control, dt);
            let out = self.physics.move_actor(0, s.position, s.yaw);
            s.position = out.position;
            s.yaw = out.yaw;
            if out.hit.is_some() {
                s.speed_mps *= out.fraction;
            }
            e.kerbs = kerb::cross_kerbs(&mut s, &vp, before, sidewalks);
            // The road under it is its lane's, bridges included (Town03, Town04), as
            // for the NPCs; flat towns (every lane at 0 m) are unchanged.
            if let Some((lane, s_m)) = e.lane {
                e.road_z = self.town.lane(lane).pose_at(s_m).2;
                self.physics.set_ground_z(0, e.road_z);
            }
            e.z = e.road_z + kerb::ride_height_m(sidewalks, s.position);
            e.state = s;
        }
        for (n, d) in self.npcs.iter_mut().zip(&decisions) {
            let stop_before = npc::next_stop_line(&self.town, &self.rules, n, &vp, 20.0);
            n.control = d.control;
            let mut s = n.state;
            let before = (s.position, s.yaw);
            s.step(&vp, d.control, dt);
            let out = self.physics.move_actor(n.id, s.position, s.yaw);
            s.position = out.position;
            s.yaw = out.yaw;
            if out.hit.is_some() {
                s.speed_mps *= out.fraction;
            }
            kerb::cross_kerbs(&mut s, &vp, before, sidewalks);
            n.state = s;
            let travelled = n.path.advance_to(&self.town, s.position);
            // The ground under it is its lane's, bridges included (Town03, Town04).
            let (_, _, z) = self.town.lane(n.path.lane()).pose_at(n.path.s_m);
            n.ground_z = z;
            self.physics.set_ground_z(n.id, z);
            if let Some((dist, light)) = stop_before
                && dist >= 0.0
                && travelled > dist
                && lights.get(light.0 as usize) == Some(&LightState::Red)
            {
                self.stats.npc_red_runs += 1;
                ran_red.push(n.id);
            }
            npc::extend_path_planning(&self.town, &mut n.path, &mut n.rng, 80.0, &mut n.change);
            // Stuck / stopped bookkeeping.
            if s.speed_mps < 0.1 {
                n.stopped_ticks += 1;
                if n.stopped_ticks == (DEADLOCK_S / dt) as u32 + 1 {
                    self.stats.deadlocks += 1;
                    deadlocked.push(n.id);
                }
            } else {
                n.stopped_ticks = 0;
            }
            if s.speed_mps < removal::STOPPED_MPS {
                n.idle_ticks += 1;
            } else {
                n.idle_ticks = 0;
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
        for id in deadlocked {
            self.note_npc(IncidentKind::Deadlock, id);
        }
        for id in ran_red {
            self.note_npc(IncidentKind::RedRun, id);
        }
        self.respawn_stuck(lights);
        if let Some(e) = &mut self.ego {
            e.lane = self
                .rules
                .lanes
                .lane_under(&self.town, e.state.position, e.state.yaw)
                .map(|lp| (lp.lane, lp.s));
        }
        self.events.clear();
        self.events.extend_from_slice(self.physics.end_tick());
        for k in 0..self.events.len() {
            let ev = self.events[k];
            if ev.started {
                self.stats.count_contact(&ev);
                self.note_contact(&ev);
            }
        }
        self.stats.ticks += 1;
        self.refresh_views();
        &self.events
    }
}
