//! Plane geometry the planner, the monitors and the expert share: projection
//! onto polylines, segment intersection, an oriented box footprint crossing a
//! marking polyline (lane invasion), and a point crossing a stop line.
//!
//! Everything works in the ground plane (x, y; metres); z is ignored.

use glam::{Vec2, Vec3};

/// Where a point projects onto a polyline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolylineProjection {
    /// Index of the segment the nearest point is on (its first vertex).
    pub segment: usize,
    /// Fraction along that segment, in [0, 1].
    pub t: f32,
    /// Arc length of the nearest point from the polyline's start (metres).
    pub s: f32,
    /// The nearest point on the polyline (metres).
    pub point: Vec2,
    /// Distance from the query point to `point` (metres).
    pub distance: f32,
    /// Signed lateral offset of the query point: positive to the left of the
    /// polyline's direction (metres).
    pub offset: f32,
}

/// Projects `p` onto the polyline `points` (ground plane). `None` for an empty
/// polyline; a single point projects onto itself.
pub fn project_to_polyline(points: &[Vec3], p: Vec2) -> Option<PolylineProjection> {
    let first = points.first()?.truncate();
    if points.len() == 1 {
        return Some(PolylineProjection {
            segment: 0,
            t: 0.0,
            s: 0.0,
            point: first,
            distance: first.distance(p),
            offset: 0.0,
        });
    }
    let mut best: Option<PolylineProjection> = None;
    let mut s_acc = 0.0f32;
    for (i, w) in points.windows(2).enumerate() {
        let a = w[0].truncate();
        let b = w[1].truncate();
        let ab = b - a;
        let len2 = ab.length_squared();
        let t = if len2 > 0.0 {
            ((p - a).dot(ab) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = a + ab * t;
        let d = q.distance(p);
        let seg_len = len2.sqrt();
        if best.is_none_or(|bp| d < bp.distance) {
            let offset = if seg_len > 0.0 {
                ab.perp_dot(p - a) / seg_len
            } else {
                0.0
            };
            best = Some(PolylineProjection {
                segment: i,
                t,
                s: s_acc + seg_len * t,
                point: q,
                distance: d,
                offset,
            });
        }
        s_acc += seg_len;
    }
    best
}

/// Cumulative arc lengths of a polyline in the ground plane (metres), one per
/// point, starting at 0.
pub fn arc_lengths(points: &[Vec3]) -> Vec<f32> {
    let mut out = Vec::with_capacity(points.len());
    let mut acc = 0.0;
    for (i, p) in points.iter().enumerate() {
        if i > 0 {
            acc += points[i - 1].truncate().distance(p.truncate());
        }
        out.push(acc);
    }
    out
}

/// The point at arc length `s` (metres) along a polyline with cumulative arc
/// lengths `cum` (see [`arc_lengths`]), clamped to its ends.
pub fn point_at(points: &[Vec3], cum: &[f32], s: f32) -> Vec3 {
    let (i, t) = locate(cum, s);
    if i + 1 >= points.len() {
        return points[points.len() - 1];
    }
    points[i].lerp(points[i + 1], t)
}

/// Unit heading (radians, counter-clockwise from +x) at arc length `s`.
pub fn heading_at(points: &[Vec3], cum: &[f32], s: f32) -> f32 {
    let (i, _) = locate(cum, s);
    let i = i.min(points.len().saturating_sub(2));
    let d = (points[(i + 1).min(points.len() - 1)] - points[i]).truncate();
    d.y.atan2(d.x)
}

/// Segment index and fraction for arc length `s` on cumulative lengths `cum`.
fn locate(cum: &[f32], s: f32) -> (usize, f32) {
    if cum.len() < 2 || s <= 0.0 {
        return (0, 0.0);
    }
    let last = cum.len() - 1;
    if s >= cum[last] {
        return (last - 1, 1.0);
    }
    let i = cum
        .partition_point(|&c| c <= s)
        .saturating_sub(1)
        .min(last - 1);
    let len = cum[i + 1] - cum[i];
    let t = if len > 0.0 { (s - cum[i]) / len } else { 0.0 };
    (i, t)
}

/// Whether the closed segments `a0-a1` and `b0-b1` intersect (touching counts).
pub fn segments_intersect(a0: Vec2, a1: Vec2, b0: Vec2, b1: Vec2) -> bool {
    segment_intersection(a0, a1, b0, b1).is_some()
}

/// The fractions `(ta, tb)` along `a0-a1` and `b0-b1` where they intersect, if
/// they do. Collinear overlapping segments report their first shared point.
pub fn segment_intersection(a0: Vec2, a1: Vec2, b0: Vec2, b1: Vec2) -> Option<(f32, f32)> {
    let r = a1 - a0;
    let s = b1 - b0;
    let denom = r.perp_dot(s);
    let qp = b0 - a0;
    const EPS: f32 = 1e-9;
    if denom.abs() < EPS {
        // Parallel: intersect only if collinear and overlapping.
        if qp.perp_dot(r).abs() > 1e-6 {
            return None;
        }
        let rr = r.length_squared();
        if rr < EPS {
            return (a0.distance(b0) < 1e-6).then_some((0.0, 0.0));
        }
        let t0 = qp.dot(r) / rr;
        let t1 = (b1 - a0).dot(r) / rr;
        let (lo, hi) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        if hi < 0.0 || lo > 1.0 {
            return None;
        }
        let ta = lo.max(0.0);
        let tb = if s.length_squared() > 0.0 {
            ((a0 + r * ta) - b0).dot(s) / s.length_squared()
        } else {
            0.0
        };
        return Some((ta, tb.clamp(0.0, 1.0)));
    }
    let ta = qp.perp_dot(s) / denom;
    let tb = qp.perp_dot(r) / denom;
    if (-1e-6..=1.0 + 1e-6).contains(&ta) && (-1e-6..=1.0 + 1e-6).contains(&tb) {
        Some((ta.clamp(0.0, 1.0), tb.clamp(0.0, 1.0)))
    } else {
        None
    }
}

/// A rectangle in the ground plane: a vehicle's footprint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrientedBox {
    /// Centre (metres).
    pub center: Vec2,
    /// Heading of the long axis (radians, counter-clockwise from +x).
    pub heading: f32,
    /// Half the length along the heading (metres).
    pub half_length: f32,
    /// Half the width across the heading (metres).
    pub half_width: f32,
}

impl OrientedBox {
    /// The four corners, counter-clockwise: front-right, front-left,
    /// rear-left, rear-right (metres).
    pub fn corners(&self) -> [Vec2; 4] {
        let f = Vec2::from_angle(self.heading);
        let l = f.perp();
        let c = self.center;
        let (hl, hw) = (self.half_length, self.half_width);
        [
            c + f * hl - l * hw,
            c + f * hl + l * hw,
            c - f * hl + l * hw,
            c - f * hl - l * hw,
        ]
    }

    /// Whether `p` lies inside or on the box.
    pub fn contains(&self, p: Vec2) -> bool {
        let f = Vec2::from_angle(self.heading);
        let d = p - self.center;
        d.dot(f).abs() <= self.half_length + 1e-6 && d.dot(f.perp()).abs() <= self.half_width + 1e-6
    }
}

/// Whether the footprint `b` touches the polyline `line` anywhere: a segment
/// crosses one of its edges or lies inside it. This is the lane-invasion test:
/// a marking under the car counts.
pub fn box_touches_polyline(b: &OrientedBox, line: &[Vec3]) -> bool {
    if line.is_empty() {
        return false;
    }
    let corners = b.corners();
    // Quick reject on distance.
    let radius = b.half_length.hypot(b.half_width);
    if line.len() == 1 {
        return b.contains(line[0].truncate());
    }
    for w in line.windows(2) {
        let (p, q) = (w[0].truncate(), w[1].truncate());
        if segment_point_distance(p, q, b.center) > radius {
            continue;
        }
        if b.contains(p) || b.contains(q) {
            return true;
        }
        for k in 0..4 {
            if segments_intersect(p, q, corners[k], corners[(k + 1) % 4]) {
                return true;
            }
        }
    }
    false
}

/// Distance from `c` to the closed segment `a-b` (metres).
pub fn segment_point_distance(a: Vec2, b: Vec2, c: Vec2) -> f32 {
    let ab = b - a;
    let l2 = ab.length_squared();
    let t = if l2 > 0.0 {
        ((c - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * t).distance(c)
}

/// Whether a point moving from `prev` to `cur` crosses the stop line with
/// ends `ends` (left end first, right end second, seen in the lane's driving
/// direction) going forward: from before the line to on or past it.
/// Moving backwards over the line, or along it, is not a crossing.
pub fn crosses_stop_line(prev: Vec2, cur: Vec2, ends: [Vec2; 2]) -> bool {
    let forward = (ends[1] - ends[0]).perp(); // ccw of left->right is the driving direction
    let before = (prev - ends[0]).dot(forward) < 0.0;
    let after = (cur - ends[0]).dot(forward) >= 0.0;
    before && after && segments_intersect(prev, cur, ends[0], ends[1])
}

/// Signed area of a polygon (positive when counter-clockwise), square metres.
pub fn signed_area(poly: &[Vec2]) -> f32 {
    let n = poly.len();
    let mut a = 0.0;
    for i in 0..n {
        a += poly[i].perp_dot(poly[(i + 1) % n]);
    }
    a * 0.5
}

/// The convex hull of `points`, counter-clockwise (Andrew's monotone chain).
pub fn convex_hull(points: &[Vec2]) -> Vec<Vec2> {
    let mut pts: Vec<Vec2> = points.iter().copied().filter(|p| p.is_finite()).collect();
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup_by(|a, b| a.distance(*b) < 1e-4);
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a - o).perp_dot(b - o);
    let mut lower: Vec<Vec2> = Vec::new();
    for &p in &pts {
        while lower.len() >= 2 && cross(lower[lower.len() - 2], lower[lower.len() - 1], p) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
    }
    let mut upper: Vec<Vec2> = Vec::new();
    for &p in pts.iter().rev() {
        while upper.len() >= 2 && cross(upper[upper.len() - 2], upper[upper.len() - 1], p) <= 0.0 {
            upper.pop();
        }
        upper.push(p);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

/// Whether `p` is inside the polygon `poly` (even-odd rule).
pub fn point_in_polygon(poly: &[Vec2], p: Vec2) -> bool {
    let n = poly.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (a, b) = (poly[i], poly[j]);
        if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// Wraps an angle to (-pi, pi] (radians).
pub fn wrap_angle(a: f32) -> f32 {
    let mut a = a % std::f32::consts::TAU;
    if a > std::f32::consts::PI {
        a -= std::f32::consts::TAU;
    } else if a <= -std::f32::consts::PI {
        a += std::f32::consts::TAU;
    }
    a
}

/// Curvature of the circle through three points (1 / metres, unsigned).
pub fn curvature(a: Vec2, b: Vec2, c: Vec2) -> f32 {
    let ab = (b - a).length();
    let bc = (c - b).length();
    let ca = (a - c).length();
    let cross = (b - a).perp_dot(c - a).abs();
    if ab * bc * ca < 1e-9 {
        0.0
    } else {
        2.0 * cross / (ab * bc * ca)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angles_wrap_into_minus_pi_exclusive_to_pi_inclusive() {
        use std::f32::consts::{FRAC_PI_2, PI, TAU};
        assert_eq!(wrap_angle(0.25), 0.25);
        assert!((wrap_angle(1.5 * PI) + FRAC_PI_2).abs() < 1e-6);
        assert!((wrap_angle(-1.5 * PI) - FRAC_PI_2).abs() < 1e-6);
        assert!((wrap_angle(3.0 * TAU + 0.5) - 0.5).abs() < 1e-5);
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
    }

    fn v3(x: f32, y: f32) -> Vec3 {
        Vec3::new(x, y, 0.0)
    }

    #[test]
    fn projection_gives_s_offset_and_distance() {
        let line = [v3(0.0, 0.0), v3(10.0, 0.0), v3(10.0, 10.0)];
        let p = project_to_polyline(&line, Vec2::new(4.0, 2.0)).unwrap();
        assert_eq!(p.segment, 0);
        assert!((p.s - 4.0).abs() < 1e-5);
        assert!((p.distance - 2.0).abs() < 1e-5);
        assert!((p.offset - 2.0).abs() < 1e-5, "left of +x is positive");
        let q = project_to_polyline(&line, Vec2::new(12.0, 5.0)).unwrap();
        assert_eq!(q.segment, 1);
        assert!((q.s - 15.0).abs() < 1e-5);
        assert!((q.offset + 2.0).abs() < 1e-5, "right of +y is negative");
    }

    #[test]
    fn box_straddling_a_marking_touches_it_and_one_beside_it_does_not() {
        // A marking along y = 1.75 (the line between two lanes).
        let marking = [v3(-50.0, 1.75), v3(50.0, 1.75)];
        // Car 4.8 x 2.1 centred in the lane at y = 0: its left side at y = 1.05.
        let inside = OrientedBox {
            center: Vec2::ZERO,
            heading: 0.0,
            half_length: 2.4,
            half_width: 1.05,
        };
        assert!(!box_touches_polyline(&inside, &marking));
        // Drifted left by 0.8 m: left side at 1.85 > 1.75.
        let drifted = OrientedBox {
            center: Vec2::new(0.0, 0.8),
            ..inside
        };
        assert!(box_touches_polyline(&drifted, &marking));
        // Yawed by 30 degrees at the lane centre: the front-left corner reaches
        // y = 2.4 sin30 + 1.05 cos30 = 2.11 > 1.75.
        let yawed = OrientedBox {
            heading: 30f32.to_radians(),
            ..inside
        };
        assert!(box_touches_polyline(&yawed, &marking));
        // A short marking piece entirely under the car also counts.
        let under = [v3(-0.5, 0.2), v3(0.5, 0.2)];
        assert!(box_touches_polyline(&inside, &under));
    }

    #[test]
    fn stop_line_crossing_is_directional() {
        // Lane drives +x; stop line at x = 10 from (10, 1.75) left to (10, -1.75) right.
        let ends = [Vec2::new(10.0, 1.75), Vec2::new(10.0, -1.75)];
        assert!(crosses_stop_line(
            Vec2::new(9.8, 0.0),
            Vec2::new(10.2, 0.0),
            ends
        ));
        assert!(!crosses_stop_line(
            Vec2::new(9.0, 0.0),
            Vec2::new(9.9, 0.0),
            ends
        ));
        assert!(
            !crosses_stop_line(Vec2::new(10.2, 0.0), Vec2::new(9.8, 0.0), ends),
            "reversing"
        );
        assert!(
            !crosses_stop_line(Vec2::new(9.8, 3.0), Vec2::new(10.2, 3.0), ends),
            "beside the lane"
        );
    }

    #[test]
    fn segments_and_hull() {
        assert!(segments_intersect(
            Vec2::ZERO,
            Vec2::ONE,
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 0.0)
        ));
        assert!(!segments_intersect(
            Vec2::ZERO,
            Vec2::new(1.0, 0.0),
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0)
        ));
        let hull = convex_hull(&[
            Vec2::ZERO,
            Vec2::new(2.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(2.0, 2.0),
            Vec2::new(0.0, 2.0),
        ]);
        assert_eq!(hull.len(), 4);
        assert!((signed_area(&hull) - 4.0).abs() < 1e-5);
        assert!(point_in_polygon(&hull, Vec2::new(1.0, 1.5)));
        assert!(!point_in_polygon(&hull, Vec2::new(3.0, 1.0)));
    }

    #[test]
    fn point_and_heading_along_polyline() {
        let line = [v3(0.0, 0.0), v3(10.0, 0.0), v3(10.0, 10.0)];
        let cum = arc_lengths(&line);
        assert_eq!(cum, vec![0.0, 10.0, 20.0]);
        assert!(point_at(&line, &cum, 15.0).distance(v3(10.0, 5.0)) < 1e-5);
        assert!((heading_at(&line, &cum, 15.0) - std::f32::consts::FRAC_PI_2).abs() < 1e-5);
        assert!(point_at(&line, &cum, 99.0).distance(v3(10.0, 10.0)) < 1e-5);
    }
}
