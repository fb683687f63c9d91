//! Queries on the lane graph: lane geometry by arc length, the nearest lane
//! to a point, and strong connectivity.

use glam::{Vec2, Vec3};

use crate::geometry::{project_to_polyline, wrap_angle};
use crate::town::{DriveLane, LaneIdx, Town};

/// A place on a lane: the lane, the arc length along it and how far the query
/// point was from its centreline.
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
}

impl DriveLane {
    /// The lane's length along its centreline (metres).
    pub fn length_m(&self) -> f32 {
        self.s.last().copied().unwrap_or(0.0)
    }

    /// The centreline point at arc length `s` (metres), clamped to the lane.
    pub fn point_at(&self, s: f32) -> Vec3 {
        crate::geometry::point_at(&self.centerline, &self.s, s)
    }

    /// Driving heading at arc length `s` (radians, counter-clockwise from +x).
    pub fn heading_at(&self, s: f32) -> f32 {
        crate::geometry::heading_at(&self.centerline, &self.s, s)
    }

    /// Lane width at arc length `s` (metres).
    pub fn width_at(&self, s: f32) -> f32 {
        let i = self
            .s
            .partition_point(|&x| x <= s)
            .saturating_sub(1)
            .min(self.width.len().saturating_sub(1));
        self.width.get(i).copied().unwrap_or(0.0)
    }
}

impl Town {
    /// The lane at `idx`.
    pub fn lane(&self, idx: LaneIdx) -> &DriveLane {
        &self.lanes[idx.0 as usize]
    }

    /// The driving lane nearest to `p` (ground plane). With `heading`
    /// (radians), lanes whose driving direction differs by more than 90
    /// degrees at the projection are passed over when any lane within 3 m
    /// of `p` agrees. `None` only for a town without lanes.
    pub fn nearest_lane(&self, p: Vec2, heading: Option<f32>) -> Option<LanePoint> {
        let mut all: Vec<LanePoint> = Vec::new();
        for (i, l) in self.lanes.iter().enumerate() {
            if let Some(pr) = project_to_polyline(&l.centerline, p) {
                all.push(LanePoint {
                    lane: LaneIdx(i as u32),
                    s: pr.s,
                    distance_m: pr.distance,
                    offset_m: pr.offset,
                });
            }
        }
        let best_any = all
            .iter()
            .copied()
            .min_by(|a, b| a.distance_m.total_cmp(&b.distance_m))?;
        if let Some(h) = heading {
            let agree = all
                .iter()
                .copied()
                .filter(|lp| lp.distance_m <= best_any.distance_m.max(0.0) + 3.0)
                .filter(|lp| {
                    wrap_angle(self.lane(lp.lane).heading_at(lp.s) - h).abs()
                        < std::f32::consts::FRAC_PI_2
                })
                .min_by(|a, b| a.distance_m.total_cmp(&b.distance_m));
            if let Some(a) = agree {
                return Some(a);
            }
        }
        Some(best_any)
    }

    /// Strongly connected components of the driving-lane graph (successor
    /// edges only), each a sorted list, in order of their smallest lane.
    pub fn lane_components(&self) -> Vec<Vec<LaneIdx>> {
        // Tarjan's algorithm, iterative.
        let n = self.lanes.len();
        let mut index = vec![usize::MAX; n];
        let mut low = vec![0usize; n];
        let mut on_stack = vec![false; n];
        let mut stack: Vec<usize> = Vec::new();
        let mut comps: Vec<Vec<LaneIdx>> = Vec::new();
        let mut next = 0usize;
        for root in 0..n {
            if index[root] != usize::MAX {
                continue;
            }
            let mut work: Vec<(usize, usize)> = vec![(root, 0)];
            while let Some(&mut (v, ref mut ei)) = work.last_mut() {
                if *ei == 0 && index[v] == usize::MAX {
                    index[v] = next;
                    low[v] = next;
                    next += 1;
                    stack.push(v);
                    on_stack[v] = true;
                }
                let succ = &self.lanes[v].successors;
                if *ei < succ.len() {
                    let w = succ[*ei].0 as usize;
                    *ei += 1;
                    if index[w] == usize::MAX {
                        work.push((w, 0));
                    } else if on_stack[w] {
                        low[v] = low[v].min(index[w]);
                    }
                } else {
                    work.pop();
                    if let Some(&(u, _)) = work.last() {
                        low[u] = low[u].min(low[v]);
                    }
                    if low[v] == index[v] {
                        let mut comp = Vec::new();
                        while let Some(w) = stack.pop() {
                            on_stack[w] = false;
                            comp.push(LaneIdx(w as u32));
                            if w == v {
                                break;
                            }
                        }
                        comp.sort();
                        comps.push(comp);
                    }
                }
            }
        }
        comps.sort_by_key(|c| c[0]);
        comps
    }

    /// Whether every driving lane can reach every other one.
    pub fn is_strongly_connected(&self) -> bool {
        self.lane_components().len() <= 1
    }

    /// Total centreline length of all driving lanes (metres).
    pub fn total_lane_length_m(&self) -> f32 {
        self.lanes.iter().map(|l| l.length_m()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::town::*;

    fn lane(pts: &[(f32, f32)], succ: &[u32]) -> DriveLane {
        let centerline: Vec<Vec3> = pts.iter().map(|&(x, y)| Vec3::new(x, y, 0.0)).collect();
        let s = crate::geometry::arc_lengths(&centerline);
        let n = centerline.len();
        DriveLane {
            road_id: "r".into(),
            od_lane: -1,
            centerline,
            s,
            width: vec![3.5; n],
            speed_limit_mps: 10.0,
            junction: None,
            successors: succ.iter().map(|&i| LaneIdx(i)).collect(),
            predecessors: vec![],
            left: None,
            right: None,
        }
    }

    pub(crate) fn town(lanes: Vec<DriveLane>) -> Town {
        Town {
            lanes,
            ..Town::empty("t")
        }
    }

    #[test]
    fn components_and_nearest_lane() {
        // 0 -> 1 -> 0 is a cycle; 2 is a dead end reached from 1.
        let t = town(vec![
            lane(&[(0.0, 0.0), (10.0, 0.0)], &[1]),
            lane(&[(10.0, 0.0), (0.0, 0.5)], &[0, 2]),
            lane(&[(0.0, 20.0), (10.0, 20.0)], &[]),
        ]);
        let c = t.lane_components();
        assert_eq!(c, vec![vec![LaneIdx(0), LaneIdx(1)], vec![LaneIdx(2)]]);
        assert!(!t.is_strongly_connected());
        // Near both 0 and 1; heading west prefers lane 1.
        let west = t
            .nearest_lane(Vec2::new(5.0, 0.1), Some(std::f32::consts::PI))
            .unwrap();
        assert_eq!(west.lane, LaneIdx(1));
        let east = t.nearest_lane(Vec2::new(5.0, 0.1), Some(0.0)).unwrap();
        assert_eq!(east.lane, LaneIdx(0));
        assert!((east.s - 5.0).abs() < 1e-4);
    }
}
