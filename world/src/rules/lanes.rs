//! The lane under a point: one rule for the ego's lane (the outside-lane
//! monitor, the NPCs' junction bookkeeping), the route planner's snapping of
//! waypoints and the labels.
//!
//! A point projects onto a lane's centreline ([`project_on_lane`]): arc
//! length, distance, signed offset, and the lane's driving heading and width
//! there (the width from [`DriveLane::width_at`], the one width lookup).
//! A heading agrees with a lane when it is within 60 degrees of the lane's
//! driving heading there ([`heading_agrees`]).
//!
//! - **Under** ([`LaneGrid::lane_under`]): among the lanes whose centreline
//!   comes within half their width plus [`ON_LANE_MARGIN_M`] of the point and
//!   whose heading agrees, the nearest; plain lanes win ties with junction
//!   lanes (by 1 cm), so a car on a lane that continues into a junction
//!   stays on it until it is really inside. `None`: off the driving lanes,
//!   or against them.
//! - **Nearest** ([`nearest_lane`]): for snapping a point that may lie
//!   beside the road (route waypoints): the nearest lane, preferring one
//!   whose heading agrees when it is at most 3 m farther.
//!
//! Distances are to the centreline polyline, so a point beyond a lane's end
//! is as far from it as from the lane's last point.

use glam::Vec2;

use crate::map::town::{DriveLane, LaneIdx, Town};

/// Extra distance beyond half a lane's width within which a point is still on it (metres).
pub const ON_LANE_MARGIN_M: f32 = 0.5;

/// How far beyond half a lane's width a car's centre may be and still count as
/// inside the driving lanes (metres): the leaderboard's `ALLOWED_OUT_DISTANCE`
/// (`OutsideRouteLanesTest`), the shoulder between a lane and its sidewalk.
pub const ALLOWED_OUT_M: f32 = 1.3;

/// The smallest angle between a car's heading and the lane under it that makes
/// it drive against the lane (degrees): the leaderboard's
/// `MAX_ALLOWED_VEHICLE_ANGLE` (`OutsideRouteLanesTest`).
pub const WRONG_WAY_DEG: f32 = 120.0;

/// How a car stands to the driving lanes, as the leaderboard's
/// `OutsideRouteLanesTest` sees it ([`LaneGrid::standing`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LaneStanding {
    /// On a driving lane, in its direction (or anywhere in a junction).
    InLane,
    /// Farther than half a lane's width plus [`ALLOWED_OUT_M`] from every
    /// driving lane: on a sidewalk, a verge, a building's lot.
    OutsideLanes,
    /// Nearest to a lane outside a junction that runs the other way (more than
    /// [`WRONG_WAY_DEG`] from the car's heading).
    WrongWay,
}

/// Cosine of the largest angle between a heading and a lane's driving
/// heading that still agree (60 degrees).
pub const HEADING_AGREEMENT_COS: f32 = 0.5;

/// How much farther a lane whose heading agrees may be than the nearest one
/// and still be chosen when snapping (metres).
pub const SNAP_AGREEMENT_M: f32 = 3.0;

/// Penalty of a junction lane against a plain one when choosing the lane under a point (metres).
const JUNCTION_TIE_M: f32 = 0.01;

/// A place on a lane: where a point projects onto the lane's centreline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LanePoint {
    /// The lane.
    pub lane: LaneIdx,
    /// Arc length along the lane (metres).
    pub s: f32,
    /// Distance from the query point to the centreline (metres).
    pub distance_m: f32,
    /// Signed lateral offset from the centreline, positive to the left (metres).
    pub offset_m: f32,
    /// The lane's driving heading there (radians, counter-clockwise from +x).
    pub heading: f32,
    /// The lane's width there (metres).
    pub width_m: f32,
}

/// Projects `p` (ground plane) onto a lane's centreline; `None` for a lane
/// without points or not in the town.
pub fn project_on_lane(town: &Town, lane: LaneIdx, p: Vec2) -> Option<LanePoint> {
    let l: &DriveLane = town.lanes.get(lane.0 as usize)?;
    let pr = l.project(p)?;
    Some(LanePoint {
        lane,
        s: pr.s,
        distance_m: pr.distance,
        offset_m: pr.offset,
        heading: l.heading_at(pr.s),
        width_m: l.width_at(pr.s),
    })
}

/// Whether a heading (radians) agrees with a lane's driving heading (radians): within 60 degrees.
pub fn heading_agrees(lane_heading: f32, heading: f32) -> bool {
    Vec2::from_angle(lane_heading).dot(Vec2::from_angle(heading)) >= HEADING_AGREEMENT_COS
}

