//! The named rules that turn a run's touches ([`super::contacts`]) into
//! collisions. Each is one function over the recorded touches, so a record
//! can be counted again under any rule (docs/protocol.md §3, docs/rule-book.md).
//!
//! | rule | source | what counts |
//! | --- | --- | --- |
//! | `paper` | TimeParam `wor_common.py`, `LeaderboardLikeScorer.on_collision` | each other actor once per run; all map geometry, kerbs and sidewalks included, is one actor (CARLA's id 0); no speed gate, no sidewalk exclusion |
//! | `leaderboard-1.0` | scenario_runner branch `leaderboard-1.0`, `srunner/scenariomanager/scenarioatomics/atomic_criteria.py`, `CollisionTest` (lines 285-437) | sidewalk contacts dropped; a touch within 3 m of a remembered collision dropped, a location forgotten once the ego is 5 m from it; the last actor id blocked for 5 s, map geometry never blocked by id; no speed gate |
//!
//! Both decide a touch from the touches before it alone, so counting the
//! touches of a run so far gives the run's first collisions (the collision
//! monitor counts `paper` as the run goes).

use std::collections::BTreeSet;

use serde::{Deserialize, Serialize};

use super::InfractionKind;
use super::contacts::{Touch, TouchWith};

/// A rule that counts collisions from touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum CountingRule {
    /// The paper's own scorer (TimeParam).
    Paper,
    /// CARLA leaderboard 1.0's `CollisionTest`.
    Leaderboard1,
}

/// A touch within this distance of a remembered collision is not counted
/// (metres; `CollisionTest.MIN_AREA_OF_COLLISION`).
pub const LB1_MIN_AREA_M: f32 = 3.0;
/// How long the last actor hit stays blocked (seconds; `CollisionTest.MAX_ID_TIME`).
pub const LB1_ID_TIME_S: f64 = 5.0;

impl CountingRule {
    /// Every rule, the primary (`paper`) first.
    pub const ALL: [CountingRule; 2] = [CountingRule::Paper, CountingRule::Leaderboard1];

    /// The rule's name in records, tables and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            CountingRule::Paper => "paper",
            CountingRule::Leaderboard1 => "leaderboard-1.0",
        }
    }

    /// The rule of a name.
    pub fn from_name(name: &str) -> Option<CountingRule> {
        Self::ALL.into_iter().find(|r| r.name() == name)
    }

    /// The indices of the touches that count as collisions, in order.
    pub fn counted(self, touches: &[Touch]) -> Vec<usize> {
        match self {
            CountingRule::Paper => paper(touches),
            CountingRule::Leaderboard1 => leaderboard_1_0(touches),
        }
    }

    /// The collisions of `touches` by kind.
    pub fn count(self, touches: &[Touch]) -> CollisionCounts {
        let mut c = CollisionCounts::default();
        for i in self.counted(touches) {
            match collision_kind(&touches[i]) {
                InfractionKind::CollisionVehicle => c.vehicle += 1,
                InfractionKind::CollisionPedestrian => c.pedestrian += 1,
                _ => c.static_ += 1,
            }
        }
        c
    }
}

/// Collisions of one run by the other party's kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct CollisionCounts {
    /// With pedestrians.
    pub pedestrian: u32,
    /// With vehicles.
    pub vehicle: u32,
    /// With map geometry (buildings, poles, kerbs).
    #[serde(rename = "static")]
    pub static_: u32,
}

impl CollisionCounts {
    /// All three together.
    pub fn total(&self) -> u32 {
        self.pedestrian + self.vehicle + self.static_
    }
}

/// The infraction a counted touch is: a vehicle, a pedestrian, or anything else
/// (TimeParam: `walker.` -> pedestrian, `vehicle.` -> vehicle, else static).
pub fn collision_kind(t: &Touch) -> InfractionKind {
    match t.with {
        TouchWith::Vehicle => InfractionKind::CollisionVehicle,
        TouchWith::Pedestrian => InfractionKind::CollisionPedestrian,
        TouchWith::Map | TouchWith::Kerb => InfractionKind::CollisionStatic,
    }
}

/// The paper's scorer (TimeParam `wor_common.py`, `LeaderboardLikeScorer.on_collision`):
/// the key is the other actor's id, each key counts once per run, and CARLA
/// reports all map geometry (buildings, poles, sidewalks and their kerbs) as one
/// actor, id 0. Its 20-frame cooldown per key never matters: a key that counted
/// never counts again.
pub fn paper(touches: &[Touch]) -> Vec<usize> {
    let mut seen: BTreeSet<Option<u32>> = BTreeSet::new();
    let mut out = Vec::new();
    for (i, t) in touches.iter().enumerate() {
        // Map geometry and kerbs have no actor: they share the key `None`.
        if seen.insert(t.actor) {
            out.push(i);
        }
    }
    out
}

