//! Driving lanes: the permanent driving lanes of the map, their centrelines
//! resampled in driving direction, widths, speed limits, junction, links
//! (successors, predecessors) and left and right neighbours.

use glam::Vec3;
use xodr::{Direction, LaneId, LaneType, Layer};

use super::{Builder, p3};
use crate::map::{DriveLane, LaneIdx};
use crate::road::geometry::{arc_lengths, point_at, project_to_polyline};

/// Spacing of resampled lane centrelines (metres).
pub const CENTERLINE_SPACING_M: f32 = 1.0;
/// Speed limit used where the map gives none (metres per second; 30 km/h).
pub const DEFAULT_SPEED_LIMIT_MPS: f32 = 30.0 / 3.6;

fn resample(points: &[Vec3], spacing: f32) -> (Vec<Vec3>, Vec<f32>) {
    let cum = arc_lengths(points);
    let total = cum.last().copied().unwrap_or(0.0);
    let n = ((total / spacing).round() as usize).max(1);
    let mut out = Vec::with_capacity(n + 1);
    let mut ss = Vec::with_capacity(n + 1);
    for i in 0..=n {
        let s = total * i as f32 / n as f32;
        out.push(point_at(points, &cum, s));
        ss.push(s);
    }
    (out, ss)
}

impl Builder<'_> {
    pub(super) fn lanes(&mut self) {
        let net = self.ctx.net;
        let chosen: Vec<&xodr::Lane> = net
            .lanes()
            .iter()
            .filter(|l| l.kind == LaneType::Driving && l.layer == Layer::Permanent)
            .collect();
        for (i, l) in chosen.iter().enumerate() {
            self.lane_of.insert(l.id, LaneIdx(i as u32));
        }
        for l in &chosen {
            let backward = l.direction == Direction::Backward;
            let mut pts: Vec<Vec3> = l.center.points().iter().map(|p| p3(*p)).collect();
            if backward {
                pts.reverse();
            }
            let (centerline, s) = resample(&pts, CENTERLINE_SPACING_M);
            let total = s.last().copied().unwrap_or(0.0).max(1e-6);
            let xl = l.center.length();
            let stored = |si: f32| {
                if backward {
                    (1.0 - si / total) * xl
                } else {
                    si / total * xl
                }
            };
            let width = s.iter().map(|&si| l.width_at(stored(si))).collect();
            let speed = match net.speed_limit_at(l.id, stored(total * 0.5)) {
                Some(xodr::SpeedLimit::Max(v)) if v.is_finite() && v > 0.0 => v,
                _ => f32::NAN, // filled below
            };
            let (road_id, od_lane) = self.ctx.road_od(l.id);
            let junction = net
                .road_lane(l.id)
                .and_then(|rl| net.road(rl.road))
                .and_then(|r| r.junction())
                .and_then(|j| self.junction_of.get(j).copied());
            let map_ids = |ids: &[LaneId]| -> Vec<LaneIdx> {
                let mut v: Vec<LaneIdx> = ids
                    .iter()
                    .filter_map(|i| self.lane_of.get(i).copied())
                    .collect();
                v.sort();
                v.dedup();
                v
            };
            self.town.lanes.push(DriveLane {
                road_id,
                od_lane,
                centerline,
                s,
                width,
                speed_limit_mps: speed,
                junction,
                successors: map_ids(&l.successors),
                predecessors: map_ids(&l.predecessors),
                left: None,
                right: None,
            });
        }
        // Neighbours: which side is the neighbour on, seen in driving direction?
        for (i, l) in chosen.iter().enumerate() {
            for n in &l.neighbors {
                let Some(&ni) = self.lane_of.get(n) else {
                    continue;
                };
                let other = &self.town.lanes[ni.0 as usize];
                let mid = other.centerline[other.centerline.len() / 2].truncate();
                if let Some(p) = project_to_polyline(&self.town.lanes[i].centerline, mid) {
                    if p.offset > 0.0 {
                        self.town.lanes[i].left = Some(ni);
                    } else {
                        self.town.lanes[i].right = Some(ni);
                    }
                }
            }
        }
        // Speed limits the map does not give: take the neighbours' in the graph.
        for _ in 0..8 {
            let mut changed = false;
            for i in 0..self.town.lanes.len() {
                if self.town.lanes[i].speed_limit_mps.is_nan() {
                    let l = &self.town.lanes[i];
                    let v = l
                        .predecessors
                        .iter()
                        .chain(&l.successors)
                        .map(|j| self.town.lanes[j.0 as usize].speed_limit_mps)
                        .filter(|v| !v.is_nan())
                        .fold(f32::NAN, f32::max);
                    if !v.is_nan() {
                        self.town.lanes[i].speed_limit_mps = v;
                        changed = true;
                    }
                }
            }
            if !changed {
                break;
            }
        }
        for l in &mut self.town.lanes {
            if l.speed_limit_mps.is_nan() {
                l.speed_limit_mps = DEFAULT_SPEED_LIMIT_MPS;
            }
        }
    }
}
