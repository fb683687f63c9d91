//! Sidewalks: the map's sidewalk lanes, with their inner (road-side) and
//! outer edges and their height.

use std::collections::HashMap;

use xodr::{LaneId, LaneType, Layer};

use super::{Builder, edge_points};
use crate::map::Sidewalk;

/// Sidewalk height where the map gives none (metres).
pub const DEFAULT_SIDEWALK_HEIGHT_M: f32 = 0.15;

impl Builder<'_> {
    pub(super) fn sidewalks(&mut self) {
        let net = self.ctx.net;
        let heights: HashMap<LaneId, f32> = self
            .prov
            .lanes
            .iter()
            .filter_map(|p| p.heights.first().map(|h| (p.lane, h.inner)))
            .collect();
        for l in net
            .lanes()
            .iter()
            .filter(|l| l.kind == LaneType::Sidewalk && l.layer == Layer::Permanent)
        {
            let (_, od) = self.ctx.road_od(l.id);
            let left = edge_points(l, 1.0);
            let right = edge_points(l, -1.0);
            let (inner, outer) = if od < 0 { (left, right) } else { (right, left) };
            let height_m = heights
                .get(&l.id)
                .copied()
                .filter(|h| h.is_finite())
                .unwrap_or(DEFAULT_SIDEWALK_HEIGHT_M);
            self.town.sidewalks.push(Sidewalk {
                inner,
                outer,
                height_m,
            });
        }
    }
}
