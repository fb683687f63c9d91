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

/// Our generated towns gen01-gen03 and CARLA's towns `carla_names`, by name
/// (for a test that has found `../shared/carla/`).
fn our_towns_and(test: &str, carla_names: &[&str]) -> Vec<(String, Arc<Town>)> {
    let mut towns: Vec<(String, Arc<Town>)> = [
        GridTownParams::gen01(),
        GridTownParams::gen02(),
        GridTownParams::gen03(),
    ]
    .into_iter()
    .map(|p| (p.name.clone(), generated(p)))
    .collect();
    for name in carla_names {
        let town = carla(test, name).expect("CARLA's towns are there");
        towns.push((name.to_string(), town));
    }
    towns
}

/// Traffic of one NPC and no walkers (seed 1), to place where a test wants it.
fn one_npc(town: &Arc<Town>) -> Traffic {
    let cfg = TrafficConfig {
        vehicles: 1,
        pedestrians: 0,
        seed: 1,
        ..Default::default()
    };
    Traffic::new(town.clone(), cfg, None)
}

/// Every connecting lane of every junction and every curved road (turning
/// more than 0.5 rad), driven by one NPC from 20 m before its start (lights
/// green): it gets through without touching a curb. Returns the smallest
/// clearance to a static collider on the way (metres).
fn drive_every_turn(town: &Arc<Town>) -> f32 {
    let mut tr = one_npc(town);
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
    soak(town, seed, 120).stats()
}

