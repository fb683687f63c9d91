//! The point of a vehicle that crosses a stop line.
//!
//! As CARLA's `RunningRedLightTest`, a vehicle has passed a stop line once
//! a point near its tail, 0.8 half-lengths behind its centre, is over it: a
//! car that stopped with its nose over the line has not passed it. The
//! paper's red-light test starts its tail segment there
//! ([`super::stop_lines::tail_segment`]); the expert waits for every stop line
//! that point has not yet passed.

use glam::Vec2;

/// How far the crossing point lies behind a vehicle's centre, in half-lengths.
pub const CROSSING_POINT_HALF_LENGTHS: f32 = 0.8;

/// Distance from a vehicle's centre back to its crossing point (metres),
/// for a body `length_m` metres long.
pub fn crossing_offset_m(length_m: f32) -> f32 {
    CROSSING_POINT_HALF_LENGTHS * length_m / 2.0
}

/// The crossing point of a vehicle whose centre is at `position` (metres)
/// heading `heading` (radians), `length_m` metres long.
pub fn crossing_point(position: Vec2, heading: f32, length_m: f32) -> Vec2 {
    position - Vec2::from_angle(heading) * crossing_offset_m(length_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_point_is_0_8_half_lengths_behind_the_centre() {
        // 5 m long: 2 m behind the centre.
        assert!((crossing_offset_m(5.0) - 2.0).abs() < 1e-6);
        let p = crossing_point(Vec2::new(10.0, 1.0), std::f32::consts::FRAC_PI_2, 5.0);
        assert!(p.distance(Vec2::new(10.0, -1.0)) < 1e-5, "{p}");
    }
}
