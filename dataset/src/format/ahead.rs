//! What stands straight ahead of the ego in a recorded frame: the nearest
//! pedestrian and the nearest stopped vehicle, by the rule book's "ahead",
//! from a frame's rows alone (no map).

use super::{ActorRow, EgoRow};

/// How far straight ahead of the ego [`pedestrian_ahead`] looks (metres):
/// about 2.5 s at the 8 m/s the expert drives, the time a pedestrian on a
/// crosswalk past a turn is in view before the car must brake.
pub const PEDESTRIAN_AHEAD_M: f32 = 20.0;

/// The distance to the nearest pedestrian straight ahead of `ego` within
/// [`PEDESTRIAN_AHEAD_M`] (metres), by the rule book's "ahead"
/// (`world::rules::nearest_ahead`) in the expert's corridor
/// (`sim::runner::AHEAD_CORRIDOR_M`), on a straight path along the ego's
/// heading: a frame property the training loader can weigh without the map.
pub fn pedestrian_ahead(ego: &EgoRow, actors: &[ActorRow]) -> Option<f32> {
    nearest_straight_ahead(ego, actors, |a| a.kind == ActorRow::PEDESTRIAN)
}

/// Below this speed a vehicle counts as stopped (metres per second).
pub const STOPPED_MPS: f32 = 0.5;

/// The distance to the nearest stopped vehicle (below [`STOPPED_MPS`]) straight ahead
/// of `ego` within [`PEDESTRIAN_AHEAD_M`] (metres), by the same rule as
/// [`pedestrian_ahead`]: a queue at a light, a car waiting to turn.
pub fn stopped_vehicle_ahead(ego: &EgoRow, actors: &[ActorRow]) -> Option<f32> {
    nearest_straight_ahead(ego, actors, |a| {
        a.kind == ActorRow::VEHICLE && a.speed.abs() < STOPPED_MPS
    })
}

/// The nearest of the `actors` that `keep` accepts in the ego's corridor on a straight
/// path along its heading, within [`PEDESTRIAN_AHEAD_M`] (the rule book's
/// `nearest_ahead`).
fn nearest_straight_ahead(
    ego: &EgoRow,
    actors: &[ActorRow],
    keep: impl Fn(&ActorRow) -> bool,
) -> Option<f32> {
    let candidates: Vec<world::rules::ActorView> = actors
        .iter()
        .filter(|a| keep(a))
        .map(ActorRow::view)
        .collect();
    if candidates.is_empty() {
        return None;
    }
    let start = world::Vec2::new(ego.x, ego.y);
    let dir = world::Vec2::from_angle(ego.yaw);
    let path: Vec<world::Vec2> = (0..=PEDESTRIAN_AHEAD_M as usize)
        .map(|k| start + dir * k as f32)
        .collect();
    world::rules::nearest_ahead(
        &path,
        &candidates,
        None,
        sim::runner::AHEAD_CORRIDOR_M,
        PEDESTRIAN_AHEAD_M,
        world::rules::walker_horizon_s(ego.speed),
    )
    .map(|a| a.distance_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stopped_vehicle_ahead_is_one_standing_in_the_corridor_in_front() {
        let ego = EgoRow {
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
            speed: 5.0,
        };
        let car = |x: f32, y: f32, speed: f32| ActorRow {
            kind: ActorRow::VEHICLE,
            id: 7,
            x,
            y,
            yaw: 0.0,
            length: 4.5,
            width: 1.9,
            speed,
        };
        let d = stopped_vehicle_ahead(&ego, &[car(12.0, 0.3, 0.0)]).expect("a queue ahead");
        assert!((8.0..12.0).contains(&d), "{d} m to its rear");
        assert_eq!(
            stopped_vehicle_ahead(&ego, &[car(12.0, 0.0, 3.0)]),
            None,
            "moving"
        );
        assert_eq!(
            stopped_vehicle_ahead(&ego, &[car(12.0, 6.0, 0.0)]),
            None,
            "next lane"
        );
        assert_eq!(
            stopped_vehicle_ahead(&ego, &[car(-8.0, 0.0, 0.0)]),
            None,
            "behind"
        );
        assert_eq!(
            stopped_vehicle_ahead(&ego, &[car(30.0, 0.0, 0.0)]),
            None,
            "too far"
        );
        let walker = ActorRow {
            kind: ActorRow::PEDESTRIAN,
            ..car(10.0, 0.0, 0.0)
        };
        assert_eq!(stopped_vehicle_ahead(&ego, &[walker]), None, "a walker");
    }

    #[test]
    fn a_pedestrian_ahead_is_one_in_the_corridor_in_front_within_range() {
        let ego = EgoRow {
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
            speed: 5.0,
        };
        let walker = |x: f32, y: f32| ActorRow {
            kind: ActorRow::PEDESTRIAN,
            id: 7,
            x,
            y,
            yaw: 1.5,
            length: 0.5,
            width: 0.5,
            speed: 1.2,
        };
        // To the near edge of its footprint: 8 m less 0.27 m (a 0.5 m walker turned 1.5 rad).
        let d = pedestrian_ahead(&ego, &[walker(8.0, 0.5)]).unwrap();
        assert!((d - 7.733).abs() < 1e-3, "{d}");
        assert_eq!(
            pedestrian_ahead(&ego, &[walker(8.0, -5.0)]),
            None,
            "on the sidewalk"
        );
        assert_eq!(pedestrian_ahead(&ego, &[walker(-3.0, 0.0)]), None, "behind");
        assert_eq!(
            pedestrian_ahead(&ego, &[walker(25.0, 0.0)]),
            None,
            "too far"
        );
        // A vehicle nearer does not hide the walker; the nearest walker counts.
        let car = ActorRow {
            kind: ActorRow::VEHICLE,
            length: 4.5,
            width: 1.9,
            ..walker(5.0, 0.0)
        };
        let d = pedestrian_ahead(&ego, &[car, walker(15.0, 0.0), walker(10.0, 1.0)]).unwrap();
        assert!((d - 9.733).abs() < 1e-3, "{d}");
        // Heading matters: facing west, the walker at x = 8 is behind.
        let west = EgoRow {
            yaw: std::f32::consts::PI,
            ..ego
        };
        assert_eq!(pedestrian_ahead(&west, &[walker(8.0, 0.0)]), None);
    }
}
