//! Positions along lanes and along chains of lanes (what NPCs follow).
//!
//! A [`LanePath`] is a queue of lanes joined end to start plus an arc length
//! on the first; NPCs extend it at the far end and drop lanes they have
//! left. [`LaneIndex`] finds the lane under a point (for the ego, which is
//! not on rails).

use crate::town::{LaneIdx, Town};
use glam::Vec2;
use std::collections::VecDeque;

/// Length of a lane (metres).
pub fn lane_len(town: &Town, lane: LaneIdx) -> f32 {
    *town.lanes[lane.0 as usize].s.last().unwrap_or(&0.0)
}

/// Point (metres, ground plane), heading (radians) and height (metres) at arc length `s` on a lane (clamped to the lane).
pub fn lane_point(town: &Town, lane: LaneIdx, s: f32) -> (Vec2, f32, f32) {
    let l = &town.lanes[lane.0 as usize];
    let n = l.s.len();
    if n < 2 {
        let p = l.centerline.first().copied().unwrap_or_default();
        return (p.truncate(), 0.0, p.z);
    }
    let s = s.clamp(0.0, l.s[n - 1]);
    // Points are about 1 m apart: start from the guess and walk.
    let i =
        l.s.partition_point(|&x| x <= s)
            .saturating_sub(1)
            .min(n - 2);
    let (a, b) = (l.centerline[i], l.centerline[i + 1]);
    let seg = (l.s[i + 1] - l.s[i]).max(1e-6);
    let t = ((s - l.s[i]) / seg).clamp(0.0, 1.0);
    let p = a.lerp(b, t);
    let d = (b - a).truncate();
    (p.truncate(), d.y.atan2(d.x), p.z)
}

