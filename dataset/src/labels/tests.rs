//! Hand-made situations with known answers, on the test town's grid of
//! two-way roads (junctions every 100 m, lanes 3.5 m wide, right-hand
//! traffic, stop lines 4 m before each lit junction).

use super::*;
use crate::action::{NUM_STEERS, index};
use world::map::testtown::{JUNCTION_HALF_M, LANE_WIDTH_M, STOP_LINE_BACK_M, grid};

const BLOCK_M: f32 = 100.0;
const RED: u8 = 0;
const GREEN: u8 = 2;

/// The ego driving east on the right-hand lane of the road y = 0, at `x`.
fn east_at(x: f32) -> EgoRow {
    EgoRow {
        x,
        y: -LANE_WIDTH_M / 2.0,
        yaw: 0.0,
        speed: 5.0,
    }
}

struct Situation {
    town: world::Town,
    labeller: Labeller,
    actors: Vec<ActorRow>,
    lights: Vec<u8>,
}

impl Situation {
    fn new(state: u8) -> Situation {
        let town = grid(3, 3, BLOCK_M);
        let labeller = Labeller::wor(&town, &VehicleParams::default());
        let lights = vec![state; town.lights.len()];
        Situation {
            town,
            labeller,
            actors: Vec::new(),
            lights,
        }
    }

    fn label(&self, ego: EgoRow, hazards: Hazards) -> Q {
        let steps = self.labeller.steps + 1;
        let actors: Vec<&[ActorRow]> = vec![&self.actors; steps];
        let lights: Vec<&[u8]> = vec![&self.lights; steps];
        let input = FrameInput {
            ego,
            actors: &actors,
            lights: &lights,
            hazards,
            lane: None,
        };
        self.labeller.label(&self.town, &input, &[0.0])[0]
    }
}

fn best(q: &[f32; NUM_ACTIONS]) -> usize {
    (0..NUM_ACTIONS).fold(0, |b, a| if q[a] > q[b] { a } else { b })
}

fn steer_bin(a: usize) -> usize {
    a % NUM_STEERS
}

#[test]
fn an_empty_straight_lane_is_driven_straight_towards_the_target_speed() {
    let s = Situation::new(GREEN);
    let q = s.label(east_at(40.0), Hazards::default());
    let follow = &q[Command::LaneFollow as usize];
    for (b, values) in follow.iter().enumerate() {
        assert_ne!(best(values), BRAKE, "bin {b}: {values:?}");
        let steer = expected_steer(values);
        assert!(steer.abs() < 0.05, "bin {b} steers {steer}: {values:?}");
    }
    // Slow: full throttle; above the 6.5 m/s target: less throttle.
    assert_eq!(best(&follow[0]) / NUM_STEERS, 2, "{:?}", follow[0]);
    assert!(best(&follow[3]) / NUM_STEERS < 2, "{:?}", follow[3]);
    // Off the road (the other side of the kerb) nothing is worth anything.
    let off = s.label(
        EgoRow {
            y: -12.0,
            ..east_at(40.0)
        },
        Hazards::default(),
    );
    assert!(off[3].iter().flatten().all(|&v| v == 0.0));
}

#[test]
fn a_red_light_within_braking_distance_makes_brake_best() {
    let s = Situation::new(RED);
    let stop_x = BLOCK_M - JUNCTION_HALF_M - STOP_LINE_BACK_M;
    // The nose 3 m before the line: within braking distance from 3 m/s up.
    let ego = east_at(stop_x - 3.0 - 2.395);
    let front = ego.x + s.labeller.params.ego_half_extents.x;
    let hazards = Hazards {
        stop_line: Some((stop_x - front, world::LightState::Red)),
        actor_ahead: None,
    };
    let q = s.label(ego, hazards);
    for (b, values) in q[Command::LaneFollow as usize].iter().enumerate().skip(1) {
        assert_eq!(best(values), BRAKE, "bin {b}: {values:?}");
    }
    // The same place on green drives on.
    let green = Situation::new(GREEN).label(ego, Hazards::default());
    assert_ne!(best(&green[3][2]), BRAKE);
    // Even without the bonus, driving into the red junction is worth less
    // than on green: the strip past the line is not free.
    let no_bonus = s.label(ego, Hazards::default());
    assert!(no_bonus[3][3][index(4, 2)] < green[3][3][index(4, 2)]);
}

