//! Errors for bad route files and routes: each names the file, what is
//! wrong, where, and how to fix it.

use std::path::PathBuf;

/// A route file or route that could not be used.
#[derive(Debug, thiserror::Error)]
pub enum RouteError {
    /// The file could not be read.
    #[error("cannot read route file {file}: {source}. Fix: check the path")]
    Read {
        /// The route file.
        file: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file does not parse as CARLA route XML or our TOML route form.
    #[error("route file {file}: {what} at {location}. Fix: {fix}")]
    Parse {
        /// The route file.
        file: PathBuf,
        /// What is wrong.
        what: String,
        /// Where in the file.
        location: String,
        /// How to fix it.
        fix: String,
    },
    /// No route with the asked id.
    #[error(
        "route file {file} has no route with id \"{id}\"; ids in the file: {available}. Fix: pick one of those ids"
    )]
    MissingId {
        /// The route file.
        file: PathBuf,
        /// The id asked for.
        id: String,
        /// The ids the file has, comma separated.
        available: String,
    },
    /// A waypoint is too far from every driving lane.
    #[error(
        "route \"{id}\" in {file}: waypoint {index} at ({x:.1}, {y:.1}) is {distance_m:.1} m from the nearest driving lane (at most {limit_m:.1} m allowed). Fix: move the waypoint onto a lane of this map, or check the route belongs to this map (CARLA XML must be read as CARLA XML so y is flipped)"
    )]
    OffMap {
        /// The route file.
        file: PathBuf,
        /// The route id.
        id: String,
        /// Waypoint index (0-based).
        index: usize,
        /// Waypoint x (metres, OpenDRIVE frame).
        x: f32,
        /// Waypoint y (metres, OpenDRIVE frame).
        y: f32,
        /// Distance to the nearest lane centreline (metres).
        distance_m: f32,
        /// The snap limit (metres).
        limit_m: f32,
    },
    /// The lane graph has no path between two waypoints.
    #[error(
        "route \"{id}\" in {file}: no drivable path from waypoint {from} to waypoint {to}. Fix: check the waypoints' order and headings, or the map's lane links"
    )]
    NoPath {
        /// The route file.
        file: PathBuf,
        /// The route id.
        id: String,
        /// Index of the waypoint the leg starts at.
        from: usize,
        /// Index of the waypoint the leg ends at.
        to: usize,
    },
    /// A route has fewer than two waypoints.
    #[error("route \"{id}\" in {file} has {count} waypoint(s). Fix: give at least two waypoints")]
    TooFewWaypoints {
        /// The route file.
        file: PathBuf,
        /// The route id.
        id: String,
        /// How many it has.
        count: usize,
    },
}
