//! Yielding at a junction without traffic lights: the ego's side of the
//! NPCs' first-come-first-served junction reservations
//! ([`crate::traffic::Reservations`]).
//!
//! CARLA's Traffic Manager lets a car into a junction without lights only
//! while nothing already in the junction is on a conflicting path. The NPCs
//! do it by reserving their connecting lane before they enter; the ego
//! reserves nothing, so before such a junction it reads the same table:
//! while a vehicle holds a lane that conflicts with the ego's next connecting
//! lane ([`JunctionConflicts`]), it stops before the junction. Once its front
//! is inside, it drives on: it is then the one already in the junction, and
//! the NPCs treat its lane as held. Where a light stands at the way in, the
//! lights decide; a way in without one (a road inside one box with the
//! junction before it, [`entry_signalled`]) is yielded at as above.
//!
//! Where the map gives one road priority over another (an OpenDRIVE junction
//! `<priority>`, such as a roundabout's ring over its entries), a car about
//! to take the lower lane also gives way to any vehicle about to enter a
//! conflicting higher one ([`must_give_way`], [`approaching`]): it yields on
//! entry, as CARLA's Traffic Manager yields to traffic already on the ring.

use crate::map::town::{JunctionIdx, LaneIdx, Town};
use crate::route::DenseRoute;
use crate::rules::route::points_around;

use crate::rules::JunctionConflicts;

/// How far ahead of its front bumper the ego looks for a junction without
/// lights (metres): more than its stopping distance from cruise speed.
pub const YIELD_RANGE_M: f32 = 30.0;

/// How far ahead, in time at its speed, a vehicle counts as about to enter
/// a lane (seconds).
pub const GIVE_WAY_HORIZON_S: f32 = 3.0;
/// ... and at least how far ahead of the lane's entry its front may be (metres).
pub const GIVE_WAY_MIN_M: f32 = 8.0;

/// Whether a vehicle whose front is `distance_m` before a lane's entry at
/// `speed_mps` is about to enter it: within [`GIVE_WAY_HORIZON_S`] of it at
/// its speed, or within [`GIVE_WAY_MIN_M`].
pub fn approaching(distance_m: f32, speed_mps: f32) -> bool {
    distance_m <= (speed_mps.max(0.0) * GIVE_WAY_HORIZON_S).max(GIVE_WAY_MIN_M)
}

/// Whether a car about to take connecting lane `lane` must give way: a lane
/// the map gives priority over it ([`JunctionConflicts::gives_way_to`]) is
/// taken or about to be, as `approaching(that lane)` says.
pub fn must_give_way(
    conflicts: &JunctionConflicts,
    lane: LaneIdx,
    approaching: impl Fn(LaneIdx) -> bool,
) -> bool {
    conflicts
        .gives_way_to(lane)
        .iter()
        .any(|&high| approaching(high))
}

/// Whether junction `j` has traffic lights (a light whose controller cycles it).
pub fn junction_signalled(town: &Town, j: JunctionIdx) -> bool {
    town.lights.iter().any(|l| l.junction == Some(j))
}

/// Whether the way into connecting lane `lane` is signalled: a light of its
/// junction has its stop line on a lane leading into it. Every approach of a
/// lit junction is, but for a road inside one box with the junction before it
/// ([`crate::map::opendrive::BOX_LINK_M`]: generated lights leave it unlit), where the
/// car yields as at a junction without lights.
pub fn entry_signalled(town: &Town, lane: LaneIdx) -> bool {
    let l = town.lane(lane);
    town.lights
        .iter()
        .filter(|light| light.junction.is_some() && light.junction == l.junction)
        .flat_map(|light| &light.stop_lines)
        .any(|sl| l.predecessors.contains(&sl.lane))
}

