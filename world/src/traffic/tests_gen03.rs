//! Tests of the traffic world on gen03's multi-lane arterials and
//! roundabout: giving way on entry, reservations round a ring, lane changes.

use std::sync::Arc;

use super::*;
use crate::agents::VehicleControl;
use crate::agents::npc::{self, PlannedChange};
use crate::map::generator::{GridTownParams, generate_grid_town};
use crate::map::opendrive::{LoadOptions, load_xodr_str};
use crate::map::testtown::grid;
use crate::map::{LaneIdx, LightState, Town};
use crate::road::LanePath;

fn gen03() -> Arc<Town> {
    let xml = generate_grid_town(&GridTownParams::gen03()).unwrap();
    Arc::new(
        load_xodr_str(&xml, "gen03", &LoadOptions::default())
            .unwrap()
            .0,
    )
}

fn cfg(vehicles: usize) -> TrafficConfig {
    TrafficConfig {
        vehicles,
        pedestrians: 0,
        seed: 3,
        ..Default::default()
    }
}

/// A roundabout junction's ring lane and the entry that gives way to it.
fn ring_and_entry(t: &Town) -> (LaneIdx, LaneIdx) {
    t.junctions
        .iter()
        .find_map(|j| j.priorities.first().copied())
        .expect("gen03 has a roundabout")
}

#[test]
fn an_npc_entering_the_roundabout_gives_way_to_one_on_the_ring() {
    let t = gen03();
    let (ring, entry) = ring_and_entry(&t);
    let ring_road = t.lane(ring).predecessors[0];
    let street = t.lane(entry).predecessors[0];
    let mut tr = Traffic::new(t.clone(), cfg(2), None);
    let half = tr.config().vehicle.length_m * 0.5;
    // The entering car has the lower id, so its request is looked at first
    // (both start asking in the same tick): first come, first served would
    // let it in. Its front is 1 m before the entry, the ring car's 3 m.
    let street_len = t.lane(street).length_m();
    let mut path = LanePath::new(street, street_len - half - 1.0);
    path.lanes.push_back(entry);
    tr.place_npc(0, path);
    let ring_len = t.lane(ring_road).length_m();
    let mut path = LanePath::new(ring_road, ring_len - half - 3.0);
    path.lanes.push_back(ring);
    tr.place_npc(1, path);
    let no_lights: Vec<LightState> = Vec::new();
    tr.step(&no_lights);
    assert_eq!(tr.npcs()[1].reservation, Some(ring), "the ring goes first");
    assert_eq!(tr.npcs()[0].reservation, None, "the entry gives way");
    // The entering car waits until the ring car has passed, then goes.
    let mut entered = false;
    for _ in 0..(40 * 20) {
        tr.step(&no_lights);
        let ring_car = &tr.npcs()[1];
        let still_coming = ring_car.path.lane() == ring_road || ring_car.path.lane() == ring;
        if still_coming {
            assert_eq!(
                tr.npcs()[0].reservation,
                None,
                "entered across the ring car"
            );
        }
        if tr.npcs()[0].path.lane() == entry {
            entered = true;
            break;
        }
    }
    assert!(entered, "the entering car never entered");
    assert_eq!(tr.stats().npc_npc_collisions, 0);
}

#[test]
fn the_ego_gives_way_by_the_same_rule_and_npcs_give_way_to_it() {
    let t = gen03();
    let (ring, entry) = ring_and_entry(&t);
    let ring_road = t.lane(ring).predecessors[0];
    let ring_len = t.lane(ring_road).length_m();
    let mut tr = Traffic::new(t.clone(), cfg(1), None);
    let half = tr.config().vehicle.length_m * 0.5;
    // An NPC 3 m before the ring lane: the ego (0), about to enter, gives way.
    let mut path = LanePath::new(ring_road, ring_len - half - 3.0);
    path.lanes.push_back(ring);
    tr.place_npc(0, path);
    assert!(tr.must_give_way(entry, 0));
    assert!(
        tr.ego_must_wait_for(entry),
        "what the runner hands the expert"
    );
    // Far back on the street it would enter from: it does not.
    let street = t.lane(entry).predecessors[0];
    tr.place_npc(0, LanePath::new(street, 5.0));
    assert!(!tr.must_give_way(entry, 0));
    assert!(!tr.ego_must_wait_for(entry));
    // Holding the ring lane (a conflicting one), wherever it is: the ego waits.
    let id = tr.npcs()[0].id;
    tr.reservations.grant(ring, id);
    assert!(tr.ego_must_wait_for(entry));
    tr.reservations.release(ring, id);
    // The ego on the ring 3 m before the ring lane: an NPC gives way to it.
    let (p, yaw, z) = t.lane(ring_road).pose_at(ring_len - half - 3.0);
    tr.teleport_ego(EgoStart {
        position: p,
        z,
        yaw,
    });
    tr.step(&[]);
    assert!(tr.must_give_way(entry, id));
    // A lane nothing has priority over gives way to nothing.
    assert!(!tr.must_give_way(ring, id));
}

