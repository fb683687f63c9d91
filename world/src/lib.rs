//! The town and everything in it.
//!
//! A [`Town`] is built from an OpenDRIVE file (CARLA's maps, or a town from
//! our own generator): drivable lanes and the lane graph, lane markings,
//! sidewalks, crosswalks, junctions, traffic lights with their stop lines,
//! and buildings. Routes are read from CARLA's leaderboard XML or our TOML
//! form and densified by the planner into a [`DenseRoute`] tagged with
//! high-level commands. [`traffic::Traffic`] moves the ego, the NPC vehicles
//! and the pedestrians through one physics world; the rules of the road are
//! written once in [`rules`] and every consumer calls them.
//!
//! Its part of the data flow (`DESIGN.md`):
//!
//! ```text
//! OpenDRIVE file ──map::opendrive──▶ Town ◀──map::generator (our towns, as OpenDRIVE)
//! route file ──route::file──▶ Route ──route::planner──▶ DenseRoute (points ~1 m apart, commands)
//! Town ──rules::RuleBook──▶ stop lines, lane grid, junction conflicts (built once, shared)
//! each 40 Hz tick of the loop (sim):
//!   traffic::Traffic::step: reservations ─▶ NPC and walker behaviour (agents)
//!                           ─▶ physics step (physics) ─▶ contacts, stats, actor snapshots
//!   traffic::LightController::step ─▶ light states (the next tick's NPCs and the monitors read them)
//! ```
//!
//! | folder | what lives there |
//! | --- | --- |
//! | [`map`] | the [`Town`] model; OpenDRIVE loading ([`map::opendrive`], one file per part: lanes, markings, sidewalks, objects, lights, crosswalks, surface, validation); the town [`map::generator`]; the grid [`map::testtown`] for tests; a top-down [`map::picture`] |
//! | [`road`] | plane [`road::geometry`], queries on the [`road::lane_graph`], positions along chains of lanes ([`road::lane_path`]) |
//! | [`route`] | route files ([`route::file`]), the global [`route::planner`], high-level [`route::command`]s |
//! | [`rules`] | the rule book: stop lines, must-stop, the crossing point, route distances, pure-pursuit lookahead, the lane under a point, junction conflicts, what is ahead along a path |
//! | [`agents`] | actor snapshots ([`agents::actor`]), the [`agents::vehicle`] model shared by every vehicle, the [`agents::npc`] driver, [`agents::pedestrian`]s |
//! | [`traffic`] | the traffic world: spawning, junction reservations, the tick, counters, actor views, soak runs, the traffic-light controller |
//! | [`physics`] | rapier3d: static colliders for the town, swept kinematic actors, contacts |
//! | [`testdata`] | what tests need from outside the checkout, and how they skip without it |
//!
//! Coordinates are OpenDRIVE's: right-handed, x east, y north, z up, metres;
//! headings in radians counter-clockwise from +x. CARLA's left-handed route
//! files are converted on reading (`y_xodr = -y`, `yaw_xodr = -yaw`).

pub mod agents;
pub mod map;
pub mod physics;
pub mod road;
pub mod route;
pub mod rules;
pub mod testdata;
pub mod traffic;

pub use agents::{ActorKind, ActorSnapshot, EgoPose};
pub use glam::{Vec2, Vec3};
pub use map::town::*;
pub use map::{
    LoadOptions, LoadReport, MapError, UnsignalledJunctions, load_xodr_file, load_xodr_str,
};
pub use route::{
    Command, DenseRoute, PlannerConfig, Route, RouteError, RouteFile, RoutePoint, RouteWaypoint,
    plan_route,
};
pub use rules::RuleBook;
pub use rules::lanes::LanePoint;
pub use traffic::{LightController, LightTiming};
