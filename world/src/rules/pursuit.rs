//! The pure-pursuit lookahead that the NPCs and the expert steer by.
//!
//! Both pursue a point on their path from the rear axle (the rear axle moves
//! along the heading, so the rear wheels stay on the lane through tight
//! turns); the point lies `clamp(2 m + 0.5 s * v, 3.5 m, 10 m)` ahead of the
//! rear axle along the path.

/// Lookahead of the pure pursuit, measured along the path from the rear
/// axle (metres), at a speed (metres per second).
pub fn pursuit_lookahead_m(speed_mps: f32) -> f32 {
    (2.0 + 0.5 * speed_mps).clamp(3.5, 10.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lookahead_grows_with_speed_between_its_bounds() {
        assert_eq!(pursuit_lookahead_m(0.0), 3.5);
        assert_eq!(pursuit_lookahead_m(4.0), 4.0);
        assert_eq!(pursuit_lookahead_m(10.0), 7.0);
        assert_eq!(pursuit_lookahead_m(30.0), 10.0);
    }
}
