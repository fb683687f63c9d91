//! A vehicle's footprint on the ground, and the crossing tests the lane and
//! red-light monitors share with the expert.

use glam::{Vec2, Vec3};

/// An oriented rectangle on the ground plane (metres, world frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Corners counter-clockwise: rear-right, front-right, front-left, rear-left.
    pub corners: [Vec2; 4],
}

impl Footprint {
    /// The footprint of a box of `length` x `width` (metres) centred at
    /// `center` and heading `heading` (radians, counter-clockwise from +x).
    pub fn new(center: Vec2, heading: f32, length: f32, width: f32) -> Self {
        let forward = Vec2::from_angle(heading);
        let left = forward.perp();
        let (hl, hw) = (forward * (length / 2.0), left * (width / 2.0));
        Self {
            corners: [
                center - hl - hw,
                center + hl - hw,
                center + hl + hw,
                center - hl + hw,
            ],
        }
    }

    /// The midpoint of the front edge.
    pub fn front_center(&self) -> Vec2 {
        (self.corners[1] + self.corners[2]) / 2.0
    }

    /// Whether the point lies inside (or on the edge).
    pub fn contains(&self, p: Vec2) -> bool {
        (0..4).all(|i| {
            let (a, b) = (self.corners[i], self.corners[(i + 1) % 4]);
            (b - a).perp_dot(p - a) >= 0.0
        })
    }

    /// Whether any edge of the footprint crosses the segment `a`-`b`, or the
    /// segment lies inside it.
    pub fn touches_segment(&self, a: Vec2, b: Vec2) -> bool {
        self.contains(a)
            || (0..4).any(|i| segments_intersect(self.corners[i], self.corners[(i + 1) % 4], a, b))
    }

    /// Whether the footprint touches the polyline (points in order; z ignored).
    pub fn touches_polyline(&self, points: &[Vec3]) -> bool {
        match points {
            [] => false,
            [p] => self.contains(p.truncate()),
            _ => points
                .windows(2)
                .any(|w| self.touches_segment(w[0].truncate(), w[1].truncate())),
        }
    }

    /// The axis-aligned bounds (min, max), for cheap rejection.
    pub fn bounds(&self) -> (Vec2, Vec2) {
        let min = self
            .corners
            .iter()
            .copied()
            .fold(Vec2::splat(f32::INFINITY), Vec2::min);
        let max = self
            .corners
            .iter()
            .copied()
            .fold(Vec2::splat(f32::NEG_INFINITY), Vec2::max);
        (min, max)
    }
}

/// Whether the closed segments `p1`-`p2` and `q1`-`q2` intersect.
pub fn segments_intersect(p1: Vec2, p2: Vec2, q1: Vec2, q2: Vec2) -> bool {
    let d1 = (q2 - q1).perp_dot(p1 - q1);
    let d2 = (q2 - q1).perp_dot(p2 - q1);
    let d3 = (p2 - p1).perp_dot(q1 - p1);
    let d4 = (p2 - p1).perp_dot(q2 - p1);
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |a: Vec2, b: Vec2, p: Vec2, d: f32| {
        d == 0.0 && p.cmpge(a.min(b)).all() && p.cmple(a.max(b)).all()
    };
    on(q1, q2, p1, d1) || on(q1, q2, p2, d2) || on(p1, p2, q1, d3) || on(p1, p2, q2, d4)
}

/// Whether a point moving from `from` to `to` crosses the line `a`-`b` from
/// its left side to its right side (seen looking from `a` to `b`). With `a`
/// the right end and `b` the left end of a stop line, as seen driving along
/// the lane, that is crossing it in the driving direction; driving back over
/// it does not count.
pub fn crosses_directed(from: Vec2, to: Vec2, a: Vec2, b: Vec2) -> bool {
    let side = |p: Vec2| (b - a).perp_dot(p - a);
    side(from) > 0.0 && side(to) <= 0.0 && segments_intersect(from, to, a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn footprint_corners_follow_heading() {
        let f = Footprint::new(Vec2::ZERO, std::f32::consts::FRAC_PI_2, 4.0, 2.0);
        // Heading north: the front is at y = +2, the right side at x = +1.
        assert!((f.front_center() - Vec2::new(0.0, 2.0)).length() < 1e-6);
        assert!((f.corners[1] - Vec2::new(1.0, 2.0)).length() < 1e-6);
        assert!(f.contains(Vec2::new(0.9, -1.9)));
        assert!(!f.contains(Vec2::new(1.1, 0.0)));
    }

    #[test]
    fn footprint_touches_a_line_it_straddles_but_not_one_beside_it() {
        let f = Footprint::new(Vec2::ZERO, 0.0, 4.8, 2.2);
        let line = [Vec3::new(-10.0, 0.5, 0.0), Vec3::new(10.0, 0.5, 0.0)];
        assert!(f.touches_polyline(&line));
        let beside = [Vec3::new(-10.0, 1.2, 0.0), Vec3::new(10.0, 1.2, 0.0)];
        assert!(!f.touches_polyline(&beside));
        // A short line wholly inside the footprint touches it too.
        let inside = [Vec3::new(-0.5, 0.0, 0.0), Vec3::new(0.5, 0.0, 0.0)];
        assert!(f.touches_polyline(&inside));
    }

    #[test]
    fn segments_intersect_handles_touching_and_parallel() {
        let (a, b) = (Vec2::new(0.0, 0.0), Vec2::new(2.0, 0.0));
        assert!(segments_intersect(
            a,
            b,
            Vec2::new(1.0, -1.0),
            Vec2::new(1.0, 1.0)
        ));
        assert!(segments_intersect(
            a,
            b,
            Vec2::new(2.0, 0.0),
            Vec2::new(3.0, 1.0)
        ));
        assert!(!segments_intersect(
            a,
            b,
            Vec2::new(0.0, 1.0),
            Vec2::new(2.0, 1.0)
        ));
        assert!(!segments_intersect(
            a,
            b,
            Vec2::new(3.0, -1.0),
            Vec2::new(3.0, 1.0)
        ));
    }

    #[test]
    fn directed_crossing_counts_one_way_only() {
        // A stop line across a lane heading +x: a = right end, b = left end.
        let (a, b) = (Vec2::new(10.0, -2.0), Vec2::new(10.0, 2.0));
        assert!(crosses_directed(
            Vec2::new(9.5, 0.0),
            Vec2::new(10.5, 0.0),
            a,
            b
        ));
        assert!(!crosses_directed(
            Vec2::new(10.5, 0.0),
            Vec2::new(9.5, 0.0),
            a,
            b
        ));
        assert!(!crosses_directed(
            Vec2::new(8.0, 0.0),
            Vec2::new(9.0, 0.0),
            a,
            b
        ));
        // Passing beside the line's end is no crossing.
        assert!(!crosses_directed(
            Vec2::new(9.5, 3.0),
            Vec2::new(10.5, 3.0),
            a,
            b
        ));
    }
}