/// Whether a projection counts as on its lane: within half the lane's width
/// plus [`ON_LANE_MARGIN_M`] of its centreline.
pub fn within_lane(lp: &LanePoint) -> bool {
    lp.distance_m <= lp.width_m * 0.5 + ON_LANE_MARGIN_M
}

/// The lane nearest to `p` (ground plane), for snapping (see the module
/// docs). With `heading` (radians), a lane whose heading agrees is chosen
/// when it is at most [`SNAP_AGREEMENT_M`] farther than the nearest lane.
/// `None` only for a town without lanes.
pub fn nearest_lane(town: &Town, p: Vec2, heading: Option<f32>) -> Option<LanePoint> {
    let all: Vec<LanePoint> = (0..town.lanes.len())
        .filter_map(|i| project_on_lane(town, LaneIdx(i as u32), p))
        .collect();
    let best_any = all
        .iter()
        .copied()
        .min_by(|a, b| a.distance_m.total_cmp(&b.distance_m))?;
    if let Some(h) = heading {
        let agree = all
            .iter()
            .copied()
            .filter(|lp| lp.distance_m <= best_any.distance_m.max(0.0) + SNAP_AGREEMENT_M)
            .filter(|lp| heading_agrees(lp.heading, h))
            .min_by(|a, b| a.distance_m.total_cmp(&b.distance_m));
        if let Some(a) = agree {
            return Some(a);
        }
    }
    Some(best_any)
}

/// A grid over lane centreline points: which lanes pass near a point.
#[derive(Debug, Clone)]
pub struct LaneGrid {
    cell_m: f32,
    origin: Vec2,
    nx: usize,
    ny: usize,
    /// For each cell, the lanes with a centreline point in it, in lane order.
    cells: Vec<Vec<LaneIdx>>,
}

impl LaneGrid {
    /// Builds the grid with `cell_m`-metre cells.
    pub fn new(town: &Town, cell_m: f32) -> LaneGrid {
        let mut lo = Vec2::splat(f32::INFINITY);
        let mut hi = Vec2::splat(f32::NEG_INFINITY);
        for l in &town.lanes {
            for p in &l.centerline {
                lo = lo.min(p.truncate());
                hi = hi.max(p.truncate());
            }
        }
        if !lo.is_finite() {
            lo = Vec2::ZERO;
            hi = Vec2::ZERO;
        }
        let origin = lo - Vec2::splat(cell_m);
        let nx = (((hi.x - origin.x) / cell_m) as usize) + 2;
        let ny = (((hi.y - origin.y) / cell_m) as usize) + 2;
        let mut cells: Vec<Vec<LaneIdx>> = vec![Vec::new(); nx * ny];
        for (li, l) in town.lanes.iter().enumerate() {
            for p in &l.centerline {
                let c = ((p.x - origin.x) / cell_m) as usize
                    + ((p.y - origin.y) / cell_m) as usize * nx;
                let lane = LaneIdx(li as u32);
                if cells[c].last() != Some(&lane) {
                    cells[c].push(lane);
                }
            }
        }
        LaneGrid {
            cell_m,
            origin,
            nx,
            ny,
            cells,
        }
    }

    /// The lanes with a centreline point in the cell of `p` or its eight
    /// neighbours, each once.
    pub fn lanes_near(&self, p: Vec2) -> Vec<LaneIdx> {
        let cx = ((p.x - self.origin.x) / self.cell_m).floor() as i64;
        let cy = ((p.y - self.origin.y) / self.cell_m).floor() as i64;
        let mut seen: Vec<LaneIdx> = Vec::new();
        for yy in cy - 1..=cy + 1 {
            for xx in cx - 1..=cx + 1 {
                if xx < 0 || yy < 0 || xx as usize >= self.nx || yy as usize >= self.ny {
                    continue;
                }
                for &lane in &self.cells[xx as usize + yy as usize * self.nx] {
                    if !seen.contains(&lane) {
                        seen.push(lane);
                    }
                }
            }
        }
        seen
    }

    /// Whether `p` lies within the paved width of some driving lane, whatever its direction.
    pub fn on_any_lane(&self, town: &Town, p: Vec2) -> bool {
        self.within_any_lane(town, p, 0.0)
    }

    /// Whether `p` lies within the paved width of some driving lane widened
    /// by `margin_m` on each side (metres), whatever its direction.
    pub fn within_any_lane(&self, town: &Town, p: Vec2, margin_m: f32) -> bool {
        self.lanes_near(p).into_iter().any(|lane| {
            project_on_lane(town, lane, p)
                .is_some_and(|lp| lp.distance_m <= lp.width_m * 0.5 + margin_m)
        })
    }

