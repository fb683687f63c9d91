//! The counters of a traffic world: what the soak runs and the reports read.

use crate::agents::ActorKind;
use crate::physics::{ContactEvent, Party};

/// Counters the soak and the reports read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TrafficStats {
    /// Ticks stepped.
    pub ticks: u64,
    /// NPC respawns because stopped for 90 s (`super::removal`).
    pub respawns_blocked: u64,
    /// NPC respawns because stopped for 180 s at a red light (`super::removal`).
    pub respawns_blocked_at_red: u64,
    /// NPC respawns because more than [`super::OFF_PATH_M`] off their path.
    pub respawns_off_path: u64,
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
    /// Walkers sent across the road ahead of the ego (`crossings.rs`).
    pub walkers_sent: u64,
    /// Lane changes NPCs made for their next turn.
    pub lane_changes: u64,
    /// Lane changes NPCs planned but gave up (no gap before the lane ran out).
    pub lane_changes_given_up: u64,
    /// Cars of a circle of waits granted their lanes to let a gridlock move
    /// ([`crate::traffic::reservations::GRIDLOCK_AFTER_S`]).
    pub gridlocks_broken: u64,
}

impl TrafficStats {
    /// NPC respawns, whatever the cause.
    pub fn respawns(&self) -> u64 {
        self.respawns_blocked + self.respawns_blocked_at_red + self.respawns_off_path
    }

    /// Counts a contact that started this tick, by the kinds of its two
    /// parties (the first is the one that moved into the other).
    pub(super) fn count_contact(&mut self, ev: &ContactEvent) {
        let kind = |p: Party| match p {
            Party::Actor { kind, .. } => Some(kind),
            Party::Static(_) => None,
        };
        match (kind(ev.a), kind(ev.b)) {
            (Some(ActorKind::Vehicle), Some(ActorKind::Vehicle)) => self.npc_npc_collisions += 1,
            (Some(ActorKind::Vehicle), Some(ActorKind::Pedestrian)) => {
                self.npc_pedestrian_collisions += 1
            }
            (Some(ActorKind::Vehicle), None) => self.npc_static_collisions += 1,
            (Some(ActorKind::Pedestrian), Some(_)) => self.pedestrian_vehicle_bumps += 1,
            _ => {}
        }
    }
}
