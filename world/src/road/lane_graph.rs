//! Queries on the lane graph: lane geometry by arc length, projection onto a
//! lane, and strong connectivity. The lane under a point is a rule:
//! [`crate::rules::lanes`].

use glam::{Vec2, Vec3};

use crate::map::town::{DriveLane, LaneIdx, Town};
use crate::road::geometry::{PolylineProjection, project_to_polyline};

impl DriveLane {
    /// The lane's length along its centreline (metres).
    pub fn length_m(&self) -> f32 {
        self.s.last().copied().unwrap_or(0.0)
    }

    /// The centreline point at arc length `s` (metres), clamped to the lane.
    pub fn point_at(&self, s: f32) -> Vec3 {
        crate::road::geometry::point_at(&self.centerline, &self.s, s)
    }

    /// Driving heading at arc length `s` (radians, counter-clockwise from +x).
    pub fn heading_at(&self, s: f32) -> f32 {
        crate::road::geometry::heading_at(&self.centerline, &self.s, s)
    }

    /// The pose at arc length `s` (metres), clamped to the lane: the ground
    /// point (metres), the driving heading (radians) and the height (metres).
    pub fn pose_at(&self, s: f32) -> (Vec2, f32, f32) {
        let p = self.point_at(s);
        (p.truncate(), self.heading_at(s), p.z)
    }

    /// Where `p` (ground plane) projects onto the centreline; `None` for a
    /// lane without points. Its `s` is the lane's arc length (interpolated in
    /// [`DriveLane::s`], the measure [`DriveLane::point_at`] takes).
    pub fn project(&self, p: Vec2) -> Option<PolylineProjection> {
        self.project_slice(p, 0, self.centerline.len())
    }

    /// Arc length (metres) of the projection of `p` onto the centreline
    /// points within `window_m` metres of arc length `around_s` (a vehicle
    /// tracking its lane searches near where it was); `None` for a lane with
    /// fewer than two points.
    pub fn project_near(&self, p: Vec2, around_s: f32, window_m: f32) -> Option<f32> {
        let n = self.centerline.len();
        if n < 2 {
            return None;
        }
        let lo = self
            .s
            .partition_point(|&x| x < around_s - window_m)
            .saturating_sub(1)
            .min(n - 2);
        let hi = (self.s.partition_point(|&x| x <= around_s + window_m) + 1)
            .max(lo + 2)
            .min(n);
        self.project_slice(p, lo, hi).map(|pr| pr.s)
    }

    /// [`project_to_polyline`] on the centreline points `lo..hi`, with the
    /// segment index and `s` in the whole lane's terms.
    fn project_slice(&self, p: Vec2, lo: usize, hi: usize) -> Option<PolylineProjection> {
        let mut pr = project_to_polyline(&self.centerline[lo..hi], p)?;
        pr.segment += lo;
        let i = pr.segment;
        pr.s = match (self.s.get(i), self.s.get(i + 1)) {
            (Some(&a), Some(&b)) => a + pr.t * (b - a),
            (Some(&a), None) => a,
            _ => pr.s,
        };
        Some(pr)
    }

    /// Lane width at arc length `s` (metres): the width at the centreline
    /// point at or before `s`. The one width lookup of every lane rule.
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
    use crate::map::town::*;

    fn lane(pts: &[(f32, f32)], succ: &[u32]) -> DriveLane {
        let pts: Vec<Vec2> = pts.iter().map(|&(x, y)| Vec2::new(x, y)).collect();
        DriveLane {
            successors: succ.iter().map(|&i| LaneIdx(i)).collect(),
            ..crate::map::testtown::lane_through(&pts)
        }
    }

    pub(crate) fn town(lanes: Vec<DriveLane>) -> Town {
        Town {
            lanes,
            ..Town::empty("t")
        }
    }

    #[test]
    fn components_and_projection() {
        // 0 -> 1 -> 0 is a cycle; 2 is a dead end reached from 1.
        let t = town(vec![
            lane(&[(0.0, 0.0), (10.0, 0.0)], &[1]),
            lane(&[(10.0, 0.0), (0.0, 0.5)], &[0, 2]),
            lane(&[(0.0, 20.0), (10.0, 20.0)], &[]),
        ]);
        let c = t.lane_components();
        assert_eq!(c, vec![vec![LaneIdx(0), LaneIdx(1)], vec![LaneIdx(2)]]);
        assert!(!t.is_strongly_connected());
        let p = t.lane(LaneIdx(0)).project(Vec2::new(5.0, 0.1)).unwrap();
        assert!((p.s - 5.0).abs() < 1e-4 && (p.offset - 0.1).abs() < 1e-5);
    }

    #[test]
    fn projection_near_an_arc_length_searches_only_there() {
        // Out along +x for 10 m and back 1 m to the side: near x = 2 the lane
        // passes twice, at s = 2 and s = 19.
        let mut pts: Vec<(f32, f32)> = (0..=10).map(|i| (i as f32, 0.0)).collect();
        pts.extend((0..=10).rev().map(|i| (i as f32, 1.0)));
        let l = &town(vec![lane(&pts, &[])]).lanes[0];
        let q = Vec2::new(2.0, 0.4);
        assert!((l.project_near(q, 2.5, 3.0).unwrap() - 2.0).abs() < 1e-4);
        assert!((l.project_near(q, 18.0, 3.0).unwrap() - 19.0).abs() < 1e-4);
        assert!((l.project(q).unwrap().s - 2.0).abs() < 1e-4);
    }
}
