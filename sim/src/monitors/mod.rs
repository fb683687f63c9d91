//! Infraction monitors: one file each, all reading the same per-tick facts
//! ([`EgoTick`]) and the world's shared definitions (markings, stop lines,
//! footprints), so a marking or a red-light crossing means one thing
//! everywhere (docs/protocol.md §3).
//!
//! Every monitor implements [`Monitor`] and [`Monitors`] observes them in one
//! fixed order, the order of this table:
//!
//! | monitor | counts |
//! | --- | --- |
//! | [`route`] | route completion, success, deviation from the route |
//! | [`collision`] | every contact recorded as a touch ([`contacts`]); collisions under the paper's rule ([`counting`]) |
//! | [`lane_crossing`] | every painted marking the footprint crosses |
//! | [`red_light`] | passages over a red light's stop line |
//! | [`blocked`] | stuck, low-speed (not counting time held by a red light) and route timeouts |
//! | [`outside_lane`] | the share of the route progress made off the driving lanes (or against them) |
//! | [`on_sidewalk`] | each stretch driven on a sidewalk (informative) |
//!
//! Beside them: [`contacts`] (the touches), [`counting`] (the named rules
//! that count collisions from touches: `paper`, `leaderboard-1.0`) and
//! [`score`] (leaderboard-1.0's driving score from the counts); `rule_cases.rs`
//! (tests) drives the four cases that tell the rules apart on hand-made towns.

pub mod blocked;
pub mod collision;
pub mod contacts;
pub mod counting;
pub mod lane_crossing;
pub mod on_sidewalk;
pub mod outside_lane;
pub mod red_light;
pub mod route;
#[cfg(test)]
mod rule_cases;
pub mod score;

use serde::{Deserialize, Serialize};
pub use world::EgoPose;
use world::agents::kerb::KerbCrossing;
use world::physics::Party;
use world::road::geometry::OrientedBox;
use world::{ActorKind, LightState};

/// What the other body in a collision was.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ContactKind {
    /// An NPC vehicle.
    Vehicle,
    /// A pedestrian.
    Pedestrian,
    /// Anything that does not move: buildings, poles, curbs.
    Static,
}

/// The ego touching another body during a tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EgoContact {
    /// The other body's id (unique within the run, statics included).
    pub other: u32,
    /// What it is.
    pub kind: ContactKind,
    /// For a static body, what it is in a word ("building", "pole", "tree").
    pub static_name: Option<&'static str>,
}

impl EgoContact {
    /// The ego's side of a physics contact between `a` and `b`: the other party
    /// as the collision monitor counts it, or `None` when the ego is neither.
    pub fn between(a: Party, b: Party) -> Option<EgoContact> {
        let other = match (a, b) {
            (Party::Actor { id: 0, .. }, other) | (other, Party::Actor { id: 0, .. }) => other,
            _ => return None,
        };
        Some(match other {
            Party::Actor {
                id,
                kind: ActorKind::Pedestrian,
            } => EgoContact {
                other: id,
                kind: ContactKind::Pedestrian,
                static_name: None,
            },
            Party::Actor { id, .. } => EgoContact {
                other: id,
                kind: ContactKind::Vehicle,
                static_name: None,
            },
            // Statics carry no per-object id: each kind counts as one "actor".
            Party::Static(kind) => EgoContact {
                other: 1_000_000 + kind as u32,
                kind: ContactKind::Static,
                static_name: Some(kind.name()),
            },
        })
    }
}

/// Everything the monitors see of one tick, after the physics step.
#[derive(Debug, Clone, Copy)]
pub struct EgoTick<'a> {
    /// The tick just completed (the first step ends at tick 1).
    pub tick: u64,
    /// Simulation time at its end (seconds).
    pub time_s: f64,
    /// The pose before the step.
    pub prev: EgoPose,
    /// The pose after the step.
    pub now: EgoPose,
    /// Speed after the step (metres per second).
    pub speed_mps: f32,
    /// The ego's length and width (metres).
    pub size_m: (f32, f32),
    /// The throttle in force during the step, in [0, 1].
    pub throttle: f32,
    /// Bodies the ego touched during the step.
    pub contacts: &'a [EgoContact],
    /// The kerbs the ego's axles went up or down during the step, front axle first.
    pub kerbs: &'a [KerbCrossing],
    /// The route distance reached after the step (metres). The route monitor
    /// measures it: [`Monitors::observe`] fills it in for the monitors after it.
    pub route_progress_m: f32,
    /// The state of every light, indexed by `LightIdx`.
    pub lights: &'a [LightState],
    /// The tick's length (seconds).
    pub dt_s: f64,
}

