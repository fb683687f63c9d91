//! Junction reservations: who holds which connecting lane, and how the
//! traffic world grants them.
//!
//! Connecting lanes of one junction conflict as [`crate::rules::conflicts`]
//! says. Before entering a junction an NPC requests its connecting lane;
//! requests are granted in order of waiting time (then id) when no other
//! vehicle holds a conflicting lane, no older request waits for a
//! conflicting lane, the NPC is the first of its lane, and the exit lane has
//! room for it ("don't block the box"). The reservation is released once the
//! vehicle has left the junction, or when it stops for a light before it.
//! The ego reserves nothing, but while it is on a connecting lane NPCs treat
//! that lane as held. Where the map gives another lane priority over the
//! requested one (a roundabout's ring over its entry), the request also
//! waits while a vehicle is about to enter that lane
//! ([`Traffic::must_give_way`], [`rules::must_give_way`]).
//!
//! Two refinements: where two junctions are closer than a car
//! (`npc::chained_link_m`), a car asks for the next junction's lane from
//! inside the first and while it still holds the first (`Npc::leaving`
//! until its rear is out); and the cars
//! standing at the entries of a double turn's two lanes
//! ([`rules::conflicts::side_by_side`]) enter together
//! (`Traffic::free_but_beside`).
//!
//! A circle of cars each waiting for the next (four cars round a full
//! roundabout, each with no room on the ring after its junction) would wait
//! forever: after [`GRIDLOCK_AFTER_S`] of standing, its cars that wait for
//! room are granted their lanes and the circle moves up together
//! (`break_gridlocks`).

use super::Traffic;
use crate::agents::VehicleParams;
use crate::agents::npc::{self, Npc};
use crate::map::{LaneIdx, LightIdx, LightState, Town};
use crate::rules::{self, JunctionConflicts};

/// Junction reservations: who holds which connecting lane.
#[derive(Debug, Clone, Default)]
pub struct Reservations {
    holders: Vec<Vec<u32>>,
}

impl Reservations {
    /// No reservations, for a town with `n_lanes` lanes.
    pub fn new(n_lanes: usize) -> Reservations {
        Reservations {
            holders: vec![Vec::new(); n_lanes],
        }
    }

    /// Whether `lane` can be granted to `id`: no other vehicle holds it or a conflicting lane.
    /// (Several vehicles may hold the same lane: they follow each other.)
    pub fn free_for(&self, conflicts: &JunctionConflicts, lane: LaneIdx, id: u32) -> bool {
        self.conflict_holders(conflicts, lane).all(|h| h == id)
    }

    /// Every holder of a lane that conflicts with `lane` (ids, repeated for
    /// each lane they hold).
    pub fn conflict_holders<'a>(
        &'a self,
        conflicts: &'a JunctionConflicts,
        lane: LaneIdx,
    ) -> impl Iterator<Item = u32> + 'a {
        conflicts
            .of(lane)
            .iter()
            .flat_map(|c| self.holders[c.0 as usize].iter().copied())
    }

    /// Records that `id` holds `lane`.
    pub fn grant(&mut self, lane: LaneIdx, id: u32) {
        let h = &mut self.holders[lane.0 as usize];
        if !h.contains(&id) {
            h.push(id);
        }
    }

    /// Drops `id`'s hold on `lane`.
    pub fn release(&mut self, lane: LaneIdx, id: u32) {
        self.holders[lane.0 as usize].retain(|&h| h != id);
    }

    /// Who holds a lane.
    pub fn holders(&self, lane: LaneIdx) -> &[u32] {
        &self.holders[lane.0 as usize]
    }
}

/// Where an actor is on the lane graph, for the box-blocking check: (lane, arc length of its rear).
pub type LaneOccupant = (LaneIdx, f32);

