//! The four cases that tell the counting rules apart (docs/protocol.md §3,
//! issue 47), each driven through the world on a hand-made town: the world's
//! physics makes the contacts, [`EgoContact::between`] hands the ego's side to
//! the collision monitor as the runner does, and each rule counts the touches.
//!
//! | case | `paper` | `leaderboard-1.0` | the rule it pins |
//! | --- | --- | --- | --- |
//! | a kerb mount | 1 static | 0 | sidewalk contacts: counted / dropped |
//! | a kerb, then two buildings | 1 static | 2 static | map geometry is one actor / located, never blocked by id |
//! | the same car hit again 9.6 s and 80 m on | 1 vehicle | 2 vehicles | each actor once / the id blocked for 5 s only |
//! | a walker walking into the standing ego | 1 pedestrian | 1 pedestrian | no speed gate under either |

use std::sync::Arc;

use world::agents::{VehicleControl, VehicleParams};
use world::map::testtown::{grid, lane_through};
use world::physics::{DT_S, Physics};
use world::road::LanePath;
use world::traffic::{EgoStart, Traffic, TrafficConfig};
use world::{ActorKind, Building, EgoPose, LaneIdx, LightState, Town, Vec2, Vec3};

use super::collision::CollisionMonitor;
use super::contacts::{Touch, TouchWith};
use super::counting::{CollisionCounts, CountingRule};
use super::{EgoContact, EgoTick, Infraction, InfractionKind, Monitor};

/// Full throttle, wheels straight.
const GO: VehicleControl = VehicleControl {
    steer: 0.0,
    throttle: 1.0,
    brake: 0.0,
};

/// The traffic world stepped tick by tick with the ego under a test's control,
/// its contacts fed to a collision monitor as the runner feeds them.
struct Drive {
    traffic: Traffic,
    monitor: CollisionMonitor,
    infractions: Vec<Infraction>,
    tick: u64,
    /// Every light green.
    lights: Vec<LightState>,
}

impl Drive {
    /// `town` with `vehicles` NPCs (placed by the test), no walkers, the ego at `start`.
    fn new(town: Town, start: EgoStart, vehicles: usize) -> Drive {
        let cfg = TrafficConfig {
            vehicles,
            pedestrians: 0,
            ..Default::default()
        };
        let lights = vec![LightState::Green; town.lights.len()];
        Drive {
            lights,
            traffic: Traffic::new(Arc::new(town), cfg, Some(start)),
            monitor: CollisionMonitor::default(),
            infractions: Vec::new(),
            tick: 0,
        }
    }

    fn pose(&self) -> EgoPose {
        let e = self.traffic.ego().expect("the ego");
        EgoPose {
            position: e.state.position.extend(e.z),
            heading: e.state.yaw,
        }
    }

    /// One tick with the ego under `control`, every light green.
    fn step(&mut self, control: VehicleControl) {
        let prev = self.pose();
        self.traffic.set_ego_control(control);
        let contacts: Vec<EgoContact> = self
            .traffic
            .step(&self.lights)
            .iter()
            .filter_map(|e| EgoContact::between(e.a, e.b))
            .collect();
        self.tick += 1;
        let e = self.traffic.ego().expect("the ego");
        let v = &self.traffic.config().vehicle;
        let tick = EgoTick {
            tick: self.tick,
            time_s: self.tick as f64 * f64::from(DT_S),
            prev,
            now: self.pose(),
            speed_mps: e.state.speed_mps,
            size_m: (v.length_m, v.width_m),
            throttle: control.throttle,
            contacts: &contacts,
            kerbs: &e.kerbs,
            route_progress_m: 0.0,
            lights: &self.lights,
            dt_s: f64::from(DT_S),
        };
        self.monitor.observe(&tick, &mut self.infractions);
    }

    fn touches(&self) -> &[Touch] {
        self.monitor.touches()
    }

    fn count(&self, rule: CountingRule) -> CollisionCounts {
        rule.count(self.touches())
    }
}

/// A rectangle standing on the ground from `lo` to `hi` (metres), 10 m tall.
fn block(lo: Vec2, hi: Vec2) -> Building {
    Building {
        footprint: vec![lo, Vec2::new(hi.x, lo.y), hi, Vec2::new(lo.x, hi.y)],
        height_m: 10.0,
    }
}

