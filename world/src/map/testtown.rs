//! A hand-made town for tests and the traffic soak: a grid of two-way roads.
//!
//! `grid(nx, ny, block_m)` lays `nx * ny` junctions on a square grid
//! `block_m` apart and joins neighbours with straight two-way roads (one
//! 3.5 m lane per direction, right-hand traffic). Every junction gets
//! connecting lanes from each approach to each exit except U-turns (cubic
//! Bezier curves, sampled at about 1 m). Junctions where three or four roads
//! meet are lit: one light per approach, group 0 for approaches along x,
//! group 1 along y, stop line 4 m before the junction, a crosswalk between the
//! stop line and the junction. Sidewalks (2.5 m wide, 0.15 m high) line every
//! road and end at the junction areas, one building fills each block. No
//! markings or road mesh: this town is for traffic, not for the camera.
//!
//! [`FixtureLights`] cycles the lit junctions on a fixed timetable, standing
//! in for the real controller in tests.

use crate::map::town::*;
use crate::route::command::Command;
use crate::route::dense::{DenseRoute, RoutePoint};
use glam::{Vec2, Vec3};

/// Half the side of a junction's square area (metres): lanes end this far from the node.
pub const JUNCTION_HALF_M: f32 = 10.0;
/// Width of one lane (metres).
pub const LANE_WIDTH_M: f32 = 3.5;
/// Distance from the end of an approach lane back to its stop line (metres).
pub const STOP_LINE_BACK_M: f32 = 4.0;
/// Speed limit on every lane of the fixture (metres per second; 30 km/h).
pub const SPEED_LIMIT_MPS: f32 = 30.0 / 3.6;

const SIDEWALK_IN_M: f32 = LANE_WIDTH_M;
const SIDEWALK_OUT_M: f32 = LANE_WIDTH_M + 2.5;
const SIDEWALK_H_M: f32 = 0.15;

/// Resamples a dense polyline to points about `step_m` apart (keeps both ends).
fn resample(dense: &[Vec2], step_m: f32) -> Vec<Vec2> {
    let mut cum = vec![0.0f32];
    for w in dense.windows(2) {
        cum.push(cum.last().unwrap() + (w[1] - w[0]).length());
    }
    let total = *cum.last().unwrap();
    let n = ((total / step_m).ceil() as usize).max(1);
    let mut out = Vec::with_capacity(n + 1);
    let mut j = 0;
    for i in 0..=n {
        let target = total * i as f32 / n as f32;
        while j + 2 < cum.len() && cum[j + 1] < target {
            j += 1;
        }
        let seg = (cum[j + 1] - cum[j]).max(1e-9);
        let t = ((target - cum[j]) / seg).clamp(0.0, 1.0);
        out.push(dense[j].lerp(dense[j + 1], t));
    }
    out
}

fn make_lane(
    points: &[Vec2],
    junction: Option<JunctionIdx>,
    road_id: String,
    od_lane: i32,
) -> DriveLane {
    let centerline: Vec<Vec3> = points.iter().map(|p| p.extend(0.0)).collect();
    let mut s = vec![0.0f32];
    for w in points.windows(2) {
        s.push(s.last().unwrap() + (w[1] - w[0]).length());
    }
    DriveLane {
        road_id,
        od_lane,
        width: vec![LANE_WIDTH_M; points.len()],
        centerline,
        s,
        speed_limit_mps: SPEED_LIMIT_MPS,
        junction,
        successors: Vec::new(),
        predecessors: Vec::new(),
        left: None,
        right: None,
    }
}

fn bezier(p0: Vec2, d0: Vec2, p3: Vec2, d3: Vec2) -> Vec<Vec2> {
    let k = 0.55 * (p3 - p0).length();
    let (p1, p2) = (p0 + d0 * k, p3 - d3 * k);
    let dense: Vec<Vec2> = (0..=200)
        .map(|i| {
            let t = i as f32 / 200.0;
            let u = 1.0 - t;
            p0 * (u * u * u) + p1 * (3.0 * u * u * t) + p2 * (3.0 * u * t * t) + p3 * (t * t * t)
        })
        .collect();
    resample(&dense, 1.0)
}

