//! The town and everything in it.
//!
//! A [`Town`] is built from an OpenDRIVE file (CARLA's maps, or a town from our
//! own [`generator`]): drivable lanes and the lane graph, lane markings,
//! sidewalks, crosswalks, junctions, traffic lights with their stop lines, and
//! building lots. Routes are read from CARLA's leaderboard XML or our TOML
//! form and densified by the [`planner`] into a [`DenseRoute`] tagged with
//! high-level commands.
//!
//! The moving part lives in [`traffic::Traffic`]: the ego and NPC vehicles
//! share one [`vehicle`] model (a kinematic bicycle), NPCs drive the lane graph
//! ([`npc`]), pedestrians walk sidewalks and crossings ([`pedestrian`]), and
//! [`physics`] (rapier3d) keeps every body out of every other. [`testtown`]
//! builds a small grid town for tests.
//!
//! The rules of the road (stop lines, must-stop, the lane under a point, the
//! route distance of a pose, ...) are written once in [`rules`]; the NPCs,
//! the expert, the monitors and the labels all call them.
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
