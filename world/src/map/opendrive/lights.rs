//! Traffic lights: the map's dynamic signals with the stop lines of the
//! lanes they control, their junction and controller group; lights
//! generated at unsignalled junctions when asked; groups for lights without
//! a controller sequence.

use std::collections::{BTreeMap, HashMap};

use super::load::{LoadOptions, LoadReport, UnsignalledJunctions};
use super::{Builder, p3};
use glam::Vec2;

use crate::map::{JunctionIdx, LaneIdx, LightIdx, StopLine, TrafficLight};
use crate::road::geometry::project_to_polyline;

/// The heading that faces the traffic arriving at a stop line (radians,
/// counter-clockwise from +x): against the driving direction, which runs
/// from the line's left end to its right end turned a quarter counter-clockwise.
fn facing_traffic(line: &StopLine) -> f32 {
    let driving = (line.ends[1] - line.ends[0]).truncate().perp();
    (-driving).y.atan2((-driving).x)
}

/// Height of a light's lamp housing above its pole's foot, as maps rarely
/// give it (metres).
pub const DEFAULT_LIGHT_HEAD_HEIGHT_M: f32 = 3.0;

/// How far before the end of its approach lane a light's pole may stand and
/// still carry the stop line (metres). Town01's poles stand 0-5 m before the
/// junction; a pole farther back than this is taken to be misplaced and the
/// line stays at the lane's end.
pub const MAX_POLE_SETBACK_M: f32 = 8.0;

/// A road shorter than this from one junction into the next lies inside one
/// box (metres): a car of 4.9 m cannot wait on it clear of both junctions with
/// a metre or two each side. Generated lights leave its end unlit, as a
/// traffic engineer signals two junctions that close as one: a car let into
/// the first on its green drives on through the second, taking its lane by
/// the junctions' first-come-first-served reservations, and never meets a
/// light a few metres past the first junction (Town04's road 2, 5.3 m between
/// junctions 317 and 386, where cars ran that light at 8-15 m/s and queued into
/// the first junction). CARLA's towns have such links of 3.5-8.5 m (Town03)
/// and 5.3-7.4 m (Town04); the next shortest are 13 m and 19 m.
pub const BOX_LINK_M: f32 = 10.0;

