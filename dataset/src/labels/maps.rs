//! What the grid's cells hold for one frame: road, lane rewards per command,
//! and per future step the free mask and the stop rewards (WOR.md §2).
//!
//! Everything is drawn in the ego frame at t = 0 by splatting the town's
//! geometry onto the nodes near it (each lane segment onto the nodes within
//! its half width, each actor onto the nodes its shape covers), so the cost
//! grows with what is near the ego, not with the town.

use glam::Vec2;
use world::route::PlannerConfig;
use world::route::planner::turn_decision;
use world::rules::StopLines;
use world::{Command, LightState, Town};

use super::LabelParams;
use super::grid::{EgoFrame, Grid};
use crate::format::ActorRow;
use world::road::geometry::wrap_angle;

/// Commands (CARLA RoadOption - 1).
pub const COMMANDS: usize = 6;

/// Which commands' lane maps each lane of a town belongs to (bit `c` for
/// command `c`), and the town's stop lines (the rule book's table).
#[derive(Debug, Clone)]
pub struct TownLanes {
    /// Bit mask per lane (index like `Town::lanes`).
    pub commands: Vec<u8>,
    /// Every stop line.
    pub stops: StopLines,
}

impl TownLanes {
    /// Lane maps per command, following the planner's lane graph: lanes
    /// outside junctions belong to LEFT, RIGHT, STRAIGHT and FOLLOW; a
    /// junction's connecting lane to its turn (CARLA's turn decision, the
    /// planner's own) and to FOLLOW; CHANGELANELEFT to lanes that have a
    /// same-direction lane on their right (the target of a change to the
    /// left), CHANGELANERIGHT likewise.
    pub fn new(town: &Town) -> TownLanes {
        let threshold = PlannerConfig::default().turn_threshold_deg.to_radians();
        let bit = |c: Command| 1u8 << (c as u8);
        let commands = town
            .lanes
            .iter()
            .enumerate()
            .map(|(i, lane)| {
                let mut m = 0u8;
                if lane.junction.is_none() {
                    m |= bit(Command::Left)
                        | bit(Command::Right)
                        | bit(Command::Straight)
                        | bit(Command::LaneFollow);
                } else {
                    m |= bit(Command::LaneFollow);
                    if let Some(&approach) = lane.predecessors.first() {
                        let idx = world::LaneIdx(i as u32);
                        m |= bit(turn_decision(town, approach, &[idx], threshold));
                    }
                }
                if lane.right.is_some() {
                    m |= bit(Command::ChangeLaneLeft);
                }
                if lane.left.is_some() {
                    m |= bit(Command::ChangeLaneRight);
                }
                m
            })
            .collect();
        let stops = StopLines::new(town);
        TownLanes { commands, stops }
    }
}

impl TownLanes {
    /// The lanes reachable from `from` along the lane graph within `reach_m`
    /// metres (successors, and the neighbours of `from` for lane changes),
    /// `from` included.
    pub fn ahead_of(town: &Town, from: world::LaneIdx, s: f32, reach_m: f32) -> Vec<bool> {
        // Distance from the ego to each lane's start (its own lanes start behind it).
        let mut best = vec![f32::INFINITY; town.lanes.len()];
        let start = town.lane(from);
        let mut todo = vec![(from, -s)];
        todo.extend(start.left.iter().chain(&start.right).map(|&l| (l, -s)));
        while let Some((lane, start_m)) = todo.pop() {
            let i = lane.0 as usize;
            if start_m > reach_m || start_m >= best[i] {
                continue;
            }
            best[i] = start_m;
            let end_m = start_m + town.lane(lane).length_m();
            todo.extend(town.lane(lane).successors.iter().map(|&next| (next, end_m)));
        }
        best.iter().map(|d| d.is_finite()).collect()
    }
}

/// The time-independent maps of one frame.
#[derive(Debug, Clone)]
pub struct StaticMaps {
    /// 1 on nodes inside a drivable lane, 0 elsewhere (unpadded, `ny x nx`).
    pub road: Vec<f32>,
    /// Lane-following reward without the speed factor, per command and yaw
    /// node: `[command][yaw][ny x nx]`.
    pub lane: Vec<Vec<Vec<f32>>>,
}

/// The maps of one future step.
#[derive(Debug, Clone)]
pub struct StepMaps {
    /// 1 where the ego may be (on the road, off every actor, not past a red stop line).
    pub free: Vec<f32>,
    /// Reward for standing still, per yaw node: `[yaw][ny x nx]`.
    pub stop: Vec<Vec<f32>>,
}

