//! The rule book: the rules of the road, each written once, which every
//! consumer calls (the NPC driver, the expert, the monitors, the resolution
//! selectors, the renderer's "light ahead" and the world-on-rails labels).
//!
//! | file | rule |
//! | --- | --- |
//! | [`stop_lines`] | the stop lines of a town by lane, the stops a route crosses, in route order, the light ahead within a range, and the line whose light holds a standing car |
//! | [`lights`] | whether a light's state makes a vehicle stop before its line (red, and yellow with one slack) |
//! | [`crossing`] | the point of a vehicle that crosses a stop line |
//! | [`route`] | the distance along a route of a pose, the route's point at a distance, the route point reached, the path ahead |
//! | [`pursuit`] | the pure-pursuit lookahead, and the NPCs' steer along a lane path |
//! | [`lanes`] | the lane under a point (heading agreement, one width lookup), the nearest lane, how a car stands to the lanes (inside, outside, against them), and [`LaneGrid`] |
//! | [`conflicts`] | which connecting lanes of a junction conflict: centrelines within 3 m, or the bodies of two cars driving them (each lane swept as an NPC drives it) within 0.25 m |
//! | [`ahead`] | what is ahead along a path: the nearest actor whose footprint reaches into a corridor (a walking pedestrian's also where it will be within 2 s), and its distance along the path |
//! | [`sidewalks`] | the sidewalk under a point, its height and the direction of its kerb |
//! | [`lane_change`] | where a route's next lane change starts and into which lane, and whether that lane has room (5 m ahead, 2 s of the follower's speed behind) |
//! | [`yielding`] | where the ego waits before a junction without lights while a conflicting connecting lane is held (the ego's side of the NPCs' reservations) |
//!
//! `docs/rule-book.md` lists where each consumer calls each rule.
//!
//! Each rule is a plain function or table built from a [`Town`] (and a
//! [`crate::DenseRoute`]): none needs a running [`crate::traffic::Traffic`].
//! [`RuleBook`] holds a town's tables, built once; a run shares one
//! ([`crate::traffic::Traffic::rules`]). The vehicle model every vehicle
//! moves by is [`crate::agents::vehicle::VehicleState::step`].

pub mod ahead;
pub mod conflicts;
pub mod crossing;
pub mod lane_change;
pub mod lanes;
pub mod lights;
pub mod pursuit;
pub mod route;
pub mod sidewalks;
pub mod stop_lines;
pub mod yielding;

pub use ahead::{ActorView, Ahead, nearest_ahead, walker_horizon_s};
pub use conflicts::JunctionConflicts;
pub use crossing::{crossing_offset_m, crossing_point};
pub use lane_change::{CHANGE_RANGE_M, lane_change_ahead, lane_change_clear, lane_change_wait};
pub use lanes::{LaneGrid, LaneStanding, heading_agrees, nearest_lane, project_on_lane};
pub use lights::{YELLOW_SLACK_M, change_interval_s, light_state, must_stop};
pub use pursuit::pursuit_lookahead_m;
pub use route::{nearest_route_point, route_ahead, route_point_at, route_s_at};
pub use sidewalks::{OnSidewalk, SidewalkGrid};
pub use stop_lines::{RouteStop, RouteStops, StopLineEntry, StopLines, tail_segment};
pub use yielding::{
    GIVE_WAY_HORIZON_S, GIVE_WAY_MIN_M, YIELD_RANGE_M, approaching, entry_signalled,
    junction_signalled, junction_yield, must_give_way,
};

use crate::map::town::Town;

/// Side of the cells of a rule book's lane grid (metres).
pub const LANE_GRID_CELL_M: f32 = 5.0;

/// A town's rule tables, built once: its stop lines by lane, its junction
/// conflicts, and the grids that find the lane and the sidewalk under a point.
#[derive(Debug, Clone)]
pub struct RuleBook {
    /// Every stop line, and by lane.
    pub stop_lines: StopLines,
    /// Conflicting connecting lanes of each junction.
    pub conflicts: JunctionConflicts,
    /// The lane under a point.
    pub lanes: LaneGrid,
    /// The sidewalk under a point.
    pub sidewalks: SidewalkGrid,
}

impl RuleBook {
    /// Builds the tables of a town.
    pub fn new(town: &Town) -> RuleBook {
        RuleBook {
            stop_lines: StopLines::new(town),
            conflicts: JunctionConflicts::new(town),
            lanes: LaneGrid::new(town, LANE_GRID_CELL_M),
            sidewalks: SidewalkGrid::new(town),
        }
    }
}
