//! Kerbs as a car meets them: its wheels climb a raised sidewalk, with a jolt
//! and a loss of speed, and come back down (CARLA's sidewalks are kerbs its
//! vehicles' wheels climb; scenario_runner counts no collision for them).
//!
//! Each axle is checked on its own: when the sidewalk height under it changes
//! during a tick ([`crate::rules::SidewalkGrid`]), the axle went up or down a
//! kerb of that height `h`. Going up, with `v` the speed, `a` the angle between
//! the heading and the kerb and `r` the wheel radius:
//! - the impact on the kerb's corner keeps the speed along the kerb and cuts the
//!   speed into it, `v sin a`, by the share `k h / r` (a wheel of radius `r`
//!   pivoting about a corner `h` high keeps angular momentum about it; one axle
//!   carries `k` = half the car);
//! - lifting that half of the car by `h` costs `g h` of `v^2`.
//!
//! Going down costs nothing (the drop's energy goes into the suspension). What it
//! gives, for the default car (wheel radius 0.334 m) and a 0.15 m kerb, speed
//! before -> after both axles (`kerb_crossing_speeds` in the tests):
//!
//! | speed | 10 deg | 30 deg | 90 deg (square) |
//! | --- | --- | --- | --- |
//! | 2 m/s | 0.99 m/s | 0.67 m/s | 0 (stops on the kerb; throttle takes it on) |
//! | 5 m/s | 4.63 m/s | 4.18 m/s | 2.59 m/s |
//! | 10 m/s | 9.73 m/s | 8.85 m/s | 5.81 m/s |
//!
//! A shallow drift keeps going; a square hit at speed is hard. The model has no
//! sideslip: the car keeps its heading and rides onto the sidewalk rather than
//! glancing off. Poles, trees, lamps and buildings beyond the kerb stay solid
//! (`crate::physics`).

use glam::Vec2;

use super::vehicle::{VehicleParams, VehicleState};
use crate::rules::SidewalkGrid;

/// Tyre radius of the default car (metres): the Tesla Model 3's 235/45 R18 tyres,
/// 0.457 m of rim plus twice 0.106 m of sidewall, halved.
pub const WHEEL_RADIUS_M: f32 = 0.334;
/// The share of the car's mass one axle carries.
const AXLE_SHARE: f32 = 0.5;
/// Gravity (metres per second squared).
const G_MPS2: f32 = 9.81;

/// An axle that went up or down a kerb in a tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KerbCrossing {
    /// The front axle (`false`: the rear).
    pub front: bool,
    /// The height climbed (metres; negative: down).
    pub height_m: f32,
    /// The angle between the heading and the kerb (radians, 0 to pi/2).
    pub angle_rad: f32,
    /// Speed before and after (metres per second).
    pub speed_mps: (f32, f32),
}

/// The speed after one axle climbs a kerb `height_m` high (metres) at `speed_mps`,
/// `angle_rad` between the heading and the kerb (see the module docs).
pub fn climb(speed_mps: f32, angle_rad: f32, height_m: f32) -> f32 {
    if height_m <= 0.0 {
        return speed_mps;
    }
    let (s, c) = angle_rad.sin_cos();
    let along = speed_mps * c.abs();
    let into = speed_mps * s.abs() * (1.0 - AXLE_SHARE * height_m / WHEEL_RADIUS_M).max(0.0);
    (along * along + into * into - G_MPS2 * height_m)
        .max(0.0)
        .sqrt()
}

/// Where a car's axles are: (front, rear) centre points on the ground.
fn axles(vp: &VehicleParams, position: Vec2, yaw: f32) -> (Vec2, Vec2) {
    let f = Vec2::from_angle(yaw);
    (position + f * vp.front_wb_m, position - f * vp.rear_wb_m)
}

/// Applies the kerbs the car's axles met moving from `before` (position, yaw) to
/// `state`'s pose: the speed after each climb ([`climb`]). Returns the crossings,
/// front axle first.
pub fn cross_kerbs(
    state: &mut VehicleState,
    vp: &VehicleParams,
    before: (Vec2, f32),
    sidewalks: &SidewalkGrid,
) -> Vec<KerbCrossing> {
    let (f0, r0) = axles(vp, before.0, before.1);
    let (f1, r1) = axles(vp, state.position, state.yaw);
    let mut out = Vec::new();
    for (front, a, b) in [(true, f0, f1), (false, r0, r1)] {
        let (ha, hb) = (sidewalks.under(a), sidewalks.under(b));
        let height_m = hb.map_or(0.0, |s| s.height_m) - ha.map_or(0.0, |s| s.height_m);
        if height_m == 0.0 {
            continue;
        }
        let kerb = hb.or(ha).map_or(Vec2::X, |s| s.kerb_dir);
        let heading = Vec2::from_angle(state.yaw);
        let angle_rad = heading.perp_dot(kerb).abs().clamp(0.0, 1.0).asin();
        let before_mps = state.speed_mps;
        state.speed_mps = climb(before_mps, angle_rad, height_m);
        out.push(KerbCrossing {
            front,
            height_m,
            angle_rad,
            speed_mps: (before_mps, state.speed_mps),
        });
    }
    out
}

/// The height of the sidewalk under a car's centre (metres above the road; 0 off it).
pub fn ride_height_m(sidewalks: &SidewalkGrid, position: Vec2) -> f32 {
    sidewalks.under(position).map_or(0.0, |s| s.height_m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Speed after both axles climb a 0.15 m kerb.
    fn both_axles(speed: f32, angle_deg: f32) -> f32 {
        let a = angle_deg.to_radians();
        climb(climb(speed, a, 0.15), a, 0.15)
    }

    #[test]
    fn kerb_crossing_speeds() {
        // The table in the module docs.
        let table = [
            (2.0, [0.99, 0.67, 0.0]),
            (5.0, [4.63, 4.18, 2.59]),
            (10.0, [9.73, 8.85, 5.81]),
        ];
        for (v, after) in table {
            for (angle, want) in [10.0, 30.0, 90.0].into_iter().zip(after) {
                let got = both_axles(v, angle);
                assert!((got - want).abs() < 0.006, "{v} m/s at {angle} deg: {got}");
            }
        }
        // Parallel to the kerb only the lift costs; down costs nothing.
        assert!((climb(5.0, 0.0, 0.15) - (25.0f32 - 9.81 * 0.15).sqrt()).abs() < 1e-5);
        assert_eq!(climb(5.0, 1.0, -0.15), 5.0);
    }
}
