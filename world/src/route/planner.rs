//! The global planner: a route's sparse waypoints densified over the lane
//! graph at about 1 m spacing and tagged with high-level commands, as CARLA's
//! `GlobalRoutePlanner.trace_route` does.
//!
//! Commands follow CARLA: points on ordinary lanes are `LaneFollow`; the
//! points of a junction crossing (its connecting lanes) carry the turn
//! decision, made at the junction entry from the heading change across the
//! junction (`Straight` under 35 degrees, otherwise `Left`/`Right` by the
//! cross product against the other ways out); points of a lane change carry
//! `ChangeLaneLeft`/`ChangeLaneRight`. A driver sees a turn before the
//! junction by looking ahead ([`DenseRoute::command_ahead`]).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use glam::{Vec2, Vec3};

use crate::map::town::{LaneIdx, Town};
use crate::route::Route;
use crate::route::RouteError;
use crate::route::command::Command;
use crate::route::dense::{DenseRoute, RoutePoint};

/// Planner settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannerConfig {
    /// Spacing of dense points (metres). CARLA's leaderboard uses 1 m.
    pub spacing_m: f32,
    /// A waypoint farther than this from every lane centreline is off the map (metres).
    pub max_snap_m: f32,
    /// Heading change across a junction below which it is `Straight` (degrees). CARLA: 35.
    pub turn_threshold_deg: f32,
    /// Extra cost of a lane change in the search (metres of driving).
    pub lane_change_cost_m: f32,
    /// Distance over which a lane change moves across (metres).
    pub lane_change_length_m: f32,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        PlannerConfig {
            spacing_m: 1.0,
            max_snap_m: 4.0,
            turn_threshold_deg: 35.0,
            lane_change_cost_m: 20.0,
            lane_change_length_m: 10.0,
        }
    }
}

/// A stretch of the lane path.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Piece {
    /// Drive along `lane` from `s0` to `s1` (metres).
    Follow { lane: LaneIdx, s0: f32, s1: f32 },
    /// Move across from `from` at `from_s` to `to` at `to_s` (end of the move).
    Change {
        from: LaneIdx,
        from_s: f32,
        to: LaneIdx,
        to_s: f32,
        left: bool,
    },
}