impl Builder<'_> {
    /// Whether the road that `lane` ends comes out of a junction less than
    /// `max_m` metres before `lane`'s end (walking back along its lane and the
    /// lanes before it, while there is one).
    fn out_of_junction_within(&self, lane: LaneIdx, max_m: f32) -> bool {
        let lanes = &self.town.lanes;
        let mut l = lane;
        let mut len = 0.0;
        loop {
            let dl = &lanes[l.0 as usize];
            len += dl.length_m();
            if len >= max_m {
                return false;
            }
            if dl
                .predecessors
                .iter()
                .any(|p| lanes[p.0 as usize].junction.is_some())
            {
                return true;
            }
            match dl.predecessors[..] {
                [p] => l = p,
                _ => return false,
            }
        }
    }

    /// The lane whose end is the stop line for traffic on `lane`: walk forward
    /// until the next lane is in a junction.
    fn stop_lane(&self, lane: LaneIdx) -> Option<LaneIdx> {
        let lanes = &self.town.lanes;
        let mut l = lane;
        if lanes[l.0 as usize].junction.is_some() {
            // A signal on a connecting road: stop where it is entered.
            return lanes[l.0 as usize]
                .predecessors
                .iter()
                .copied()
                .find(|p| lanes[p.0 as usize].junction.is_none());
        }
        for _ in 0..16 {
            let dl = &lanes[l.0 as usize];
            if dl
                .successors
                .iter()
                .any(|s| lanes[s.0 as usize].junction.is_some())
                || dl.successors.len() != 1
            {
                return Some(l);
            }
            l = dl.successors[0];
        }
        Some(l)
    }

    /// The stop line of an approach lane: where the lane passes the light's
    /// pole, as CARLA's trigger volumes stand at the light, so that a car
    /// waiting at the line still has the light in view. Without a pole, or
    /// with one beside the junction or more than [`MAX_POLE_SETBACK_M`]
    /// before it, the line is at the lane's end, where the junction begins.
    fn stop_line(&self, lane: LaneIdx, pole: Option<Vec2>) -> StopLine {
        let dl = &self.town.lanes[lane.0 as usize];
        let n = dl.centerline.len();
        let end_s = dl.s[n - 1];
        let at_pole = pole
            .and_then(|p| project_to_polyline(&dl.centerline, p))
            .filter(|pr| pr.s < end_s && pr.s > end_s - MAX_POLE_SETBACK_M && pr.segment + 1 < n);
        let (centre, dir, width, s) = match at_pole {
            Some(pr) => {
                let (a, b) = (dl.centerline[pr.segment], dl.centerline[pr.segment + 1]);
                let w =
                    dl.width[pr.segment] + (dl.width[pr.segment + 1] - dl.width[pr.segment]) * pr.t;
                (a.lerp(b, pr.t), (b - a).truncate(), w, pr.s)
            }
            None => (
                dl.centerline[n - 1],
                (dl.centerline[n - 1] - dl.centerline[n - 2]).truncate(),
                dl.width[n - 1],
                end_s,
            ),
        };
        let left = dir.normalize_or_zero().perp();
        let hw = width * 0.5;
        StopLine {
            lane,
            s,
            ends: [
                centre + (left * hw).extend(0.0),
                centre - (left * hw).extend(0.0),
            ],
        }
    }

    /// The junction a stop lane leads into.
    fn junction_after(&self, lane: LaneIdx) -> Option<JunctionIdx> {
        let lanes = &self.town.lanes;
        lanes[lane.0 as usize]
            .successors
            .iter()
            .find_map(|s| lanes[s.0 as usize].junction)
    }

    pub(super) fn lights(&mut self, opts: &LoadOptions, report: &mut LoadReport) {
        let net = self.ctx.net;
        // controller id -> (junction od id, sequence) from the junctions' lists.
        let mut ctrl_junction: HashMap<xodr::ControllerId, (String, Option<u32>)> = HashMap::new();
        for cp in &self.prov.controllers {
            if let Some(j) = cp.junctions.first() {
                let seq = j
                    .sequence
                    .or_else(|| net.controller(cp.controller).and_then(|c| c.sequence));
                ctrl_junction.insert(cp.controller, (j.junction_id.clone(), seq));
            }
        }
        let od_ids: HashMap<xodr::SignalId, String> = self
            .prov
            .signals
            .iter()
            .map(|s| (s.signal, s.od_id.clone()))
            .collect();
        for sig in net.signals() {
            let is_light = sig.dynamic
                && (sig.kind == "1000001"
                    || !sig.controllers.is_empty()
                    || sig.name.to_ascii_lowercase().contains("light"));
            if !is_light {
                continue;
            }
            let mut stop_lanes: Vec<LaneIdx> = sig
                .lanes
                .iter()
                .filter_map(|l| self.lane_of.get(l).copied())
                .filter_map(|l| self.stop_lane(l))
                .collect();
            stop_lanes.sort();
            stop_lanes.dedup();
            let from_ctrl = sig
                .controllers
                .iter()
                .find_map(|c| ctrl_junction.get(c).cloned());
            let junction = from_ctrl
                .as_ref()
                .and_then(|(j, _)| self.junction_of.get(j).copied())
                .or_else(|| stop_lanes.iter().find_map(|l| self.junction_after(*l)));
            let group = from_ctrl.and_then(|(_, s)| s).unwrap_or(u32::MAX);
            let pole = p3(sig.position).truncate();
            let stop_lines: Vec<StopLine> = stop_lanes
                .iter()
                .map(|l| self.stop_line(*l, Some(pole)))
                .collect();
            // The lamps face the traffic they stop. Maps disagree on how
            // `orientation` and `hOffset` combine (read by the standard, half
            // of CARLA Town01's lights, those with orientation "-", would turn
            // their backs on their lanes), so the lanes decide.
            let heading = stop_lines.first().map_or(sig.heading, facing_traffic);
            self.town.lights.push(TrafficLight {
                od_id: od_ids
                    .get(&sig.id)
                    .cloned()
                    .unwrap_or_else(|| sig.name.clone()),
                position: p3(sig.position),
                heading,
                head_height_m: DEFAULT_LIGHT_HEAD_HEIGHT_M,
                junction,
                group,
                stop_lines,
            });
        }
        if self.town.lights.is_empty() && opts.unsignalled == UnsignalledJunctions::GenerateLights {
            self.generate_lights();
            report.generated_lights = true;
        }
        self.assign_groups();
    }

    /// Lights without a controller sequence get groups by approach road order.
    fn assign_groups(&mut self) {
        let mut by_junction: BTreeMap<Option<JunctionIdx>, Vec<usize>> = BTreeMap::new();
        for (i, l) in self.town.lights.iter().enumerate() {
            by_junction.entry(l.junction).or_default().push(i);
        }
        for (j, idx) in by_junction {
            let mut next = idx
                .iter()
                .map(|&i| self.town.lights[i].group)
                .filter(|g| *g != u32::MAX)
                .max()
                .map_or(0, |g| g + 1);
            for &i in &idx {
                if self.town.lights[i].group == u32::MAX {
                    self.town.lights[i].group = next;
                    next += 1;
                }
            }
            if let Some(j) = j {
                let mut list: Vec<usize> = idx.clone();
                list.sort_by_key(|&i| (self.town.lights[i].group, i));
                self.town.junctions[j.0 as usize].lights =
                    list.into_iter().map(|i| LightIdx(i as u32)).collect();
            }
        }
    }

    fn generate_lights(&mut self) {
        // Approach lanes per (junction, road).
        let mut approaches: BTreeMap<(JunctionIdx, String), Vec<LaneIdx>> = BTreeMap::new();
        for (i, l) in self.town.lanes.iter().enumerate() {
            if l.junction.is_some() {
                continue;
            }
            if let Some(j) = self.junction_after(LaneIdx(i as u32)) {
                approaches
                    .entry((j, l.road_id.clone()))
                    .or_default()
                    .push(LaneIdx(i as u32));
            }
        }
        let mut per_junction: BTreeMap<JunctionIdx, Vec<(String, Vec<LaneIdx>)>> = BTreeMap::new();
        for ((j, road), lanes) in approaches {
            per_junction.entry(j).or_default().push((road, lanes));
        }
        for (j, roads) in per_junction {
            if roads.len() < 3 {
                continue;
            }
            // Yellow long enough for the fastest approach (the map sets no timing).
            let fastest = roads
                .iter()
                .flat_map(|(_, lanes)| lanes)
                .map(|l| self.town.lanes[l.0 as usize].speed_limit_mps)
                .fold(0.0_f32, f32::max);
            self.town.junctions[j.0 as usize].yellow_s =
                Some(crate::rules::change_interval_s(fastest));
            // Links inside the box (shorter than `BOX_LINK_M`) get no light.
            let lit: Vec<&(String, Vec<LaneIdx>)> = roads
                .iter()
                .filter(|(_, lanes)| {
                    !lanes
                        .iter()
                        .all(|l| self.out_of_junction_within(*l, BOX_LINK_M))
                })
                .collect();
            for (g, (road, lanes)) in lit.into_iter().enumerate() {
                let stop_lines: Vec<StopLine> =
                    lanes.iter().map(|l| self.stop_line(*l, None)).collect();
                // Pole beside the rightmost stop line's right end, facing traffic.
                let across = (stop_lines[0].ends[1] - stop_lines[0].ends[0])
                    .truncate()
                    .normalize_or_zero();
                let sl = stop_lines
                    .iter()
                    .max_by(|a, b| {
                        a.ends[1]
                            .truncate()
                            .dot(across)
                            .total_cmp(&b.ends[1].truncate().dot(across))
                    })
                    .unwrap_or(&stop_lines[0]);
                let forward = across.perp();
                let pos = sl.ends[1] + (across * 1.5).extend(0.0);
                let heading = (-forward).y.atan2((-forward).x);
                self.town.lights.push(TrafficLight {
                    od_id: format!("gen-{}-{}", self.town.junctions[j.0 as usize].od_id, road),
                    position: pos,
                    heading,
                    head_height_m: DEFAULT_LIGHT_HEAD_HEIGHT_M,
                    junction: Some(j),
                    group: g as u32,
                    stop_lines,
                });
            }
        }
    }
}