impl Traffic {
    /// Whether an NPC must stop for the light ahead: (must stop, distance from its front to the stop line).
    pub(super) fn light_stop(
        &self,
        n: &Npc,
        lights: &[LightState],
    ) -> Option<(bool, f32, LightIdx)> {
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

    /// Whether a vehicle other than `me` (the ego is 0) is on connecting lane
    /// `lane` or about to enter it ([`rules::approaching`]): an NPC whose
    /// next junction lane it is, the ego on a lane leading into it.
    pub fn about_to_enter(&self, lane: LaneIdx, me: u32) -> bool {
        let vp = &self.cfg.vehicle;
        let half = vp.length_m * 0.5;
        let npc = self.npcs.iter().filter(|n| n.id != me).any(|n| {
            n.path.lane() == lane
                || npc::next_junction_lane(&self.town, n, vp)
                    .is_some_and(|(l, d)| l == lane && rules::approaching(d, n.state.speed_mps))
        });
        let ego = me != 0
            && self.ego.as_ref().is_some_and(|e| {
                e.lane.is_some_and(|(l, s)| {
                    l == lane
                        || (self.town.lanes[lane.0 as usize].predecessors.contains(&l)
                            && rules::approaching(
                                self.town.lane(l).length_m() - s - half,
                                e.state.speed_mps,
                            ))
                })
            });
        npc || ego
    }

    /// Whether a vehicle `me` about to take connecting lane `lane` must give
    /// way to another on or about to enter a lane the map gives priority
    /// over it ([`rules::must_give_way`]).
    pub fn must_give_way(&self, lane: LaneIdx, me: u32) -> bool {
        rules::must_give_way(&self.rules.conflicts, lane, |high| {
            self.about_to_enter(high, me)
        })
    }

    /// Whether the ego, about to take connecting lane `lane` at a junction
    /// without lights, must wait: another vehicle holds a lane that
    /// conflicts with it (the ego holds nothing, so any holder is another),
    /// or it must give way ([`Traffic::must_give_way`]). What the runner
    /// hands the expert ([`crate::rules::junction_yield`]'s `held`).
    pub fn ego_must_wait_for(&self, lane: LaneIdx) -> bool {
        !self
            .reservations
            .free_for(&self.rules.conflicts, lane, u32::MAX)
            || self.must_give_way(lane, 0)
    }

    /// The connecting lanes NPCs treat as the ego's while they grant theirs:
    /// the one it is on, or, while it moves (at least `removal::STOPPED_MPS`)
    /// toward a junction as near as an NPC that asks for its lane (within its
    /// comfortable stopping distance and 10 m, along its lane and the lanes
    /// that lane runs on into: a road in several sections) and no light
    /// stops it, every connecting lane its road leads into, since it may take
    /// any of them. CARLA's Traffic Manager sees the hero vehicle coming the
    /// same way, by its motion; before 2026-12-06 an NPC was let into a
    /// roundabout's entry while the ego came round the ring 4 m off, too close
    /// to stop (Town03, route 4).
    pub(super) fn ego_held_lanes(&self, lights: &[LightState]) -> Vec<LaneIdx> {
        let Some((e, (lane, s))) = self.ego.as_ref().and_then(|e| Some((e, e.lane?))) else {
            return Vec::new();
        };
        if self.town.lane(lane).junction.is_some() {
            return vec![lane];
        }
        let v = e.state.speed_mps;
        if v < super::removal::STOPPED_MPS {
            return Vec::new();
        }
        let comfort = self.cfg.npc.comfort_decel_mps2;
        let near_m = v * v / (2.0 * comfort) + 10.0;
        // Along its road to the junction: the lane whose end it is, and the
        // distance from the front bumper to that end (metres).
        let mut at = lane;
        let mut end = self.town.lane(lane).length_m() - s - self.cfg.vehicle.length_m * 0.5;
        let into = loop {
            let l = self.town.lane(at);
            if end - l.length_m() > near_m {
                return Vec::new();
            }
            // A light it must stop for holds it, not the junction.
            let stops = self.rules.stop_lines.on_lane(at).any(|line| {
                let d = end - l.length_m() + line.s;
                d > -0.3 && rules::must_stop(rules::light_state(lights, line.light), d, v, comfort)
            });
            if stops {
                return Vec::new();
            }
            let into: Vec<LaneIdx> = l
                .successors
                .iter()
                .copied()
                .filter(|s| self.town.lane(*s).junction.is_some())
                .collect();
            match l.successors[..] {
                _ if !into.is_empty() => break into,
                [next] => {
                    at = next;
                    end += self.town.lane(next).length_m();
                }
                _ => return Vec::new(),
            }
        };
        if end < near_m { into } else { Vec::new() }
    }

    /// Where each vehicle's rear is on the lane graph (for the box check).
    fn occupants(&self) -> Vec<LaneOccupant> {
        let half = self.cfg.vehicle.length_m * 0.5;
        let mut occ: Vec<LaneOccupant> = self
            .npcs
            .iter()
            .map(|n| (n.path.lane(), n.path.s_m - half))
            .collect();
        if let Some((l, s)) = self.ego.as_ref().and_then(|e| e.lane) {
            occ.push((l, s - half));
        }
        occ
    }

    pub(super) fn update_reservations(&mut self, lights: &[LightState]) {
        let tick = self.stats.ticks;
        let vp = self.cfg.vehicle;
        // Release: left the junction, or now stopping for a light before it.
        for i in 0..self.npcs.len() {
            let n = &self.npcs[i];
            let id = n.id;
            if let Some(res) = n.leaving
                && self.gives_back(n, res, lights)
            {
                self.reservations.release(res, id);
                self.npcs[i].leaving = None;
            }
            let n = &self.npcs[i];
            if let Some(res) = n.reservation
                && self.gives_back(n, res, lights)
            {
                self.reservations.release(res, id);
                self.npcs[i].reservation = None;
            }
        }
        // Requests.
        let occ = self.occupants();
        let mut requests: Vec<(u64, u32, usize, LaneIdx)> = Vec::new();
        for (i, n) in self.npcs.iter_mut().enumerate() {
            // Inside a junction chained to the next (`npc::chained_link_m`), the
            // next junction's lane is asked for from there.
            let inside = self.town.lanes[n.path.lane().0 as usize].junction.is_some();
            let Some((lane, d)) = npc::next_junction_lane(&self.town, n, &vp)
                .or_else(|| npc::chained_junction_lane(&self.town, &self.rules.conflicts, n, &vp))
            else {
                n.request = None;
                continue;
            };
            // One reservation at a time: the next is asked for once the last is
            // given back; but where the road between the two junctions is too
            // short for a car waiting at the second to have left the first
            // (`chained_junctions`), it asks while it holds the last, which it
            // keeps as `leaving`.
            if let Some(res) = n.reservation {
                let chained = n.leaving.is_none()
                    && lane != res
                    && (inside
                        || chained_junctions(
                            &self.town,
                            &self.rules.conflicts,
                            &vp,
                            n,
                            res,
                            lane,
                            d,
                        ));
                if !chained {
                    n.request = None;
                    continue;
                }
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
        // Requests refused for want of room on the exit: (NPC, lane).
        let mut room_waits: Vec<(usize, LaneIdx)> = Vec::new();
        // Requests refused while another NPC holds a conflicting lane: (NPC, that NPC).
        let mut held_by: Vec<(usize, usize)> = Vec::new();
        let mut waiting: Vec<LaneIdx> = Vec::new();
        // The ego reserves nothing, but NPCs treat as held the connecting lane
        // it is on and those it is about to enter (`ego_held_lanes`).
        let ego_lanes = self.ego_held_lanes(lights);
        for &l in &ego_lanes {
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
            // Giving way (the map gives a conflicting lane priority and a vehicle
            // is about to take it): wait, without holding up the one it gives way to.
            if self.must_give_way(lane, id) {
                continue;
            }
            let free = self.reservations.free_for(&self.rules.conflicts, lane, id)
                || self.free_but_beside(lane, id, d_entry);
            if queued_behind || !free {
                waiting.push(lane);
                if let Some(h) = self.conflicting_holder(lane, id) {
                    held_by.push((i, h));
                }
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
            // Don't block the box: the exit lane (the first out of the junction
            // after the lanes of this movement) needs room for this car.
            let exit = rules::conflicts::movement_exit(&self.town, lane);
            let junction = self.town.lanes[lane.0 as usize].junction;
            let exit_on_path = n
                .path
                .lanes
                .iter()
                .skip_while(|&&l| l != lane)
                .skip(1)
                .find(|l| self.town.lanes[l.0 as usize].junction != junction)
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
                room_waits.push((i, lane));
                continue;
            }
            self.reservations.grant(lane, id);
            self.npcs[i].take_grant(lane);
        }
        self.break_gridlocks(&occ, &room_waits, &held_by);
        for &l in &ego_lanes {
            self.reservations.release(l, 0);
        }
    }
}

/// How long every car of a circle of waits must have stood before the
/// circle is let move (seconds).
pub const GRIDLOCK_AFTER_S: f32 = 5.0;

/// How far along its path a standing car looks for the car it waits behind (metres).
const WAIT_BEHIND_M: f32 = 30.0;

/// How far (front bumper, metres) a car may have driven into its lane for a
/// car beside it to enter the neighbouring lane with it
/// (`Traffic::free_but_beside`): two cars that move off a stop line together.
const ENTER_TOGETHER_M: f32 = 2.0;

/// Whether NPC `n`, on the exit of junction lane `res` and `d_m` (front
/// bumper, metres) before the entry of the next junction's lane `next`,
/// would stand waiting for `next` with its rear still less than the release
/// distance (1 m) out of `res`'s junction: the road between them is shorter
/// than a car length, that metre, the place it waits back from the entry
/// (`JunctionConflicts::hold_back_m`) and the slack of its stop
/// ([`npc::AT_ENTRY_M`]). Town03's road 14 (6.4 m between junctions 685 and 678).
fn chained_junctions(
    town: &Town,
    conflicts: &JunctionConflicts,
    vp: &VehicleParams,
    n: &Npc,
    res: LaneIdx,
    next: LaneIdx,
    d_m: f32,
) -> bool {
    let on_exit = n.path.lane() == rules::conflicts::movement_exit(town, res);
    let link_m = n.path.s_m + vp.length_m * 0.5 + d_m;
    on_exit && link_m < npc::chained_link_m(conflicts, vp, next)
}

impl Npc {
    /// Takes a granted junction lane; one still held (the car stands at this
    /// junction's entry with its rear in the last) is kept as `leaving`.
    fn take_grant(&mut self, lane: LaneIdx) {
        if let Some(last) = self.reservation.replace(lane) {
            self.leaving = Some(last);
        }
        self.request = None;
    }
}

impl Traffic {
    /// Whether NPC `n` gives back its hold on junction lane `res`: it has
    /// left the junction, is lost (neither in its movement, nor before it, nor
    /// on its exit), or now stops for a light before it.
    fn gives_back(&self, n: &Npc, res: LaneIdx, lights: &[LightState]) -> bool {
        let vp = self.cfg.vehicle;
        let half = vp.length_m * 0.5;
        // In its movement (the reserved lane and the lanes of its junction after
        // it: `rules::conflicts::movement`), or it is the next junction lane on
        // the path (a path round a roundabout may come back to the same lane
        // later: that is not this one).
        let now = n.path.lane();
        let in_junction = self.town.lanes[now.0 as usize].junction.is_some();
        let inside = in_junction && self.rules.conflicts.in_movement(res, now);
        // (From inside a junction: the next junction's lane on the path, one
        // asked for where the two are chained, `npc::chained_junction_lane`.)
        let junction_now = self.town.lanes[now.0 as usize].junction;
        let ahead = n
            .path
            .lanes
            .iter()
            .skip_while(|l| in_junction && self.town.lanes[l.0 as usize].junction == junction_now)
            .find(|l| self.town.lanes[l.0 as usize].junction.is_some())
            == Some(&res);
        let inside_or_ahead = inside || ahead;
        // Left: the rear a metre past the junction; or, on a road too short for
        // that (Town03's road 14, 6.4 m between junctions 685 and 678), the rear
        // past it and the front at the next junction's entry, where the car waits
        // for a reservation it may ask for only once this one is given back.
        let at_next_entry = || {
            npc::next_junction_lane(&self.town, n, &vp)
                .is_some_and(|(l, d)| l != res && d < npc::AT_ENTRY_M)
        };
        let left =
            !inside_or_ahead && (n.path.s_m > half + 1.0 || (n.path.s_m > half && at_next_entry()));
        let lost =
            !inside_or_ahead && !left && now != rules::conflicts::movement_exit(&self.town, res);
        let entry = npc::next_junction_lane(&self.town, n, &vp)
            .filter(|(l, _)| *l == res)
            .map(|(_, d)| d);
        let stop_for_light = ahead
            && entry.is_some_and(|d_entry| {
                self.light_stop(n, lights)
                    .is_some_and(|(stop, d, _)| stop && d > -0.3 && d <= d_entry + 0.1)
            });
        left || lost || stop_for_light
    }

    /// Whether `lane` is free for NPC `id`, standing `d_m` (front bumper,
    /// metres) before its entry, but for cars entering a lane beside it
    /// ([`rules::conflicts::side_by_side`]) at the same time: every other
    /// holder of a lane conflicting with `lane` holds such a lane and has
    /// driven at most [`ENTER_TOGETHER_M`] into it, this car's front is at
    /// most that far behind the other's, and this car stands at its own entry. The two lanes of a double turn then go together on a
    /// green, as in CARLA, while a car is still kept from entering half a turn
    /// behind the car beside, where their bodies would meet.
    fn free_but_beside(&self, lane: LaneIdx, id: u32, d_m: f32) -> bool {
        if d_m > npc::AT_ENTRY_M + self.rules.conflicts.hold_back_m(lane) {
            return false;
        }
        let half = self.cfg.vehicle.length_m * 0.5;
        let mut beside = false;
        let all_beside = self.rules.conflicts.of(lane).iter().all(|&c| {
            self.reservations.holders(c).iter().all(|&h| {
                if h == id {
                    return true;
                }
                let Some(n) = (h as usize).checked_sub(1).and_then(|k| self.npcs.get(k)) else {
                    return false; // the ego (0) holds it
                };
                // How far its front is into its lane (negative: before the entry).
                let now = n.path.lane();
                let into_m = if now == c {
                    n.path.s_m + half
                } else if self.town.lanes[now.0 as usize].junction.is_none() {
                    npc::next_junction_lane(&self.town, n, &self.cfg.vehicle)
                        .filter(|&(l, _)| l == c)
                        .map_or(0.0, |(_, d)| -d)
                } else {
                    f32::INFINITY
                };
                // Beside it, not a part of the turn behind: this car's front at
                // most `ENTER_TOGETHER_M` behind the other's (Town03's junction
                // 545, where an inner car 5 m behind the outer one swung into it).
                let ok = into_m <= ENTER_TOGETHER_M
                    && d_m + into_m <= ENTER_TOGETHER_M
                    && rules::conflicts::side_by_side(&self.town, lane, c);
                beside |= ok;
                ok
            })
        });
        all_beside && beside
    }

    /// The NPC (index) holding a lane that conflicts with `lane`, other than `id`.
    fn conflicting_holder(&self, lane: LaneIdx, id: u32) -> Option<usize> {
        self.reservations
            .conflict_holders(&self.rules.conflicts, lane)
            .filter(|&h| h != id && h != 0)
            .map(|h| h as usize - 1)
            .min()
    }

    /// The car (index in `occ`) NPC `i` stands behind: the first whose rear
    /// is ahead of its own along its path, within [`WAIT_BEHIND_M`].
    fn car_ahead_on_path(&self, occ: &[LaneOccupant], i: usize) -> Option<usize> {
        let path = &self.npcs[i].path;
        let (_, my_rear) = occ[i];
        let mut offset = -my_rear;
        for (step, &lane) in path.lanes.iter().enumerate() {
            let floor = if step == 0 {
                my_rear
            } else {
                f32::NEG_INFINITY
            };
            let ahead = occ
                .iter()
                .enumerate()
                .filter(|&(k, &(l, r))| k != i && l == lane && r > floor)
                .min_by(|a, b| a.1.1.total_cmp(&b.1.1).then(a.0.cmp(&b.0)));
            if let Some((k, _)) = ahead {
                return Some(k);
            }
            offset += self.town.lane(lane).length_m();
            if offset > WAIT_BEHIND_M {
                break;
            }
        }
        None
    }

    /// Lets a gridlock move. A standing NPC waits for the NPC holding a
    /// junction lane that conflicts with the one it asks for (`held_by`),
    /// else for the car ahead of it along its path. A circle of such waits,
    /// every car of it standing for [`GRIDLOCK_AFTER_S`], waits for itself
    /// forever (four cars round a full roundabout, full streets round a
    /// block, each front car with no room on its exit). Its cars refused for
    /// want of room (`room_waits`) are granted their lanes where nothing
    /// conflicting is held, so the circle moves up together, each car
    /// following the one ahead.
    fn break_gridlocks(
        &mut self,
        occ: &[LaneOccupant],
        room_waits: &[(usize, LaneIdx)],
        held_by: &[(usize, usize)],
    ) {
        if room_waits.is_empty() {
            return;
        }
        let n = self.npcs.len();
        let long = (GRIDLOCK_AFTER_S / self.cfg.tick_s).round() as u32;
        let standing = |i: usize| i < n && self.npcs[i].stopped_ticks >= long;
        if !room_waits.iter().any(|&(i, _)| standing(i)) {
            return;
        }
        let mut waits_for: Vec<Option<usize>> = vec![None; n];
        for (i, w) in waits_for.iter_mut().enumerate() {
            if standing(i) {
                *w = held_by
                    .iter()
                    .find(|&&(k, _)| k == i)
                    .map(|&(_, h)| h)
                    .or_else(|| self.car_ahead_on_path(occ, i));
            }
        }
        // Circles of the wait graph (at most one wait per car), in NPC order.
        let mut state = vec![0u8; n]; // 0 unseen, 1 on this walk, 2 done
        let mut in_circle = vec![false; n];
        for start in 0..n {
            let mut walk = Vec::new();
            let mut at = Some(start);
            while let Some(i) = at {
                if i >= n || state[i] == 2 {
                    break;
                }
                if state[i] == 1 {
                    let from = walk.iter().position(|&w| w == i).expect("on the walk");
                    for &w in &walk[from..] {
                        in_circle[w] = true;
                    }
                    break;
                }
                state[i] = 1;
                walk.push(i);
                at = waits_for[i];
            }
            for w in walk {
                state[w] = 2;
            }
        }
        for &(i, lane) in room_waits {
            let id = self.npcs[i].id;
            if in_circle[i] && self.reservations.free_for(&self.rules.conflicts, lane, id) {
                self.reservations.grant(lane, id);
                self.npcs[i].take_grant(lane);
                self.stats.gridlocks_broken += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown::grid;

    #[test]
    fn reservations_block_conflicts_only() {
        let t = grid(3, 3, 60.0);
        let conflicts = JunctionConflicts::new(&t);
        let mut r = Reservations::new(t.lanes.len());
        let a = (0..t.lanes.len())
            .map(|i| LaneIdx(i as u32))
            .find(|&l| !conflicts.of(l).is_empty())
            .unwrap();
        let b = conflicts.of(a)[0];
        r.grant(a, 1);
        assert!(!r.free_for(&conflicts, b, 2));
        assert!(r.free_for(&conflicts, a, 2));
        r.release(a, 1);
        assert!(r.free_for(&conflicts, b, 2));
    }
}
