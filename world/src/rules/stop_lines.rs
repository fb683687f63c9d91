//! Stop lines: one table per town, indexed by lane, and the stops a route
//! crosses, in route order.
//!
//! A town's stop lines come from its lights ([`crate::TrafficLight::stop_lines`]).
//! [`StopLines`] lists them once, with what every consumer needs (the light,
//! the lane and arc length, the line's centre and ends, the driving heading
//! there), and indexes them by lane. [`StopLines::on_route`] finds the stops
//! a dense route crosses: a stop line is on the route where a route point's
//! lane is the stop line's lane and the route passes its arc length.

use glam::Vec2;

use super::{crossing_point, heading_agrees, light_state, must_stop, nearest_lane};
use crate::map::town::{LaneIdx, LightIdx, LightState, Town};
use crate::road::geometry::segments_intersect;
use crate::route::dense::DenseRoute;

/// One stop line of a town, as the table lists it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StopLineEntry {
    /// The light that governs it.
    pub light: LightIdx,
    /// The lane it is on (the approach lane).
    pub lane: LaneIdx,
    /// Arc length along that lane (metres).
    pub s: f32,
    /// Centre of the line (metres, ground plane).
    pub position: Vec2,
    /// Driving heading of the lane at the line (radians, counter-clockwise from +x).
    pub heading: f32,
    /// The line's ends (metres, ground plane): left end first, right end
    /// second, seen in the driving direction.
    pub ends: [Vec2; 2],
}

/// How far behind the rear bumper the paper's tail segment reaches (metres;
/// TimeParam `wor_common.py` `_vehicle_tail_segment`: `extent + 1.5`).
pub const TAIL_BEYOND_REAR_M: f32 = 1.5;
/// Half the paper's stop-line segment, in lane widths (TimeParam `_stop_line_segment`:
/// `0.6 * lane_width` each way). A town's stop lines span half a lane width each way.
pub const RED_LINE_HALF_LANES: f32 = 0.6;

/// The paper's tail segment of a vehicle (TimeParam `_vehicle_tail_segment`): from its
/// crossing point ([`crossing_point`], 0.8 half-lengths behind the centre) back to
/// [`TAIL_BEYOND_REAR_M`] behind the rear bumper.
pub fn tail_segment(position: Vec2, heading: f32, length_m: f32) -> (Vec2, Vec2) {
    let back = Vec2::from_angle(heading);
    (
        crossing_point(position, heading, length_m),
        position - back * (length_m / 2.0 + TAIL_BEYOND_REAR_M),
    )
}

impl StopLineEntry {
    /// Whether a vehicle at `position` (metres) heading `heading` (radians), `length_m`
    /// long, stands over this line as the paper's scorer tests it each tick
    /// (TimeParam `_check_red_light`, docs/protocol.md §3): it faces the line's lane
    /// direction (a positive dot product), its tail segment ([`tail_segment`])
    /// crosses the line widened to [`RED_LINE_HALF_LANES`] lane widths each way, and
    /// the driving lane nearest the segment's far end is on the line's road and
    /// OpenDRIVE lane. The light's state is the caller's to check.
    pub fn under_tail(&self, town: &Town, position: Vec2, heading: f32, length_m: f32) -> bool {
        if Vec2::from_angle(self.heading).dot(Vec2::from_angle(heading)) <= 0.0 {
            return false;
        }
        let (close, far) = tail_segment(position, heading, length_m);
        let widen = RED_LINE_HALF_LANES / 0.5;
        let a = self.position + (self.ends[0] - self.position) * widen;
        let b = self.position + (self.ends[1] - self.position) * widen;
        if !segments_intersect(close, far, a, b) {
            return false;
        }
        let (Some(line_lane), Some(lp)) = (
            town.lanes.get(self.lane.0 as usize),
            nearest_lane(town, far, None),
        ) else {
            return false;
        };
        let under = &town.lanes[lp.lane.0 as usize];
        (&under.road_id, under.od_lane) == (&line_lane.road_id, line_lane.od_lane)
    }
}

/// Every stop line of a town, and for each lane its stop lines by arc length.
#[derive(Debug, Clone, Default)]
pub struct StopLines {
    lines: Vec<StopLineEntry>,
    /// For each lane, indices into `lines`, sorted by arc length (then light).
    by_lane: Vec<Vec<usize>>,
}

