//! Junctions: one per OpenDRIVE junction id, and each one's outline (the
//! map's junction area, or the convex hull of its lanes' edges).
//!
//! A junction that roads with driving lanes lead into but that has no
//! connecting driving lane (no `<connection>`, or connections whose roads
//! hold no driving lane) cannot be crossed or arbitrated: the lanes into it
//! end there. The map is refused with the junction's id and the fix
//! ([`Builder::reject_junctions_without_lanes`]) rather than loaded with dead
//! ends that traffic would pile up at. Crossings and virtual junctions have
//! no connecting roads by design and are left alone. A connecting lane that
//! leads to no exit (or from no entry) is loaded, named in the load report's
//! warnings with the fix ([`Builder::warn_dangling_junction_lanes`]), and
//! driven around by the NPCs (`crate::agents::npc::extend_path`).

use std::collections::BTreeMap;

use glam::Vec2;
use xodr::{LaneType, Layer};

use super::{Builder, edge_points};
use crate::map::{Junction, JunctionIdx, MapError};
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
                    priorities: Vec::new(),
                    yellow_s: None,
                });
            }
        }
    }

    /// The junctions' `<priority>` elements as lane pairs: each driving lane
    /// of the `high` road over each driving lane of the `low` road, where
    /// both roads are connecting roads of one junction (other pairs say
    /// nothing a car can use and are left out). Call after [`Builder::lanes`].
    pub(super) fn priorities(&mut self) {
        let net = self.ctx.net;
        for pr in net.priorities() {
            let od = |r| net.road(r).map(|r| r.od_id().to_string());
            let (Some(high), Some(low)) = (od(pr.high), od(pr.low)) else {
                continue;
            };
            let lanes_of = |road: &str| -> Vec<(crate::map::LaneIdx, JunctionIdx)> {
                self.town
                    .lanes
                    .iter()
                    .enumerate()
                    .filter(|(_, l)| l.road_id == road)
                    .filter_map(|(i, l)| Some((crate::map::LaneIdx(i as u32), l.junction?)))
                    .collect()
            };
            let (hs, ls) = (lanes_of(&high), lanes_of(&low));
            for &(h, jh) in &hs {
                for &(l, jl) in &ls {
                    if jh == jl {
                        self.town.junctions[jh.0 as usize].priorities.push((h, l));
                    }
                }
            }
        }
    }

    /// Refuses a junction that roads with driving lanes link into (a
    /// `<link>`'s `<predecessor>` or `<successor>` with
    /// `elementType="junction"`) but that has no connecting driving lane,
    /// naming the junction, the roads and the fix. Call after
    /// [`Builder::lanes`]; `xml` is the document (the importer keeps no road
    /// links).
    pub(super) fn reject_junctions_without_lanes(&self, xml: &str) -> Result<(), MapError> {
        let Ok(doc) = roxmltree::Document::parse(xml) else {
            return Ok(()); // the importer read it; nothing more to learn here
        };
        let net = self.ctx.net;
        let by_design: Vec<&str> = net
            .crossings()
            .iter()
            .map(|c| c.od_id.as_str())
            .chain(net.virtual_junctions().iter().map(|v| v.od_id.as_str()))
            .collect();
        let with_lanes: std::collections::BTreeSet<&str> =
            self.town.lanes.iter().map(|l| l.road_id.as_str()).collect();
        // Junction id -> the roads with driving lanes that link into it.
        let mut into: BTreeMap<String, Vec<String>> = BTreeMap::new();
        for road in doc.descendants().filter(|n| n.has_tag_name("road")) {
            let Some(road_id) = road.attribute("id") else {
                continue;
            };
            if !with_lanes.contains(road_id) {
                continue;
            }
            let links = road
                .children()
                .filter(|n| n.has_tag_name("link"))
                .flat_map(|l| l.children())
                .filter(|n| n.has_tag_name("predecessor") || n.has_tag_name("successor"));
            for link in links {
                if link.attribute("elementType") == Some("junction")
                    && let Some(j) = link.attribute("elementId")
                    && !by_design.contains(&j)
                {
                    into.entry(j.to_string())
                        .or_default()
                        .push(road_id.to_string());
                }
            }
        }
        for (j, roads) in into {
            let idx = self.junction_of.get(&j).copied();
            if idx.is_some_and(|ji| self.town.lanes.iter().any(|l| l.junction == Some(ji))) {
                continue;
            }
            let declared = if idx.is_some() {
                "has no connecting driving lane"
            } else {
                "is not declared (no <junction> with that id)"
            };
            return Err(MapError::Invalid {
                file: self.ctx.file.clone(),
                what: format!(
                    "junction {j} {declared}, so the lanes of road {} that lead into it end there and traffic cannot cross it",
                    roads.join(", road ")
                ),
                location: format!(r#"junction id="{j}""#),
                fix: format!(
                    "give junction {j} a <connection incomingRoad=\"...\" connectingRoad=\"...\" contactPoint=\"start\"> with a <laneLink from=\"...\" to=\"...\"/> for each way through it, each connecting road marked junction=\"{j}\" with a driving lane; or remove the junction and link the roads to each other directly"
                ),
            });
        }
        Ok(())
    }

    /// A warning for each connecting lane that leads to no exit or comes
    /// from no entry: NPCs drive around it, but a route through it is cut.
    pub(super) fn warn_dangling_junction_lanes(&self, warnings: &mut Vec<String>) {
        for l in &self.town.lanes {
            let Some(j) = l.junction else { continue };
            let (to, from) = (l.successors.is_empty(), l.predecessors.is_empty());
            if !to && !from {
                continue;
            }
            let j_id = &self.town.junctions[j.0 as usize].od_id;
            let what = match (to, from) {
                (true, true) => "leads from no lane and to no lane",
                (true, false) => "leads to no lane (traffic drives around it)",
                _ => "is reached from no lane (traffic never uses it)",
            };
            warnings.push(format!(
                "junction {j_id}: connecting road {} lane {} {what}; fix: give road {} a <predecessor> and <successor> (elementType=\"road\") and its lane a <link>, and list it in junction {j_id}'s <connection>s",
                l.road_id, l.od_lane, l.road_id
            ));
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
