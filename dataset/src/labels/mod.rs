//! World-on-rails action values: `Q[command, speed bin, action]` for a frame,
//! computed from mrdrive's own vehicle model and the recorded future of every
//! other actor and light (WOR.md §2, docs/protocol.md §5). `docs/labels.md` lists each
//! difference from WoR's code with its reason.
//!
//! For one frame: the ego's pose at t = 0 fixes a local grid ([`grid`]); the
//! town's lanes give the road and a lane-following reward per command
//! ([`maps::static_maps`]); each future step (0.25 s apart, up to 1.25 s)
//! gives a free mask and stop rewards from the actors and lights recorded at
//! that time ([`maps::step_maps`]); a backward recursion ([`bellman`]) gives
//! the values of the first step, read at the ego's position for each camera
//! view's yaw and each of the four speed bins, plus WoR's brake bonus when a
//! hazard is in the ego's way.

pub mod bellman;
pub mod dynamics;
pub mod episode;
pub mod grid;
pub mod maps;

use glam::Vec2;
use world::Command;
use world::agents::VehicleParams;

use crate::action::{BRAKE, NUM_ACTIONS, NUM_COMMANDS, NUM_SPEED_BINS};
use crate::decode::SPEED_BIN_CENTRES_MPS;
use crate::format::{ActorRow, EgoRow};
use bellman::{Region, Transition, backup, reach, sample, transitions};
use dynamics::{Move, move_table};
use grid::{EgoFrame, Grid, GridSpec, hat_weights};
use maps::{StaticMaps, StepMaps, TownLanes, static_maps, step_maps};

/// The version of the labels this build makes; label files of another
/// version are refused (bump it whenever the values change).
pub const LABEL_VERSION: u32 = 4;

/// How far along the lane graph a junction's connecting lanes count as the
/// ego's (metres): beyond the grid's reach.
const AHEAD_REACH_M: f32 = 40.0;

/// Values of one label: `[command][speed bin][action]`.
pub type Q = [[[f32; NUM_ACTIONS]; NUM_SPEED_BINS]; NUM_COMMANDS];

/// The rewards and hazard shapes (WoR's numbers where it has them).
#[derive(Debug, Clone, PartialEq)]
pub struct LabelParams {
    /// Target speed on turns, commands LEFT and RIGHT (metres per second; WoR 6.0).
    pub turn_mps: f32,
    /// Target speed otherwise (metres per second; WoR 6.5).
    pub cruise_mps: f32,
    /// The lane reward across the lane: 1 within `flat` metres of the
    /// centreline, falling linearly to 0 at `zero` metres.
    pub lane_profile_m: Plateau,
    /// The lane reward against heading: 1 within `flat` radians of the
    /// lane's heading, falling linearly to 0 at `zero` radians.
    pub heading_profile_rad: Plateau,
    /// Reward for standing still where a hazard or a red light says stop (WoR 0.1).
    pub stop_reward: f32,
    /// Bonus to the brake action at t = 0 when a hazard is in the way (WoR 5.0).
    pub brake_bonus: f32,
    /// Depth of the stop zone around pedestrians and behind vehicles (metres).
    pub stop_zone_m: f32,
    /// How far the stop zone behind a vehicle reaches sideways past its side (metres; WoR ~1.2).
    pub vehicle_side_m: f32,
    /// Depth of the zone before a red stop line where standing is rewarded (metres).
    pub red_zone_before_m: f32,
    /// Depth of the strip past a red stop line's crossing point that is not free (metres).
    pub red_block_m: f32,
    /// How far the ego's centre may pass a stop line before the red-light
    /// rule counts a crossing (metres): the rule book's crossing point.
    pub crossing_offset_m: f32,
    /// The ego's half length and half width (metres).
    pub ego_half_extents: Vec2,
    /// Deceleration that decides whether a hazard is "in the way" (m/s^2).
    pub hazard_decel_mps2: f32,
    /// Reaction time added to the stopping distance (seconds).
    pub hazard_reaction_s: f32,
    /// Gap to keep to an actor ahead, bumper to footprint (metres).
    pub actor_gap_m: f32,
    /// Extra distance before a red stop line that still counts as in the way (metres).
    pub red_margin_m: f32,
}