impl StopLines {
    /// Collects the stop lines of a town's lights, in light order.
    pub fn new(town: &Town) -> StopLines {
        let mut lines = Vec::new();
        let mut by_lane = vec![Vec::new(); town.lanes.len()];
        for (li, light) in town.lights.iter().enumerate() {
            for sl in &light.stop_lines {
                let ends = [sl.ends[0].truncate(), sl.ends[1].truncate()];
                let lane = town.lanes.get(sl.lane.0 as usize);
                let heading = match lane {
                    Some(l) => l.heading_at(sl.s),
                    // A line on no lane faces across its ends (left -> right, turned clockwise).
                    None => {
                        let f = (ends[1] - ends[0]).perp();
                        f.y.atan2(f.x)
                    }
                };
                if let Some(v) = by_lane.get_mut(sl.lane.0 as usize) {
                    v.push(lines.len());
                }
                lines.push(StopLineEntry {
                    light: LightIdx(li as u32),
                    lane: sl.lane,
                    s: sl.s,
                    position: (ends[0] + ends[1]) * 0.5,
                    heading,
                    ends,
                });
            }
        }
        for v in &mut by_lane {
            v.sort_by(|&a, &b| {
                lines[a]
                    .s
                    .total_cmp(&lines[b].s)
                    .then(lines[a].light.cmp(&lines[b].light))
            });
        }
        StopLines { lines, by_lane }
    }

    /// Every stop line, in light order.
    pub fn all(&self) -> &[StopLineEntry] {
        &self.lines
    }

    /// The stop lines on a lane, by arc length (none for a lane not in the town).
    pub fn on_lane(&self, lane: LaneIdx) -> impl Iterator<Item = &StopLineEntry> + '_ {
        self.by_lane
            .get(lane.0 as usize)
            .map_or(&[][..], |v| &v[..])
            .iter()
            .map(|&k| &self.lines[k])
    }

    /// The stop line whose light holds a standing vehicle at `position`
    /// (metres) heading `heading` (radians), `length_m` long: a line in its
    /// driving direction ([`heading_agrees`]) whose light says stop to a
    /// standing vehicle ([`must_stop`]: red or yellow), which the vehicle's
    /// crossing point ([`crossing_point`]) has not passed, with the front
    /// bumper at most `queue_m` metres before it (room for the cars queued
    /// ahead) and within the line's width (plus half a metre) sideways.
    /// `lights` is indexed by [`LightIdx`].
    pub fn holding(
        &self,
        position: Vec2,
        heading: f32,
        length_m: f32,
        lights: &[LightState],
        queue_m: f32,
    ) -> Option<&StopLineEntry> {
        let forward = Vec2::from_angle(heading);
        let front = position + forward * (length_m / 2.0);
        let cross = crossing_point(position, heading, length_m);
        self.lines.iter().find(|line| {
            let along = Vec2::from_angle(line.heading);
            let half_width = line.ends[0].distance(line.ends[1]) / 2.0;
            heading_agrees(line.heading, heading)
                && must_stop(light_state(lights, line.light), 0.0, 0.0, 1.0)
                && (line.position - cross).dot(along) > 0.0
                && (line.position - front).dot(along) <= queue_m
                && (front - line.position).dot(along.perp()).abs() <= half_width + 0.5
        })
    }

    /// The stop lines a dense route crosses, in route order. A line counts
    /// where a route point's lane is the line's lane and the next point is
    /// past its arc length (or on another lane); one light's line met twice
    /// within 0.5 m counts once.
    pub fn on_route(&self, route: &DenseRoute) -> RouteStops {
        let mut stops: Vec<RouteStop> = Vec::new();
        for w in route.points.windows(2) {
            let (a, b) = (w[0], w[1]);
            for line in self.on_lane(a.lane) {
                if a.s <= line.s && (b.lane != a.lane || line.s < b.s) {
                    let route_s = a.route_s + (line.s - a.s);
                    if stops.last().is_none_or(|last| {
                        (last.route_s - route_s).abs() > 0.5 || last.light != line.light
                    }) {
                        stops.push(RouteStop {
                            route_s,
                            light: line.light,
                            line: *line,
                        });
                    }
                }
            }
        }
        stops.sort_by(|a, b| a.route_s.total_cmp(&b.route_s));
        RouteStops { stops }
    }
}

