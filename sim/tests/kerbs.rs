//! Kerbs, sidewalks and collisions as CARLA has them, through the whole loop on
//! hand-made towns: a kerb is climbed, not hit; a wall and a pole are hit; a
//! stretch on the sidewalk is an informative event and shows in the
//! outside-lanes share (docs/rule-book.md, "Kerbs and sidewalks").

use std::path::Path;
use std::sync::Arc;

use sim::driver::{Driver, DriverNeeds, Observation};
use sim::monitors::InfractionKind;
use sim::observe::Moments;
use sim::record::RunRecord;
use sim::runner::{self, Prepared, RunInputs};
use sim::scenario::Scenario;
use sim::selector::Fixed;
use world::agents::vehicle::VehicleControl;
use world::map::testtown::{self, lane_through, route_through};
use world::{Building, Town, TrafficLight, Vec2, Vec3};

/// Holds a speed with the wheels straight: throttle below it, coast above.
struct Cruise {
    speed_mps: f32,
}

impl Driver for Cruise {
    fn name(&self) -> String {
        format!("cruise at {} m/s", self.speed_mps)
    }

    fn needs(&self) -> DriverNeeds {
        DriverNeeds::default()
    }

    fn act(&mut self, obs: &Observation<'_>) -> VehicleControl {
        VehicleControl {
            steer: 0.0,
            throttle: if obs.speed_mps < self.speed_mps {
                0.7
            } else {
                0.0
            },
            brake: 0.0,
        }
    }
}

/// Drives `route` (its first segment sets the start pose) in `town` with [`Cruise`]
/// for `seconds`, no traffic; the record and the ego's last position.
fn cruise(town: Town, route: &[Vec2], speed_mps: f32, seconds: f64) -> (RunRecord, Vec2) {
    let text = "[map]\nfile = \"x\"\n[route]\nfile = \"x\"\nid = \"0\"\n\
                [traffic]\nvehicles = 0\npedestrians = 0\n";
    let scenario = Scenario::from_toml_str(text, Path::new("kerbs.toml")).unwrap();
    let prepared = Prepared {
        town: Arc::new(town),
        route: route_through(&dense(route)),
        route_file: "kerbs".into(),
    };
    let mut driver = Cruise { speed_mps };
    let mut selector = Fixed { scale: 1.0 };
    let mut last = Moments::last();
    let record = runner::run(
        &scenario,
        Path::new("kerbs.toml"),
        RunInputs {
            prepared: &prepared,
            driver: &mut driver,
            selector: &mut selector,
            camera: None,
            observers: vec![&mut last],
            max_ticks: Some((seconds / 0.025).round() as u64),
        },
    )
    .unwrap();
    let at = last.kept[0].actors[0].position.truncate();
    (record, at)
}

/// The polyline `points` with a point every metre (the route monitor measures from
/// the route's points).
fn dense(points: &[Vec2]) -> Vec<Vec2> {
    let mut out = vec![points[0]];
    for w in points.windows(2) {
        let n = w[0].distance(w[1]).ceil().max(1.0) as usize;
        out.extend((1..=n).map(|k| w[0].lerp(w[1], k as f32 / n as f32)));
    }
    out
}

fn count(r: &RunRecord, kind: InfractionKind) -> u32 {
    r.result.counts.get(&kind).copied().unwrap_or(0)
}

/// A straight lane along +x at y = 0 from x = 0 to 200, nothing else.
fn one_lane() -> Town {
    let pts: Vec<Vec2> = (0..=200).map(|x| Vec2::new(x as f32, 0.0)).collect();
    Town {
        lanes: vec![lane_through(&pts)],
        bounds: (Vec2::new(0.0, -20.0), Vec2::new(200.0, 20.0)),
        ..Town::empty("one lane")
    }
}

