//! Junctions: one per OpenDRIVE junction id, and each one's outline (the
//! map's junction area, or the convex hull of its lanes' edges).

use std::collections::BTreeMap;

use glam::Vec2;
use xodr::{LaneType, Layer};

use super::{Builder, edge_points};
use crate::map::{Junction, JunctionIdx};
use crate::road::geometry::{convex_hull, signed_area};

impl Builder<'_> {
    pub(super) fn junctions(&mut self) {
        let mut ids: Vec<String> = self
            .prov
            .junctions
            .iter()
            .map(|j| j.od_id.clone())
            .collect();
        for road in self.ctx.net.roads() {
            if let Some(j) = road.junction() {
                ids.push(j.to_string());
            }
        }
        for id in ids {
            if !self.junction_of.contains_key(&id) {
                self.junction_of
                    .insert(id.clone(), JunctionIdx(self.town.junctions.len() as u32));
                self.town.junctions.push(Junction {
                    od_id: id,
                    outline: Vec::new(),
                    lights: Vec::new(),
                });
            }
        }
    }

    pub(super) fn junction_outlines(&mut self) {
        let net = self.ctx.net;
        let mut pts: BTreeMap<JunctionIdx, Vec<Vec2>> = BTreeMap::new();
        for l in net.lanes().iter().filter(|l| {
            l.layer == Layer::Permanent && !matches!(l.kind, LaneType::Sidewalk | LaneType::None)
        }) {
            let Some(j) = net
                .road_lane(l.id)
                .and_then(|rl| net.road(rl.road))
                .and_then(|r| r.junction())
            else {
                continue;
            };
            let Some(&ji) = self.junction_of.get(j) else {
                continue;
            };
            let e = pts.entry(ji).or_default();
            for side in [-1.0, 1.0] {
                e.extend(edge_points(l, side).iter().map(|p| p.truncate()));
            }
        }
        for area in net.junction_areas() {
            if let Some(&ji) = self.junction_of.get(&area.od_id)
                && area.boundary.len() >= 3
            {
                let mut poly: Vec<Vec2> =
                    area.boundary.iter().map(|p| Vec2::new(p.x, p.y)).collect();
                if signed_area(&poly) < 0.0 {
                    poly.reverse();
                }
                self.town.junctions[ji.0 as usize].outline = poly;
                pts.remove(&ji);
            }
        }
        for (ji, p) in pts {
            self.town.junctions[ji.0 as usize].outline = convex_hull(&p);
        }
    }
}
