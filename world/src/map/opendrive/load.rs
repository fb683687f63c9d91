//! Loading an OpenDRIVE file (through the `xodr` crate) into a [`Town`].
//!
//! What the importer gives is validated (finite, bounded coordinates; positive
//! lengths) before it is used: the crate accepts NaN or 1e308 coordinates and
//! negative geometry lengths without complaint.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use xodr::{Direction, LaneId, LaneType, Layer, RoadMarkType, RoadNetwork};

use crate::map::MapError;
use crate::map::town::*;
use crate::road::geometry::{arc_lengths, convex_hull, project_to_polyline, signed_area};

/// Largest coordinate magnitude accepted from a map (metres): 1000 km.
pub const MAX_COORD_M: f32 = 1.0e6;
/// Spacing of resampled lane centrelines (metres).
pub const CENTERLINE_SPACING_M: f32 = 1.0;
/// Speed limit used where the map gives none (metres per second; 30 km/h).
pub const DEFAULT_SPEED_LIMIT_MPS: f32 = 30.0 / 3.6;
/// Sidewalk height where the map gives none (metres).
pub const DEFAULT_SIDEWALK_HEIGHT_M: f32 = 0.15;
/// Height of a light's lamp housing above its pole's foot, as maps rarely
/// give it (metres).
pub const DEFAULT_LIGHT_HEAD_HEIGHT_M: f32 = 3.0;
/// Depth of a generated crosswalk along the road (metres).
pub const CROSSWALK_DEPTH_M: f32 = 4.0;
/// Gap between a generated crosswalk and the junction (metres).
pub const CROSSWALK_SETBACK_M: f32 = 1.0;

/// What to do at junctions when the map has no traffic lights at all.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UnsignalledJunctions {
    /// Leave them without lights.
    #[default]
    NoLights,
    /// Put one light per approach road at every junction with three or more
    /// approaches, each approach its own controller group.
    GenerateLights,
}

/// Options for loading a map.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// Lights for maps with no `<signal>` traffic lights.
    pub unsignalled: UnsignalledJunctions,
}

/// What a load found besides the town: counts from the file and the
/// importer's warnings.
#[derive(Debug, Clone, Default)]
pub struct LoadReport {
    /// The map file (or `<string>`).
    pub file: PathBuf,
    /// OpenDRIVE roads.
    pub roads: usize,
    /// Lanes of every type the importer baked (one per lane section).
    pub lanes: usize,
    /// `<signal>`s of every kind.
    pub signals: usize,
    /// Whether the traffic lights were generated rather than read.
    pub generated_lights: bool,
    /// The importer's warnings (`xodr::Provenance::warnings`), as text.
    pub warnings: Vec<String>,
}

impl Town {
    /// Loads an OpenDRIVE file with default [`LoadOptions`].
    pub fn from_xodr_file(path: impl AsRef<Path>) -> Result<Town, MapError> {
        load_xodr_file(path, &LoadOptions::default()).map(|(t, _)| t)
    }

    /// Loads OpenDRIVE text with default [`LoadOptions`]; `name` names the town
    /// and stands for the file in errors.
    pub fn from_xodr_str(xml: &str, name: &str) -> Result<Town, MapError> {
        load_xodr_str(xml, name, &LoadOptions::default()).map(|(t, _)| t)
    }
}

/// Loads an OpenDRIVE file into a [`Town`] and a [`LoadReport`].
pub fn load_xodr_file(
    path: impl AsRef<Path>,
    opts: &LoadOptions,
) -> Result<(Town, LoadReport), MapError> {
    let path = path.as_ref();
    let xml = std::fs::read(path).map_err(|source| MapError::Read {
        file: path.to_path_buf(),
        source,
    })?;
    let xml = String::from_utf8(xml).map_err(|e| MapError::Import {
        file: path.to_path_buf(),
        detail: format!(
            "not UTF-8 text (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ),
        fix: "give an OpenDRIVE .xodr file (XML text)".into(),
    })?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "town".into());
    load_impl(&xml, &name, path.to_path_buf(), opts)
}