/// The grid town a command line names: `spec` is `NXxNY` junctions (e.g.
/// `4x4`, 2 to 2,500 junctions, at most 50 a side), `block_m` metres apart
/// (40-1,000). The error says which value is wrong and how to write it.
pub fn grid_of_spec(spec: &str, block_m: f32) -> Result<Town, String> {
    let (nx, ny) = spec
        .split_once('x')
        .and_then(|(a, b)| Some((a.parse::<usize>().ok()?, b.parse::<usize>().ok()?)))
        .ok_or_else(|| format!("--fixture {spec:?}: expected NXxNY, e.g. 4x4"))?;
    if nx * ny < 2 || nx > 50 || ny > 50 {
        return Err(format!(
            "--fixture {spec:?}: between 2 and 2500 junctions, at most 50 per side"
        ));
    }
    if !(40.0..=1000.0).contains(&block_m) {
        return Err(format!(
            "--block-m {block_m}: must be between 40 and 1000 metres"
        ));
    }
    Ok(grid(nx, ny, block_m))
}

/// A grid town of `nx * ny` junctions `block_m` apart (see the module docs).
pub fn grid(nx: usize, ny: usize, block_m: f32) -> Town {
    assert!(nx >= 1 && ny >= 1 && nx * ny >= 2 && block_m > 2.0 * JUNCTION_HALF_M + 10.0);
    let node = |i: usize, j: usize| Vec2::new(i as f32 * block_m, j as f32 * block_m);
    let nid = |i: usize, j: usize| j * nx + i;
    let mut lanes: Vec<DriveLane> = Vec::new();
    // Per node: approach lanes (lane, direction of travel) and exit lanes.
    let mut approaches: Vec<Vec<(usize, Vec2)>> = vec![Vec::new(); nx * ny];
    let mut exits: Vec<Vec<(usize, Vec2)>> = vec![Vec::new(); nx * ny];
    let mut sidewalks = Vec::new();
    let mut crosswalks = Vec::new();
    let mut road = 0;
    for j in 0..ny {
        for i in 0..nx {
            for (di, dj) in [(1usize, 0usize), (0, 1)] {
                let (i2, j2) = (i + di, j + dj);
                if i2 >= nx || j2 >= ny {
                    continue;
                }
                let (a, b) = (node(i, j), node(i2, j2));
                let dir = (b - a).normalize();
                let right = Vec2::new(dir.y, -dir.x);
                let j_m = JUNCTION_HALF_M;
                for (from, to, d, na, nb, od) in [
                    (a, b, dir, nid(i, j), nid(i2, j2), -1),
                    (b, a, -dir, nid(i2, j2), nid(i, j), 1),
                ] {
                    let r = Vec2::new(d.y, -d.x);
                    let p0 = from + d * j_m + r * (LANE_WIDTH_M * 0.5);
                    let p1 = to - d * j_m + r * (LANE_WIDTH_M * 0.5);
                    let pts = resample(&[p0, p1], 1.0);
                    let idx = lanes.len();
                    lanes.push(make_lane(&pts, None, road.to_string(), od));
                    exits[na].push((idx, d));
                    approaches[nb].push((idx, d));
                }
                // Sidewalks on both sides, between the junction areas.
                for side in [1.0f32, -1.0] {
                    let n = right * side;
                    let line = |off: f32| {
                        resample(&[a + dir * j_m + n * off, b - dir * j_m + n * off], 3.0)
                            .into_iter()
                            .map(|p| p.extend(0.0))
                            .collect::<Vec<_>>()
                    };
                    sidewalks.push(Sidewalk {
                        inner: line(SIDEWALK_IN_M),
                        outer: line(SIDEWALK_OUT_M),
                        height_m: SIDEWALK_H_M,
                    });
                }
                // Crosswalks at both ends, just outside the junction areas.
                for (c, d) in [(a, dir), (b, -dir)] {
                    let x0 = c + d * (j_m + 0.5);
                    let x1 = c + d * (j_m + 3.5);
                    let w = right * SIDEWALK_IN_M;
                    crosswalks.push(Crosswalk {
                        corners: [
                            (x0 - w).extend(0.0),
                            (x1 - w).extend(0.0),
                            (x1 + w).extend(0.0),
                            (x0 + w).extend(0.0),
                        ],
                        from_map: false,
                    });
                }
                road += 1;
            }
        }
    }
    let mut junctions = Vec::new();
    let mut lights = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let n = nid(i, j);
            let c = node(i, j);
            let jidx = JunctionIdx(junctions.len() as u32);
            let h = JUNCTION_HALF_M;
            let mut junction = Junction {
                od_id: format!("J{i}_{j}"),
                outline: vec![
                    c + Vec2::new(-h, -h),
                    c + Vec2::new(h, -h),
                    c + Vec2::new(h, h),
                    c + Vec2::new(-h, h),
                ],
                lights: Vec::new(),
                priorities: Vec::new(),
                yellow_s: None,
            };
            let lit = approaches[n].len() >= 3;
            for &(ain, din) in &approaches[n] {
                for &(aout, dout) in &exits[n] {
                    if din.dot(dout) < -0.5 {
                        continue; // no U-turns
                    }
                    let p0 = lanes[ain].centerline.last().unwrap().truncate();
                    let p3 = lanes[aout].centerline[0].truncate();
                    let pts = bezier(p0, din, p3, dout);
                    let idx = lanes.len();
                    let mut l = make_lane(&pts, Some(jidx), format!("J{i}_{j}"), -1);
                    l.predecessors.push(LaneIdx(ain as u32));
                    l.successors.push(LaneIdx(aout as u32));
                    lanes.push(l);
                    lanes[ain].successors.push(LaneIdx(idx as u32));
                    lanes[aout].predecessors.push(LaneIdx(idx as u32));
                }
                if lit {
                    let lane = &lanes[ain];
                    let len = *lane.s.last().unwrap();
                    let s = len - STOP_LINE_BACK_M;
                    let centre = lane.centerline[0].truncate() + din * s;
                    let r = Vec2::new(din.y, -din.x);
                    let half = r * (LANE_WIDTH_M * 0.5);
                    let li = LightIdx(lights.len() as u32);
                    lights.push(TrafficLight {
                        od_id: format!("L{}", lights.len()),
                        position: (centre + r * (SIDEWALK_IN_M + 1.0)).extend(0.0),
                        heading: (-din.y).atan2(-din.x),
                        head_height_m: 3.0,
                        junction: Some(jidx),
                        group: if din.x.abs() > 0.5 { 0 } else { 1 },
                        stop_lines: vec![StopLine {
                            lane: LaneIdx(ain as u32),
                            s,
                            ends: [(centre - half).extend(0.0), (centre + half).extend(0.0)],
                        }],
                    });
                    junction.lights.push(li);
                }
            }
            junctions.push(junction);
        }
    }
    let mut buildings = Vec::new();
    for j in 0..ny.saturating_sub(1) {
        for i in 0..nx.saturating_sub(1) {
            let lo = node(i, j) + Vec2::splat(SIDEWALK_OUT_M + 1.0);
            let hi = node(i + 1, j + 1) - Vec2::splat(SIDEWALK_OUT_M + 1.0);
            buildings.push(Building {
                footprint: vec![lo, Vec2::new(hi.x, lo.y), hi, Vec2::new(lo.x, hi.y)],
                height_m: 12.0,
            });
        }
    }
    let margin = Vec2::splat(SIDEWALK_OUT_M);
    Town {
        name: format!("fixture-grid-{nx}x{ny}"),
        lanes,
        markings: Vec::new(),
        sidewalks,
        crosswalks,
        junctions,
        lights,
        buildings,
        road_surface: Mesh::default(),
        bounds: (node(0, 0) - margin, node(nx - 1, ny - 1) + margin),
    }
}