/// The grid test town's eastbound lane (y = -1.75) has its kerb at y = -3.5, a
/// 0.15 m step up to a 2.5 m sidewalk. A car started at (30, -1.75) heading
/// `yaw` (radians, below 0: drifting right) at full throttle.
fn drifting(town: Town, yaw: f32) -> Drive {
    let start = EgoStart {
        position: Vec2::new(30.0, -1.75),
        z: 0.0,
        yaw,
    };
    Drive::new(town, start, 0)
}

fn kinds(d: &Drive) -> Vec<(TouchWith, &str)> {
    d.touches()
        .iter()
        .map(|t| (t.with, t.what.as_str()))
        .collect()
}

#[test]
fn a_kerb_mount_is_one_static_collision_for_the_paper_and_none_for_leaderboard_1_0() {
    let mut d = drifting(grid(3, 1, 100.0), -0.25);
    while d.touches().len() < 2 && d.tick < 400 {
        d.step(GO);
    }
    for (t, front) in d.touches().iter().zip([true, false]) {
        let k = t.kerb.expect("a kerb touch");
        assert_eq!((t.with, t.what.as_str()), (TouchWith::Kerb, "kerb up"));
        assert_eq!(k.front_axle, front);
        assert!((k.height_m - 0.15).abs() < 1e-4);
        assert!(k.speed_mps.1 < k.speed_mps.0, "{k:?}");
    }
    assert_eq!(d.touches().len(), 2, "{:?}", d.touches());
    let kinds: Vec<InfractionKind> = d.infractions.iter().map(|i| i.kind).collect();
    assert_eq!(kinds, [InfractionKind::CollisionStatic]);
    assert_eq!(d.count(CountingRule::Paper).static_, 1);
    assert_eq!(d.count(CountingRule::Leaderboard1).total(), 0);
}

#[test]
fn a_kerb_and_two_buildings_are_one_static_collision_for_the_paper() {
    // Up the kerb and into a building standing on the sidewalk. Our cars do
    // not reverse, so the ego is then lifted back onto its lane (as a tow
    // would) and driven into a second building across the road 20 m on.
    let mut town = grid(3, 1, 100.0);
    town.buildings
        .push(block(Vec2::new(60.0, -9.0), Vec2::new(62.0, -3.6)));
    town.buildings
        .push(block(Vec2::new(80.0, -3.4), Vec2::new(82.0, -0.2)));
    let mut d = drifting(town, -0.08);
    let mut towed = false;
    for _ in 0..(20.0 / DT_S) as usize {
        let e = d.traffic.ego().unwrap().state;
        let on_first = d.touches().iter().any(|t| t.what == "building");
        if on_first && !towed && e.speed_mps < 0.1 {
            d.traffic.teleport_ego(EgoStart {
                position: Vec2::new(64.0, -1.75),
                z: 0.0,
                yaw: 0.0,
            });
            towed = true;
        }
        d.step(VehicleControl {
            throttle: if e.speed_mps < 5.0 { 0.7 } else { 0.0 },
            ..GO
        });
    }
    let what = kinds(&d);
    assert_eq!(what[0], (TouchWith::Kerb, "kerb up"), "{what:?}");
    let buildings: Vec<[f32; 2]> = d
        .touches()
        .iter()
        .filter(|t| t.what == "building")
        .map(|t| t.position)
        .collect();
    assert!(
        buildings.iter().any(|p| p[0] < 60.0) && buildings.iter().any(|p| p[0] > 70.0),
        "both buildings touched: {:?}",
        d.touches()
    );
    assert_eq!(
        d.count(CountingRule::Paper),
        CollisionCounts {
            static_: 1,
            ..Default::default()
        }
    );
    assert_eq!(
        d.count(CountingRule::Leaderboard1),
        CollisionCounts {
            static_: 2,
            ..Default::default()
        },
        "{:?}",
        d.touches()
    );
}

/// A straight one-lane road along +x at y = 0 from x = 0 to `length_m`.
fn long_road(length_m: u32) -> Town {
    let pts: Vec<Vec2> = (0..=length_m).map(|x| Vec2::new(x as f32, 0.0)).collect();
    Town {
        lanes: vec![lane_through(&pts)],
        bounds: (Vec2::new(0.0, -20.0), Vec2::new(length_m as f32, 20.0)),
        ..Town::empty("long road")
    }
}