impl EgoTick<'_> {
    /// The footprint after the step.
    pub fn footprint(&self) -> OrientedBox {
        OrientedBox {
            center: self.now.ground(),
            heading: self.now.heading,
            half_length: self.size_m.0 / 2.0,
            half_width: self.size_m.1 / 2.0,
        }
    }
}

/// One thing counted about a run, from one tick at a time (like Waymax's
/// metrics): every monitor sees the same [`EgoTick`].
pub trait Monitor {
    /// Looks at one tick and pushes what it counts to `out`, which already
    /// holds what the monitors before it pushed for this tick.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>);

    /// Reports what was still in progress when the run ended.
    fn finish(&mut self, _out: &mut Vec<Infraction>) {}
}

/// Every monitor of a run, observed in the module table's order (the
/// blocked monitor after the collisions: standing after a collision counted
/// this tick is stuck).
#[derive(Debug, Clone)]
pub struct Monitors {
    /// Route completion, success and deviation.
    pub route: route::RouteMonitor,
    /// Collisions.
    pub collisions: collision::CollisionMonitor,
    /// Lane markings crossed.
    pub lane_crossings: lane_crossing::LaneCrossingMonitor,
    /// Red lights run.
    pub red_lights: red_light::RedLightMonitor,
    /// Stuck, low speed, route timeout.
    pub blocked: blocked::BlockedMonitor,
    /// Route progress made off the lanes.
    pub outside_lane: outside_lane::OutsideLaneMonitor,
    /// Stretches on the sidewalk.
    pub on_sidewalk: on_sidewalk::OnSidewalkMonitor,
}

impl Monitors {
    /// The monitors of a run in `town` along `route`: deviation limit
    /// (metres), stuck and low-speed limits and route timeout (seconds).
    pub fn new(
        town: &std::sync::Arc<world::Town>,
        rules: std::sync::Arc<world::rules::RuleBook>,
        route: &world::route::DenseRoute,
        deviation_m: f32,
        (stuck_s, low_speed_s, timeout_s): (f64, f64, f64),
    ) -> Monitors {
        Monitors {
            route: route::RouteMonitor::new(route, deviation_m),
            collisions: collision::CollisionMonitor::default(),
            lane_crossings: lane_crossing::LaneCrossingMonitor::new(town),
            red_lights: red_light::RedLightMonitor::new(town.clone(), rules.clone()),
            outside_lane: outside_lane::OutsideLaneMonitor::new(town.clone(), rules.clone()),
            on_sidewalk: on_sidewalk::OnSidewalkMonitor::new(town.clone(), rules.clone()),
            blocked: blocked::BlockedMonitor::new(stuck_s, low_speed_s, timeout_s)
                .waiting_at_lights_of(rules),
        }
    }

    /// Every monitor looks at the tick, in order; their reports go to `out`.
    pub fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        self.route.observe(tick, out);
        let tick = EgoTick {
            route_progress_m: self.route.progress_m(),
            ..*tick
        };
        for m in self.after_route() {
            m.observe(&tick, out);
        }
    }

    /// Reports what was still in progress when the run ended (a stretch on the sidewalk).
    pub fn finish(&mut self, out: &mut Vec<Infraction>) {
        self.route.finish(out);
        for m in self.after_route() {
            m.finish(out);
        }
    }

    /// The monitors after the route monitor, in order.
    fn after_route(&mut self) -> [&mut dyn Monitor; 6] {
        [
            &mut self.collisions,
            &mut self.lane_crossings,
            &mut self.red_lights,
            &mut self.blocked,
            &mut self.outside_lane,
            &mut self.on_sidewalk,
        ]
    }
}

/// The kinds of infraction and event the monitors report.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InfractionKind {
    /// Collision with a pedestrian.
    CollisionPedestrian,
    /// Collision with a vehicle.
    CollisionVehicle,
    /// Collision with a static object.
    CollisionStatic,
    /// Crossed the stop line of a red light.
    RedLight,
    /// Crossed a painted lane marking.
    LaneCrossing,
    /// Drove on the sidewalk (informative: no penalty, no end; its distance counts in
    /// the outside-lanes share).
    OnSidewalk,
    /// Drove more than the allowed distance away from the route (ends the run).
    RouteDeviation,
    /// Stood still while pressing the throttle, or after a collision (ends the run).
    Stuck,
    /// Stood still too long (ends the run).
    LowSpeedTimeout,
    /// Did not finish in time (ends the run).
    RouteTimeout,
}

impl InfractionKind {
    /// Every kind, in table order.
    pub const ALL: [InfractionKind; 10] = [
        Self::CollisionPedestrian,
        Self::CollisionVehicle,
        Self::CollisionStatic,
        Self::RedLight,
        Self::LaneCrossing,
        Self::OnSidewalk,
        Self::RouteDeviation,
        Self::Stuck,
        Self::LowSpeedTimeout,
        Self::RouteTimeout,
    ];