/// Projects a point onto a lane: (arc length, signed lateral offset, positive left) (metres).
///
/// Searches the points within `window_m` of `hint_s` (all points when `hint_s` is None).
pub fn project_on_lane(
    town: &Town,
    lane: LaneIdx,
    p: Vec2,
    hint_s: Option<f32>,
    window_m: f32,
) -> (f32, f32) {
    let l = &town.lanes[lane.0 as usize];
    let n = l.centerline.len();
    if n < 2 {
        return (0.0, 0.0);
    }
    let (lo, hi) = match hint_s {
        Some(h) => (
            l.s.partition_point(|&x| x < h - window_m).saturating_sub(1),
            (l.s.partition_point(|&x| x <= h + window_m) + 1).min(n),
        ),
        None => (0, n),
    };
    let lo = lo.min(n - 2);
    let hi = hi.max(lo + 2).min(n);
    let mut best = (f32::INFINITY, 0.0f32, 0.0f32);
    for i in lo..hi - 1 {
        let a = l.centerline[i].truncate();
        let b = l.centerline[i + 1].truncate();
        let ab = b - a;
        let len2 = ab.length_squared().max(1e-12);
        let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
        let q = a + ab * t;
        let d2 = (p - q).length_squared();
        if d2 < best.0 {
            let lat = ab.perp_dot(p - a) / len2.sqrt();
            best = (d2, l.s[i] + t * (l.s[i + 1] - l.s[i]), lat);
        }
    }
    (best.1, best.2)
}

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
        self.lanes.iter().map(|&l| lane_len(town, l)).sum::<f32>() - self.s_m
    }

    /// Lane and arc length at `ahead_m` metres ahead of the position (clamped to the path's end).
    pub fn locate(&self, town: &Town, ahead_m: f32) -> (LaneIdx, f32) {
        let mut s = self.s_m + ahead_m.max(0.0);
        for (k, &l) in self.lanes.iter().enumerate() {
            let len = lane_len(town, l);
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
        lane_point(town, l, s)
    }

    /// Moves the position to the projection of `p` (searching near the current position), dropping lanes left behind; returns the distance advanced (metres).
    pub fn advance_to(&mut self, town: &Town, p: Vec2) -> f32 {
        let mut travelled = 0.0;
        loop {
            let l = self.lane();
            let len = lane_len(town, l);
            let (s, _) = project_on_lane(town, l, p, Some(self.s_m), 3.0);
            let s = s.max(self.s_m);
            travelled += s - self.s_m;
            self.s_m = s;
            if self.s_m >= len - 1e-3 && self.lanes.len() > 1 {
                // Continue on the next lane if p lies beyond this one's end.
                let next = self.lanes[1];
                let (s2, _) = project_on_lane(town, next, p, Some(0.0), 3.0);
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

/// A grid over lane centreline points, to find the lane under a point.
#[derive(Debug, Clone)]
pub struct LaneIndex {
    cell_m: f32,
    origin: Vec2,
    nx: usize,
    ny: usize,
    cells: Vec<Vec<(LaneIdx, u32)>>,
}

impl LaneIndex {
    /// Builds the grid with `cell_m`-metre cells.
    pub fn new(town: &Town, cell_m: f32) -> LaneIndex {
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
        let mut cells = vec![Vec::new(); nx * ny];
        for (li, l) in town.lanes.iter().enumerate() {
            for (pi, p) in l.centerline.iter().enumerate() {
                let c = ((p.x - origin.x) / cell_m) as usize
                    + ((p.y - origin.y) / cell_m) as usize * nx;
                cells[c].push((LaneIdx(li as u32), pi as u32));
            }
        }
        LaneIndex {
            cell_m,
            origin,
            nx,
            ny,
            cells,
        }
    }

    /// The best lane under a point for a heading: (lane, arc length, |lateral offset|) (metres).
    ///
    /// Candidates lie within half their width (plus `margin_m`) of the point and
    /// point within 60 degrees of `heading`; among them the laterally nearest wins,
    /// with plain lanes preferred over junction lanes on ties.
    pub fn locate(
        &self,
        town: &Town,
        p: Vec2,
        heading: f32,
        margin_m: f32,
    ) -> Option<(LaneIdx, f32, f32)> {
        let cx = ((p.x - self.origin.x) / self.cell_m).floor() as i64;
        let cy = ((p.y - self.origin.y) / self.cell_m).floor() as i64;
        let mut best: Option<(LaneIdx, f32, f32)> = None;
        let dir = Vec2::new(heading.cos(), heading.sin());
        let mut seen: Vec<LaneIdx> = Vec::new();
        for yy in cy - 1..=cy + 1 {
            for xx in cx - 1..=cx + 1 {
                if xx < 0 || yy < 0 || xx as usize >= self.nx || yy as usize >= self.ny {
                    continue;
                }
                for &(lane, _) in &self.cells[xx as usize + yy as usize * self.nx] {
                    if seen.contains(&lane) {
                        continue;
                    }
                    seen.push(lane);
                    let (s, lat) = project_on_lane(town, lane, p, None, 0.0);
                    let (_, h, _) = lane_point(town, lane, s);
                    if Vec2::new(h.cos(), h.sin()).dot(dir) < 0.5 {
                        continue;
                    }
                    let l = &town.lanes[lane.0 as usize];
                    let i =
                        l.s.partition_point(|&x| x < s)
                            .min(l.width.len().saturating_sub(1));
                    let half_w = l.width.get(i).copied().unwrap_or(3.5) * 0.5;
                    if lat.abs() > half_w + margin_m {
                        continue;
                    }
                    let key = lat.abs() + if l.junction.is_some() { 0.01 } else { 0.0 };
                    if best.is_none_or(|b| {
                        key < b.2
                            + if town.lanes[b.0.0 as usize].junction.is_some() {
                                0.01
                            } else {
                                0.0
                            }
                    }) {
                        best = Some((lane, s, lat.abs()));
                    }
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testtown::grid;

    #[test]
    fn path_advances_across_lane_boundaries() {
        let t = grid(3, 1, 60.0);
        let l0 = LaneIdx(0);
        let mut p = LanePath::new(l0, 0.0);
        let next = t.lanes[0].successors[0];
        p.lanes.push_back(next);
        let len0 = lane_len(&t, l0);
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
        crate::npc::extend_path(&t, &mut p, &mut rng, 120.0);
        let mut pts = Vec::new();
        p.sample_ahead(&t, 1.0, 100.0, &mut pts);
        assert_eq!(pts.len(), 101);
        for (i, q) in pts.iter().enumerate() {
            let (r, _, _) = p.point_ahead(&t, i as f32);
            assert!((*q - r).length() < 1e-3, "sample {i}: {q} vs {r}");
        }
    }

    #[test]
    fn index_finds_the_lane_for_the_heading() {
        let t = grid(3, 1, 60.0);
        let idx = LaneIndex::new(&t, 5.0);
        // Lane 0 runs +x at y = -1.75, lane 1 runs -x at y = +1.75.
        let (l, s, lat) = idx.locate(&t, Vec2::new(30.0, -1.5), 0.0, 0.5).unwrap();
        assert_eq!(l, LaneIdx(0));
        assert!((s - 20.0).abs() < 0.01 && (lat - 0.25).abs() < 0.01);
        let (l, _, _) = idx
            .locate(&t, Vec2::new(30.0, 1.5), std::f32::consts::PI, 0.5)
            .unwrap();
        assert_eq!(l, LaneIdx(1));
        assert!(
            idx.locate(&t, Vec2::new(30.0, -1.5), std::f32::consts::PI, 0.5)
                .is_none()
        );
        assert!(idx.locate(&t, Vec2::new(30.0, 20.0), 0.0, 0.5).is_none());
    }
}