/// A stop line on a route.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RouteStop {
    /// Distance along the route (metres).
    pub route_s: f32,
    /// The light.
    pub light: LightIdx,
    /// The stop line.
    pub line: StopLineEntry,
}

/// The stop lines a route crosses, sorted by distance along the route.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RouteStops {
    stops: Vec<RouteStop>,
}

impl RouteStops {
    /// Every stop, in route order.
    pub fn all(&self) -> &[RouteStop] {
        &self.stops
    }

    /// The first stop farther along the route than `route_s` (metres).
    pub fn next_after(&self, route_s: f32) -> Option<&RouteStop> {
        self.after(route_s).next()
    }

    /// Every stop farther along the route than `route_s` (metres), nearest
    /// first.
    pub fn after(&self, route_s: f32) -> impl Iterator<Item = &RouteStop> {
        self.stops.iter().skip_while(move |s| s.route_s <= route_s)
    }

    /// The light ahead: the first stop farther along the route than
    /// `route_s` and no more than `range_m` beyond it (metres), with its
    /// distance from `route_s` (metres). What "the light ahead" means for the
    /// selectors (any range), the dataset's statistics and `mrdrive render`.
    pub fn light_ahead(&self, route_s: f32, range_m: f32) -> Option<(&RouteStop, f32)> {
        let stop = self.next_after(route_s)?;
        let d = stop.route_s - route_s;
        (d <= range_m).then_some((stop, d))
    }