#[derive(Clone, Copy, PartialEq)]
struct Node {
    cost: f32,
    lane: u32,
}
impl Eq for Node {}
impl Ord for Node {
    fn cmp(&self, o: &Self) -> Ordering {
        o.cost
            .total_cmp(&self.cost)
            .then_with(|| o.lane.cmp(&self.lane))
    }
}
impl PartialOrd for Node {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

#[derive(Clone, Copy)]
enum Via {
    Start,
    Succ(LaneIdx),
    Change(LaneIdx, f32, bool),
}

/// Plans `route` over `town`: snaps each waypoint to its lane, finds the
/// shortest lane path between consecutive waypoints and densifies it.
pub fn plan_route(
    town: &Town,
    route: &Route,
    cfg: &PlannerConfig,
) -> Result<DenseRoute, RouteError> {
    if route.waypoints.len() < 2 {
        return Err(RouteError::TooFewWaypoints {
            file: route.source.clone(),
            id: route.id.clone(),
            count: route.waypoints.len(),
        });
    }
    let mut snapped = Vec::new();
    for (i, w) in route.waypoints.iter().enumerate() {
        let lp = crate::rules::nearest_lane(town, w.position.truncate(), w.yaw_rad);
        match lp {
            Some(lp) if lp.distance_m <= cfg.max_snap_m => snapped.push((lp.lane, lp.s)),
            other => {
                return Err(RouteError::OffMap {
                    file: route.source.clone(),
                    id: route.id.clone(),
                    index: i,
                    x: w.position.x,
                    y: w.position.y,
                    distance_m: other.map_or(f32::INFINITY, |l| l.distance_m),
                    limit_m: cfg.max_snap_m,
                });
            }
        }
    }
    let mut pieces: Vec<Piece> = Vec::new();
    let mut leg_ends = vec![0usize];
    for i in 0..snapped.len() - 1 {
        let leg =
            plan_leg(town, snapped[i], snapped[i + 1], cfg).ok_or_else(|| RouteError::NoPath {
                file: route.source.clone(),
                id: route.id.clone(),
                from: i,
                to: i + 1,
            })?;
        pieces.extend(leg);
        leg_ends.push(pieces.len());
    }
    let commands = tag_pieces(town, &pieces, cfg.turn_threshold_deg.to_radians());
    Ok(densify(town, &route.id, &pieces, &commands, &leg_ends, cfg))
}

/// The pieces from `(a, sa)` to `(b, sb)`, or `None` when unreachable.
fn plan_leg(
    town: &Town,
    (a, sa): (LaneIdx, f32),
    (b, sb): (LaneIdx, f32),
    cfg: &PlannerConfig,
) -> Option<Vec<Piece>> {
    if a == b && sb >= sa - 0.01 {
        return Some(vec![Piece::Follow {
            lane: a,
            s0: sa,
            s1: sb.max(sa),
        }]);
    }
    let n = town.lanes.len();
    let mut dist = vec![f32::INFINITY; n];
    let mut entry = vec![0.0f32; n];
    let mut via = vec![Via::Start; n];
    let mut done = vec![false; n];
    let mut heap = BinaryHeap::new();
    // Edges out of the start position (it is not a node: the start lane may be
    // re-entered at s = 0 to loop back to a point behind).
    let relax = |from: LaneIdx,
                 e: f32,
                 base: f32,
                 dist: &mut Vec<f32>,
                 entry: &mut Vec<f32>,
                 via: &mut Vec<Via>,
                 heap: &mut BinaryHeap<Node>| {
        let l = town.lane(from);
        let rest = (l.length_m() - e).max(0.0);
        for &s in &l.successors {
            let c = base + rest;
            if c < dist[s.0 as usize] {
                dist[s.0 as usize] = c;
                entry[s.0 as usize] = 0.0;
                via[s.0 as usize] = Via::Succ(from);
                heap.push(Node { cost: c, lane: s.0 });
            }
        }
        for (nb, left) in [(l.left, true), (l.right, false)] {
            let Some(nb) = nb else { continue };
            let end_s = e + cfg.lane_change_length_m;
            if end_s > l.length_m() {
                continue;
            }
            let target = town.lane(nb);
            let Some(p) = crate::road::geometry::project_to_polyline(
                &target.centerline,
                l.point_at(end_s).truncate(),
            ) else {
                continue;
            };
            let c = base + cfg.lane_change_length_m + cfg.lane_change_cost_m;
            if c < dist[nb.0 as usize] {
                dist[nb.0 as usize] = c;
                entry[nb.0 as usize] = p.s;
                via[nb.0 as usize] = Via::Change(from, e, left);
                heap.push(Node {
                    cost: c,
                    lane: nb.0,
                });
            }
        }
    };
    relax(a, sa, 0.0, &mut dist, &mut entry, &mut via, &mut heap);
    let mut start_via = vec![false; n]; // whether the node's via refers to the start position
    for i in 0..n {
        start_via[i] = dist[i].is_finite();
    }
    while let Some(Node { cost, lane }) = heap.pop() {
        let li = lane as usize;
        if done[li] || cost > dist[li] {
            continue;
        }
        done[li] = true;
        if LaneIdx(lane) == b && entry[li] <= sb + 0.01 {
            break;
        }
        let e = entry[li];
        let before: Vec<f32> = dist.clone();
        relax(
            LaneIdx(lane),
            e,
            cost,
            &mut dist,
            &mut entry,
            &mut via,
            &mut heap,
        );
        for i in 0..n {
            if dist[i] < before[i] {
                start_via[i] = false;
            }
        }
    }
    if !dist[b.0 as usize].is_finite() || entry[b.0 as usize] > sb + 0.01 {
        return None;
    }
    // Walk back from b.
    let mut rev: Vec<Piece> = vec![Piece::Follow {
        lane: b,
        s0: entry[b.0 as usize],
        s1: sb,
    }];
    let mut cur = b;
    let mut guard = 0;
    loop {
        guard += 1;
        if guard > n + 2 {
            return None;
        }
        let ci = cur.0 as usize;
        let from_start = start_via[ci];
        match via[ci] {
            Via::Start => return None,
            Via::Succ(p) => {
                let s0 = if from_start && p == a {
                    sa
                } else {
                    entry[p.0 as usize]
                };
                rev.push(Piece::Follow {
                    lane: p,
                    s0,
                    s1: town.lane(p).length_m(),
                });
                if from_start && p == a {
                    break;
                }
                cur = p;
            }
            Via::Change(p, at, left) => {
                rev.push(Piece::Change {
                    from: p,
                    from_s: at,
                    to: cur,
                    to_s: entry[ci],
                    left,
                });
                rev.push(Piece::Follow {
                    lane: p,
                    s0: at,
                    s1: at,
                });
                if from_start && p == a {
                    if let Some(Piece::Follow { s0, .. }) = rev.last_mut() {
                        *s0 = sa;
                    }
                    break;
                }
                if let Some(Piece::Follow { s0, .. }) = rev.last_mut() {
                    *s0 = entry[p.0 as usize];
                }
                cur = p;
            }
        }
    }
    rev.reverse();
    Some(rev)
}

/// Unit vector of a 3-D difference in the ground plane.
fn unit(v: Vec3) -> Vec2 {
    v.truncate().normalize_or_zero()
}

/// CARLA's turn decision for driving from `approach` into the junction lanes
/// `run` (consecutive connecting lanes, in order). `threshold_rad`: heading
/// change under which it is `Straight`.
pub fn turn_decision(
    town: &Town,
    approach: LaneIdx,
    run: &[LaneIdx],
    threshold_rad: f32,
) -> Command {
    let Some(&first) = run.first() else {
        return Command::LaneFollow;
    };
    let last = *run.last().unwrap_or(&first);
    let exit_vec = |l: LaneIdx| {
        let c = &town.lane(l).centerline;
        unit(c[c.len() - 1] - c[c.len() - 2])
    };
    let net_vec = |l: LaneIdx| {
        let c = &town.lane(l).centerline;
        unit(c[c.len() - 1] - c[0])
    };
    let cv = exit_vec(approach);
    let nv = exit_vec(last);
    let mut cross_list: Vec<f32> = town
        .lane(approach)
        .successors
        .iter()
        .filter(|&&s| s != first)
        .map(|&s| cv.perp_dot(net_vec(s)))
        .collect();
    let next_cross = cv.perp_dot(nv);
    let deviation = cv.dot(nv).clamp(-1.0, 1.0).acos();
    if cross_list.is_empty() {
        cross_list.push(0.0);
    }
    let max = cross_list.iter().copied().fold(f32::MIN, f32::max);
    let min = cross_list.iter().copied().fold(f32::MAX, f32::min);
    // CARLA's frame is left-handed; here a left turn has a positive cross product.
    if deviation < threshold_rad {
        Command::Straight
    } else if next_cross > max {
        Command::Left
    } else if next_cross < min {
        Command::Right
    } else if next_cross > 0.0 {
        Command::Left
    } else {
        Command::Right
    }
}

/// The command of each piece.
fn tag_pieces(town: &Town, pieces: &[Piece], threshold_rad: f32) -> Vec<Command> {
    let mut out = vec![Command::LaneFollow; pieces.len()];
    let mut i = 0;
    while i < pieces.len() {
        match pieces[i] {
            Piece::Change { left, .. } => {
                out[i] = if left {
                    Command::ChangeLaneLeft
                } else {
                    Command::ChangeLaneRight
                };
                i += 1;
            }
            Piece::Follow { lane, .. } if town.lane(lane).junction.is_some() => {
                // A run of junction lanes; the approach is the piece before it.
                let mut j = i;
                let mut run = Vec::new();
                while j < pieces.len() {
                    match pieces[j] {
                        Piece::Follow { lane, .. } if town.lane(lane).junction.is_some() => {
                            run.push(lane)
                        }
                        _ => break,
                    }
                    j += 1;
                }
                let approach = if i > 0 {
                    match pieces[i - 1] {
                        Piece::Follow { lane, .. } => Some(lane),
                        Piece::Change { to, .. } => Some(to),
                    }
                } else {
                    None
                };
                let cmd = match approach {
                    Some(a) => turn_decision(town, a, &run, threshold_rad),
                    None => Command::LaneFollow,
                };
                for k in out.iter_mut().take(j).skip(i) {
                    *k = cmd;
                }
                i = j;
            }
            _ => i += 1,
        }
    }
    out
}

fn densify(
    town: &Town,
    id: &str,
    pieces: &[Piece],
    commands: &[Command],
    leg_ends: &[usize],
    cfg: &PlannerConfig,
) -> DenseRoute {
    let mut pts: Vec<RoutePoint> = Vec::new();
    fn push(
        pts: &mut Vec<RoutePoint>,
        position: Vec3,
        heading: f32,
        lane: LaneIdx,
        s: f32,
        command: Command,
    ) {
        if pts
            .last()
            .is_some_and(|last| last.position.distance(position) < 0.05)
        {
            return;
        }
        pts.push(RoutePoint {
            position,
            heading,
            lane,
            s,
            command,
            route_s: 0.0,
        });
    }
    let mut waypoint_points = vec![0usize];
    let mut leg = 1;
    for (pi, piece) in pieces.iter().enumerate() {
        let cmd = commands[pi];
        match *piece {
            Piece::Follow { lane, s0, s1 } => {
                let l = town.lane(lane);
                let len = (s1 - s0).max(0.0);
                let n = (len / cfg.spacing_m).ceil().max(1.0) as usize;
                for k in 0..=n {
                    let s = s0 + len * k as f32 / n as f32;
                    push(&mut pts, l.point_at(s), l.heading_at(s), lane, s, cmd);
                }
            }
            Piece::Change {
                from,
                from_s,
                to,
                to_s,
                ..
            } => {
                let (lf, lt) = (town.lane(from), town.lane(to));
                let d = cfg.lane_change_length_m;
                let n = (d / cfg.spacing_m).ceil().max(1.0) as usize;
                for k in 1..=n {
                    let t = k as f32 / n as f32;
                    let pa = lf.point_at(from_s + d * t);
                    let pb = lt.point_at(to_s - d * (1.0 - t));
                    let (lane, s) = if t < 0.5 {
                        (from, from_s + d * t)
                    } else {
                        (to, to_s - d * (1.0 - t))
                    };
                    push(
                        &mut pts,
                        pa.lerp(pb, t),
                        town.lane(lane).heading_at(s),
                        lane,
                        s,
                        cmd,
                    );
                }
            }
        }
        while leg < leg_ends.len() && leg_ends[leg] == pi + 1 {
            waypoint_points.push(pts.len().saturating_sub(1));
            leg += 1;
        }
    }
    let mut acc = 0.0;
    for i in 0..pts.len() {
        if i > 0 {
            acc += pts[i - 1].position.distance(pts[i].position);
        }
        pts[i].route_s = acc;
    }
    DenseRoute {
        id: id.to_string(),
        points: pts,
        length_m: acc,
        waypoint_points,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::town::*;
    use crate::route::RouteWaypoint;
    use std::path::PathBuf;

    fn lane(pts: Vec<Vec3>, junction: Option<u32>) -> DriveLane {
        let pts: Vec<Vec2> = pts.iter().map(|p| p.truncate()).collect();
        DriveLane {
            junction: junction.map(JunctionIdx),
            ..crate::map::testtown::lane_through(&pts)
        }
    }

    fn line(a: (f32, f32), b: (f32, f32)) -> Vec<Vec3> {
        let n = 20;
        (0..=n)
            .map(|k| {
                let t = k as f32 / n as f32;
                Vec3::new(a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t, 0.0)
            })
            .collect()
    }

    fn arc(center: (f32, f32), r: f32, a0: f32, a1: f32) -> Vec<Vec3> {
        let n = 24;
        (0..=n)
            .map(|k| {
                let a = a0 + (a1 - a0) * k as f32 / n as f32;
                Vec3::new(center.0 + r * a.cos(), center.1 + r * a.sin(), 0.0)
            })
            .collect()
    }

    /// A hand-made T/4-way junction at the origin, box half size 10 m, lanes
    /// 3.5 m wide driving on the right. Approach from the west (lane 0, along
    /// y = -1.75); connecting lanes: 1 straight, 2 left, 3 right; exits: 4
    /// east, 5 north, 6 south.
    fn junction_town() -> Town {
        use std::f32::consts::{FRAC_PI_2, PI};
        let mut lanes = vec![
            lane(line((-60.0, -1.75), (-10.0, -1.75)), None),
            lane(line((-10.0, -1.75), (10.0, -1.75)), Some(0)),
            // Left: centre (-10, 10), radius 11.75, from angle -90 deg to 0.
            lane(arc((-10.0, 10.0), 11.75, -FRAC_PI_2, 0.0), Some(0)),
            // Right: centre (-10, -10), radius 8.25, from 90 deg down to 0.
            lane(arc((-10.0, -10.0), 8.25, FRAC_PI_2, 0.0), Some(0)),
            lane(line((10.0, -1.75), (60.0, -1.75)), None),
            lane(line((1.75, 10.0), (1.75, 60.0)), None),
            lane(line((-1.75, -10.0), (-1.75, -60.0)), None),
        ];
        let _ = PI;
        lanes[0].successors = vec![LaneIdx(1), LaneIdx(2), LaneIdx(3)];
        lanes[1].successors = vec![LaneIdx(4)];
        lanes[2].successors = vec![LaneIdx(5)];
        lanes[3].successors = vec![LaneIdx(6)];
        for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 4), (2, 5), (3, 6)] {
            lanes[b].predecessors.push(LaneIdx(a));
        }
        Town {
            name: "hand".into(),
            lanes,
            markings: vec![],
            sidewalks: vec![],
            crosswalks: vec![],
            junctions: vec![Junction {
                od_id: "j".into(),
                outline: vec![],
                lights: vec![],
                priorities: vec![],
                yellow_s: None,
            }],
            lights: vec![],
            buildings: vec![],
            road_surface: Mesh::default(),
            bounds: (Vec2::splat(-60.0), Vec2::splat(60.0)),
        }
    }

