//! Lane markings: the map's road marks outside junctions, along the lane
//! edge they belong to and clipped to the stretch of road they cover.

use glam::Vec3;
use xodr::{Layer, RoadMarkType, RoadNetwork};

use super::{Builder, edge_points};
use crate::map::{LaneMarking, MarkColor, MarkKind};
use crate::road::geometry::{arc_lengths, point_at};

impl Builder<'_> {
    pub(super) fn markings(&mut self) {
        let net = self.ctx.net;
        for (mi, mark) in net.road_marks().iter().enumerate() {
            let kind = match mark.kind {
                RoadMarkType::Solid => MarkKind::Solid,
                RoadMarkType::Broken | RoadMarkType::BottsDots => MarkKind::Broken,
                RoadMarkType::SolidSolid => MarkKind::SolidSolid,
                RoadMarkType::SolidBroken => MarkKind::SolidBroken,
                RoadMarkType::BrokenSolid => MarkKind::BrokenSolid,
                RoadMarkType::BrokenBroken => MarkKind::BrokenBroken,
                RoadMarkType::Curb => MarkKind::Curb,
                _ => continue,
            };
            // The mark runs along the right edge of its left lane, or the left
            // edge of its right lane (looking along the reference direction).
            let (lane, side) = match (
                mark.left.and_then(|l| net.lane(l)),
                mark.right.and_then(|l| net.lane(l)),
            ) {
                (Some(l), _) => (l, -1.0),
                (None, Some(r)) => (r, 1.0),
                _ => continue,
            };
            if lane.layer != Layer::Permanent {
                continue;
            }
            // Junction connecting roads carry road marks in many exports
            // (CARLA's towns: hundreds of `broken` ones) that are not
            // painted: they are the overlapping virtual boundaries of the
            // paths through the junction. Nothing is drawn there and no
            // crossing of them counts.
            let in_junction = net
                .road_lane(lane.id)
                .and_then(|rl| net.road(rl.road))
                .is_some_and(|r| r.junction().is_some());
            if in_junction {
                continue;
            }
            let edge = edge_points(lane, side);
            // Clip to the stretch of road the mark covers.
            let points = match self
                .prov
                .road_marks
                .get(mi)
                .filter(|p| p.road_mark == mark.id)
            {
                Some(mp) => clip_to_mark(net, lane, &edge, mp.s, mp.length),
                None => edge,
            };
            if points.len() < 2 {
                continue;
            }
            let color = if mark.color.eq_ignore_ascii_case("yellow") {
                MarkColor::Yellow
            } else {
                MarkColor::White
            };
            let dash_m = mark.lines.iter().find_map(|line| match line.pattern {
                xodr::LinePattern::Dashed { length, space } => Some((length, space)),
                _ => None,
            });
            let dash_m = dash_m.or(match kind {
                MarkKind::Broken
                | MarkKind::BrokenBroken
                | MarkKind::SolidBroken
                | MarkKind::BrokenSolid => Some((4.0, 8.0)),
                _ => None,
            });
            self.town.markings.push(LaneMarking {
                points,
                kind,
                color,
                width_m: mark.width.max(0.05),
                dash_m,
            });
        }
    }
}

/// Clips a lane edge (stored direction) to the mark's stretch `[s, s+len]` of
/// the road's reference line, mapping reference s to the edge proportionally
/// over the lane's own span of reference s.
fn clip_to_mark(
    net: &RoadNetwork,
    lane: &xodr::Lane,
    edge: &[Vec3],
    s: f64,
    len: f64,
) -> Vec<Vec3> {
    let Some(rl) = net.road_lane(lane.id) else {
        return edge.to_vec();
    };
    let pts = lane.center.points();
    let (Some(a), Some(b)) = (
        net.road_position_on(rl.road, pts[0]).map(|p| p.s),
        net.road_position_on(rl.road, pts[pts.len() - 1])
            .map(|p| p.s),
    ) else {
        return edge.to_vec();
    };
    if (b - a).abs() < 1e-6 {
        return edge.to_vec();
    }
    let f0 = (((s - a) / (b - a)).clamp(0.0, 1.0)) as f32;
    let f1 = (((s + len - a) / (b - a)).clamp(0.0, 1.0)) as f32;
    if f0 <= 0.001 && f1 >= 0.999 {
        return edge.to_vec();
    }
    let cum = arc_lengths(edge);
    let total = cum.last().copied().unwrap_or(0.0);
    let (s0, s1) = (f0 * total, f1 * total);
    let mut out = vec![point_at(edge, &cum, s0)];
    for (p, c) in edge.iter().zip(&cum) {
        if *c > s0 && *c < s1 {
            out.push(*p);
        }
    }
    out.push(point_at(edge, &cum, s1));
    out
}
