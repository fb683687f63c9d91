//! The incidents a traffic world counts, listed: each contact an NPC starts,
//! each deadlock, each respawn, with where and how fast the actors were.
//!
//! [`TrafficStats`](super::TrafficStats) counts; this keeps the first
//! [`INCIDENTS_PER_KIND`] of each kind so that a soak run can say what
//! happened (`mrdrive traffic soak --incidents`). The list is bounded: a long
//! run's memory stays flat.

use std::fmt;

use glam::Vec2;

use super::Traffic;
use crate::agents::ActorKind;
use crate::map::LaneIdx;
use crate::physics::{ContactEvent, DT_S, Party, StaticKind};

/// How many incidents of each kind are kept (the first ones).
pub const INCIDENTS_PER_KIND: usize = 50;

/// What happened.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum IncidentKind {
    /// An NPC vehicle drove into another NPC vehicle.
    NpcNpc,
    /// An NPC vehicle drove into the ego.
    NpcEgo,
    /// An NPC vehicle drove into a pedestrian.
    NpcPedestrian,
    /// An NPC vehicle touched a static collider (a building, a pole, a tree).
    NpcStatic(StaticKind),
    /// An NPC had stood still for 60 s.
    Deadlock,
    /// An NPC drove over the stop line of a light that was red.
    RedRun,
    /// An NPC was respawned, for this reason.
    Respawn(RespawnCause),
}

/// Why an NPC was respawned.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RespawnCause {
    /// Stood (below 0.8 m/s) for 90 s, its light not red (`super::removal`).
    Blocked,
    /// Stood for 180 s, its light red (`super::removal`).
    BlockedAtRed,
    /// More than [`super::OFF_PATH_M`] from the point of its lane it follows.
    OffPath,
}

impl RespawnCause {
    /// A few words for the incident list.
    pub fn name(self) -> &'static str {
        match self {
            RespawnCause::Blocked => "stopped 90 s",
            RespawnCause::BlockedAtRed => "stopped 180 s at a red light",
            RespawnCause::OffPath => "off its path",
        }
    }
}

impl IncidentKind {
    /// A short name ("NPC-NPC", "NPC-static (tree)", "deadlock", ...).
    pub fn name(self) -> String {
        match self {
            IncidentKind::NpcNpc => "NPC-NPC".into(),
            IncidentKind::NpcEgo => "NPC-ego".into(),
            IncidentKind::NpcPedestrian => "NPC-pedestrian".into(),
            IncidentKind::NpcStatic(k) => format!("NPC-static ({})", k.name()),
            IncidentKind::Deadlock => "deadlock".into(),
            IncidentKind::RedRun => "red light run".into(),
            IncidentKind::Respawn(c) => format!("respawn ({})", c.name()),
        }
    }

    fn same_class(self, other: IncidentKind) -> bool {
        std::mem::discriminant(&self) == std::mem::discriminant(&other)
    }
}

/// Where an actor was on the lane graph.
#[derive(Debug, Clone, PartialEq)]
pub struct IncidentLane {
    /// The lane.
    pub lane: LaneIdx,
    /// Its OpenDRIVE road id.
    pub road_id: String,
    /// Its OpenDRIVE lane id.
    pub od_lane: i32,
    /// Arc length along it (metres).
    pub s_m: f32,
    /// The OpenDRIVE id of the junction the lane runs through, if any.
    pub junction: Option<String>,
}

/// One actor of an incident, as it was at the end of the tick.
#[derive(Debug, Clone, PartialEq)]
pub struct IncidentActor {
    /// Its id (the ego is 0).
    pub id: u32,
    /// Ego, vehicle or pedestrian.
    pub kind: ActorKind,
    /// Centre of its footprint (metres).
    pub position: Vec2,
    /// Heading (radians).
    pub yaw: f32,
    /// Speed (metres per second).
    pub speed_mps: f32,
    /// The lane it was on (a vehicle's), if any.
    pub lane: Option<IncidentLane>,
    /// The connecting lane it held (an NPC's junction reservation), if any.
    pub reservation: Option<LaneIdx>,
    /// The connecting lane it was asking for (an NPC's junction request) and since
    /// how long (seconds), if any.
    pub asking: Option<(LaneIdx, f32)>,
}

/// One incident.
#[derive(Debug, Clone, PartialEq)]
pub struct Incident {
    /// The tick it happened in (counted from 0).
    pub tick: u64,
    /// Simulated time at the end of that tick (seconds).
    pub time_s: f64,
    /// What happened.
    pub kind: IncidentKind,
    /// The NPC concerned (the one that moved into the other, for a contact).
    pub a: IncidentActor,
    /// The other actor of a contact, if it was one.
    pub b: Option<IncidentActor>,
}