/// What is in the way of `ego` driving east: the rule book's "ahead" along
/// a straight path from the ego, as the labeller's episode loop asks it.
fn hazards_east(s: &Situation, ego: EgoRow) -> Hazards {
    use sim::runner::{AHEAD_CORRIDOR_M, AHEAD_RANGE_M};
    let path: Vec<Vec2> = (0..=AHEAD_RANGE_M as usize)
        .map(|k| Vec2::new(ego.x + k as f32, ego.y))
        .collect();
    let views: Vec<_> = s.actors.iter().map(ActorRow::view).collect();
    let ahead = world::rules::nearest_ahead(
        &path,
        &views,
        None,
        AHEAD_CORRIDOR_M,
        AHEAD_RANGE_M,
        world::rules::walker_horizon_s(ego.speed),
    );
    let stops = world::rules::RouteStops::default();
    Hazards::measure(
        &s.labeller.params,
        &stops,
        ego.x,
        |_| world::LightState::Green,
        ahead,
    )
}

#[test]
fn a_walker_about_to_step_into_the_lane_makes_brake_best() {
    let mut s = Situation::new(GREEN);
    let ego = east_at(40.0);
    // 8 m ahead, 3.1 m to the left of the lane's centre (outside the 1.4 m
    // corridor), walking towards the lane at 1.3 m/s: in it within 2 s.
    let walker = ActorRow {
        kind: ActorRow::PEDESTRIAN,
        id: 2,
        x: ego.x + 8.0,
        y: ego.y + 3.1,
        yaw: -std::f32::consts::FRAC_PI_2,
        length: 0.6,
        width: 0.6,
        speed: 1.3,
    };
    s.actors.push(walker);
    let q = s.label(ego, hazards_east(&s, ego));
    for (b, values) in q[Command::LaneFollow as usize].iter().enumerate().skip(1) {
        assert_eq!(best(values), BRAKE, "bin {b}: {values:?}");
    }
    // Standing at the kerb, the same walker is not in the way.
    s.actors[0].speed = 0.0;
    let hazards = hazards_east(&s, ego);
    assert_eq!(hazards.actor_ahead, None);
    let q = s.label(ego, hazards);
    assert_ne!(best(&q[Command::LaneFollow as usize][2]), BRAKE);
}

#[test]
fn a_car_stopped_ahead_makes_brake_best() {
    let mut s = Situation::new(GREEN);
    let ego = east_at(40.0);
    let length = 4.5;
    s.actors.push(ActorRow {
        kind: ActorRow::VEHICLE,
        id: 1,
        x: ego.x + 9.0,
        y: ego.y,
        yaw: 0.0,
        length,
        width: 2.0,
        speed: 0.0,
    });
    let gap = 9.0 - length / 2.0 - s.labeller.params.ego_half_extents.x;
    let q = s.label(
        ego,
        Hazards {
            stop_line: None,
            actor_ahead: Some((gap, 0.0)),
        },
    );
    for (b, values) in q[Command::LaneFollow as usize].iter().enumerate().skip(1) {
        assert_eq!(best(values), BRAKE, "bin {b}: {values:?}");
    }
    // Driving into the car is worth nothing: full throttle at 7 m/s reaches
    // it within the horizon, so its value is below an empty road's.
    let empty = Situation::new(GREEN).label(ego, Hazards::default());
    assert!(q[3][3][index(4, 2)] < empty[3][3][index(4, 2)]);
}