/// Lane width of [`t_junction`] (metres; Town02's lanes).
pub const T_LANE_WIDTH_M: f32 = 4.0;
/// Half the side of [`t_junction`]'s junction area (metres).
pub const T_JUNCTION_HALF_M: f32 = 9.0;
/// Length of each arm of [`t_junction`] (metres).
pub const T_ARM_M: f32 = 60.0;

/// A connecting lane from `p0` (heading `din`) to `p3` (heading `dout`)
/// as CARLA's junctions draw them: straight, an arc of `radius_m` tangent to
/// both headings, straight again (1 m points). A straight lane when the
/// headings agree.
fn corner_lane(p0: Vec2, din: Vec2, p3: Vec2, dout: Vec2, radius_m: f32) -> Vec<Vec2> {
    let turn = din.perp_dot(dout);
    if turn.abs() < 1e-3 {
        return resample(&[p0, p3], 1.0);
    }
    // The corner where the two straight lines meet: p0 + din * a = p3 - dout * b.
    let a = (p3 - p0).perp_dot(dout) / din.perp_dot(dout);
    let corner = p0 + din * a;
    let (t1, t2) = (corner - din * radius_m, corner + dout * radius_m);
    let normal = if turn > 0.0 { din.perp() } else { -din.perp() };
    let centre = t1 + normal * radius_m;
    let (a1, a2) = ((t1 - centre).to_angle(), (t2 - centre).to_angle());
    let sweep = crate::road::geometry::wrap_angle(a2 - a1);
    let mut dense = vec![p0];
    dense.extend(
        (0..=64).map(|i| centre + Vec2::from_angle(a1 + sweep * i as f32 / 64.0) * radius_m),
    );
    dense.push(p3);
    resample(&dense, 1.0)
}