/// Leaderboard 1.0 (`CollisionTest._count_collisions` and `update`): a touch of
/// the last actor counted within [`LB1_ID_TIME_S`] is dropped (map geometry is
/// never blocked by id); a sidewalk (kerb) touch is dropped; a touch within
/// [`LB1_MIN_AREA_M`] of a remembered collision location is dropped; the others
/// count and their location is remembered until the ego is
/// [`super::contacts::FORGET_M`] from it.
pub fn leaderboard_1_0(touches: &[Touch]) -> Vec<usize> {
    let mut remembered: Vec<usize> = Vec::new();
    let mut last: Option<(u32, f64)> = None;
    let mut out = Vec::new();
    for (i, t) in touches.iter().enumerate() {
        // `update` ran on the ticks before: locations left, the id's time passed.
        remembered.retain(|&r| touches[r].left_tick.is_none_or(|left| left >= t.tick));
        if last.is_some_and(|(_, at)| t.time_s - at > LB1_ID_TIME_S) {
            last = None;
        }
        if t.actor.is_some() && last.map(|(id, _)| id) == t.actor {
            continue;
        }
        let near = |r: &usize| {
            let p = touches[*r].position;
            (p[0] - t.position[0]).hypot(p[1] - t.position[1]) <= LB1_MIN_AREA_M
        };
        if remembered.iter().any(near) {
            continue;
        }
        if t.with == TouchWith::Kerb {
            continue;
        }
        out.push(i);
        remembered.push(i);
        // The id is remembered with the time of the last collision counted.
        last = match t.actor {
            Some(id) => Some((id, t.time_s)),
            None => last.map(|(id, _)| (id, t.time_s)),
        };
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn touch(tick: u64, with: TouchWith, actor: Option<u32>, x: f32) -> Touch {
        Touch {
            tick,
            time_s: tick as f64 * 0.025,
            with,
            actor,
            what: String::new(),
            position: [x, 0.0],
            speed_mps: 3.0,
            repeat: false,
            kerb: None,
            left_tick: None,
        }
    }

    fn kinds(rule: CountingRule, touches: &[Touch]) -> CollisionCounts {
        rule.count(touches)
    }

    const STATIC_ONE: CollisionCounts = CollisionCounts {
        pedestrian: 0,
        vehicle: 0,
        static_: 1,
    };

    #[test]
    fn a_kerb_mount_is_a_static_collision_for_the_paper_and_none_for_leaderboard_1() {
        let mount = [touch(10, TouchWith::Kerb, None, 0.0)];
        assert_eq!(kinds(CountingRule::Paper, &mount), STATIC_ONE);
        assert_eq!(
            kinds(CountingRule::Leaderboard1, &mount),
            CollisionCounts::default()
        );
    }

    #[test]
    fn all_map_geometry_is_one_actor_for_the_paper() {
        // Two buildings 50 m apart, then a kerb, each left behind.
        let mut run = vec![
            touch(10, TouchWith::Map, None, 0.0),
            touch(400, TouchWith::Map, None, 50.0),
            touch(800, TouchWith::Kerb, None, 100.0),
        ];
        run[0].left_tick = Some(50);
        run[1].left_tick = Some(450);
        assert_eq!(kinds(CountingRule::Paper, &run), STATIC_ONE);
        // Leaderboard 1.0 counts both buildings (never blocked by id) and drops the kerb.
        assert_eq!(kinds(CountingRule::Leaderboard1, &run).static_, 2);
    }

    #[test]
    fn the_same_car_again_after_six_seconds_counts_for_leaderboard_1_only() {
        let mut run = vec![
            touch(40, TouchWith::Vehicle, Some(7), 0.0),
            touch(40 + 240, TouchWith::Vehicle, Some(7), 30.0),
        ];
        run[0].left_tick = Some(60);
        assert_eq!(kinds(CountingRule::Paper, &run).vehicle, 1);
        assert_eq!(kinds(CountingRule::Leaderboard1, &run).vehicle, 2);
        // Within 5 s the id is blocked; close to the first place, the area is.
        let soon = [
            run[0].clone(),
            touch(40 + 120, TouchWith::Vehicle, Some(7), 30.0),
        ];
        assert_eq!(kinds(CountingRule::Leaderboard1, &soon).vehicle, 1);
        let mut near = run.clone();
        near[0].left_tick = None;
        near[1].position = [2.0, 0.0];
        assert_eq!(kinds(CountingRule::Leaderboard1, &near).vehicle, 1);
    }

    #[test]
    fn leaderboard_1_drops_another_actor_hit_where_a_collision_was_remembered() {
        let run = [
            touch(40, TouchWith::Vehicle, Some(7), 0.0),
            touch(60, TouchWith::Pedestrian, Some(9), 1.0),
        ];
        assert_eq!(kinds(CountingRule::Leaderboard1, &run).total(), 1);
        assert_eq!(kinds(CountingRule::Paper, &run).total(), 2);
    }

    #[test]
    fn a_walker_into_a_standing_ego_counts_for_both() {
        let mut hit = touch(100, TouchWith::Pedestrian, Some(9), 0.0);
        hit.speed_mps = 0.0;
        for rule in CountingRule::ALL {
            assert_eq!(kinds(rule, std::slice::from_ref(&hit)).pedestrian, 1);
            assert_eq!(CountingRule::from_name(rule.name()), Some(rule));
        }
    }
}