    fn route(points: &[(f32, f32)]) -> Route {
        Route {
            id: "t".into(),
            town: None,
            waypoints: points
                .iter()
                .map(|&(x, y)| RouteWaypoint {
                    position: Vec3::new(x, y, 0.0),
                    yaw_rad: None,
                })
                .collect(),
            source: PathBuf::from("hand.toml"),
        }
    }

    #[test]
    fn turn_decisions_on_a_hand_made_junction() {
        let t = junction_town();
        let th = 35f32.to_radians();
        assert_eq!(
            turn_decision(&t, LaneIdx(0), &[LaneIdx(1)], th),
            Command::Straight
        );
        assert_eq!(
            turn_decision(&t, LaneIdx(0), &[LaneIdx(2)], th),
            Command::Left
        );
        assert_eq!(
            turn_decision(&t, LaneIdx(0), &[LaneIdx(3)], th),
            Command::Right
        );
    }

    #[test]
    fn dense_route_tags_the_junction_and_is_continuous() {
        let t = junction_town();
        let cfg = PlannerConfig::default();
        for (end, want, lane) in [
            ((30.0, -1.75), Command::Straight, 1),
            ((1.75, 40.0), Command::Left, 2),
            ((-1.75, -40.0), Command::Right, 3),
        ] {
            let r = plan_route(&t, &route(&[(-50.0, -1.75), end]), &cfg).unwrap();
            assert!(r.max_gap_m() <= 1.5, "gap {}", r.max_gap_m());
            // Commands: LaneFollow before, the turn inside, LaneFollow after.
            let inside: Vec<_> = r
                .points
                .iter()
                .filter(|p| p.lane == LaneIdx(lane))
                .collect();
            assert!(!inside.is_empty());
            assert!(inside.iter().all(|p| p.command == want), "{want:?}");
            assert_eq!(r.points[0].command, Command::LaneFollow);
            assert_eq!(r.points.last().unwrap().command, Command::LaneFollow);
            // The driver sees the turn 5 m before the junction.
            let before = r
                .points
                .iter()
                .position(|p| p.position.x >= -15.0 && p.lane == LaneIdx(0))
                .unwrap();
            assert_eq!(r.command_ahead(before, 6.0), want);
            assert_eq!(r.command_ahead(0, 6.0), Command::LaneFollow);
        }
        // Straight: 40 m on lane 0, 20 m through, 20 m on lane 4 = 80 m.
        let r = plan_route(&t, &route(&[(-50.0, -1.75), (30.0, -1.75)]), &cfg).unwrap();
        assert!((r.length_m - 80.0).abs() < 0.2, "{}", r.length_m);
        assert_eq!(r.waypoint_points, vec![0, r.points.len() - 1]);
    }