/// An unsignalled T-junction in the shape of CARLA's Town02 junctions: arms
/// west, east and north of the origin, [`T_ARM_M`] long, one
/// [`T_LANE_WIDTH_M`] lane per direction (right-hand traffic), the junction
/// area [`T_JUNCTION_HALF_M`] to each side of the origin. Its six connecting
/// lanes are straight, arc, straight ([`corner_lane`]): the two straights
/// west-east, the left turns (west to north, north to east) on arcs that leave
/// 4 m of straight at each end, the right turns (north to west, east to north)
/// on arcs of `right_turn_radius_m` (Town02's are about 3.5 m, tighter than
/// the Model 3's 5.5 m turning radius). No lights, sidewalks or buildings.
///
/// Lanes: 0 west arm eastbound, 1 west arm westbound, 2 east arm eastbound,
/// 3 east arm westbound, 4 north arm northbound, 5 north arm southbound, then
/// the connecting lanes 6 west-east, 7 east-west, 8 west-north (left),
/// 9 north-west (right), 10 north-east (left), 11 east-north (right).
pub fn t_junction(right_turn_radius_m: f32) -> Town {
    let (h, w, arm) = (T_JUNCTION_HALF_M, T_LANE_WIDTH_M * 0.5, T_ARM_M);
    let v = Vec2::new;
    let plain = |a: Vec2, b: Vec2, road: &str, od: i32| {
        let mut l = make_lane(&resample(&[a, b], 1.0), None, road.to_string(), od);
        l.width = vec![T_LANE_WIDTH_M; l.centerline.len()];
        l
    };
    let mut lanes = vec![
        plain(v(-h - arm, -w), v(-h, -w), "west", -1),
        plain(v(-h, w), v(-h - arm, w), "west", 1),
        plain(v(h, -w), v(h + arm, -w), "east", -1),
        plain(v(h + arm, w), v(h, w), "east", 1),
        plain(v(w, h), v(w, h + arm), "north", -1),
        plain(v(-w, h + arm), v(-w, h), "north", 1),
    ];
    let left_r = h + w - 4.0;
    // (from lane, to lane, radius)
    let links = [
        (0usize, 2usize, 0.0f32),
        (3, 1, 0.0),
        (0, 4, left_r),
        (5, 1, right_turn_radius_m),
        (5, 2, left_r),
        (3, 4, right_turn_radius_m),
    ];
    for (k, &(from, to, r)) in links.iter().enumerate() {
        let end = |l: &DriveLane, last: bool| {
            let c = &l.centerline;
            let (p, q) = if last {
                (c[c.len() - 2], c[c.len() - 1])
            } else {
                (c[0], c[1])
            };
            (
                if last { q } else { p }.truncate(),
                (q - p).truncate().normalize(),
            )
        };
        let (p0, din) = end(&lanes[from], true);
        let (p3, dout) = end(&lanes[to], false);
        let mut l = make_lane(
            &corner_lane(p0, din, p3, dout, r),
            Some(JunctionIdx(0)),
            format!("T{k}"),
            -1,
        );
        l.width = vec![T_LANE_WIDTH_M; l.centerline.len()];
        l.predecessors.push(LaneIdx(from as u32));
        l.successors.push(LaneIdx(to as u32));
        let idx = LaneIdx(lanes.len() as u32);
        lanes.push(l);
        lanes[from].successors.push(idx);
        lanes[to].predecessors.push(idx);
    }
    Town {
        name: "fixture-t-junction".into(),
        lanes,
        junctions: vec![Junction {
            od_id: "T".into(),
            outline: vec![v(-h, -h), v(h, -h), v(h, h), v(-h, h)],
            lights: Vec::new(),
            priorities: Vec::new(),
            yellow_s: None,
        }],
        bounds: (v(-h - arm, -h), v(h + arm, h + arm)),
        ..Town::empty("fixture-t-junction")
    }
}