#[test]
fn a_reservation_is_given_back_on_a_path_that_comes_round_to_it_again() {
    // Two laps of the ring: the path holds each ring lane twice. Leaving a
    // junction lane gives its reservation back even though the path meets
    // it again a lap later; otherwise the car would hold it and never ask
    // for the next one.
    let t = gen03();
    let (ring, _) = ring_and_entry(&t);
    let mut lanes = vec![t.lane(ring).predecessors[0]];
    while lanes.len() < 16 {
        let through = ring_lane_after(&t, *lanes.last().unwrap());
        lanes.push(through);
        lanes.push(t.lane(through).successors[0]);
    }
    let mut tr = Traffic::new(t.clone(), cfg(1), None);
    let mut path = LanePath::new(lanes[0], 3.0);
    path.lanes.extend(lanes[1..].iter().copied());
    tr.place_npc(0, path);
    let no_lights: Vec<LightState> = Vec::new();
    let start = tr.npcs()[0].state.position;
    let mut travelled = 0.0;
    let mut last = start;
    for _ in 0..(40 * 20) {
        tr.step(&no_lights);
        let p = tr.npcs()[0].state.position;
        travelled += p.distance(last);
        last = p;
    }
    // A lap is about 75 m; at the ring's curve speed it drives more than one in 20 s.
    assert!(travelled > 80.0, "drove {travelled} m round the ring");
    assert_eq!(tr.stats().deadlocks, 0);
}

/// The ring lane of the junction after ring road `road`: the way on round
/// the ring (the lane with priority there).
fn ring_lane_after(t: &Town, road: LaneIdx) -> LaneIdx {
    *t.lane(road)
        .successors
        .iter()
        .find(|s| {
            let j = t
                .lane(**s)
                .junction
                .expect("a ring road ends in a junction");
            t.junctions[j.0 as usize]
                .priorities
                .iter()
                .any(|(h, _)| h == *s)
        })
        .expect("the ring goes on")
}

#[test]
fn four_cars_round_a_full_roundabout_are_let_move_together() {
    // One car at the end of each ring road, each going on round the ring:
    // each has no room on the ring road after its junction, where the next
    // car stands. Every one waits for the next; after 5 s of standing the
    // circle is granted its lanes and moves up together.
    let t = gen03();
    let (ring, _) = ring_and_entry(&t);
    let ring_roads: Vec<LaneIdx> = {
        let mut roads = vec![t.lane(ring).predecessors[0]];
        while roads.len() < 4 {
            let through = ring_lane_after(&t, *roads.last().unwrap());
            roads.push(t.lane(through).successors[0]);
        }
        roads
    };
    let mut tr = Traffic::new(t.clone(), cfg(4), None);
    let half = tr.config().vehicle.length_m * 0.5;
    for (k, &road) in ring_roads.iter().enumerate() {
        // Round the ring from here: ring road, the junction's ring lane, next ring road...
        let mut path = LanePath::new(road, t.lane(road).length_m() - half - 0.6);
        let mut at = road;
        for _ in 0..8 {
            let through = ring_lane_after(&t, at);
            at = t.lane(through).successors[0];
            path.lanes.push_back(through);
            path.lanes.push_back(at);
        }
        tr.place_npc(k, path);
    }
    let start: Vec<_> = tr.npcs().iter().map(|n| n.state.position).collect();
    let no_lights: Vec<LightState> = Vec::new();
    for _ in 0..(40 * 4) {
        tr.step(&no_lights);
    }
    // Gridlocked: nobody has moved.
    for (n, p) in tr.npcs().iter().zip(&start) {
        assert!(n.state.position.distance(*p) < 0.5, "NPC {} moved", n.id);
        assert_eq!(n.reservation, None);
    }
    for _ in 0..(40 * 26) {
        tr.step(&no_lights);
    }
    let s = tr.stats();
    assert!(s.gridlocks_broken >= 4, "{s:?}");
    assert_eq!((s.deadlocks, s.npc_npc_collisions), (0, 0), "{s:?}");
    for (n, p) in tr.npcs().iter().zip(&start) {
        assert!(
            n.state.position.distance(*p) > 5.0,
            "NPC {} still stands",
            n.id
        );
    }
}

