//! The road and its paint: the road surface (the map's mesh, or lanes
//! paved along their centrelines), lane markings, sidewalks with curbs, and
//! crosswalk stripes.

use glam::Vec3;
use world::{MarkColor, MarkKind, Town};

use super::merge::{kept_ribs, merged_mesh};
use super::primitives::{Line, PAINT_LIFT_M, Tris, pack, paint};
use crate::render::classes;

/// Default dash pattern (paint, gap) for broken lines without one (metres).
const DEFAULT_DASH_M: (f32, f32) = (3.0, 6.0);

/// The road surface: the map's mesh (merged where straight), else each
/// lane paved along its centreline.
pub(super) fn road(town: &Town, t: &mut Tris) {
    let col = pack(paint::ASPHALT, classes::ROAD, false);
    let m = &town.road_surface;
    if !m.indices.is_empty() {
        let n = m.positions.len() as u32;
        let tris: Vec<[u32; 3]> = m
            .indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .filter(|c| c.iter().all(|&i| i < n))
            .collect();
        merged_mesh(&m.positions, &tris, t, col);
        return;
    }
    // No mesh: pave each lane's width along its centreline.
    for lane in &town.lanes {
        let Some(line) = Line::new(&lane.centerline) else {
            continue;
        };
        for i in 0..line.p.len() - 1 {
            let w0 = lane.width.get(i).copied().unwrap_or(3.5) * 0.5;
            let w1 = lane.width.get(i + 1).copied().unwrap_or(3.5) * 0.5;
            let (p0, p1, n0, n1) = (line.p[i], line.p[i + 1], line.n[i], line.n[i + 1]);
            t.quad(p0 - n0 * w0, p1 - n1 * w1, p1 + n1 * w1, p0 + n0 * w0, col);
        }
    }
}

/// A line's paint pattern: `None` solid, `Some((paint, gap))` dashed (metres).
type Pattern = Option<(f32, f32)>;

/// Lane markings as painted strips (solid, broken, double).
pub(super) fn markings(town: &Town, t: &mut Tris) {
    for m in &town.markings {
        let Some(line) = Line::new(&m.points) else {
            continue;
        };
        let rgb = match m.color {
            MarkColor::White => paint::WHITE,
            MarkColor::Yellow => paint::YELLOW,
        };
        let col = pack(rgb, classes::LANE_MARKING, false);
        let w = if m.width_m.is_finite() && m.width_m > 0.0 {
            m.width_m
        } else {
            0.12
        };
        let dash = Some(m.dash_m.unwrap_or(DEFAULT_DASH_M)).filter(|d| d.0 > 0.0 && d.1 >= 0.0);
        let solid = None;
        // (left line, right line) relative to the points' direction; None = no line.
        let lines: [(f32, Option<Pattern>); 2] = match m.kind {
            MarkKind::Solid => [(0.0, Some(solid)), (0.0, None)],
            MarkKind::Broken => [(0.0, Some(dash)), (0.0, None)],
            MarkKind::SolidSolid => [(w, Some(solid)), (-w, Some(solid))],
            MarkKind::SolidBroken => [(w, Some(solid)), (-w, Some(dash))],
            MarkKind::BrokenSolid => [(w, Some(dash)), (-w, Some(solid))],
            MarkKind::BrokenBroken => [(w, Some(dash)), (-w, Some(dash))],
            MarkKind::Curb => continue,
        };
        for (offset, pattern) in lines {
            if let Some(pattern) = pattern {
                line.strip(t, offset, w, pattern, PAINT_LIFT_M, col);
            }
        }
    }
}

/// Sidewalk tops and curbs down to the ground.
pub(super) fn sidewalks(town: &Town, ground_z: f32, t: &mut Tris) {
    let top = pack(paint::SIDEWALK, classes::SIDEWALK, false);
    let curb = pack(paint::CURB, classes::SIDEWALK, false);
    for sw in &town.sidewalks {
        let n = sw.inner.len().min(sw.outer.len());
        let h = if sw.height_m.is_finite() {
            sw.height_m.clamp(0.0, 1.0)
        } else {
            0.15
        };
        let kept = kept_ribs(n, |i| sw.inner[i], |i| sw.outer[i]);
        for w in kept.windows(2) {
            let (i, k) = (w[0], w[1]);
            let (a, b) = (sw.inner[i], sw.inner[k]);
            let (c, d) = (sw.outer[k], sw.outer[i]);
            if ![a, b, c, d].iter().all(|p| p.is_finite()) {
                continue;
            }
            let up = Vec3::Z * h;
            t.quad(a + up, b + up, c + up, d + up, top);
            t.quad(a, b, b + up, a + up, curb);
            let down = |p: Vec3| Vec3::new(p.x, p.y, ground_z);
            t.quad(down(d), down(c), c + up, d + up, curb);
        }
    }
}

/// Zebra stripes across each crosswalk.
pub(super) fn crosswalks(town: &Town, t: &mut Tris) {
    let col = pack(paint::WHITE, classes::CROSSWALK, false);
    for cw in &town.crosswalks {
        let c = cw.corners;
        if !c.iter().all(|p| p.is_finite()) {
            continue;
        }
        // Stripes run across the long side (the one spanning the road).
        let (a, b, d) = if c[0].distance(c[1]) >= c[1].distance(c[2]) {
            (c[0], c[1], c[3])
        } else {
            (c[1], c[2], c[0])
        };
        let long = b - a;
        let short = d - a;
        let len = long.length();
        let (paint_m, gap_m) = (0.5, 0.5);
        let mut x = gap_m * 0.5;
        while x + paint_m <= len {
            let u0 = long * (x / len);
            let u1 = long * ((x + paint_m) / len);
            let lift = Vec3::Z * PAINT_LIFT_M;
            t.quad(
                a + u0 + lift,
                a + u1 + lift,
                a + u1 + short + lift,
                a + u0 + short + lift,
                col,
            );
            x += paint_m + gap_m;
        }
    }
}