/// A plain lane along the polyline `points` (ground plane, metres), for
/// hand-made towns in tests: 3.5 m wide, the fixture's speed limit, no
/// junction, no neighbours; set other fields with struct update syntax.
pub fn lane_through(points: &[Vec2]) -> DriveLane {
    make_lane(points, None, "hand".to_string(), -1)
}

/// A straight road `length_m` long along +x with two lanes in the same
/// direction, for lane-change tests: lane 0 on the right (centre y = -1.75),
/// lane 1 on its left (y = 1.75), each the other's neighbour. No junction,
/// light or sidewalk.
pub fn two_lane_road(length_m: f32) -> Town {
    let line = |y: f32| resample(&[Vec2::new(0.0, y), Vec2::new(length_m, y)], 1.0);
    let mut right = make_lane(&line(-LANE_WIDTH_M / 2.0), None, "0".into(), -1);
    let mut left = make_lane(&line(LANE_WIDTH_M / 2.0), None, "0".into(), -2);
    right.left = Some(LaneIdx(1));
    left.right = Some(LaneIdx(0));
    Town {
        lanes: vec![right, left],
        bounds: (Vec2::new(0.0, -10.0), Vec2::new(length_m, 10.0)),
        ..Town::empty("fixture-two-lane-road")
    }
}

/// The route a planner gives through `waypoints` (x, y in metres, heading
/// in radians) on `town`, for tests and scripted scenes.
pub fn planned_route(
    town: &Town,
    waypoints: &[(f32, f32, f32)],
) -> Result<DenseRoute, crate::route::RouteError> {
    let route = crate::route::Route {
        id: "planned".into(),
        town: None,
        waypoints: waypoints
            .iter()
            .map(|&(x, y, yaw)| crate::route::RouteWaypoint {
                position: Vec3::new(x, y, 0.0),
                yaw_rad: Some(yaw),
            })
            .collect(),
        source: "testtown::planned_route".into(),
    };
    crate::route::planner::plan_route(
        town,
        &route,
        &crate::route::planner::PlannerConfig::default(),
    )
}

/// A dense route along the polyline `points` (ground plane, metres), for
/// tests and scripted scenes that need no lanes: headings along the
/// segments, every point on lane 0 with `s` = `route_s` = the distance along
/// the points, commands `LaneFollow`.
pub fn route_through(points: &[Vec2]) -> DenseRoute {
    let mut pts = Vec::with_capacity(points.len());
    let mut acc = 0.0;
    for (i, p) in points.iter().enumerate() {
        if i > 0 {
            acc += points[i - 1].distance(*p);
        }
        let d = match (i.checked_sub(1), points.get(i + 1)) {
            (_, Some(next)) => *next - *p,
            (Some(prev), None) => *p - points[prev],
            (None, None) => Vec2::X,
        };
        pts.push(RoutePoint {
            position: p.extend(0.0),
            heading: d.y.atan2(d.x),
            lane: LaneIdx(0),
            s: acc,
            command: Command::LaneFollow,
            route_s: acc,
        });
    }
    DenseRoute {
        id: "route-through".into(),
        points: pts,
        length_m: acc,
        waypoint_points: vec![0, points.len().saturating_sub(1)],
    }
}