impl LabelParams {
    /// WoR's rewards for an ego of this vehicle model.
    pub fn for_vehicle(vehicle: &VehicleParams) -> LabelParams {
        let half = vehicle.half_extents();
        LabelParams {
            turn_mps: 6.0,
            cruise_mps: 6.5,
            lane_profile_m: Plateau {
                flat: 0.5,
                zero: 1.5,
            },
            heading_profile_rad: Plateau {
                flat: 5f32.to_radians(),
                zero: 45f32.to_radians(),
            },
            stop_reward: 0.1,
            brake_bonus: 5.0,
            stop_zone_m: 2.0,
            vehicle_side_m: 1.2,
            red_zone_before_m: 8.0,
            red_block_m: 3.0,
            crossing_offset_m: world::rules::crossing_offset_m(vehicle.length_m),
            ego_half_extents: half,
            hazard_decel_mps2: 3.0,
            hazard_reaction_s: 0.25,
            actor_gap_m: 4.0,
            red_margin_m: 2.0,
        }
    }

    /// The target speed of a command (metres per second).
    pub fn target_mps(&self, command: usize) -> f32 {
        if command == Command::Left as usize || command == Command::Right as usize {
            self.turn_mps
        } else {
            self.cruise_mps
        }
    }

    /// Stopping distance from `speed_mps` with the hazard deceleration and reaction time (metres).
    pub fn stopping_m(&self, speed_mps: f32) -> f32 {
        speed_mps * self.hazard_reaction_s + speed_mps * speed_mps / (2.0 * self.hazard_decel_mps2)
    }
}

/// A reward profile with a flat top: 1 up to `flat`, then falling linearly
/// to 0 at `zero`.
///
/// The flat top matters: values between grid nodes are linear
/// interpolations, which underestimate a pointed peak; a state exactly on a
/// node (going straight, say) would then look better than its neighbours
/// for no reason but the grid. On a flat top interpolation is exact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plateau {
    /// Half width of the flat top.
    pub flat: f32,
    /// Where the profile reaches 0.
    pub zero: f32,
}

impl Plateau {
    /// The profile at distance `d` from its centre.
    pub fn at(&self, d: f32) -> f32 {
        let d = d.abs();
        if d <= self.flat {
            1.0
        } else {
            ((self.zero - d) / (self.zero - self.flat)).max(0.0)
        }
    }
}

/// What lies in the ego's way at t = 0, measured along its route.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Hazards {
    /// The next stop line on the route that the ego has not crossed (by the
    /// rule book's crossing point): the distance from the ego's front bumper
    /// to it (metres; negative with the nose over the line) and its light.
    pub stop_line: Option<(f32, world::LightState)>,
    /// The nearest actor ahead on the route: the gap from the ego's front
    /// bumper to its footprint (metres) and its speed along the route (m/s).
    pub actor_ahead: Option<(f32, f32)>,
}

impl Hazards {
    /// What is in the way of an ego whose centre is `ego_s` metres along its
    /// route: the next stop line its crossing point has not passed, with its
    /// light's state from `light`, and the nearest actor ahead (`ahead`: the
    /// loop's "ahead" query along the route).
    pub fn measure(
        prm: &LabelParams,
        stops: &world::rules::RouteStops,
        ego_s: f32,
        light: impl Fn(world::LightIdx) -> world::LightState,
        ahead: Option<world::rules::Ahead>,
    ) -> Hazards {
        let front_s = ego_s + prm.ego_half_extents.x;
        let stop_line = stops
            .next_after(ego_s - prm.crossing_offset_m)
            .map(|s| (s.route_s - front_s, light(s.light)));
        let actor_ahead = ahead.map(|a| (a.distance_m - prm.ego_half_extents.x, a.speed_along_mps));
        Hazards {
            stop_line,
            actor_ahead,
        }
    }

    /// Whether a hazard is in the way of an ego at `speed_mps`: a stop line
    /// within stopping distance (plus a margin) whose light says stop by the
    /// rule book's rule (red; yellow if the ego can still stop), or an actor
    /// ahead that the ego closes on within stopping distance of the closing
    /// speed plus the gap to keep.
    pub fn in_way(&self, prm: &LabelParams, speed_mps: f32) -> bool {
        let red = self.stop_line.is_some_and(|(d, state)| {
            world::rules::must_stop(state, d, speed_mps, prm.hazard_decel_mps2)
                && d <= prm.stopping_m(speed_mps) + prm.red_margin_m
        });
        let actor = self.actor_ahead.is_some_and(|(gap, along)| {
            gap <= prm.stopping_m((speed_mps - along).max(0.0)) + prm.actor_gap_m
        });
        red || actor
    }
}