impl fmt::Display for IncidentActor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let kind = match self.kind {
            ActorKind::Ego => "ego",
            ActorKind::Vehicle => "NPC",
            ActorKind::Pedestrian => "walker",
        };
        write!(
            f,
            "{kind} {} at ({:.1}, {:.1}) heading {:.0} deg, {:.1} m/s",
            self.id,
            self.position.x,
            self.position.y,
            self.yaw.to_degrees(),
            self.speed_mps
        )?;
        if let Some(l) = &self.lane {
            write!(
                f,
                ", road {} lane {} s {:.1} m",
                l.road_id, l.od_lane, l.s_m
            )?;
            if let Some(j) = &l.junction {
                write!(f, " (junction {j})")?;
            }
        }
        if let Some(r) = self.reservation {
            write!(f, ", holding lane #{}", r.0)?;
        }
        if let Some((l, s)) = self.asking {
            write!(f, ", asking for lane #{} for {s:.1} s", l.0)?;
        }
        Ok(())
    }
}

impl fmt::Display for Incident {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "tick {} ({:.2} s) {}: {}",
            self.tick,
            self.time_s,
            self.kind.name(),
            self.a
        )?;
        if let Some(b) = &self.b {
            write!(f, " -> {b}")?;
        }
        Ok(())
    }
}

impl Traffic {
    /// The first [`INCIDENTS_PER_KIND`] incidents of each kind so far, in the order they happened.
    pub fn incidents(&self) -> &[Incident] {
        &self.incidents
    }

    /// An actor as an incident names it (None for an id not in the world).
    fn incident_actor(&self, id: u32) -> Option<IncidentActor> {
        let lane_of = |lane: LaneIdx, s_m: f32| {
            let l = self.town.lane(lane);
            IncidentLane {
                lane,
                road_id: l.road_id.clone(),
                od_lane: l.od_lane,
                s_m,
                junction: l
                    .junction
                    .and_then(|j| self.town.junctions.get(j.0 as usize))
                    .map(|j| j.od_id.clone()),
            }
        };
        if id == 0 {
            let e = self.ego.as_ref()?;
            return Some(IncidentActor {
                id,
                kind: ActorKind::Ego,
                position: e.state.position,
                yaw: e.state.yaw,
                speed_mps: e.state.speed_mps,
                lane: e.lane.map(|(l, s)| lane_of(l, s)),
                reservation: None,
                asking: None,
            });
        }
        if let Some(n) = self.npcs.iter().find(|n| n.id == id) {
            return Some(IncidentActor {
                id,
                kind: ActorKind::Vehicle,
                position: n.state.position,
                yaw: n.state.yaw,
                speed_mps: n.state.speed_mps,
                lane: Some(lane_of(n.path.lane(), n.path.s_m)),
                reservation: n.reservation,
                asking: n
                    .request
                    .map(|(l, since)| (l, (self.stats.ticks - since) as f32 * DT_S)),
            });
        }
        let p = self.pedestrians.iter().find(|p| p.id == id)?;
        Some(IncidentActor {
            id,
            kind: ActorKind::Pedestrian,
            position: p.position,
            yaw: p.yaw,
            speed_mps: p.current_speed_mps,
            lane: None,
            reservation: None,
            asking: None,
        })
    }

    /// Lists an incident if fewer than [`INCIDENTS_PER_KIND`] of its kind are listed.
    fn note_incident(&mut self, kind: IncidentKind, a: u32, b: Option<u32>) {
        let listed = self
            .incidents
            .iter()
            .filter(|i| i.kind.same_class(kind))
            .count();
        if listed >= INCIDENTS_PER_KIND {
            return;
        }
        let Some(actor_a) = self.incident_actor(a) else {
            return;
        };
        let tick = self.stats.ticks;
        self.incidents.push(Incident {
            tick,
            time_s: (tick + 1) as f64 * f64::from(self.cfg.tick_s),
            kind,
            a: actor_a,
            b: b.and_then(|id| self.incident_actor(id)),
        });
    }

    /// Lists a contact event that an NPC vehicle started (others are not incidents).
    pub(super) fn note_contact(&mut self, ev: &ContactEvent) {
        let Party::Actor {
            id,
            kind: ActorKind::Vehicle,
        } = ev.a
        else {
            return;
        };
        match ev.b {
            Party::Actor { id: other, kind } => {
                let k = match kind {
                    ActorKind::Vehicle => IncidentKind::NpcNpc,
                    ActorKind::Ego => IncidentKind::NpcEgo,
                    ActorKind::Pedestrian => IncidentKind::NpcPedestrian,
                };
                self.note_incident(k, id, Some(other));
            }
            Party::Static(s) => self.note_incident(IncidentKind::NpcStatic(s), id, None),
        }
    }

    /// Lists an NPC's deadlock (stopped 60 s) or respawn.
    pub(super) fn note_npc(&mut self, kind: IncidentKind, id: u32) {
        self.note_incident(kind, id, None);
    }
}
