//! Integration tests: NPC traffic on real maps (CARLA's towns, our generated towns).

use std::sync::Arc;
use world::map::generator::{GridTownParams, generate_grid_town};
use world::road::LanePath;
use world::testdata::carla_dir;
use world::traffic::{Traffic, TrafficConfig};
use world::{LaneIdx, LightController, LightIdx, LightTiming, LoadOptions, Town, load_xodr_str};

fn generated(p: GridTownParams) -> Arc<Town> {
    let xml = generate_grid_town(&p).unwrap();
    Arc::new(
        load_xodr_str(&xml, &p.name, &LoadOptions::default())
            .unwrap()
            .0,
    )
}

fn carla(test: &str, name: &str) -> Option<Arc<Town>> {
    let dir = carla_dir(test)?;
    Some(Arc::new(
        Town::from_xodr_file(dir.join(format!("{name}.xodr"))).unwrap(),
    ))
}

/// Total turn of a lane's heading from start to end (radians, absolute).
fn heading_change_rad(l: &world::DriveLane) -> f32 {
    let c = &l.centerline;
    let n = c.len();
    if n < 3 {
        return 0.0;
    }
    let d0 = (c[1] - c[0]).truncate();
    let d1 = (c[n - 1] - c[n - 2]).truncate();
    d0.perp_dot(d1).atan2(d0.dot(d1)).abs()
}

/// Every connecting lane of every junction and every curved road (turning
/// more than 0.5 rad), driven by one NPC from 20 m before its start (lights
/// green): it gets through without touching a curb. Returns the smallest
/// clearance to a static collider on the way (metres).
fn drive_every_turn(town: &Arc<Town>) -> f32 {
    let cfg = TrafficConfig {
        vehicles: 1,
        pedestrians: 0,
        seed: 1,
        ..Default::default()
    };
    let mut tr = Traffic::new(town.clone(), cfg, None);
    assert_eq!(tr.realised_vehicles(), 1);
    let id = tr.npcs()[0].id;
    let half = tr.config().vehicle.length_m * 0.5;
    let mut min_clearance = f32::INFINITY;
    let mut driven = 0;
    for turn in 0..town.lanes.len() {
        let l = &town.lanes[turn];
        if l.junction.is_none() && heading_change_rad(l) < 0.5 {
            continue;
        }
        let turn = LaneIdx(turn as u32);
        let Some(&approach) = l
            .predecessors
            .iter()
            .find(|p| town.lanes[p.0 as usize].junction.is_none())
            .or(l.predecessors.first())
        else {
            continue;
        };
        let len = town.lane(approach).length_m();
        let s = (len - 20.0).max(half + 0.5).min(len);
        let mut path = LanePath::new(approach, s);
        path.lanes.push_back(turn);
        tr.place_npc(0, path);
        let exit = tr.npcs()[0].path.lanes[2];
        let before = tr.stats();
        let mut through = false;
        let mut lane_min = f32::INFINITY;
        for _ in 0..(40 * 90) {
            tr.step(&[]);
            let c = tr.physics().static_clearance(id);
            let n = &tr.npcs()[0];
            lane_min = lane_min.min(c);
            let left_turn_lane = !n.path.lanes.contains(&turn);
            if left_turn_lane && (n.path.lane() != exit || n.path.s_m > half + 2.0) {
                through = true;
                break;
            }
        }
        min_clearance = min_clearance.min(lane_min);
        let after = tr.stats();
        assert_eq!(
            after.npc_static_collisions, before.npc_static_collisions,
            "{}: NPC touched a static collider turning through lane {} ({} -> {})",
            town.name, turn.0, approach.0, exit.0
        );
        assert_eq!(
            after.respawns(),
            before.respawns(),
            "{}: respawned",
            town.name
        );
        assert!(
            through,
            "{}: NPC did not get through lane {}",
            town.name, turn.0
        );
        driven += 1;
    }
    assert!(driven > 20, "{}: only {driven} junction lanes", town.name);
    min_clearance
}

#[test]
fn npcs_drive_every_turn_of_the_generated_towns_without_touching_a_curb() {
    for p in [
        GridTownParams::gen01(),
        GridTownParams::gen02(),
        GridTownParams::gen03(),
    ] {
        let town = generated(p);
        let c = drive_every_turn(&town);
        // The generated towns put curbs at the lane edges (3.5 m lanes, 2.16 m
        // cars: 0.67 m a side); in their 11.75 m left turns against an outer
        // curb the swinging front corner keeps about 0.08 m.
        assert!(c > 0.05, "{}: clearance to a curb {c} m", town.name);
    }
}

#[test]
fn npcs_drive_every_turn_of_carlas_towns_without_touching_a_curb() {
    for name in ["Town01", "Town02"] {
        let Some(town) = carla(
            "npcs_drive_every_turn_of_carlas_towns_without_touching_a_curb",
            name,
        ) else {
            return;
        };
        let c = drive_every_turn(&town);
        assert!(c > 0.1, "{name}: clearance to a curb {c} m");
    }
}

/// Two simulated minutes with 20 vehicles and 40 pedestrians under the real light controller.
fn soak_two_minutes(town: Arc<Town>, seed: u64) -> world::traffic::TrafficStats {
    let cfg = TrafficConfig {
        vehicles: 20,
        pedestrians: 40,
        seed,
        ..Default::default()
    };
    let mut lights = LightController::new(&town, LightTiming::default(), seed);
    let n = town.lights.len();
    let mut tr = Traffic::new(town, cfg, None);
    let mut states = Vec::new();
    for tick in 0..(40 * 120) {
        if tick > 0 {
            lights.step(f64::from(world::physics::DT_S));
        }
        states.clear();
        states.extend((0..n).map(|i| lights.state(LightIdx(i as u32))));
        tr.step(&states);
    }
    tr.stats()
}

fn assert_clean(name: &str, s: world::traffic::TrafficStats) {
    assert_eq!(s.npc_npc_collisions, 0, "{name}: {s:?}");
    assert_eq!(s.npc_red_runs, 0, "{name}: {s:?}");
    assert_eq!(s.npc_static_collisions, 0, "{name}: {s:?}");
    assert_eq!(s.npc_pedestrian_collisions, 0, "{name}: {s:?}");
    assert_eq!(s.pedestrian_vehicle_bumps, 0, "{name}: {s:?}");
    assert_eq!(s.respawns(), 0, "{name}: {s:?}");
}

#[test]
fn traffic_on_the_generated_towns_has_no_collisions_or_red_runs() {
    for p in [
        GridTownParams::gen01(),
        GridTownParams::gen02(),
        GridTownParams::gen03(),
    ] {
        let name = p.name.clone();
        assert_clean(&name, soak_two_minutes(generated(p), 1));
    }
}

#[test]
fn traffic_on_carlas_towns_has_no_collisions_or_red_runs() {
    for name in ["Town01", "Town02"] {
        let Some(town) = carla(
            "traffic_on_carlas_towns_has_no_collisions_or_red_runs",
            name,
        ) else {
            return;
        };
        assert_clean(name, soak_two_minutes(town, 1));
    }
}