/// The node range of a local box, clamped to the grid.
fn node_range(grid: &Grid, lo: Vec2, hi: Vec2) -> Option<(usize, usize, usize, usize)> {
    let a = grid.to_node(lo);
    let b = grid.to_node(hi);
    let i0 = a.x.ceil().max(0.0);
    let j0 = a.y.ceil().max(0.0);
    let i1 = b.x.floor().min((grid.nx - 1) as f32);
    let j1 = b.y.floor().min((grid.ny - 1) as f32);
    (i0 <= i1 && j0 <= j1).then_some((i0 as usize, i1 as usize, j0 as usize, j1 as usize))
}

/// Distance from `p` to the segment `a`-`b`.
fn segment_distance(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let t = if ab.length_squared() > 0.0 {
        ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    p.distance(a + ab * t)
}

/// Draws the road and the lane rewards of every command.
///
/// `ahead` marks the lanes the ego can reach from where it is (see
/// [`TownLanes::ahead_of`]): a junction's connecting lanes count only if the
/// ego can enter them, so the LEFT map at a junction is the left turn the
/// ego can take, not every left turn of the junction.
pub fn static_maps(
    town: &Town,
    lanes: &TownLanes,
    ahead: &[bool],
    grid: &Grid,
    frame: &EgoFrame,
    prm: &LabelParams,
) -> StaticMaps {
    let cells = grid.cells();
    let yaws = &grid.spec.yaws_rad;
    let mut road = vec![0.0f32; cells];
    let mut lane_r = vec![vec![vec![0.0f32; cells]; yaws.len()]; COMMANDS];
    let reach = grid.spec.x_max_m.abs().max(grid.spec.x_min_m.abs()) + grid.spec.y_half_m + 5.0;
    let mut yaw_w = vec![0.0f32; yaws.len()];
    for (li, lane) in town.lanes.iter().enumerate() {
        let mask = if lane.junction.is_some() && !ahead[li] {
            0
        } else {
            lanes.commands[li]
        };
        for (k, w) in lane.centerline.windows(2).enumerate() {
            let (a, b) = (w[0].truncate(), w[1].truncate());
            if a.distance(frame.origin) > reach && b.distance(frame.origin) > reach {
                continue;
            }
            let half_w = 0.5 * lane.width.get(k).copied().unwrap_or(3.5);
            let (la, lb) = (frame.to_local(a), frame.to_local(b));
            let heading = wrap_angle((lb - la).to_angle());
            let pad = Vec2::splat(half_w);
            let Some((i0, i1, j0, j1)) = node_range(grid, la.min(lb) - pad, la.max(lb) + pad)
            else {
                continue;
            };
            yaw_weights(yaws, heading, &prm.heading_profile_rad, &mut yaw_w);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let d = segment_distance(grid.node(i, j), la, lb);
                    if d > half_w {
                        continue;
                    }
                    let c = j * grid.nx + i;
                    road[c] = 1.0;
                    let centre = prm.lane_profile_m.at(d);
                    if centre == 0.0 {
                        continue;
                    }
                    for (cmd, plane) in lane_r.iter_mut().enumerate() {
                        if mask & (1 << cmd) == 0 {
                            continue;
                        }
                        for (y, &wy) in yaw_w.iter().enumerate() {
                            let v = centre * wy;
                            if v > plane[y][c] {
                                plane[y][c] = v;
                            }
                        }
                    }
                }
            }
        }
    }
    StaticMaps { road, lane: lane_r }
}

/// How well each yaw node agrees with a heading (radians, ego frame): the
/// heading profile at their difference on the circle.
pub fn yaw_weights(yaws: &[f32], heading: f32, profile: &super::Plateau, out: &mut [f32]) {
    for (o, &y) in out.iter_mut().zip(yaws) {
        *o = profile.at(wrap_angle(y - heading));
    }
}

/// Whether a light says stop on the labels' future maps: red, and yellow
/// as red (WoR; the decision at t = 0 uses the rule book's yellow rule, see
/// [`super::Hazards`]).
pub fn light_stops(state: LightState) -> bool {
    state != LightState::Green
}