    #[test]
    fn off_map_waypoint_and_unreachable_leg_are_errors() {
        let t = junction_town();
        let e = plan_route(
            &t,
            &route(&[(-50.0, -1.75), (30.0, 30.0)]),
            &PlannerConfig::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("hand.toml")
                && e.contains("waypoint 1")
                && e.contains("from the nearest driving lane"),
            "{e}"
        );
        // From the east exit back west: no lane leads there.
        let e = plan_route(
            &t,
            &route(&[(30.0, -1.75), (-50.0, -1.75)]),
            &PlannerConfig::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("no drivable path from waypoint 0 to waypoint 1"),
            "{e}"
        );
    }

    #[test]
    fn lane_change_is_tagged_and_continuous() {
        // Two parallel lanes driving +x; lane 1 is left of lane 0.
        let mut a = lane(line((0.0, 0.0), (100.0, 0.0)), None);
        let mut b = lane(line((0.0, 3.5), (100.0, 3.5)), None);
        a.left = Some(LaneIdx(1));
        b.right = Some(LaneIdx(0));
        let mut t = junction_town();
        t.lanes = vec![a, b];
        let r = plan_route(
            &t,
            &route(&[(5.0, 0.0), (80.0, 3.5)]),
            &PlannerConfig::default(),
        )
        .unwrap();
        assert!(
            r.points
                .iter()
                .any(|p| p.command == Command::ChangeLaneLeft)
        );
        assert!(
            !r.points
                .iter()
                .any(|p| p.command == Command::ChangeLaneRight)
        );
        assert!(r.max_gap_m() <= 1.5, "{}", r.max_gap_m());
        assert_eq!(r.points.last().unwrap().lane, LaneIdx(1));
    }
}