/// Loads OpenDRIVE text into a [`Town`] named `name`.
pub fn load_xodr_str(
    xml: &str,
    name: &str,
    opts: &LoadOptions,
) -> Result<(Town, LoadReport), MapError> {
    load_impl(xml, name, PathBuf::from(format!("<{name}>")), opts)
}

fn p3(p: xodr::Point) -> Vec3 {
    Vec3::new(p.x, p.y, p.z)
}

fn load_impl(
    xml: &str,
    name: &str,
    file: PathBuf,
    opts: &LoadOptions,
) -> Result<(Town, LoadReport), MapError> {
    if !xml.contains("<OpenDRIVE") {
        return Err(MapError::Import {
            file,
            detail: "no <OpenDRIVE> root element".into(),
            fix: "give an OpenDRIVE .xodr file; if it was cut short, copy it again".into(),
        });
    }
    let (net, prov) = xodr::load_str_with_provenance(xml).map_err(|e| MapError::Import {
        file: file.clone(),
        detail: match &e {
            xodr::ImportError::Xml(x) => format!("{e} (at line {}, column {})", x.pos().row, x.pos().col),
            _ => e.to_string(),
        },
        fix: match e {
            xodr::ImportError::Xml(_) => "the XML is broken at the position named (a truncated file ends early); re-export or copy the file again".into(),
            _ => "the file holds no usable roads; check it is an OpenDRIVE map".into(),
        },
    })?;
    let ctx = Ctx {
        net: &net,
        file: &file,
    };
    ctx.reject_dropped_geometry(&prov.warnings)?;
    ctx.validate()?;
    let report = LoadReport {
        file: file.clone(),
        roads: net.roads().len(),
        lanes: net.lanes().len(),
        signals: net.signals().len(),
        generated_lights: false,
        warnings: prov.warnings.iter().map(|w| w.to_string()).collect(),
    };
    let mut b = Builder {
        ctx,
        prov: &prov,
        town: Town::empty(name),
        lane_of: HashMap::new(),
        junction_of: BTreeMap::new(),
    };
    b.junctions();
    b.lanes();
    b.markings();
    b.sidewalks();
    b.objects();
    b.junction_outlines();
    let mut report = report;
    b.lights(opts, &mut report);
    b.generated_crosswalks();
    b.surface();
    b.bounds();
    Ok((b.town, report))
}

struct Ctx<'a> {
    net: &'a RoadNetwork,
    file: &'a PathBuf,
}

