//! Positions along lanes and along chains of lanes (what NPCs follow).
//!
//! A [`LanePath`] is a queue of lanes joined end to start plus an arc length
//! on the first; NPCs extend it at the far end and drop lanes they have
//! left. The lane under a point (for the ego, which is not on rails) is a
//! rule: [`crate::rules::lanes`].

use crate::map::town::{LaneIdx, Town};
use glam::Vec2;
use std::collections::VecDeque;

/// A chain of lanes, each a successor of the one before, with a position on the first.
#[derive(Debug, Clone, PartialEq)]
pub struct LanePath {
    /// The lanes in driving order; the first is the one the position is on.
    pub lanes: VecDeque<LaneIdx>,
    /// Arc length on the first lane (metres).
    pub s_m: f32,
}

impl LanePath {
    /// A path starting on `lane` at `s_m`.
    pub fn new(lane: LaneIdx, s_m: f32) -> LanePath {
        LanePath {
            lanes: VecDeque::from([lane]),
            s_m,
        }
    }

    /// The lane the position is on.
    pub fn lane(&self) -> LaneIdx {
        self.lanes[0]
    }

    /// Path length ahead of the position (metres).
    pub fn remaining_m(&self, town: &Town) -> f32 {
        self.lanes
            .iter()
            .map(|&l| town.lane(l).length_m())
            .sum::<f32>()
            - self.s_m
    }

    /// Lane and arc length at `ahead_m` metres ahead of the position (clamped to the path's end).
    pub fn locate(&self, town: &Town, ahead_m: f32) -> (LaneIdx, f32) {
        let mut s = self.s_m + ahead_m.max(0.0);
        for (k, &l) in self.lanes.iter().enumerate() {
            let len = town.lane(l).length_m();
            if s <= len || k + 1 == self.lanes.len() {
                return (l, s.min(len));
            }
            s -= len;
        }
        (self.lanes[0], self.s_m)
    }

    /// Point, heading, height at `ahead_m` metres ahead of the position.
    pub fn point_ahead(&self, town: &Town, ahead_m: f32) -> (Vec2, f32, f32) {
        let (l, s) = self.locate(town, ahead_m);
        town.lane(l).pose_at(s)
    }

    /// Ground point at `ahead_m` metres ahead of the position: [`LanePath::point_ahead`]'s
    /// point without the heading (the pure pursuit's target, asked every tick).
    pub fn ground_point_ahead(&self, town: &Town, ahead_m: f32) -> Vec2 {
        let (l, s) = self.locate(town, ahead_m);
        town.lane(l).point_at(s).truncate()
    }

    /// Moves the position to the projection of `p` (searching near the current position), dropping lanes left behind; returns the distance advanced (metres).
    pub fn advance_to(&mut self, town: &Town, p: Vec2) -> f32 {
        let mut travelled = 0.0;
        loop {
            let lane = town.lane(self.lane());
            let len = lane.length_m();
            let s = lane.project_near(p, self.s_m, 3.0).unwrap_or(0.0);
            let s = s.max(self.s_m);
            travelled += s - self.s_m;
            self.s_m = s;
            if self.s_m >= len - 1e-3 && self.lanes.len() > 1 {
                // Continue on the next lane if p lies beyond this one's end.
                let next = self.lanes[1];
                let s2 = town.lane(next).project_near(p, 0.0, 3.0).unwrap_or(0.0);
                if s2 > 1e-3 {
                    self.lanes.pop_front();
                    self.s_m = 0.0;
                    continue;
                }
            }
            return travelled;
        }
    }

    /// Samples the path ahead every `step_m` up to `len_m` (ground-plane points, metres).
    pub fn sample_ahead(&self, town: &Town, step_m: f32, len_m: f32, out: &mut Vec<Vec2>) {
        out.clear();
        let n = (len_m / step_m).ceil() as usize;
        let mut lane_k = 0usize;
        let mut s = self.s_m;
        let mut l = &town.lanes[self.lanes[0].0 as usize];
        let mut len = *l.s.last().unwrap_or(&0.0);
        // Walk the centreline points forward instead of searching for each sample.
        let mut j =
            l.s.partition_point(|&x| x <= s)
                .saturating_sub(1)
                .min(l.s.len().saturating_sub(2));
        for i in 0..=n {
            if i > 0 {
                s += step_m;
            }
            while s > len && lane_k + 1 < self.lanes.len() {
                s -= len;
                lane_k += 1;
                l = &town.lanes[self.lanes[lane_k].0 as usize];
                len = *l.s.last().unwrap_or(&0.0);
                j = 0;
            }
            if s > len || l.s.len() < 2 {
                break;
            }
            while j + 2 < l.s.len() && l.s[j + 1] < s {
                j += 1;
            }
            let seg = (l.s[j + 1] - l.s[j]).max(1e-6);
            let t = ((s - l.s[j]) / seg).clamp(0.0, 1.0);
            out.push(
                l.centerline[j]
                    .truncate()
                    .lerp(l.centerline[j + 1].truncate(), t),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown::grid;

    #[test]
    fn path_advances_across_lane_boundaries() {
        let t = grid(3, 1, 60.0);
        let l0 = LaneIdx(0);
        let mut p = LanePath::new(l0, 0.0);
        let next = t.lanes[0].successors[0];
        p.lanes.push_back(next);
        let len0 = t.lane(l0).length_m();
        // Walk there in 0.3 m steps, as a vehicle would.
        let mut total = 0.0;
        let mut ahead = 0.0;
        let start = p.clone();
        while ahead < len0 + 2.0 {
            ahead = (ahead + 0.3f32).min(len0 + 2.0);
            let (q, _, _) = start.point_ahead(&t, ahead);
            total += p.advance_to(&t, q);
        }
        assert!((total - (len0 + 2.0)).abs() < 0.05, "{total}");
        assert_eq!(p.lane(), next);
        assert!((p.s_m - 2.0).abs() < 0.05, "{}", p.s_m);
    }

    #[test]
    fn sampling_matches_point_lookup() {
        let t = grid(3, 3, 60.0);
        let mut p = LanePath::new(LaneIdx(0), 3.3);
        let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(1);
        crate::agents::npc::extend_path(&t, &mut p, &mut rng, 120.0);
        let mut pts = Vec::new();
        p.sample_ahead(&t, 1.0, 100.0, &mut pts);
        assert_eq!(pts.len(), 101);
        for (i, q) in pts.iter().enumerate() {
            let (r, _, _) = p.point_ahead(&t, i as f32);
            assert!((*q - r).length() < 1e-3, "sample {i}: {q} vs {r}");
        }
    }
}