    /// How a car at `p` heading `heading` (radians) stands to the driving lanes
    /// ([`LaneStanding`]): the nearest lane decides, plain lanes winning ties with
    /// junction lanes as in [`LaneGrid::lane_under`].
    pub fn standing(&self, town: &Town, p: Vec2, heading: f32) -> LaneStanding {
        let mut nearest: Option<(f32, LanePoint)> = None;
        for lane in self.lanes_near(p) {
            let Some(lp) = project_on_lane(town, lane, p) else {
                continue;
            };
            let junction = town.lane(lp.lane).junction.is_some();
            let key =
                lp.distance_m - lp.width_m * 0.5 + if junction { JUNCTION_TIE_M } else { 0.0 };
            if nearest.is_none_or(|(k, _)| key < k) {
                nearest = Some((key, lp));
            }
        }
        let Some((beyond, lp)) = nearest else {
            return LaneStanding::OutsideLanes;
        };
        if beyond > ALLOWED_OUT_M {
            return LaneStanding::OutsideLanes;
        }
        let against = Vec2::from_angle(lp.heading).dot(Vec2::from_angle(heading))
            < WRONG_WAY_DEG.to_radians().cos();
        if against && town.lane(lp.lane).junction.is_none() {
            LaneStanding::WrongWay
        } else {
            LaneStanding::InLane
        }
    }

