//! A lane change's gap check: whether the lane a route changes into has room
//! for the car, as CARLA's Traffic Manager and its behaviour agent ask before
//! they move across.
//!
//! The route planner marks the points of a lane change `ChangeLaneLeft` or
//! `ChangeLaneRight` ([`crate::route::planner`]). Before the first of them the
//! car looks at the target lane: the change is clear when no other vehicle on
//! that lane is within [`GAP_AHEAD_M`] ahead of the car's front or, behind its
//! rear, within the distance the follower covers in [`GAP_BEHIND_S`] (at least
//! [`GAP_AHEAD_M`]). Until then it waits in its lane before the change; once
//! its front has passed the change's start, it goes on.

use glam::Vec2;

use crate::agents::ActorKind;
use crate::map::town::{LaneIdx, Town};
use crate::route::DenseRoute;
use crate::route::command::Command;
use crate::rules::ahead::ActorView;
use crate::rules::lanes::project_on_lane;
use crate::rules::route::points_around;

/// Room the target lane needs ahead of the car's front (metres).
pub const GAP_AHEAD_M: f32 = 5.0;
/// Room behind the car's rear, in seconds of the follower's speed.
pub const GAP_BEHIND_S: f32 = 2.0;
/// How far ahead of its front a car looks for a lane change (metres).
pub const CHANGE_RANGE_M: f32 = 30.0;

/// The next lane change of `route` within `range_m` ahead of `front_s` (the
/// route arc length of the car's front): the route arc length where it starts
/// and the lane it moves into. `None` once the front has passed a change's start.
pub fn lane_change_ahead(route: &DenseRoute, front_s: f32, range_m: f32) -> Option<(f32, LaneIdx)> {
    next_change(route, front_s, range_m).map(|(i, lane)| (route.points[i].route_s, lane))
}

/// [`lane_change_ahead`] with the index of the change's first point.
fn next_change(route: &DenseRoute, front_s: f32, range_m: f32) -> Option<(usize, LaneIdx)> {
    let changing = |c: Command| matches!(c, Command::ChangeLaneLeft | Command::ChangeLaneRight);
    let (behind, first) = points_around(route, front_s);
    // In a change behind its front, it has begun.
    if behind.is_some_and(|i| changing(route.points[i].command)) {
        return None;
    }
    let start = route.points[first..]
        .iter()
        .take_while(|p| p.route_s - front_s <= range_m)
        .position(|p| changing(p.command))?
        + first;
    let target = route.points[start..]
        .iter()
        .find(|p| !changing(p.command))?;
    Some((start, target.lane))
}

/// Where a car must wait before the next lane change of `route` (the route
/// arc length where the change starts), or `None` to go on: the change is
/// within [`CHANGE_RANGE_M`] of its front (`front_s`) and the target lane has
/// no room for the car as it will stand when it moves across, its front at
/// the change's start ([`lane_change_clear`]). `me` is the car's own actor id.
pub fn lane_change_wait(
    town: &Town,
    route: &DenseRoute,
    front_s: f32,
    half_length_m: f32,
    me: u32,
    actors: &[ActorView],
) -> Option<f32> {
    let (i, target) = next_change(route, front_s, CHANGE_RANGE_M)?;
    let start = &route.points[i];
    let centre = start.position.truncate() - Vec2::from_angle(start.heading) * half_length_m;
    (!lane_change_clear(town, target, centre, half_length_m, me, actors)).then_some(start.route_s)
}