impl Ctx<'_> {
    fn invalid(&self, what: String, location: String, fix: &str) -> MapError {
        MapError::Invalid {
            file: self.file.clone(),
            what,
            location,
            fix: fix.into(),
        }
    }

    fn road_od(&self, lane: LaneId) -> (String, i32) {
        match self.net.road_lane(lane) {
            Some(rl) => (
                self.net
                    .road(rl.road)
                    .map(|r| r.od_id().to_string())
                    .unwrap_or_default(),
                rl.od_id,
            ),
            None => (String::new(), 0),
        }
    }

    /// The importer drops roads, geometries and numbers it cannot read (NaN,
    /// infinite, negative lengths) with a warning; a town missing them would
    /// mislead every run, so those warnings are errors here.
    fn reject_dropped_geometry(&self, warnings: &[xodr::Warning]) -> Result<(), MapError> {
        for w in warnings {
            let (what, location) = match w {
                xodr::Warning::RoadSkipped { road_id, reason, .. } => (
                    format!("road dropped by the importer ({reason:?}: no finite positive length, no readable <geometry>, or values out of range)"),
                    format!("road id=\"{road_id}\""),
                ),
                xodr::Warning::GeometryDropped { road_id, s, .. } => (
                    "a <geometry> with a missing or non-finite x/y/hdg/length, or a length not above 0".to_string(),
                    format!("road id=\"{road_id}\" geometry s={}", s.map_or("?".into(), |v| v.to_string())),
                ),
                xodr::Warning::RecordValueUnreadable { road_id, record, attribute, s, .. } => (
                    format!("<{record}> {attribute} is not a finite number"),
                    format!("road id=\"{road_id}\" s={}", s.map_or("?".into(), |v| v.to_string())),
                ),
                _ => continue,
            };
            return Err(self.invalid(
                what,
                location,
                "give finite numbers and positive lengths (check the exporter or repair the file)",
            ));
        }
        Ok(())
    }

    fn validate(&self) -> Result<(), MapError> {
        let ok = |p: xodr::Point| {
            p.is_finite()
                && p.x.abs() < MAX_COORD_M
                && p.y.abs() < MAX_COORD_M
                && p.z.abs() < MAX_COORD_M
        };
        for road in self.net.roads() {
            let len = road.length();
            if !len.is_finite() || len <= 0.0 || len > 1.0e6 {
                return Err(self.invalid(
                    format!("road length {len} is not a positive length"),
                    format!("road id=\"{}\"", road.od_id()),
                    "give the road (and its <geometry> records) positive, finite lengths",
                ));
            }
        }
        for lane in self.net.lanes() {
            let (road, od) = self.road_od(lane.id);
            let loc = || format!("road id=\"{road}\" lane id=\"{od}\"");
            if let Some(p) = lane.center.points().iter().find(|p| !ok(**p)) {
                return Err(self.invalid(
                    format!(
                        "lane point ({}, {}, {}) is not finite or beyond {MAX_COORD_M} m",
                        p.x, p.y, p.z
                    ),
                    loc(),
                    "fix the road's <geometry> x/y/hdg/length and <elevation> values",
                ));
            }
            let len = lane.center.length();
            if !len.is_finite() || len <= 0.0 {
                return Err(self.invalid(
                    format!("lane length {len} is not positive"),
                    loc(),
                    "give the road a positive length",
                ));
            }
            let w = lane.width;
            if !w.is_finite()
                || !(0.0..=100.0).contains(&w)
                || lane
                    .widths
                    .iter()
                    .any(|w| !w.is_finite() || *w < 0.0 || *w > 100.0)
            {
                return Err(self.invalid(
                    format!("lane width {w} is negative, not finite or over 100 m"),
                    loc(),
                    "fix the lane's <width> records",
                ));
            }
        }
        for s in self.net.signals() {
            if !ok(s.position) || !s.heading.is_finite() {
                return Err(self.invalid(
                    format!(
                        "signal position ({}, {}, {}) or heading {} is not finite",
                        s.position.x, s.position.y, s.position.z, s.heading
                    ),
                    format!("signal \"{}\"", s.name),
                    "fix the signal's s/t/zOffset/hOffset",
                ));
            }
        }
        Ok(())
    }
}

struct Builder<'a> {
    ctx: Ctx<'a>,
    prov: &'a xodr::Provenance,
    town: Town,
    /// xodr lane id -> our lane index (drivable lanes only).
    lane_of: HashMap<LaneId, LaneIdx>,
    /// OpenDRIVE junction id -> our index.
    junction_of: BTreeMap<String, JunctionIdx>,
}

/// A lane's centreline in its stored (reference) direction, resampled.
fn edge_points(lane: &xodr::Lane, side: f32) -> Vec<Vec3> {
    // side: +1 left edge, -1 right edge (looking along the stored direction).
    let pts = lane.center.points();
    let tans = lane.center.tangents();
    let cum = arc_lengths(&pts.iter().map(|p| p3(*p)).collect::<Vec<_>>());
    let total = cum.last().copied().unwrap_or(0.0).max(1e-6);
    let xl = lane.center.length();
    pts.iter()
        .zip(tans)
        .zip(&cum)
        .map(|((p, t), c)| {
            let n = Vec2::new(-t.y, t.x).normalize_or_zero();
            let w = lane.width_at(c / total * xl);
            let q = p3(*p);
            q + (n * side * w * 0.5).extend(0.0)
        })
        .collect()
}

fn resample(points: &[Vec3], spacing: f32) -> (Vec<Vec3>, Vec<f32>) {
    let cum = arc_lengths(points);
    let total = cum.last().copied().unwrap_or(0.0);
    let n = ((total / spacing).round() as usize).max(1);
    let mut out = Vec::with_capacity(n + 1);
    let mut ss = Vec::with_capacity(n + 1);
    for i in 0..=n {
        let s = total * i as f32 / n as f32;
        out.push(crate::road::geometry::point_at(points, &cum, s));
        ss.push(s);
    }
    (out, ss)
}