    /// The lane under a point for a heading (radians), see the module docs;
    /// `None` off the driving lanes or against them.
    pub fn lane_under(&self, town: &Town, p: Vec2, heading: f32) -> Option<LanePoint> {
        let tie = |lp: &LanePoint| {
            lp.distance_m
                + if town.lane(lp.lane).junction.is_some() {
                    JUNCTION_TIE_M
                } else {
                    0.0
                }
        };
        let mut best: Option<LanePoint> = None;
        for lane in self.lanes_near(p) {
            let Some(lp) = project_on_lane(town, lane, p) else {
                continue;
            };
            if !heading_agrees(lp.heading, heading) || !within_lane(&lp) {
                continue;
            }
            if best.is_none_or(|b| tie(&lp) < tie(&b)) {
                best = Some(lp);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown::{grid, lane_through};
    use crate::map::town::{JunctionIdx, Town};
    use std::f32::consts::PI;

    fn lane(pts: &[(f32, f32)], width: f32, junction: Option<JunctionIdx>) -> DriveLane {
        let pts: Vec<Vec2> = pts.iter().map(|&(x, y)| Vec2::new(x, y)).collect();
        DriveLane {
            width: vec![width; pts.len()],
            junction,
            ..lane_through(&pts)
        }
    }

    fn town(lanes: Vec<DriveLane>) -> Town {
        Town {
            lanes,
            ..Town::empty("t")
        }
    }

    #[test]
    fn a_car_stands_in_its_lane_outside_the_lanes_or_against_them() {
        // Lane 0 runs +x at y = -1.75, lane 1 runs -x at y = +1.75, each 3.5 m wide.
        let t = grid(3, 1, 60.0);
        let g = LaneGrid::new(&t, 5.0);
        let at = |x: f32, y: f32, heading: f32| g.standing(&t, Vec2::new(x, y), heading);
        assert_eq!(at(30.0, -1.75, 0.0), LaneStanding::InLane);
        assert_eq!(
            at(30.0, 1.75, 0.0),
            LaneStanding::WrongWay,
            "the oncoming lane"
        );
        assert_eq!(at(30.0, -1.75, PI), LaneStanding::WrongWay, "turned around");
        // 1.3 m of shoulder beyond the lane's edge at -3.5 m still counts as in it.
        assert_eq!(at(30.0, -4.7, 0.0), LaneStanding::InLane);
        assert_eq!(
            at(30.0, -5.0, 0.0),
            LaneStanding::OutsideLanes,
            "on the sidewalk"
        );
        assert_eq!(at(30.0, -40.0, 0.0), LaneStanding::OutsideLanes, "far off");
    }

    #[test]
    fn the_grid_finds_the_lane_for_the_heading() {
        let t = grid(3, 1, 60.0);
        let g = LaneGrid::new(&t, 5.0);
        // Lane 0 runs +x at y = -1.75, lane 1 runs -x at y = +1.75.
        let lp = g.lane_under(&t, Vec2::new(30.0, -1.5), 0.0).unwrap();
        assert_eq!(lp.lane, LaneIdx(0));
        assert!((lp.s - 20.0).abs() < 0.01 && (lp.distance_m - 0.25).abs() < 0.01);
        assert!((lp.offset_m - 0.25).abs() < 0.01, "left of +x is positive");
        assert_eq!((lp.heading, lp.width_m), (0.0, 3.5));
        let lp = g.lane_under(&t, Vec2::new(30.0, 1.5), PI).unwrap();
        assert_eq!(lp.lane, LaneIdx(1));
        // Against the lane: none.
        assert!(g.lane_under(&t, Vec2::new(30.0, -1.5), PI).is_none());
        // 50 degrees off still agrees, 70 does not.
        assert!(
            g.lane_under(&t, Vec2::new(30.0, -1.5), 50f32.to_radians())
                .is_some()
        );
        assert!(
            g.lane_under(&t, Vec2::new(30.0, -1.5), 70f32.to_radians())
                .is_none()
        );
        // Beside the road: none.
        assert!(g.lane_under(&t, Vec2::new(30.0, 20.0), 0.0).is_none());
    }

    #[test]
    fn the_width_gate_is_half_the_width_plus_the_margin() {
        // One 4 m wide lane along +x: on it up to 2.5 m from the centre.
        let t = town(vec![lane(
            &[(0.0, 0.0), (10.0, 0.0), (20.0, 0.0)],
            4.0,
            None,
        )]);
        let g = LaneGrid::new(&t, 5.0);
        assert!(g.lane_under(&t, Vec2::new(10.0, 2.45), 0.0).is_some());
        assert!(g.lane_under(&t, Vec2::new(10.0, -2.55), 0.0).is_none());
    }

    #[test]
    fn a_point_beyond_a_lane_end_is_not_on_it() {
        // A lane ending at x = 10 and a junction lane going on from there.
        let t = town(vec![
            lane(&[(0.0, 0.0), (5.0, 0.0), (10.0, 0.0)], 3.5, None),
            lane(
                &[(10.0, 0.0), (15.0, 0.0), (20.0, 0.0)],
                3.5,
                Some(JunctionIdx(0)),
            ),
        ]);
        let g = LaneGrid::new(&t, 5.0);
        // On the shared end point the plain lane wins the tie ...
        assert_eq!(
            g.lane_under(&t, Vec2::new(10.0, 0.0), 0.0).unwrap().lane,
            LaneIdx(0)
        );
        // ... 3 m into the junction lane the car is on it: it lies on the plain
        // lane's extension, 0.2 m from it measured sideways but 3 m from its end.
        let lp = g.lane_under(&t, Vec2::new(13.0, 0.2), 0.0).unwrap();
        assert_eq!(lp.lane, LaneIdx(1));
        assert!((lp.s - 3.0).abs() < 1e-4);
    }

    #[test]
    fn snapping_prefers_an_agreeing_lane_within_3_m() {
        // Lane 0 east along y = 0, lane 1 west along y = 0.5, lane 2 far away.
        let t = town(vec![
            lane(&[(0.0, 0.0), (10.0, 0.0)], 3.5, None),
            lane(&[(10.0, 0.5), (0.0, 0.5)], 3.5, None),
            lane(&[(0.0, 20.0), (10.0, 20.0)], 3.5, None),
        ]);
        let west = nearest_lane(&t, Vec2::new(5.0, 0.1), Some(PI)).unwrap();
        assert_eq!(west.lane, LaneIdx(1));
        let east = nearest_lane(&t, Vec2::new(5.0, 0.4), Some(0.0)).unwrap();
        assert_eq!(east.lane, LaneIdx(0));
        assert!((east.s - 5.0).abs() < 1e-4 && (east.distance_m - 0.4).abs() < 1e-5);
        // No heading: the nearest; a heading nothing near agrees with: the nearest too.
        assert_eq!(
            nearest_lane(&t, Vec2::new(5.0, 0.4), None).unwrap().lane,
            LaneIdx(1)
        );
        assert_eq!(
            nearest_lane(&t, Vec2::new(5.0, 0.4), Some(PI / 2.0))
                .unwrap()
                .lane,
            LaneIdx(1)
        );
        // Lane 2 agrees with north-east but is 19.6 m farther: not chosen.
        assert_ne!(
            nearest_lane(&t, Vec2::new(5.0, 0.4), Some(0.3))
                .unwrap()
                .lane,
            LaneIdx(2)
        );
        assert!(nearest_lane(&Town::empty("e"), Vec2::ZERO, None).is_none());
    }
}
