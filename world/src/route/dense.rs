//! A dense route: a route's waypoints densified over the lane graph (the
//! [`super::planner`] makes it), one point about every metre in driving order,
//! each with its lane, its distance along the route and its command.

use glam::Vec3;

use crate::map::town::LaneIdx;
use crate::route::command::Command;

/// One point of a dense route.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoutePoint {
    /// Position on the lane centreline (metres).
    pub position: Vec3,
    /// Driving heading (radians, counter-clockwise from +x).
    pub heading: f32,
    /// The lane the point is on.
    pub lane: LaneIdx,
    /// Arc length along that lane (metres).
    pub s: f32,
    /// The high-level command at this point.
    pub command: Command,
    /// Distance along the route from its first point (metres).
    pub route_s: f32,
}

/// A route densified over the lane graph.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseRoute {
    /// The route's id.
    pub id: String,
    /// Points about `spacing_m` apart, in driving order.
    pub points: Vec<RoutePoint>,
    /// Total length along the points (metres).
    pub length_m: f32,
    /// For each input waypoint, the index of its dense point.
    pub waypoint_points: Vec<usize>,
}

impl DenseRoute {
    /// The first command other than `LaneFollow` within `lookahead_m` metres
    /// ahead of point `i`, else the command at `i`.
    pub fn command_ahead(&self, i: usize, lookahead_m: f32) -> Command {
        let Some(p) = self.points.get(i) else {
            return Command::LaneFollow;
        };
        self.points[i..]
            .iter()
            .take_while(|q| q.route_s - p.route_s <= lookahead_m)
            .map(|q| q.command)
            .find(|c| *c != Command::LaneFollow)
            .unwrap_or(p.command)
    }

    /// How many points carry each command, in `Command` order.
    pub fn command_counts(&self) -> Vec<(Command, usize)> {
        use Command::*;
        [
            Left,
            Right,
            Straight,
            LaneFollow,
            ChangeLaneLeft,
            ChangeLaneRight,
        ]
        .into_iter()
        .map(|c| (c, self.points.iter().filter(|p| p.command == c).count()))
        .collect()
    }

    /// The largest gap between consecutive points (metres).
    pub fn max_gap_m(&self) -> f32 {
        self.points
            .windows(2)
            .map(|w| w[0].position.distance(w[1].position))
            .fold(0.0, f32::max)
    }
}