/// One frame to label: the ego now, and the other actors and lights now and
/// at each future step.
#[derive(Debug, Clone, Copy)]
pub struct FrameInput<'a> {
    /// The ego at t = 0.
    pub ego: EgoRow,
    /// Actors at t = 0, 1, ..., steps (index = step).
    pub actors: &'a [&'a [ActorRow]],
    /// Light states at t = 0, 1, ..., steps.
    pub lights: &'a [&'a [u8]],
    /// What is in the ego's way at t = 0.
    pub hazards: Hazards,
    /// The lane the ego drives on and its arc length there (metres): the
    /// route's lane at the ego; `None` to take the nearest lane.
    pub lane: Option<(world::LaneIdx, f32)>,
}

/// Computes labels for frames of one town.
#[derive(Debug, Clone)]
pub struct Labeller {
    /// Rewards and shapes.
    pub params: LabelParams,
    /// Future steps (WoR: 5).
    pub steps: usize,
    /// Compute values only where the ego can reach (the default; `false`
    /// computes the whole grid, for checking that both agree).
    pub reach_only: bool,
    grid: Grid,
    lanes: TownLanes,
    trans: Vec<Transition>,
    grid_moves: Vec<[Move; NUM_ACTIONS]>,
    bin_moves: Vec<[Move; NUM_ACTIONS]>,
}

impl Labeller {
    /// A labeller for `town` and an ego of `vehicle`, `steps` steps of
    /// `step_s` seconds integrated at `tick_s`.
    pub fn new(
        town: &world::Town,
        vehicle: &VehicleParams,
        spec: GridSpec,
        steps: usize,
        step_s: f32,
        tick_s: f32,
    ) -> Labeller {
        let grid_moves = move_table(vehicle, &spec.speeds_mps, step_s, tick_s);
        let bin_moves = move_table(vehicle, &SPEED_BIN_CENTRES_MPS, step_s, tick_s);
        let max_move = grid_moves
            .iter()
            .chain(&bin_moves)
            .flatten()
            .map(|m| m.delta.length())
            .fold(0.0, f32::max);
        let grid = Grid::new(spec, max_move);
        let trans = transitions(&grid, &grid_moves);
        Labeller {
            params: LabelParams::for_vehicle(vehicle),
            steps,
            reach_only: true,
            grid,
            lanes: TownLanes::new(town),
            trans,
            grid_moves,
            bin_moves,
        }
    }

    /// WoR's set-up: 5 steps of 0.25 s at 40 Hz on the default grid.
    pub fn wor(town: &world::Town, vehicle: &VehicleParams) -> Labeller {
        Labeller::new(town, vehicle, GridSpec::default(), 5, 0.25, 0.025)
    }

    /// The town's stop lines (the rule book's table, built once with the labeller).
    pub fn stop_lines(&self) -> &world::rules::StopLines {
        &self.lanes.stops
    }

    /// The grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// Labels one frame for each view yaw (radians, counter-clockwise, relative
    /// to the ego): `out[view]`.
    pub fn label(
        &self,
        town: &world::Town,
        input: &FrameInput<'_>,
        view_yaws_rad: &[f32],
    ) -> Vec<Q> {
        self.label_commands(town, input, view_yaws_rad, &[true; NUM_COMMANDS])
    }