/// Where the ego must wait before a junction without lights (or a way into
/// one that has none, [`entry_signalled`]): the route arc
/// length (metres) at which `route` enters the next junction within `range_m`
/// ahead of `front_s` (the route arc length of the ego's front bumper), when
/// `held(lane)` says another vehicle holds a lane that conflicts with the
/// route's connecting lane there. `None` once the front has passed into a
/// junction (it has entered: it goes on), when the way into the next junction
/// within range has a light, or when nothing conflicting is held.
pub fn junction_yield(
    town: &Town,
    route: &DenseRoute,
    front_s: f32,
    range_m: f32,
    held: impl Fn(LaneIdx) -> bool,
) -> Option<f32> {
    let (behind, first) = points_around(route, front_s);
    // On a junction lane behind its front, it has entered.
    if behind.is_some_and(|i| town.lane(route.points[i].lane).junction.is_some()) {
        return None;
    }
    let entry = route.points[first..]
        .iter()
        .take_while(|p| p.route_s - front_s <= range_m)
        .find(|p| town.lane(p.lane).junction.is_some())?;
    (!entry_signalled(town, entry.lane) && held(entry.lane)).then_some(entry.route_s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown;
    use crate::route::{PlannerConfig, Route, RouteWaypoint, plan_route};
    use glam::Vec3;

    /// A 3 x 3 grid town (junctions 60 m apart) without its lights, and a
    /// route east along the middle street through the centre junction.
    fn unlit() -> (Town, DenseRoute) {
        let mut town = testtown::grid(3, 3, 60.0);
        town.lights.clear();
        let point = |x: f32| RouteWaypoint {
            position: Vec3::new(x, 60.0 - 1.75, 0.0),
            yaw_rad: Some(0.0),
        };
        let route = Route {
            id: "through".into(),
            town: None,
            waypoints: vec![point(10.0), point(110.0)],
            source: "test".into(),
        };
        let dense = plan_route(&town, &route, &PlannerConfig::default()).unwrap();
        (town, dense)
    }

    #[test]
    fn the_ego_waits_before_an_unlit_junction_while_a_conflicting_lane_is_held() {
        let (town, route) = unlit();
        let entry = route
            .points
            .iter()
            .find(|p| town.lane(p.lane).junction.is_some())
            .expect("the route crosses a junction");
        let (entry_s, entry_lane) = (entry.route_s, entry.lane);
        let held_crossing = |l: LaneIdx| l == entry_lane;
        let nothing = |_: LaneIdx| false;
        // 20 m before the junction, something conflicting is held: wait at the entry.
        assert_eq!(
            junction_yield(&town, &route, entry_s - 20.0, YIELD_RANGE_M, held_crossing),
            Some(entry_s)
        );
        // Nothing held: go.
        assert_eq!(
            junction_yield(&town, &route, entry_s - 20.0, YIELD_RANGE_M, nothing),
            None
        );
        // Out of range: not yet.
        assert_eq!(
            junction_yield(&town, &route, entry_s - 40.0, YIELD_RANGE_M, held_crossing),
            None
        );
        // The front already inside: it has entered and goes on.
        assert_eq!(
            junction_yield(&town, &route, entry_s + 1.0, YIELD_RANGE_M, held_crossing),
            None
        );
    }

    #[test]
    fn lights_decide_at_a_signalled_junction() {
        let (_, route) = unlit();
        let lit = testtown::grid(3, 3, 60.0);
        assert!(!lit.lights.is_empty());
        let entry = route
            .points
            .iter()
            .find(|p| lit.lane(p.lane).junction.is_some())
            .unwrap();
        let j = lit.lane(entry.lane).junction.unwrap();
        assert!(junction_signalled(&lit, j));
        assert!(entry_signalled(&lit, entry.lane));
        assert_eq!(
            junction_yield(&lit, &route, entry.route_s - 20.0, YIELD_RANGE_M, |_| true),
            None
        );
        // The same junction with the light of the route's way in taken off (a
        // road inside one box, which generated lights leave unlit): it yields there.
        let mut one_unlit = lit.clone();
        let before = lit.lane(entry.lane).predecessors.clone();
        for light in &mut one_unlit.lights {
            light.stop_lines.retain(|sl| !before.contains(&sl.lane));
        }
        assert!(junction_signalled(&one_unlit, j));
        assert!(!entry_signalled(&one_unlit, entry.lane));
        assert_eq!(
            junction_yield(
                &one_unlit,
                &route,
                entry.route_s - 20.0,
                YIELD_RANGE_M,
                |_| true
            ),
            Some(entry.route_s)
        );
    }
}

#[cfg(test)]
mod towns {
    use super::*;
    use crate::map::opendrive::{LoadOptions, load_xodr_file};

    /// For each junction without lights (with at least one connecting lane),
    /// how many lanes lead into it.
    fn unlit_junction_approaches(town: &Town) -> Vec<usize> {
        let mut js: Vec<JunctionIdx> = town.lanes.iter().filter_map(|l| l.junction).collect();
        js.sort_by_key(|j| j.0);
        js.dedup();
        js.into_iter()
            .filter(|&j| !junction_signalled(town, j))
            .map(|j| {
                let mut into: Vec<LaneIdx> = town
                    .lanes
                    .iter()
                    .filter(|l| l.junction == Some(j))
                    .flat_map(|l| l.predecessors.iter().copied())
                    .filter(|&p| town.lane(p).junction.is_none())
                    .collect();
                into.sort_by_key(|l| l.0);
                into.dedup();
                into.len()
            })
            .collect()
    }

    #[test]
    fn the_study_towns_yield_only_at_their_corners() {
        // CARLA's Town01 and Town02 have lights at every junction; our generated
        // towns leave only their corners (two roads meeting, two lanes in)
        // unlit. So the expert's yielding changes nothing at a crossing of the
        // study's towns, only where two turning cars at a corner would touch.
        let root = crate::testdata::workspace_root();
        for (name, corners) in [("gen01", 4), ("gen02", 4), ("held01", 4)] {
            let map = root.join(format!("maps/{name}.xodr"));
            let (town, _) = load_xodr_file(&map, &LoadOptions::default()).unwrap();
            let unlit = unlit_junction_approaches(&town);
            assert_eq!(unlit, vec![2; corners], "{name}");
        }
        if let Some(carla) =
            crate::testdata::carla_dir("the_study_towns_yield_only_at_their_corners")
        {
            for name in ["Town01", "Town02"] {
                let map = carla.join(format!("{name}.xodr"));
                let (town, _) = load_xodr_file(&map, &LoadOptions::default()).unwrap();
                assert_eq!(
                    unlit_junction_approaches(&town),
                    Vec::<usize>::new(),
                    "{name}"
                );
            }
        }
    }
}