impl Builder<'_> {
    fn junctions(&mut self) {
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

    fn lanes(&mut self) {
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

    fn markings(&mut self) {
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

    fn sidewalks(&mut self) {
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

    fn objects(&mut self) {
        for o in self.ctx.net.objects() {
            let poly: Option<(Vec<Vec2>, f32)> = match &o.shape {
                xodr::Shape::Outline {
                    corners,
                    closed: true,
                    ..
                } if corners.len() >= 3 => {
                    let h = corners
                        .iter()
                        .map(|c| c.top.z - c.base.z)
                        .fold(0.0, f32::max);
                    Some((
                        corners
                            .iter()
                            .map(|c| Vec2::new(c.base.x, c.base.y))
                            .collect(),
                        h,
                    ))
                }
                xodr::Shape::Solid {
                    position,
                    heading,
                    extent:
                        Some(xodr::Extent::Box {
                            length,
                            width,
                            height,
                        }),
                    ..
                } => {
                    let f = Vec2::from_angle(*heading);
                    let l = f.perp();
                    let c = Vec2::new(position.x, position.y);
                    let (hl, hw) = (length * 0.5, width * 0.5);
                    Some((
                        vec![
                            c - f * hl - l * hw,
                            c + f * hl - l * hw,
                            c + f * hl + l * hw,
                            c - f * hl + l * hw,
                        ],
                        *height,
                    ))
                }
                _ => None,
            };
            let Some((mut poly, h)) = poly else { continue };
            if poly
                .iter()
                .any(|p| !p.is_finite() || p.x.abs() > MAX_COORD_M || p.y.abs() > MAX_COORD_M)
            {
                continue;
            }
            if signed_area(&poly) < 0.0 {
                poly.reverse();
            }
            match o.kind {
                xodr::ObjectType::Building => self.town.buildings.push(Building {
                    footprint: poly,
                    height_m: if h > 0.0 { h } else { 10.0 },
                }),
                xodr::ObjectType::Crosswalk if poly.len() == 4 => {
                    let z = 0.0;
                    let c = [
                        poly[0].extend(z),
                        poly[1].extend(z),
                        poly[2].extend(z),
                        poly[3].extend(z),
                    ];
                    self.town.crosswalks.push(Crosswalk {
                        corners: c,
                        from_map: true,
                    });
                }
                _ => {}
            }
        }
    }

    fn junction_outlines(&mut self) {
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

    fn stop_line(&self, lane: LaneIdx) -> StopLine {
        let dl = &self.town.lanes[lane.0 as usize];
        let n = dl.centerline.len();
        let end = dl.centerline[n - 1];
        let dir = (end - dl.centerline[n - 2]).truncate().normalize_or_zero();
        let left = dir.perp();
        let hw = dl.width[n - 1] * 0.5;
        StopLine {
            lane,
            s: dl.s[n - 1],
            ends: [end + (left * hw).extend(0.0), end - (left * hw).extend(0.0)],
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

    fn lights(&mut self, opts: &LoadOptions, report: &mut LoadReport) {
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
            let stop_lines = stop_lanes.iter().map(|l| self.stop_line(*l)).collect();
            self.town.lights.push(TrafficLight {
                od_id: od_ids
                    .get(&sig.id)
                    .cloned()
                    .unwrap_or_else(|| sig.name.clone()),
                position: p3(sig.position),
                heading: sig.heading,
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
            for (g, (road, lanes)) in roads.iter().enumerate() {
                let stop_lines: Vec<StopLine> = lanes.iter().map(|l| self.stop_line(*l)).collect();
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

    fn generated_crosswalks(&mut self) {
        if !self.town.crosswalks.is_empty() {
            return;
        }
        // Lane ends at junction approaches, grouped by (junction, road).
        #[derive(Default)]
        struct End {
            pts: Vec<(Vec2, f32)>,
            dir: Option<Vec2>,
        }
        let mut ends: BTreeMap<(JunctionIdx, String), End> = BTreeMap::new();
        let lanes = &self.town.lanes;
        for l in lanes.iter().filter(|l| l.junction.is_none()) {
            let n = l.centerline.len();
            if let Some(j) = l
                .successors
                .iter()
                .find_map(|s| lanes[s.0 as usize].junction)
            {
                let e = ends.entry((j, l.road_id.clone())).or_default();
                let p = l.centerline[n - 1].truncate();
                e.pts.push((p, l.width[n - 1]));
                e.dir
                    .get_or_insert((p - l.centerline[n - 2].truncate()).normalize_or_zero());
            }
            if let Some(j) = l
                .predecessors
                .iter()
                .find_map(|s| lanes[s.0 as usize].junction)
            {
                let e = ends.entry((j, l.road_id.clone())).or_default();
                let p = l.centerline[0].truncate();
                e.pts.push((p, l.width[0]));
                e.dir
                    .get_or_insert((p - l.centerline[1].truncate()).normalize_or_zero());
            }
        }
        for (_, e) in ends {
            let Some(d) = e.dir else { continue };
            if d == Vec2::ZERO || e.pts.is_empty() {
                continue;
            }
            let n = d.perp();
            let o = e.pts[0].0;
            let mut lo = f32::MAX;
            let mut hi = f32::MIN;
            let mut along = f32::MIN;
            for (p, w) in &e.pts {
                let c = (*p - o).dot(n);
                lo = lo.min(c - w * 0.5);
                hi = hi.max(c + w * 0.5);
                along = along.max((*p - o).dot(d));
            }
            let base = o + d * along;
            let near = base - d * CROSSWALK_SETBACK_M;
            let far = near - d * CROSSWALK_DEPTH_M;
            let mut c = vec![far + n * lo, near + n * lo, near + n * hi, far + n * hi];
            if signed_area(&c) < 0.0 {
                c.reverse();
            }
            self.town.crosswalks.push(Crosswalk {
                corners: [
                    c[0].extend(0.0),
                    c[1].extend(0.0),
                    c[2].extend(0.0),
                    c[3].extend(0.0),
                ],
                from_map: false,
            });
        }
    }

    fn surface(&mut self) {
        let mesh = self.ctx.net.surface_mesh();
        let mut out = Mesh::default();
        let mut remap: HashMap<u32, u32> = HashMap::new();
        for span in &mesh.lanes {
            if !self.lane_of.contains_key(&span.lane) {
                continue;
            }
            for tri in
                mesh.indices[span.indices.start as usize..span.indices.end as usize].chunks_exact(3)
            {
                let mut idx = [0u32; 3];
                for k in 0..3 {
                    let v = tri[k];
                    idx[k] = *remap.entry(v).or_insert_with(|| {
                        out.positions.push(p3(mesh.vertices[v as usize]));
                        (out.positions.len() - 1) as u32
                    });
                }
                let a = out.positions[idx[0] as usize].truncate();
                let b = out.positions[idx[1] as usize].truncate();
                let c = out.positions[idx[2] as usize].truncate();
                if (b - a).perp_dot(c - a) < 0.0 {
                    idx.swap(1, 2);
                }
                out.indices.extend_from_slice(&idx);
            }
        }
        self.town.road_surface = out;
    }

    fn bounds(&mut self) {
        let mut lo = Vec2::splat(f32::MAX);
        let mut hi = Vec2::splat(f32::MIN);
        for l in self.ctx.net.lanes() {
            for p in l.center.points() {
                let q = Vec2::new(p.x, p.y);
                lo = lo.min(q - Vec2::splat(l.width * 0.5));
                hi = hi.max(q + Vec2::splat(l.width * 0.5));
            }
        }
        if lo.x > hi.x {
            lo = Vec2::ZERO;
            hi = Vec2::ZERO;
        }
        self.town.bounds = (lo, hi);
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
    let mut out = vec![crate::road::geometry::point_at(edge, &cum, s0)];
    for (p, c) in edge.iter().zip(&cum) {
        if *c > s0 && *c < s1 {
            out.push(*p);
        }
    }
    out.push(crate::road::geometry::point_at(edge, &cum, s1));
    out
}