    /// Like [`Labeller::label`], for the commands marked in `wanted` only
    /// (the others stay 0): what a driver that knows its command needs.
    pub fn label_commands(
        &self,
        town: &world::Town,
        input: &FrameInput<'_>,
        view_yaws_rad: &[f32],
        wanted: &[bool; NUM_COMMANDS],
    ) -> Vec<Q> {
        assert_eq!(
            input.actors.len(),
            self.steps + 1,
            "actors for t = 0..=steps"
        );
        assert_eq!(
            input.lights.len(),
            self.steps + 1,
            "lights for t = 0..=steps"
        );
        let frame = EgoFrame {
            origin: Vec2::new(input.ego.x, input.ego.y),
            yaw: input.ego.yaw,
        };
        let prm = &self.params;
        // Connecting lanes count from the approach lane, so every command's
        // turn out of this junction is on its map.
        let lane = input.lane.or_else(|| {
            world::rules::nearest_lane(town, frame.origin, Some(frame.yaw))
                .map(|lp| (lp.lane, lp.s))
        });
        let ahead = match lane {
            Some((l, s)) => match town.lane(l).predecessors.first() {
                Some(&before) if town.lane(l).junction.is_some() => {
                    TownLanes::ahead_of(town, before, town.lane(before).length_m(), AHEAD_REACH_M)
                }
                _ => TownLanes::ahead_of(town, l, s, AHEAD_REACH_M),
            },
            None => vec![false; town.lanes.len()],
        };
        let statics = static_maps(town, &self.lanes, &ahead, &self.grid, &frame, prm);
        let steps: Vec<StepMaps> = (1..=self.steps)
            .map(|t| {
                step_maps(
                    &statics,
                    &self.lanes,
                    &self.grid,
                    &frame,
                    input.actors[t],
                    input.lights[t],
                    prm,
                )
            })
            .collect();
        let mut out =
            vec![[[[0.0f32; NUM_ACTIONS]; NUM_SPEED_BINS]; NUM_COMMANDS]; view_yaws_rad.len()];
        let lo = view_yaws_rad.iter().copied().fold(0.0f32, f32::min);
        let hi = view_yaws_rad.iter().copied().fold(0.0f32, f32::max);
        let regions = reach(
            &self.grid,
            (lo, hi),
            &self.bin_moves,
            &self.grid_moves,
            self.steps,
        );
        // Commands with the same lane map and target speed share their values.
        // (command, W_1) of each distinct command computed so far.
        let mut done: Vec<(usize, Vec<Vec<f32>>)> = Vec::new();
        for cmd in (0..NUM_COMMANDS).filter(|&c| wanted[c]) {
            let same = done.iter().position(|&(c, _)| {
                prm.target_mps(c) == prm.target_mps(cmd) && statics.lane[c] == statics.lane[cmd]
            });
            let k = same.unwrap_or_else(|| {
                done.push((cmd, self.first_step_values(&statics, &steps, &regions, cmd)));
                done.len() - 1
            });
            let w1 = &done[k].1;
            for (view, &yaw) in view_yaws_rad.iter().enumerate() {
                for (b, &v) in SPEED_BIN_CENTRES_MPS.iter().enumerate() {
                    let bonus = input.hazards.in_way(prm, v);
                    for (a, (q, m)) in out[view][cmd][b]
                        .iter_mut()
                        .zip(&self.bin_moves[b])
                        .enumerate()
                    {
                        let p = Vec2::from_angle(yaw).rotate(m.delta);
                        *q = sample(&self.grid, w1, p, yaw + m.dyaw, m.speed_mps);
                        if a == BRAKE && bonus {
                            *q += prm.brake_bonus;
                        }
                    }
                }
            }
        }
        out
    }

    /// `W_1` for one command: the backward recursion from the horizon.
    fn first_step_values(
        &self,
        statics: &StaticMaps,
        steps: &[StepMaps],
        regions: &[Region],
        cmd: usize,
    ) -> Vec<Vec<f32>> {
        let grid = &self.grid;
        let spec = &grid.spec;
        let (yaws, speeds) = (spec.yaws_rad.len(), spec.speeds_mps.len());
        let mut speed_w = vec![0.0f32; speeds];
        hat_weights(&spec.speeds_mps, self.params.target_mps(cmd), &mut speed_w);
        let planes = yaws * speeds;
        let mut w = vec![vec![0.0f32; grid.padded_len()]; planes];
        let mut v = vec![vec![0.0f32; grid.cells()]; planes];
        let mut scratch = Vec::new();
        let lane = &statics.lane[cmd];
        let nothing = |p: &Vec<Vec<f32>>| p.iter().all(|q| q.iter().all(|&x| x == 0.0));
        if nothing(lane) && steps.iter().all(|s| nothing(&s.stop)) {
            return w;
        }
        for t in (0..steps.len()).rev() {
            // W_{t+1} = free * (R + V_{t+1}) where it is read (V = 0 at the horizon).
            let step = &steps[t];
            let region = &regions[t];
            for (k, lane_k) in lane.iter().enumerate() {
                for (l, &sw) in speed_w.iter().enumerate() {
                    let plane = &mut w[k * speeds + l];
                    plane.fill(0.0);
                    if k < region.k.0 || k >= region.k.1 {
                        continue;
                    }
                    let vals = &v[k * speeds + l];
                    for j in region.j.0..region.j.1 {
                        for i in region.i.0..region.i.1 {
                            let c = j * grid.nx + i;
                            let mut r = lane_k[c] * sw;
                            if l == 0 {
                                r += step.stop[k][c];
                            }
                            plane[grid.padded_at(i, j)] = step.free[c] * (r + vals[c]);
                        }
                    }
                }
            }
            if t > 0 {
                backup(grid, &self.trans, &w, &mut v, &regions[t - 1], &mut scratch);
            }
        }
        w
    }
}

#[cfg(test)]
mod tests;