/// The steer a policy trained on `q` expects: E[steer] under WoR's soft
/// target softmax(Q / 0.01), brake counted as steer 0.
fn expected_steer(q: &[f32; NUM_ACTIONS]) -> f32 {
    let max = q.iter().copied().fold(f32::MIN, f32::max);
    let p: Vec<f32> = q.iter().map(|v| ((v - max) / 0.01).exp()).collect();
    let sum: f32 = p.iter().sum();
    (0..BRAKE)
        .map(|a| p[a] * crate::action::STEERS[a % NUM_STEERS])
        .sum::<f32>()
        / sum
}

#[test]
fn at_a_junction_each_turn_command_steers_its_own_way() {
    // 3 m into the four-way junction at (100, 100), heading east on the
    // approach's line, at 5 m/s: where the three connectors part.
    let s = Situation::new(GREEN);
    let ego = EgoRow {
        x: BLOCK_M - JUNCTION_HALF_M + 3.0,
        y: BLOCK_M - LANE_WIDTH_M / 2.0,
        yaw: 0.0,
        speed: 5.0,
    };
    let q = s.label(ego, Hazards::default());
    let bin = 2;
    let steer = |c: Command| expected_steer(&q[c as usize][bin]);
    assert!(
        steer(Command::Left) < -0.2,
        "LEFT: E[steer] {}",
        steer(Command::Left)
    );
    assert!(
        steer(Command::Right) > 0.2,
        "RIGHT: E[steer] {}",
        steer(Command::Right)
    );
    assert!(
        steer(Command::Straight).abs() < 0.1,
        "STRAIGHT: E[steer] {}",
        steer(Command::Straight)
    );
}

#[test]
fn labels_are_deterministic_and_views_differ() {
    let s = Situation::new(GREEN);
    let steps = s.labeller.steps + 1;
    let actors: Vec<&[ActorRow]> = vec![&[]; steps];
    let lights: Vec<&[u8]> = vec![&s.lights; steps];
    let input = FrameInput {
        ego: east_at(40.0),
        actors: &actors,
        lights: &lights,
        hazards: Hazards::default(),
        lane: None,
    };
    let views = [0.0, 30f32.to_radians(), -30f32.to_radians()];
    let a = s.labeller.label(&s.town, &input, &views);
    let b = s.labeller.label(&s.town, &input, &views);
    assert_eq!(a, b);
    // Yawed 30 deg to the left of the lane, the best move steers right.
    let yawed_left = best(&a[1][3][2]);
    assert!(steer_bin(yawed_left) > 4, "{:?}", a[1][3][2]);
    let yawed_right = best(&a[2][3][2]);
    assert!(steer_bin(yawed_right) < 4, "{:?}", a[2][3][2]);
}

#[test]
fn computing_only_the_reachable_region_changes_nothing() {
    let mut s = Situation::new(RED);
    s.actors.push(ActorRow {
        kind: ActorRow::PEDESTRIAN,
        id: 3,
        x: 48.0,
        y: -1.0,
        yaw: 1.0,
        length: 0.5,
        width: 0.5,
        speed: 1.0,
    });
    let steps = s.labeller.steps + 1;
    let actors: Vec<&[ActorRow]> = vec![&s.actors; steps];
    let lights: Vec<&[u8]> = vec![&s.lights; steps];
    let views = [0.0, 30f32.to_radians(), -30f32.to_radians()];
    for x in [40.0, BLOCK_M - JUNCTION_HALF_M - 2.0] {
        let input = FrameInput {
            ego: east_at(x),
            actors: &actors,
            lights: &lights,
            hazards: Hazards::default(),
            lane: None,
        };
        let fast = s.labeller.label(&s.town, &input, &views);
        let mut full = s.labeller.clone();
        full.reach_only = false;
        assert_eq!(fast, full.label(&s.town, &input, &views), "at x = {x}");
    }
}