/// Draws one future step: actors and lights at that time.
pub fn step_maps(
    statics: &StaticMaps,
    lanes: &TownLanes,
    grid: &Grid,
    frame: &EgoFrame,
    actors: &[ActorRow],
    lights: &[u8],
    prm: &LabelParams,
) -> StepMaps {
    let yaws = &grid.spec.yaws_rad;
    let mut free = statics.road.clone();
    let mut stop = vec![vec![0.0f32; grid.cells()]; yaws.len()];
    let ego_half = prm.ego_half_extents;
    let mut yaw_w = vec![0.0f32; yaws.len()];
    for a in actors {
        let centre = frame.to_local(Vec2::new(a.x, a.y));
        let yaw = a.yaw - frame.yaw;
        let (fwd, left) = (Vec2::from_angle(yaw), Vec2::from_angle(yaw).perp());
        let half = Vec2::new(a.length, a.width) * 0.5;
        if a.kind == ActorRow::PEDESTRIAN {
            // Pedestrians on the sidewalk are no hazard (WoR); on the road a
            // disc of their size plus the ego's half length.
            let on_road = grid.sample_node_value(&statics.road, centre) > 0.5;
            if !on_road {
                continue;
            }
            let r_block = half.max_element() + ego_half.x;
            let r_stop = r_block + prm.stop_zone_m;
            let Some((i0, i1, j0, j1)) = node_range(
                grid,
                centre - Vec2::splat(r_stop),
                centre + Vec2::splat(r_stop),
            ) else {
                continue;
            };
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let d = grid.node(i, j).distance(centre);
                    let c = j * grid.nx + i;
                    if d <= r_block {
                        free[c] = 0.0;
                    } else if d <= r_stop {
                        for plane in stop.iter_mut() {
                            plane[c] = prm.stop_reward;
                        }
                    }
                }
            }
        } else {
            // Vehicles: blocked where the footprints would overlap (the box
            // grown by the ego's half length and half width); the stop zone is
            // the box grown by the ego's length behind it and 1.2 m sideways.
            let block = half + Vec2::new(ego_half.x, ego_half.y);
            let behind = half.x + 2.0 * ego_half.x + prm.stop_zone_m;
            let side = half.y + prm.vehicle_side_m;
            let r = behind.max(block.x) + side;
            let Some((i0, i1, j0, j1)) =
                node_range(grid, centre - Vec2::splat(r), centre + Vec2::splat(r))
            else {
                continue;
            };
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let d = grid.node(i, j) - centre;
                    let (u, w) = (d.dot(fwd), d.dot(left));
                    let c = j * grid.nx + i;
                    if u.abs() <= block.x && w.abs() <= block.y {
                        free[c] = 0.0;
                    } else if u < 0.0 && u >= -behind && w.abs() <= side {
                        for plane in stop.iter_mut() {
                            plane[c] = prm.stop_reward;
                        }
                    }
                }
            }
        }
    }
    // Lights that say stop: standing before the line is rewarded at the
    // lane's heading; the strip just past the point where a crossing counts
    // (the rule book's crossing point) is not free.
    let cross_u = prm.crossing_offset_m;
    for s in lanes.stops.all() {
        let state = lights
            .get(s.light.0 as usize)
            .copied()
            .map(crate::format::light_of_code);
        if !state.is_some_and(light_stops) {
            continue;
        }
        let half_width_m = s.ends[0].distance(s.ends[1]) * 0.5;
        let centre = frame.to_local(s.position);
        if centre.length() > grid.spec.x_max_m + grid.spec.y_half_m + 10.0 {
            continue;
        }
        let heading = wrap_angle(s.heading - frame.yaw);
        let (fwd, left) = (Vec2::from_angle(heading), Vec2::from_angle(heading).perp());
        let r = prm.red_zone_before_m.max(cross_u + prm.red_block_m) + half_width_m;
        let Some((i0, i1, j0, j1)) =
            node_range(grid, centre - Vec2::splat(r), centre + Vec2::splat(r))
        else {
            continue;
        };
        yaw_weights(yaws, heading, &prm.heading_profile_rad, &mut yaw_w);
        for j in j0..=j1 {
            for i in i0..=i1 {
                let d = grid.node(i, j) - centre;
                let (u, w) = (d.dot(fwd), d.dot(left));
                if w.abs() > half_width_m {
                    continue;
                }
                let c = j * grid.nx + i;
                if u > cross_u && u <= cross_u + prm.red_block_m {
                    free[c] = 0.0;
                } else if u <= cross_u && u >= -prm.red_zone_before_m {
                    for (plane, &wy) in stop.iter_mut().zip(&yaw_w) {
                        plane[c] = plane[c].max(prm.stop_reward * wy);
                    }
                }
            }
        }
    }
    StepMaps { free, stop }
}

impl Grid {
    /// Nearest-node read of an unpadded plane at a local point; 0 outside.
    pub fn sample_node_value(&self, plane: &[f32], local: Vec2) -> f32 {
        let n = self.to_node(local).round();
        if n.x < 0.0 || n.y < 0.0 || n.x >= self.nx as f32 || n.y >= self.ny as f32 {
            return 0.0;
        }
        plane[n.y as usize * self.nx + n.x as usize]
    }
}