    /// The last stop at or before `route_s` along the route (metres).
    pub fn last_up_to(&self, route_s: f32) -> Option<&RouteStop> {
        self.stops.iter().rev().find(|s| s.route_s <= route_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown::{JUNCTION_HALF_M, STOP_LINE_BACK_M, grid, planned_route};
    use crate::map::town::{StopLine, TrafficLight};
    use glam::Vec3;
    use std::f32::consts::PI;

    #[test]
    fn the_table_indexes_every_line_by_lane_with_its_pose() {
        let t = grid(3, 3, 60.0);
        let lines = StopLines::new(&t);
        assert_eq!(
            lines.all().len(),
            t.lights.iter().map(|l| l.stop_lines.len()).sum()
        );
        // The junction at (60, 0) is lit (three roads meet); its west approach
        // runs +x on lane 0 (y = -1.75) from x = 10 to x = 50; the stop line
        // is 4 m before its end.
        let on0: Vec<_> = lines.on_lane(LaneIdx(0)).collect();
        assert_eq!(on0.len(), 1);
        let l = on0[0];
        let s = 40.0 - STOP_LINE_BACK_M;
        assert!((l.s - s).abs() < 1e-4, "{}", l.s);
        let x = JUNCTION_HALF_M + s;
        assert!(
            l.position.distance(Vec2::new(x, -1.75)) < 1e-4,
            "{}",
            l.position
        );
        assert!(l.heading.abs() < 1e-4);
        // Left end first, seen driving +x: the left end is on the north side.
        assert!(l.ends[0].y > l.ends[1].y);
        // The oncoming lane 1 (-x) ends at the corner junction (0, 0): unlit.
        assert_eq!(lines.on_lane(LaneIdx(1)).count(), 0);
        assert_eq!(lines.on_lane(LaneIdx(999)).count(), 0);
    }

    #[test]
    fn a_red_light_holds_a_car_standing_before_its_line_in_its_direction() {
        let t = grid(3, 3, 60.0);
        let lines = StopLines::new(&t);
        // Lane 0's line: heading +x at y = -1.75, governed by `light`.
        let line = *lines.on_lane(LaneIdx(0)).next().unwrap();
        let x = line.position.x;
        let mut lights = vec![LightState::Green; t.lights.len()];
        let red = |lights: &mut Vec<LightState>, s| lights[line.light.0 as usize] = s;
        let car = 4.6;
        // The car's front 1 m before the line.
        let at = |dx: f32, dy: f32| Vec2::new(x - car / 2.0 - 1.0 + dx, -1.75 + dy);
        assert_eq!(lines.holding(at(0.0, 0.0), 0.0, car, &lights, 20.0), None);
        red(&mut lights, LightState::Red);
        assert_eq!(
            lines.holding(at(0.0, 0.0), 0.0, car, &lights, 20.0),
            Some(&line)
        );
        red(&mut lights, LightState::Yellow);
        assert!(
            lines
                .holding(at(0.0, 0.0), 0.0, car, &lights, 20.0)
                .is_some()
        );
        red(&mut lights, LightState::Red);
        // Queued 15 m back: held; 25 m back: not.
        assert!(
            lines
                .holding(at(-15.0, 0.0), 0.0, car, &lights, 20.0)
                .is_some()
        );
        assert!(
            lines
                .holding(at(-25.0, 0.0), 0.0, car, &lights, 20.0)
                .is_none()
        );
        // Nose over the line, the crossing point (4.14 m behind the front) not: still
        // held; the crossing point past the line: not.
        assert!(
            lines
                .holding(at(2.0, 0.0), 0.0, car, &lights, 20.0)
                .is_some()
        );
        assert!(
            lines
                .holding(at(6.0, 0.0), 0.0, car, &lights, 20.0)
                .is_none()
        );
        // In the oncoming lane, or facing the other way: not held by it.
        assert!(
            lines
                .holding(at(0.0, 3.5), 0.0, car, &lights, 20.0)
                .is_none()
        );
        assert!(
            lines
                .holding(at(0.0, 0.0), PI, car, &lights, 20.0)
                .is_none()
        );
    }

    #[test]
    fn a_route_through_a_lit_junction_meets_its_stop_line_once_at_its_route_distance() {
        let t = grid(3, 3, 60.0);
        // From x = 15 on lane 0 straight through the junction at (60, 0) to x = 100.
        let dense = planned_route(&t, &[(15.0, -1.75, 0.0), (100.0, -1.75, 0.0)]).unwrap();
        let stops = StopLines::new(&t).on_route(&dense);
        assert_eq!(stops.all().len(), 1, "{:?}", stops.all());
        let st = stops.all()[0];
        // The line is at x = 46: 31 m from the start.
        assert!((st.route_s - 31.0).abs() < 0.01, "{}", st.route_s);
        assert_eq!(st.line.lane, LaneIdx(0));
        assert_eq!(stops.next_after(30.0).map(|s| s.light), Some(st.light));
        assert!(stops.next_after(31.5).is_none());
        // The light ahead: within range only, with its distance.
        let (ahead, d) = stops.light_ahead(20.0, 15.0).unwrap();
        assert_eq!(ahead.light, st.light);
        assert!((d - (ahead.route_s - 20.0)).abs() < 1e-6);
        assert!(stops.light_ahead(20.0, d - 0.01).is_none());
        assert!(stops.light_ahead(31.5, f32::INFINITY).is_none());
        assert!(stops.last_up_to(30.0).is_none());
        assert_eq!(stops.last_up_to(40.0).map(|s| s.route_s), Some(st.route_s));
    }

    #[test]
    fn a_route_that_starts_past_the_line_or_on_the_other_lane_meets_none() {
        let t = grid(3, 3, 60.0);
        let dense = planned_route(&t, &[(47.0, -1.75, 0.0), (100.0, -1.75, 0.0)]).unwrap();
        assert!(StopLines::new(&t).on_route(&dense).all().is_empty());
        // Westbound through the junction at (60, 0): its east approach is lit.
        let dense = planned_route(&t, &[(100.0, 1.75, PI), (20.0, 1.75, PI)]).unwrap();
        let stops = StopLines::new(&t).on_route(&dense);
        assert_eq!(stops.all().len(), 1);
        // The east approach ends at x = 70; its line is at x = 74: 26 m from x = 100.
        assert!((stops.all()[0].route_s - 26.0).abs() < 0.01);
    }

    #[test]
    fn lines_on_a_lane_are_sorted_by_arc_length() {
        let t0 = grid(3, 3, 60.0);
        let line = |s: f32| StopLine {
            lane: LaneIdx(0),
            s,
            ends: [Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, -1.0, 0.0)],
        };
        let light = |s: f32| TrafficLight {
            od_id: "x".into(),
            position: Vec3::ZERO,
            heading: 0.0,
            head_height_m: 3.0,
            junction: None,
            group: 0,
            stop_lines: vec![line(s)],
        };
        let t = Town {
            lights: vec![light(20.0), light(5.0), light(12.0)],
            ..t0
        };
        let s: Vec<(f32, u32)> = StopLines::new(&t)
            .on_lane(LaneIdx(0))
            .map(|l| (l.s, l.light.0))
            .collect();
        assert_eq!(s, vec![(5.0, 1), (12.0, 2), (20.0, 0)]);
    }
}
