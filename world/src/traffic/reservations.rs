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
//! that lane as held.

use super::Traffic;
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
        conflicts
            .of(lane)
            .iter()
            .all(|c| self.holders[c.0 as usize].iter().all(|&h| h == id))
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
    fn light_stop(&self, n: &Npc, lights: &[LightState]) -> Option<(bool, f32, LightIdx)> {
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
