//! Lane crossings: every painted marking the ego's footprint crosses, like
//! CARLA's lane-invasion sensor (solid or broken, any colour; curbs are not
//! paint). A crossing is counted when the footprint starts touching a
//! marking it did not touch on the tick before, so driving over a line and
//! back counts two.

use std::collections::BTreeSet;

use world::road::geometry::box_touches_polyline;
use world::{MarkKind, Town, Vec2, Vec3};

use super::{EgoTick, Infraction, InfractionKind, Monitor};

/// Side of a grid cell of the marking index (metres).
const CELL_M: f32 = 8.0;

/// Counts marking crossings; holds a grid index over the town's markings.
#[derive(Debug, Clone)]
pub struct LaneCrossingMonitor {
    /// Per cell: (marking index, segment index) pairs whose bounds touch it.
    grid: std::collections::HashMap<(i32, i32), Vec<(u32, u32)>>,
    /// Segments of each marking.
    segments: Vec<Vec<[Vec3; 2]>>,
    touching: BTreeSet<u32>,
    scratch: BTreeSet<u32>,
}

fn cell(p: Vec2) -> (i32, i32) {
    ((p.x / CELL_M).floor() as i32, (p.y / CELL_M).floor() as i32)
}

impl LaneCrossingMonitor {
    /// Indexes the town's painted markings.
    pub fn new(town: &Town) -> Self {
        let mut grid: std::collections::HashMap<(i32, i32), Vec<(u32, u32)>> = Default::default();
        let mut segments = Vec::with_capacity(town.markings.len());
        for (m, marking) in town.markings.iter().enumerate() {
            let segs: Vec<[Vec3; 2]> = if marking.kind == MarkKind::Curb {
                Vec::new()
            } else {
                marking.points.windows(2).map(|w| [w[0], w[1]]).collect()
            };
            for (s, [a, b]) in segs.iter().enumerate() {
                let (a, b) = (a.truncate(), b.truncate());
                let (lo, hi) = (cell(a.min(b)), cell(a.max(b)));
                for cx in lo.0..=hi.0 {
                    for cy in lo.1..=hi.1 {
                        grid.entry((cx, cy)).or_default().push((m as u32, s as u32));
                    }
                }
            }
            segments.push(segs);
        }
        Self {
            grid,
            segments,
            touching: BTreeSet::new(),
            scratch: BTreeSet::new(),
        }
    }

    /// The markings the footprint touches this tick, into `self.scratch`.
    fn collect_touching(&mut self, tick: &EgoTick<'_>) {
        let footprint = tick.footprint();
        let corners = footprint.corners();
        let lo = corners
            .iter()
            .copied()
            .fold(Vec2::splat(f32::INFINITY), Vec2::min);
        let hi = corners
            .iter()
            .copied()
            .fold(Vec2::splat(f32::NEG_INFINITY), Vec2::max);
        let (lo, hi) = (cell(lo), cell(hi));
        self.scratch.clear();
        for cx in lo.0..=hi.0 {
            for cy in lo.1..=hi.1 {
                let Some(entries) = self.grid.get(&(cx, cy)) else {
                    continue;
                };
                for &(m, s) in entries {
                    if self.scratch.contains(&m) {
                        continue;
                    }
                    if box_touches_polyline(&footprint, &self.segments[m as usize][s as usize]) {
                        self.scratch.insert(m);
                    }
                }
            }
        }
    }
}

impl Monitor for LaneCrossingMonitor {
    /// Pushes a crossing for each marking the footprint newly touches.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        self.collect_touching(tick);
        for &m in self.scratch.difference(&self.touching) {
            out.push(Infraction::at(
                tick,
                InfractionKind::LaneCrossing,
                format!("marking {m}"),
            ));
        }
        std::mem::swap(&mut self.touching, &mut self.scratch);
    }
}

#[cfg(test)]
mod tests {
    use super::super::{EgoPose, scripted};
    use super::*;
    use world::{LaneMarking, MarkColor};

    /// A town with one broken centre line along y = 0 and a curb at y = -4.
    fn two_lane_road() -> Town {
        let line = |y: f32, kind| LaneMarking {
            points: (0..=100).map(|i| Vec3::new(i as f32, y, 0.0)).collect(),
            kind,
            color: MarkColor::White,
            width_m: 0.15,
            dash_m: Some((3.0, 9.0)),
        };
        Town {
            markings: vec![line(0.0, MarkKind::Broken), line(-4.0, MarkKind::Curb)],
            bounds: (Vec2::new(0.0, -5.0), Vec2::new(100.0, 5.0)),
            ..Town::empty("road")
        }
    }

    fn count(poses: &[EgoPose]) -> usize {
        let mut monitor = LaneCrossingMonitor::new(&two_lane_road());
        let mut out = Vec::new();
        scripted::drive(poses, 5.0, &[], |t| monitor.observe(t, &mut out));
        out.len()
    }

    /// Drives along +x, with the lateral position given per tick.
    fn weave(lateral: impl Fn(usize) -> f32) -> Vec<EgoPose> {
        (0..400)
            .map(|i| scripted::pose(10.0 + 0.2 * i as f32, lateral(i), 0.0))
            .collect()
    }

    #[test]
    fn staying_in_lane_crosses_nothing() {
        assert_eq!(count(&weave(|_| -1.75)), 0);
    }

    #[test]
    fn crossing_a_broken_line_over_and_back_counts_two() {
        // In the right lane, over into the left lane, then back, moving
        // sideways at 0.35 m a tick.
        let ramp = |i: usize, start: usize| ((i as f32 - start as f32) * 0.35).clamp(0.0, 3.5);
        let got = count(&weave(|i| -1.75 + ramp(i, 100) - ramp(i, 200)));
        assert_eq!(got, 2);
    }

    #[test]
    fn straddling_a_line_for_long_counts_once() {
        assert_eq!(
            count(&weave(|i| if (50..300).contains(&i) { 0.0 } else { -1.75 })),
            1
        );
    }

    #[test]
    fn a_curb_is_not_a_marking() {
        assert_eq!(count(&weave(|_| -3.9)), 0);
    }
}
