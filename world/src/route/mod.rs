//! Routes: route [`file`]s (CARLA XML, our TOML), the global [`planner`]
//! that densifies them over the lane graph into a [`dense`] route, and the
//! high-level [`command`]s the points carry.

pub mod command;
pub mod dense;
pub mod error;
pub mod file;
pub mod planner;

pub use command::Command;
pub use dense::{DenseRoute, RoutePoint};
pub use error::RouteError;
pub use file::{Route, RouteFile, RouteWaypoint};
pub use planner::{PlannerConfig, plan_route};