#[test]
fn a_car_drifting_into_a_kerb_at_a_shallow_angle_rides_onto_the_sidewalk_and_keeps_going() {
    // The test town's eastbound lane is at y = -1.75, its kerb at y = -3.5, the sidewalk
    // 2.5 m wide and 0.15 m high. The route leaves the lane at about 6 degrees.
    let town = testtown::grid(3, 1, 100.0);
    let route = [Vec2::new(15.0, -1.75), Vec2::new(65.0, -7.0)];
    let (r, at) = cruise(town, &route, 5.0, 9.0);
    // Both axles' climbs are recorded; the mount is one static collision as the
    // paper's scorer counts (the sidewalk is map geometry, CARLA's actor 0) and none
    // as leaderboard 1.0 counts (sidewalk contacts dropped).
    let ups: Vec<bool> = r
        .result
        .contacts
        .iter()
        .filter(|t| t.what == "kerb up")
        .map(|t| t.kerb.expect("a kerb touch").front_axle)
        .collect();
    assert_eq!(ups, [true, false], "{:?}", r.result.contacts);
    assert_eq!(
        count(&r, InfractionKind::CollisionStatic),
        1,
        "{:?}",
        r.result.infractions
    );
    assert_eq!(r.result.collisions["paper"].static_, 1);
    assert_eq!(r.result.collisions["leaderboard-1.0"].total(), 0);
    assert!(at.y < -3.5, "the car is up on the sidewalk: {at}");
    assert!(at.x > 45.0, "and kept going: {at}");
    assert_eq!(
        count(&r, InfractionKind::OnSidewalk),
        1,
        "{:?}",
        r.result.infractions
    );
    assert!(
        r.result.outside_lane_pct > 10.0,
        "{}",
        r.result.outside_lane_pct
    );
    assert!(
        r.result.driving_score < r.result.completion_pct,
        "the outside share comes off the score: {} of {}",
        r.result.driving_score,
        r.result.completion_pct
    );
}

#[test]
fn a_car_driven_square_into_a_building_wall_records_one_static_collision() {
    // A wall across the lane at x = 60; the car reaches 5 m/s well before it.
    let mut town = one_lane();
    town.buildings.push(Building {
        footprint: vec![
            Vec2::new(60.0, -10.0),
            Vec2::new(70.0, -10.0),
            Vec2::new(70.0, 10.0),
            Vec2::new(60.0, 10.0),
        ],
        height_m: 10.0,
    });
    let (r, at) = cruise(
        town,
        &[Vec2::new(20.0, 0.0), Vec2::new(150.0, 0.0)],
        5.0,
        20.0,
    );
    assert_eq!(
        count(&r, InfractionKind::CollisionStatic),
        1,
        "{:?}",
        r.result.infractions
    );
    let hit = r
        .result
        .infractions
        .iter()
        .find(|i| i.kind == InfractionKind::CollisionStatic)
        .unwrap();
    assert!((56.0..=58.0).contains(&hit.position[0]), "{hit:?}");
    assert!(at.x < 60.0 - 2.3, "the car stops at the wall: {at}");
    // Pressed against the wall, the contact goes on: repeats, but one collision
    // under either rule (the paper: one map actor; leaderboard 1.0: within 3 m).
    assert!(r.result.contacts.len() > 1, "{:?}", r.result.contacts);
    assert!(r.result.contacts.iter().all(|t| t.what == "building"));
    assert_eq!(r.result.collisions["leaderboard-1.0"].static_, 1);
}

#[test]
fn a_pole_still_counts_as_a_static_collision() {
    // A traffic light's pole in the middle of the lane at x = 60.
    let mut town = one_lane();
    town.lights.push(TrafficLight {
        od_id: "pole".into(),
        position: Vec3::new(60.0, 0.0, 0.0),
        heading: 0.0,
        head_height_m: 3.0,
        junction: None,
        group: 0,
        stop_lines: Vec::new(),
    });
    let (r, _) = cruise(
        town,
        &[Vec2::new(20.0, 0.0), Vec2::new(150.0, 0.0)],
        5.0,
        20.0,
    );
    assert_eq!(
        count(&r, InfractionKind::CollisionStatic),
        1,
        "{:?}",
        r.result.infractions
    );
    assert!(
        r.result.infractions[0]
            .detail
            .to_lowercase()
            .contains("pole"),
        "{:?}",
        r.result.infractions
    );
}
