//! Routes: route [`file`]s (CARLA XML, our TOML), the global [`planner`]
//! that densifies them over the lane graph, and the high-level
//! [`command`]s the points carry.

pub mod command;
pub mod error;
pub mod file;
pub mod planner;

pub use command::Command;
pub use error::RouteError;
pub use file::{Route, RouteFile, RouteWaypoint};
pub use planner::{DenseRoute, PlannerConfig, RoutePoint, plan_route};
