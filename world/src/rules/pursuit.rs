//! The pure-pursuit lookahead that the NPCs and the expert steer by, and
//! the NPCs' steer along a lane path.
//!
//! Both pursue a point on their path from the rear axle (the rear axle moves
//! along the heading, so the rear wheels stay on the lane through tight
//! turns); the point lies `clamp(2 m + 0.5 s * v, 3.5 m, 10 m)` ahead of the
//! rear axle along the path.

use glam::Vec2;

use crate::agents::vehicle::{VehicleParams, VehicleState};
use crate::map::town::Town;
use crate::road::lane_path::LanePath;

/// The lateral acceleration the NPCs take curves at, by default (metres per
/// second squared; `NpcParams::max_lateral_accel_mps2`): their speed in a curve
/// of curvature k is at most sqrt(a / k). The junction-lane sweeps use it too.
pub const CURVE_LATERAL_ACCEL_MPS2: f32 = 2.5;

/// The speed at which a curve of `curvature_per_m` (1 / metres, > 0) asks
/// `lateral_accel_mps2` of a car: sqrt(a / k) (metres per second). The NPCs
/// slow to it before a curve; the junction-lane sweeps drive at it.
pub fn curve_speed_mps(curvature_per_m: f32, lateral_accel_mps2: f32) -> f32 {
    (lateral_accel_mps2 / curvature_per_m).sqrt()
}

/// Lookahead of the pure pursuit, measured along the path from the rear
/// axle (metres), at a speed (metres per second).
pub fn pursuit_lookahead_m(speed_mps: f32) -> f32 {
    (2.0 + 0.5 * speed_mps).clamp(3.5, 10.0)
}

/// Steer that follows a lane path: pure pursuit from the rear axle (the
/// NPCs' steer, and the drive [`crate::rules::conflicts`] sweeps a junction
/// lane with).
///
/// The rear axle moves along the heading (the body centre does not: it
/// slips by the side-slip angle in a turn), so pursuing from the rear axle
/// keeps the rear wheels on the lane through tight junction turns instead of
/// cutting across the inside curb. The pursued curvature is the rear axle's;
/// it is converted to the body centre's for [`VehicleParams::steer_for_curvature`].
pub fn pursuit_steer(
    town: &Town,
    vp: &VehicleParams,
    state: &VehicleState,
    path: &LanePath,
) -> f32 {
    let forward = Vec2::from_angle(state.yaw);
    let rear = state.position - forward * vp.rear_wb_m;
    let ld = pursuit_lookahead_m(state.speed_mps);
    let target = path.ground_point_ahead(town, ld - vp.rear_wb_m);
    let rel = target - rear;
    let (dx, dy) = (rel.dot(forward), forward.perp_dot(rel));
    let d2 = (dx * dx + dy * dy).max(1e-3);
    let kappa_rear = 2.0 * dy / d2;
    // Rear axle curvature tan(delta) / L; body centre: sin(beta) / l_r with tan(beta) = l_r * kappa_rear.
    let kappa_centre = (vp.rear_wb_m * kappa_rear).atan().sin() / vp.rear_wb_m;
    vp.steer_for_curvature(kappa_centre)
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