/// An outer arterial lane that a neighbour beside it can leave by a way
/// it cannot (a left turn), and that way.
fn change_for_a_left_turn(t: &Town) -> PlannedChange {
    let exit_road = |l: LaneIdx| t.lane(t.lane(l).successors[0]).road_id.clone();
    t.lanes
        .iter()
        .enumerate()
        .filter(|(_, l)| l.junction.is_none() && l.length_m() > 55.0)
        .find_map(|(i, l)| {
            let from = LaneIdx(i as u32);
            let to = l.left?;
            let own: Vec<String> = l.successors.iter().map(|s| exit_road(*s)).collect();
            let then = *t
                .lane(to)
                .successors
                .iter()
                .find(|s| !own.contains(&exit_road(**s)))?;
            Some(PlannedChange { from, to, then })
        })
        .expect("an arterial lane with a left turn only from its neighbour")
}

#[test]
fn an_npc_changes_lanes_for_its_turn_when_the_lane_beside_is_free() {
    let t = gen03();
    let c = change_for_a_left_turn(&t);
    let mut tr = Traffic::new(t.clone(), cfg(1), None);
    tr.place_npc(0, LanePath::new(c.from, 6.0));
    tr.npcs[0].path = LanePath::new(c.from, 6.0);
    tr.npcs[0].change = Some(c);
    let no_lights: Vec<LightState> = Vec::new();
    let mut turned = false;
    for _ in 0..(40 * 20) {
        tr.step(&no_lights);
        if tr.npcs()[0].path.lane() == c.then {
            turned = true;
            break;
        }
    }
    assert!(turned, "it did not take the turn from the lane beside");
    let s = tr.stats();
    assert_eq!((s.lane_changes, s.lane_changes_given_up), (1, 0));
    assert_eq!(s.npc_static_collisions, 0);
}

#[test]
fn an_npc_gives_up_a_lane_change_while_a_car_is_beside_it() {
    let t = gen03();
    let c = change_for_a_left_turn(&t);
    let vp = crate::agents::VehicleParams::default();
    let half = vp.length_m * 0.5;
    // At rest 26 m of lane before the point where it must give a change up
    // (the give-up distance at rest), with the ego standing still beside it:
    // the lane beside has no room until it has pulled 10 m ahead, and by
    // then it has run out of road.
    let from = t.lane(c.from);
    let s0 = from.length_m() - half - 26.0;
    let beside = t.lane(c.to);
    let s = beside.project_near(from.pose_at(s0).0, s0, 5.0).unwrap();
    let (p, yaw, z) = beside.pose_at(s);
    let ego = EgoStart {
        position: p,
        z,
        yaw,
    };
    let mut tr = Traffic::new(t.clone(), cfg(1), Some(ego));
    tr.set_ego_control(VehicleControl::BRAKE);
    tr.place_npc(0, LanePath::new(c.from, s0));
    tr.npcs[0].path = LanePath::new(c.from, s0);
    tr.npcs[0].change = Some(c);
    let no_lights: Vec<LightState> = Vec::new();
    let own = &t.lane(c.from).successors;
    let mut went_on = None;
    for _ in 0..(40 * 20) {
        tr.step(&no_lights);
        if went_on.is_none() && tr.stats().lane_changes_given_up == 1 {
            // Given up: the path goes on from its own lane.
            let n = &tr.npcs()[0];
            assert_eq!(n.path.lane(), c.from);
            went_on = Some(n.path.lanes[1]);
        }
    }
    let s = tr.stats();
    assert_eq!((s.lane_changes, s.lane_changes_given_up), (0, 1));
    assert_eq!(s.npc_npc_collisions, 0);
    let next = went_on.expect("given up");
    assert!(
        own.contains(&next),
        "went on into {next:?}, not a way from its lane"
    );
    assert!(
        !tr.npcs()[0].path.lanes.contains(&c.then),
        "it took the turn anyway"
    );
}

#[test]
fn on_roads_of_one_lane_each_way_planning_draws_what_extending_draws() {
    use rand::SeedableRng;
    let t = grid(3, 3, 60.0);
    for seed in 0..20u64 {
        let start = LaneIdx((seed % t.lanes.len() as u64) as u32);
        let mut a = LanePath::new(start, 0.0);
        let mut b = a.clone();
        let mut ra = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut rb = ra.clone();
        let mut change = None;
        npc::extend_path(&t, &mut a, &mut ra, 300.0);
        npc::extend_path_planning(&t, &mut b, &mut rb, 300.0, &mut change);
        assert_eq!(a, b);
        assert_eq!(change, None);
        assert_eq!(ra, rb, "the random streams diverged");
    }
}