    /// Whether this is a collision (with a pedestrian, a vehicle or the map).
    pub fn is_collision(self) -> bool {
        matches!(
            self,
            Self::CollisionPedestrian | Self::CollisionVehicle | Self::CollisionStatic
        )
    }

    /// Whether this event ends the run.
    pub fn terminates(self) -> bool {
        matches!(
            self,
            Self::RouteDeviation | Self::Stuck | Self::LowSpeedTimeout | Self::RouteTimeout
        )
    }

    /// A stable snake_case name, for tables and logs.
    pub fn name(self) -> &'static str {
        match self {
            Self::CollisionPedestrian => "collision_pedestrian",
            Self::CollisionVehicle => "collision_vehicle",
            Self::CollisionStatic => "collision_static",
            Self::RedLight => "red_light",
            Self::LaneCrossing => "lane_crossing",
            Self::OnSidewalk => "on_sidewalk",
            Self::RouteDeviation => "route_deviation",
            Self::Stuck => "stuck",
            Self::LowSpeedTimeout => "low_speed_timeout",
            Self::RouteTimeout => "route_timeout",
        }
    }
}

/// One infraction, where and when it happened.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Infraction {
    /// The tick it was detected at.
    pub tick: u64,
    /// Simulation time (seconds).
    pub time_s: f64,
    /// What it was.
    pub kind: InfractionKind,
    /// Where the ego was (metres, world frame).
    pub position: [f32; 2],
    /// A human-readable detail (the other actor, the light, the marking).
    pub detail: String,
}

impl Infraction {
    /// An infraction at this tick's ego position.
    pub fn at(tick: &EgoTick<'_>, kind: InfractionKind, detail: String) -> Self {
        Self {
            tick: tick.tick,
            time_s: tick.time_s,
            kind,
            position: tick.now.ground().to_array(),
            detail,
        }
    }
}

#[cfg(test)]
pub(crate) mod scripted {
    //! Scripted ego motions for the monitors' tests.
    use super::*;

    /// A pose on the ground at (x, y) (metres) heading `heading` (radians).
    pub fn pose(x: f32, y: f32, heading: f32) -> EgoPose {
        EgoPose {
            position: world::Vec3::new(x, y, 0.0),
            heading,
        }
    }

    /// A straight drive along +x at `speed_mps` from `x0`, one pose a tick
    /// of 25 ms, at lateral position `y`.
    pub fn straight(x0: f32, y: f32, speed_mps: f32, ticks: usize) -> Vec<EgoPose> {
        (0..=ticks)
            .map(|i| pose(x0 + speed_mps * 0.025 * i as f32, y, 0.0))
            .collect()
    }

    /// A vehicle, a walker and two pieces of map geometry to touch.
    pub const CAR: EgoContact = EgoContact {
        other: 7,
        kind: ContactKind::Vehicle,
        static_name: None,
    };
    pub const WALKER: EgoContact = EgoContact {
        other: 9,
        kind: ContactKind::Pedestrian,
        static_name: None,
    };
    pub const WALL: EgoContact = EgoContact {
        other: 100,
        kind: ContactKind::Static,
        static_name: Some("building"),
    };
    pub const TREE: EgoContact = EgoContact {
        other: 101,
        kind: ContactKind::Static,
        static_name: Some("tree"),
    };

    /// Drives `ticks` ticks along +x from the origin at `speed_mps`, touching
    /// `contact_at(tick)` at each.
    pub fn touching(
        speed_mps: f32,
        ticks: usize,
        contact_at: impl Fn(u64) -> Vec<EgoContact>,
        mut observe: impl FnMut(&EgoTick<'_>),
    ) {
        let poses = straight(0.0, 0.0, speed_mps, ticks);
        drive(&poses, speed_mps, &[], |t| {
            let contacts = contact_at(t.tick);
            observe(&EgoTick {
                contacts: &contacts,
                ..*t
            });
        });
    }

    /// Feeds a pose sequence to `observe`, one tick per consecutive pair.
    pub fn drive(
        poses: &[EgoPose],
        speed_mps: f32,
        lights: &[LightState],
        mut observe: impl FnMut(&EgoTick<'_>),
    ) {
        for (i, w) in poses.windows(2).enumerate() {
            let tick = EgoTick {
                tick: i as u64 + 1,
                time_s: (i + 1) as f64 * 0.025,
                prev: w[0],
                now: w[1],
                speed_mps,
                size_m: (4.79, 2.16),
                throttle: 0.5,
                contacts: &[],
                kerbs: &[],
                route_progress_m: 0.0,
                lights,
                dt_s: 0.025,
            };
            observe(&tick);
        }
    }
}