/// A fixed-time light controller for the fixture: group 0 and group 1 take turns.
///
/// Each junction cycles green (`green_s`), yellow (`yellow_s`), all red
/// (`all_red_s`) for group 0, then the same for group 1.
#[derive(Debug, Clone)]
pub struct FixtureLights {
    /// Green time per group (seconds).
    pub green_s: f32,
    /// Yellow time per group (seconds).
    pub yellow_s: f32,
    /// All-red clearance after each yellow (seconds).
    pub all_red_s: f32,
    groups: Vec<u32>,
}

impl FixtureLights {
    /// A controller for a town's lights with CARLA-like timings (10 s green, 3 s yellow, 2 s all red).
    pub fn new(town: &Town) -> FixtureLights {
        FixtureLights {
            green_s: 10.0,
            yellow_s: 3.0,
            all_red_s: 2.0,
            groups: town.lights.iter().map(|l| l.group).collect(),
        }
    }

    /// The states at a tick (40 Hz), indexed by `LightIdx`.
    pub fn states_at(&self, tick: u64, out: &mut Vec<LightState>) {
        let t = tick as f32 * 0.025;
        let half = self.green_s + self.yellow_s + self.all_red_s;
        let phase = t % (2.0 * half);
        let (active, p) = if phase < half {
            (0, phase)
        } else {
            (1, phase - half)
        };
        out.clear();
        out.extend(self.groups.iter().map(|&g| {
            if g != active || p >= self.green_s + self.yellow_s {
                LightState::Red
            } else if p < self.green_s {
                LightState::Green
            } else {
                LightState::Yellow
            }
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_spec_is_nx_by_ny_in_bounds() {
        assert_eq!(grid_of_spec("3x2", 80.0).unwrap().junctions.len(), 6);
        assert!(
            grid_of_spec("3", 80.0)
                .unwrap_err()
                .contains("expected NXxNY")
        );
        assert!(
            grid_of_spec("1x1", 80.0)
                .unwrap_err()
                .contains("between 2 and 2500")
        );
        assert!(grid_of_spec("51x2", 80.0).is_err());
        assert!(
            grid_of_spec("2x2", 30.0)
                .unwrap_err()
                .contains("--block-m 30")
        );
    }

    #[test]
    fn grid_lane_graph_is_connected_and_dense() {
        let t = grid(3, 3, 60.0);
        // 12 roads x 2 lanes, plus connecting lanes.
        let plain = t.lanes.iter().filter(|l| l.junction.is_none()).count();
        assert_eq!(plain, 24);
        for (i, l) in t.lanes.iter().enumerate() {
            assert!(!l.successors.is_empty(), "lane {i} is a dead end");
            for w in l.centerline.windows(2) {
                let d = (w[1] - w[0]).length();
                assert!(d > 0.3 && d <= 1.01, "lane {i} spacing {d}");
            }
            for &s in &l.successors {
                let gap =
                    (t.lanes[s.0 as usize].centerline[0] - *l.centerline.last().unwrap()).length();
                assert!(gap < 1e-3, "lane {i} -> {} gap {gap}", s.0);
            }
        }
        // The centre junction has 4 approaches -> 4 lights; corners are unlit.
        assert_eq!(t.junctions[4].lights.len(), 4);
        assert!(t.junctions[0].lights.is_empty());
        assert_eq!(t.lights.len(), 4 + 4 * 3);
    }

    #[test]
    fn fixture_lights_alternate_groups() {
        let t = grid(3, 3, 60.0);
        let c = FixtureLights::new(&t);
        let mut s = Vec::new();
        c.states_at(0, &mut s);
        for (l, st) in t.lights.iter().zip(&s) {
            assert_eq!(
                *st,
                if l.group == 0 {
                    LightState::Green
                } else {
                    LightState::Red
                }
            );
        }
        c.states_at(40 * 11, &mut s);
        assert!(
            s.iter()
                .zip(&t.lights)
                .all(|(st, l)| l.group == 1 || *st == LightState::Yellow)
        );
        c.states_at(40 * 16, &mut s);
        assert!(
            s.iter()
                .zip(&t.lights)
                .all(|(st, l)| (l.group == 1) == (*st == LightState::Green))
        );
    }
}