/// 20 vehicles and 40 walkers (`seed`) driven `seconds` under the town's cycling lights.
fn soak(town: Arc<Town>, seed: u64, seconds: u32) -> Traffic {
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
    for tick in 0..(40 * seconds) {
        if tick > 0 {
            lights.step(f64::from(world::physics::DT_S));
        }
        states.clear();
        states.extend((0..n).map(|i| lights.state(LightIdx(i as u32))));
        tr.step(&states);
    }
    tr
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

/// The first lane of `road` lane `od` that `keep` accepts (`what` names it if none does).
fn find_lane(
    town: &Town,
    road: &str,
    od: i32,
    what: &str,
    keep: impl Fn(&world::DriveLane) -> bool,
) -> LaneIdx {
    let i = town
        .lanes
        .iter()
        .position(|l| l.road_id == road && l.od_lane == od && keep(l))
        .unwrap_or_else(|| panic!("road {road} lane {od}: no {what}"));
    LaneIdx(i as u32)
}

/// The connecting lane of `road` lane `od` whose centreline passes within 1 m of `near`.
fn piece_near(town: &Town, road: &str, od: i32, near: glam::Vec2) -> LaneIdx {
    find_lane(town, road, od, "piece there", |l| {
        l.centerline
            .iter()
            .any(|p| (p.truncate() - near).length() < 1.0)
    })
}

/// The connecting lane of `road` lane `od` entered from outside its junction.
fn entry_piece(town: &Town, road: &str, od: i32) -> LaneIdx {
    find_lane(town, road, od, "entry", |l| {
        l.junction.is_some()
            && l.predecessors
                .iter()
                .all(|p| town.lanes[p.0 as usize].junction != l.junction)
    })
}

#[test]
fn a_connecting_road_in_many_sections_conflicts_as_one_movement() {
    // Town06's junction 281: connecting road 317 (lane 2, southbound) is drawn in
    // 14 lane sections; its fifth crosses road 344 (lane 5, westbound) near
    // (-8.9, 22.5). A car reserves the first piece of each; before the two
    // counted as one movement, the first pieces did not conflict, both cars were
    // let in, and they met (the NPC-NPC collisions of the soaks there).
    let Some(town) = carla(
        "a_connecting_road_in_many_sections_conflicts_as_one_movement",
        "Town06",
    ) else {
        return;
    };
    let conflicts = world::rules::JunctionConflicts::new(&town);
    let south = entry_piece(&town, "317", 2);
    let west = entry_piece(&town, "344", 5);
    let crossing = piece_near(&town, "317", 2, glam::Vec2::new(-8.88, 22.5));
    let movement = world::rules::conflicts::movement(&town, south);
    assert!(
        movement.len() > 5 && movement.contains(&crossing),
        "{movement:?}"
    );
    assert!(conflicts.of(south).contains(&west));
    assert!(conflicts.of(west).contains(&south));
    // The way out is the first lane after the junction, not the next piece.
    let out = world::rules::conflicts::movement_exit(&town, south);
    assert!(town.lanes[out.0 as usize].junction.is_none());
    // An NPC driving it holds its reservation of the first piece across the
    // crossing piece (it let go two pieces in before), and lets go once out (it
    // may hold the next junction's lane by then).
    let mut tr = one_npc(&town);
    let approach = town.lanes[south.0 as usize].predecessors[0];
    let len = town.lane(approach).length_m();
    let mut path = LanePath::new(approach, (len - 20.0).max(3.0));
    path.lanes.push_back(south);
    tr.place_npc(0, path);
    let (mut on_crossing, mut out_free) = (None, None);
    for _ in 0..(20 * 60) {
        tr.step(&[]);
        let n = &tr.npcs()[0];
        if n.path.lane() == crossing && on_crossing.is_none() {
            on_crossing = Some(n.reservation);
        }
        if town.lanes[n.path.lane().0 as usize].junction.is_none()
            && on_crossing.is_some()
            && n.path.s_m > 6.0
        {
            out_free = Some(n.reservation);
            break;
        }
    }
    assert_eq!(
        on_crossing,
        Some(Some(south)),
        "the NPC never got onto the crossing piece"
    );
    let out = out_free.expect("the NPC never left the junction");
    assert_ne!(out, Some(south));
}

#[test]
fn a_sweep_follows_a_chain_of_short_pieces_so_parallel_movements_do_not_conflict() {
    // Town06's junction 508: road 20's lanes -3 and -4 go on into connecting roads 540
    // and 531, side by side (3.48 m apart at their closest), each drawn in pieces of a
    // few tenths of a metre. A piece was swept along itself and one successor, so the
    // sweeping car ran off that short path's end, steered for it and crossed the lane
    // beside: every lane of the approach conflicted with its neighbours and one car
    // turned per green (stops of over 60 s, docs/rule-book.md).
    let Some(town) = carla(
        "a_sweep_follows_a_chain_of_short_pieces_so_parallel_movements_do_not_conflict",
        "Town06",
    ) else {
        return;
    };
    let conflicts = world::rules::JunctionConflicts::new(&town);
    let left = entry_piece(&town, "540", -3);
    let right = entry_piece(&town, "531", -4);
    assert!(
        !conflicts.of(left).contains(&right),
        "{:?}",
        conflicts.of(left)
    );
    assert!(!conflicts.of(right).contains(&left));
    // Every piece's sweep stays on its movement (or the lane after it).
    let vp = world::agents::VehicleParams::default();
    for entry in [left, right] {
        let movement = world::rules::conflicts::movement(&town, entry);
        assert!(movement.len() > 5, "{movement:?}");
        let exit = world::rules::conflicts::movement_exit(&town, entry);
        let on: Vec<glam::Vec2> = movement
            .iter()
            .chain([&exit])
            .flat_map(|l| town.lane(*l).centerline.iter().map(|p| p.truncate()))
            .collect();
        for &piece in &movement {
            let sweep = world::rules::conflicts::lane_sweep(&town, &vp, 3.0, piece);
            for (p, _) in &sweep.poses {
                let off = on
                    .iter()
                    .map(|q| (*q - *p).length())
                    .fold(f32::INFINITY, f32::min);
                assert!(off < 1.0, "piece #{} swept {off:.2} m off at {p}", piece.0);
            }
        }
    }
}

#[test]
fn a_car_on_a_road_shorter_than_its_release_gives_back_the_junction_behind_it() {
    // Town03's road 14 is 6.4 m between junctions 685 and 678. A car that came out of
    // 685 and waits at 678's entry had its rear less than a metre past 685, so it kept
    // 685's lane, and could not ask for 678's (one reservation at a time): it stood
    // there holding #715 while the cars asking for #715 stood behind it (seed 1: from
    // 80 s on, 779 s by 800 s). Now a car whose rear has left its junction gives it
    // back once it stands at the next junction's entry.
    let Some(town) = carla(
        "a_car_on_a_road_shorter_than_its_release_gives_back_the_junction_behind_it",
        "Town03",
    ) else {
        return;
    };
    let tr = soak(town.clone(), 1, 180);
    let stuck: Vec<String> = tr
        .incidents()
        .iter()
        .filter(|i| i.kind == world::traffic::IncidentKind::Deadlock)
        .filter(|i| {
            i.a.reservation.is_some() && i.a.lane.as_ref().is_some_and(|l| l.junction.is_none())
        })
        .map(|i| i.to_string())
        .collect();
    assert!(stuck.is_empty(), "{stuck:#?}");
}

#[test]
fn a_car_waits_clear_of_a_turn_that_swings_over_its_usual_place() {
    // Town03's junction 813: the right turn of road 822 swings its body over the lane
    // of road 22 where cars wait to enter #815 (road 817); they wait 1.5 m further
    // back. Town01, Town02 and our towns have no such place: every car waits where it
    // did, so their traffic is unchanged.
    let test = "a_car_waits_clear_of_a_turn_that_swings_over_its_usual_place";
    let Some(town03) = carla(test, "Town03") else {
        return;
    };
    let conflicts = world::rules::JunctionConflicts::new(&town03);
    let entry = entry_piece(&town03, "817", -1);
    assert!(conflicts.hold_back_m(entry) > 0.0);
    for (name, town) in our_towns_and(test, &["Town01", "Town02"]) {
        let c = world::rules::JunctionConflicts::new(&town);
        let held: Vec<usize> = (0..town.lanes.len())
            .filter(|&i| c.hold_back_m(LaneIdx(i as u32)) > 0.0)
            .collect();
        assert!(held.is_empty(), "{name}: {held:?}");
    }
}

#[test]
fn a_car_through_a_junction_sees_the_next_across_a_road_of_several_sections() {
    // Town03's junctions 595 and 524 are 3.5 m apart, over two lane sections
    // (road 11, then road 38). A car coming through 595 at 7 m/s looked for 524's
    // lane only once out of 595, 6 m before 524's entry: too late to stop where it
    // waits (`hold_back_m`), it braked to a stand 0.7 m into the swing of 524's turn
    // on road 526 and was struck (seed 3's soak, 868 s). From inside 595 it now sees
    // 524's entry over both sections (`npc::chained_junction_lane`).
    let test = "a_car_through_a_junction_sees_the_next_across_a_road_of_several_sections";
    let Some(town) = carla(test, "Town03") else {
        return;
    };
    let road_lane =
        |road: &str, od: i32| find_lane(&town, road, od, "road", |l| l.junction.is_none());
    let (road11, road38) = (road_lane("11", -5), road_lane("38", -5));
    assert_eq!(town.lane(road11).successors, vec![road38]);
    let next = *town
        .lane(road38)
        .successors
        .first()
        .expect("road 38 leads into junction 524");
    let into_11 = *town
        .lane(road11)
        .predecessors
        .first()
        .expect("road 11 is entered from junction 595");
    assert!(town.lane(into_11).junction.is_some() && town.lane(next).junction.is_some());
    let mut tr = one_npc(&town);
    let mut path = LanePath::new(into_11, 0.0);
    path.lanes.extend([road11, road38, next]);
    tr.place_npc(0, path);
    let vp = tr.config().vehicle;
    let conflicts = world::rules::JunctionConflicts::new(&town);
    let (lane, d) =
        world::agents::npc::chained_junction_lane(&town, &conflicts, &tr.npcs()[0], &vp)
            .expect("524's lane seen from inside 595");
    let link_m = town.lane(road11).length_m() + town.lane(road38).length_m();
    assert!(link_m < world::agents::npc::chained_link_m(&conflicts, &vp, next));
    let want = town.lane(into_11).length_m() + link_m - vp.length_m * 0.5;
    assert_eq!(lane, next);
    assert!((d - want).abs() < 1e-3, "{d} m to the entry, want {want}");
}

#[test]
fn no_walker_stands_in_a_driving_lane() {
    // Where a junction's connecting roads overlap, one road's sidewalk lane can run
    // across another's turn: Town03's junction 793 had a walk node 1.7 m from road
    // 806's lane centre (3.5 m wide). A walker waiting there to cross held up the
    // car turning through it, and waited for that car (seed 1: the car and the four
    // queued behind it stood for the rest of the hour once the chained junctions
    // changed the traffic). The walk graph keeps no node where a walker's body would
    // be in a lane; Town01's, Town02's and our towns' graphs have none such.
    let test = "no_walker_stands_in_a_driving_lane";
    let Some(town03) = carla(test, "Town03") else {
        return;
    };
    let mut towns = our_towns_and(test, &["Town01", "Town02", "Town04"]);
    towns.push(("Town03".into(), town03));
    for (name, town) in towns {
        let g = world::agents::pedestrian::WalkGraph::new(&town, &Default::default());
        let lanes = world::rules::LaneGrid::new(&town, 8.0);
        let radius = world::physics::PEDESTRIAN_RADIUS_M;
        let in_lane: Vec<_> = g
            .nodes
            .iter()
            .filter(|n| lanes.within_any_lane(&town, n.position, radius))
            .map(|n| n.position)
            .collect();
        assert!(
            in_lane.is_empty(),
            "{name}: walk nodes in a lane at {in_lane:?}"
        );
        assert!(g.nodes.len() > 500, "{name}: {} walk nodes", g.nodes.len());
    }
}
