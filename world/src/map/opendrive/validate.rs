//! Validation of what the importer gives, before it is used: the `xodr`
//! crate accepts NaN or 1e308 coordinates and negative geometry lengths
//! without complaint, and drops what it cannot read with only a warning.
//! Each error names the file, what is wrong, where (road, lane, signal) and
//! the fix.

use xodr::LaneId;

use super::Ctx;
use crate::map::MapError;

/// Largest coordinate magnitude accepted from a map (metres): 1000 km.
pub const MAX_COORD_M: f32 = 1.0e6;

impl Ctx<'_> {
    fn invalid(&self, what: String, location: String, fix: &str) -> MapError {
        MapError::Invalid {
            file: self.file.clone(),
            what,
            location,
            fix: fix.into(),
        }
    }

    pub(super) fn road_od(&self, lane: LaneId) -> (String, i32) {
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

    /// The importer drops roads, geometries, lanes, records and numbers it
    /// cannot read (NaN, infinite, negative lengths) with a warning; a town
    /// missing them would mislead every run, so those warnings are errors
    /// here. (A lane whose `<width>` has an unreadable `a` would otherwise
    /// vanish, and the lanes outside it move in.)
    pub(super) fn reject_dropped_geometry(
        &self,
        warnings: &[xodr::Warning],
    ) -> Result<(), MapError> {
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
                xodr::Warning::RecordDropped { road_id, record, lane, s, attribute, .. } => (
                    format!("<{record}> without a readable {attribute} (the importer dropped it)"),
                    record_location(road_id, *lane, *s),
                ),
                xodr::Warning::LaneDropped { road_id, lane, .. } => (
                    "a lane with no readable <width> or <border> (the importer dropped it and its road marks)".to_string(),
                    record_location(road_id, Some(*lane), None),
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

    pub(super) fn validate(&self) -> Result<(), MapError> {
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

/// Where a dropped record or lane was: `road id="1" lane id="-1" s=0`.
fn record_location(road_id: &str, lane: Option<i32>, s: Option<f64>) -> String {
    let mut at = format!("road id=\"{road_id}\"");
    if let Some(lane) = lane {
        at += &format!(" lane id=\"{lane}\"");
    }
    if let Some(s) = s {
        at += &format!(" s={s}");
    }
    at
}