/// Whether `lane` has room for a car at `position` (its centre; half length
/// `half_length_m`): no vehicle of `actors` other than `me` on the lane (its
/// centre within half a lane width plus half its width of the centreline, its
/// heading along the lane) within [`GAP_AHEAD_M`] ahead of the front, or
/// behind the rear within [`GAP_BEHIND_S`] of its speed (at least
/// [`GAP_AHEAD_M`]).
pub fn lane_change_clear(
    town: &Town,
    lane: LaneIdx,
    position: Vec2,
    half_length_m: f32,
    me: u32,
    actors: &[ActorView],
) -> bool {
    let Some(here) = project_on_lane(town, lane, position) else {
        return true;
    };
    actors
        .iter()
        .filter(|a| a.id != me && matches!(a.kind, ActorKind::Vehicle | ActorKind::Ego))
        .all(|a| {
            let Some(there) = project_on_lane(town, lane, a.position) else {
                return true;
            };
            let along = Vec2::from_angle(there.heading).dot(Vec2::from_angle(a.yaw)) > 0.5;
            let on = there.distance_m <= there.width_m / 2.0 + a.half_width_m;
            if !(on && along) {
                return true;
            }
            let ds = there.s - here.s;
            let gap = ds.abs() - half_length_m - a.half_length_m;
            if ds >= 0.0 {
                gap >= GAP_AHEAD_M
            } else {
                gap >= (GAP_BEHIND_S * a.speed_mps).max(GAP_AHEAD_M)
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown::planned_route;
    use crate::map::testtown::two_lane_road;

    fn car(id: u32, x: f32, y: f32, speed_mps: f32) -> ActorView {
        ActorView {
            id,
            kind: ActorKind::Vehicle,
            position: Vec2::new(x, y),
            yaw: 0.0,
            speed_mps,
            half_length_m: 2.4,
            half_width_m: 0.95,
        }
    }

    #[test]
    fn a_change_is_found_ahead_and_its_target_lane_named() {
        let town = two_lane_road(200.0);
        // From the right lane (y = -1.75) to the left one (y = 1.75).
        let route = planned_route(&town, &[(10.0, -1.75, 0.0), (190.0, 1.75, 0.0)]).unwrap();
        let start = route
            .points
            .iter()
            .find(|p| p.command == Command::ChangeLaneLeft)
            .expect("the planner changes lanes")
            .route_s;
        let (s, target) = lane_change_ahead(&route, start - 10.0, CHANGE_RANGE_M).unwrap();
        assert_eq!(s, start);
        assert_eq!(target, LaneIdx(1));
        assert_eq!(
            lane_change_ahead(&route, start - 40.0, CHANGE_RANGE_M),
            None
        );
        assert_eq!(lane_change_ahead(&route, start + 0.5, CHANGE_RANGE_M), None);
    }

    #[test]
    fn a_car_waits_for_room_where_the_change_starts() {
        let town = two_lane_road(200.0);
        let route = planned_route(
            &town,
            &[(10.0, -1.75, 0.0), (100.0, -1.75, 0.0), (190.0, 1.75, 0.0)],
        )
        .unwrap();
        let (start_s, _) = lane_change_ahead(&route, 80.0, CHANGE_RANGE_M).unwrap();
        let start_x = route.points[route.points.partition_point(|p| p.route_s < start_s)]
            .position
            .x;
        // A car standing in the target lane where the change starts: wait, though it
        // is 20 m ahead of where the car is now.
        let blocker = [car(1, start_x, 1.75, 0.0)];
        assert_eq!(
            lane_change_wait(&town, &route, 80.0, 2.4, 0, &blocker),
            Some(start_s)
        );
        // 20 m further on, it leaves room.
        let ahead = [car(1, start_x + 20.0, 1.75, 0.0)];
        assert_eq!(lane_change_wait(&town, &route, 80.0, 2.4, 0, &ahead), None);
        assert_eq!(lane_change_wait(&town, &route, 80.0, 2.4, 0, &[]), None);
    }

    #[test]
    fn the_gap_check_wants_room_ahead_and_behind() {
        let town = two_lane_road(200.0);
        let me = Vec2::new(80.0, -1.75);
        let check = |actors: &[ActorView]| lane_change_clear(&town, LaneIdx(1), me, 2.4, 0, actors);
        assert!(check(&[]));
        // Alongside in the target lane: no.
        assert!(!check(&[car(1, 81.0, 1.75, 6.0)]));
        // 9 m ahead (4.2 m of gap): no; 12 m ahead: yes.
        assert!(!check(&[car(1, 89.0, 1.75, 6.0)]));
        assert!(check(&[car(1, 92.0, 1.75, 6.0)]));
        // 15 m behind at 8 m/s (10.2 m of gap, 16 m needed): no; standing: yes.
        assert!(!check(&[car(1, 65.0, 1.75, 8.0)]));
        assert!(check(&[car(1, 65.0, 1.75, 0.0)]));
        // In the car's own lane, or going the other way: not in the way of the change.
        assert!(check(&[car(1, 85.0, -1.75, 6.0)]));
        let mut oncoming = car(1, 81.0, 1.75, 6.0);
        oncoming.yaw = std::f32::consts::PI;
        assert!(check(&[oncoming]));
    }
}
