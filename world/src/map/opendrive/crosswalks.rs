//! Crosswalks for maps that have none: one across each road where it meets
//! a junction, set back from the junction and as wide as the road's lanes.

use std::collections::BTreeMap;

use glam::Vec2;

use super::Builder;
use crate::map::{Crosswalk, JunctionIdx};
use crate::road::geometry::signed_area;

/// Depth of a generated crosswalk along the road (metres).
pub const CROSSWALK_DEPTH_M: f32 = 4.0;
/// Gap between a generated crosswalk and the junction (metres).
pub const CROSSWALK_SETBACK_M: f32 = 1.0;

impl Builder<'_> {
    pub(super) fn generated_crosswalks(&mut self) {
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
}