#[test]
fn the_same_car_hit_again_after_6_s_counts_for_leaderboard_1_0_only() {
    // An NPC starts 25 m ahead of the ego and drives at the speed limit; the
    // ego, at full throttle, runs into its back, brakes for 3 s, and runs into
    // it again farther down the road.
    let mut d = Drive::new(
        grid(3, 1, 400.0),
        EgoStart {
            position: Vec2::new(12.0, -1.75),
            z: 0.0,
            yaw: 0.0,
        },
        1,
    );
    d.traffic.place_npc(0, LanePath::new(LaneIdx(0), 30.0));
    let npc = d.traffic.npcs()[0].id;
    let hits = |d: &Drive| {
        d.touches()
            .iter()
            .filter(|t| t.with == TouchWith::Vehicle && !t.repeat)
            .count()
    };
    let mut brake_until = None;
    while d.tick < (40.0 / DT_S) as u64 && hits(&d) < 2 {
        let braking = brake_until.is_some_and(|until| d.tick < until);
        d.step(if braking { VehicleControl::BRAKE } else { GO });
        if hits(&d) == 1 && brake_until.is_none() {
            brake_until = Some(d.tick + (3.0 / DT_S) as u64);
        }
    }
    let first: Vec<&Touch> = d
        .touches()
        .iter()
        .filter(|t| t.with == TouchWith::Vehicle && !t.repeat)
        .collect();
    assert_eq!(first.len(), 2, "{:?}", d.touches());
    assert!(first.iter().all(|t| t.actor == Some(npc)));
    let (a, b) = (first[0], first[1]);
    assert!(b.time_s - a.time_s > 6.0, "{a:?} {b:?}");
    assert!(b.position[0] - a.position[0] > 5.0, "{a:?} {b:?}");
    assert_eq!(d.count(CountingRule::Paper).vehicle, 1);
    assert_eq!(d.count(CountingRule::Leaderboard1).vehicle, 2);
}

#[test]
fn a_walker_walking_into_the_standing_ego_counts_under_both_rules() {
    // Our walkers stop short of a vehicle's body (`Pedestrian::decide`), as
    // CARLA's walker AI does; a scenario's scripted walker does not. So the
    // walker here is moved by the physics alone, across the road into the
    // side of the ego, which stands braked on its lane.
    let town = long_road(100);
    let vp = VehicleParams::default();
    let mut physics = Physics::new(&town);
    let at = Vec2::new(30.0, 0.0);
    physics.add_vehicle(
        0,
        ActorKind::Ego,
        Vec3::new(vp.length_m, vp.width_m, vp.height_m),
        at,
        0.0,
        0.0,
    );
    let walker = 7;
    let mut p = Vec2::new(30.0, 6.0);
    physics.add_pedestrian(walker, p, 0.0);
    let pose = EgoPose {
        position: at.extend(0.0),
        heading: 0.0,
    };
    let mut monitor = CollisionMonitor::default();
    let mut out = Vec::new();
    for tick in 1..=200u64 {
        p.y -= 1.4 * DT_S;
        p = physics
            .move_actor(walker, p, -std::f32::consts::FRAC_PI_2)
            .position;
        let contacts: Vec<EgoContact> = physics
            .end_tick()
            .iter()
            .filter_map(|e| EgoContact::between(e.a, e.b))
            .collect();
        monitor.observe(
            &EgoTick {
                tick,
                time_s: tick as f64 * f64::from(DT_S),
                prev: pose,
                now: pose,
                speed_mps: 0.0,
                size_m: (vp.length_m, vp.width_m),
                throttle: 0.0,
                contacts: &contacts,
                kerbs: &[],
                route_progress_m: 0.0,
                lights: &[],
                dt_s: f64::from(DT_S),
            },
            &mut out,
        );
    }
    let touches = monitor.touches();
    assert!(!touches.is_empty(), "the walker reached the ego");
    assert!(
        touches.iter().all(|t| t.with == TouchWith::Pedestrian
            && t.actor == Some(walker)
            && t.speed_mps == 0.0),
        "{touches:?}"
    );
    assert!(p.y > 0.0, "the ego's body stopped the walker: {p}");
    for rule in CountingRule::ALL {
        assert_eq!(
            rule.count(touches),
            CollisionCounts {
                pedestrian: 1,
                ..Default::default()
            },
            "{}",
            rule.name()
        );
    }
    assert_eq!(out.len(), 1, "{out:?}");
}
