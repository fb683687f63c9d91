//! The vehicle model shared by the ego and the NPC vehicles.
//!
//! A kinematic bicycle with the parameter shape of World on Rails' `EgoModel`
//! (`rails/models/ego_model.py`): front and rear wheelbase (distances from the
//! reference point to the axles), a steer gain (wheel angle at full steer), a
//! throttle-to-acceleration gain and a brake deceleration, plus aerodynamic
//! drag, a steering-rate limit and first-order actuator lag, integrated at the
//! simulation's fixed step (40 Hz).
//!
//! One step of length `dt` (seconds), with `v` the speed and `yaw` the heading:
//!
//! ```text
//! steer_cmd  = clamp(steer, -1, 1), rate-limited by steer_rate_per_s * dt
//! steer_act += (steer_cmd - steer_act) * dt / (steer_lag_s + dt)      (lag)
//! accel_cmd  = brake > 0 ? -brake * brake_decel_mps2 : throttle * throttle_accel_mps2
//! accel_act += (accel_cmd - accel_act) * dt / (accel_lag_s + dt)      (lag)
//! wheel      = -steer_gain_rad * steer_act          (positive steer turns right, as in CARLA)
//! beta       = atan(rear_wb / (front_wb + rear_wb) * tan(wheel))      (slip angle)
//! x         += v * cos(yaw + beta) * dt
//! y         += v * sin(yaw + beta) * dt
//! yaw       += v / rear_wb * sin(beta) * dt
//! v          = max(0, v + (accel_act - drag_per_m * v^2 - rolling_mps2) * dt)
//! ```
//!
//! WoR learns `front_wb`, `rear_wb`, `steer_gain` and the accelerations from
//! CARLA logs in CARLA's left-handed frame; our frame is right-handed
//! (counter-clockwise yaw), hence the minus sign on the wheel angle. Brake
//! overrides throttle as in WoR. There is no reverse gear (throttle is in
//! [0, 1]), like the controls the policy emits.

use glam::Vec2;

use crate::road::geometry::wrap_angle;

/// Controls for one vehicle, as a driver emits them.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VehicleControl {
    /// Steering in [-1, 1]; positive turns right (as in CARLA).
    pub steer: f32,
    /// Throttle in [0, 1].
    pub throttle: f32,
    /// Brake in [0, 1].
    pub brake: f32,
}

impl VehicleControl {
    /// Full brake, wheels straight.
    pub const BRAKE: VehicleControl = VehicleControl {
        steer: 0.0,
        throttle: 0.0,
        brake: 1.0,
    };

    /// The control with every field clamped to its range (NaN becomes 0).
    pub fn clamped(self) -> VehicleControl {
        let c = |x: f32, lo: f32, hi: f32| if x.is_nan() { 0.0 } else { x.clamp(lo, hi) };
        VehicleControl {
            steer: c(self.steer, -1.0, 1.0),
            throttle: c(self.throttle, 0.0, 1.0),
            brake: c(self.brake, 0.0, 1.0),
        }
    }
}

/// Parameters of the vehicle model; the default is a car of CARLA's Tesla Model 3 size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleParams {
    /// Body length (metres).
    pub length_m: f32,
    /// Body width (metres).
    pub width_m: f32,
    /// Body height (metres).
    pub height_m: f32,
    /// Distance from the reference point (body centre) to the front axle (metres).
    pub front_wb_m: f32,
    /// Distance from the reference point (body centre) to the rear axle (metres).
    pub rear_wb_m: f32,
    /// Front wheel angle at full steer (radians).
    pub steer_gain_rad: f32,
    /// Acceleration at full throttle, before drag (metres per second squared).
    pub throttle_accel_mps2: f32,
    /// Deceleration at full brake (metres per second squared).
    pub brake_decel_mps2: f32,
    /// Aerodynamic drag: deceleration per squared speed (1 / metres).
    pub drag_per_m: f32,
    /// Rolling resistance while moving (metres per second squared).
    pub rolling_mps2: f32,
    /// Largest change of the steer command per second (steer units per second).
    pub steer_rate_per_s: f32,
    /// Time constant of the steering actuator's first-order lag (seconds; 0 = none).
    pub steer_lag_s: f32,
    /// Time constant of the throttle/brake actuator's first-order lag (seconds; 0 = none).
    pub accel_lag_s: f32,
}

impl Default for VehicleParams {
    fn default() -> Self {
        // Tesla Model 3: 4.79 m x 2.16 m (CARLA's bounding box, mirrors
        // included), 1.45 m tall, 2.875 m wheelbase split evenly about the
        // centre. 0.5 rad of wheel angle gives a ~5.5 m turning radius.
        VehicleParams {
            length_m: 4.79,
            width_m: 2.16,
            height_m: 1.45,
            front_wb_m: 1.4375,
            rear_wb_m: 1.4375,
            steer_gain_rad: 0.5,
            throttle_accel_mps2: 4.0,
            brake_decel_mps2: 8.0,
            drag_per_m: 0.0025,
            rolling_mps2: 0.1,
            steer_rate_per_s: 3.0,
            steer_lag_s: 0.05,
            accel_lag_s: 0.1,
        }
    }
}

impl VehicleParams {
    /// Half the body's length and width (metres).
    pub fn half_extents(&self) -> Vec2 {
        Vec2::new(self.length_m * 0.5, self.width_m * 0.5)
    }

    /// Path curvature (1 / metres, positive = left) of a steady turn at a steer value.
    pub fn curvature_for_steer(&self, steer: f32) -> f32 {
        let wheel = -self.steer_gain_rad * steer.clamp(-1.0, 1.0);
        let beta = (self.rear_wb_m / (self.front_wb_m + self.rear_wb_m) * wheel.tan()).atan();
        beta.sin() / self.rear_wb_m
    }

    /// The steer value that turns along a path of this curvature (1 / metres, positive = left).
    pub fn steer_for_curvature(&self, curvature_per_m: f32) -> f32 {
        let sin_beta = (curvature_per_m * self.rear_wb_m).clamp(-0.99, 0.99);
        let beta = sin_beta.asin();
        let wheel = (beta.tan() * (self.front_wb_m + self.rear_wb_m) / self.rear_wb_m).atan();
        (-wheel / self.steer_gain_rad).clamp(-1.0, 1.0)
    }

    /// Throttle and brake that ask for an acceleration at a speed (metres per second squared; m/s).
    pub fn pedals_for_accel(&self, accel_mps2: f32, speed_mps: f32) -> (f32, f32) {
        let resist = self.drag_per_m * speed_mps * speed_mps
            + if speed_mps > 0.0 {
                self.rolling_mps2
            } else {
                0.0
            };
        let need = accel_mps2 + resist;
        if need >= 0.0 {
            ((need / self.throttle_accel_mps2).clamp(0.0, 1.0), 0.0)
        } else {
            (0.0, (-need / self.brake_decel_mps2).clamp(0.0, 1.0))
        }
    }
}

/// The state of one vehicle: pose, speed and its actuators.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VehicleState {
    /// Position of the body centre on the ground plane (metres, world frame).
    pub position: Vec2,
    /// Heading (radians, counter-clockwise from +x).
    pub yaw: f32,
    /// Speed along the heading (metres per second, never negative).
    pub speed_mps: f32,
    /// Steering actually applied after rate limit and lag (steer units, positive = right).
    pub steer_actual: f32,
    /// The rate-limited steer command before the lag (steer units).
    pub steer_command: f32,
    /// Longitudinal acceleration actually applied after lag, before drag (m/s^2).
    pub accel_actual: f32,
}

impl VehicleState {
    /// A vehicle at rest at a pose (metres; radians).
    pub fn at_rest(position: Vec2, yaw: f32) -> VehicleState {
        VehicleState {
            position,
            yaw,
            ..Default::default()
        }
    }

    /// Advances the state by `dt_s` seconds under `control` (see the module docs).
    pub fn step(&mut self, params: &VehicleParams, control: VehicleControl, dt_s: f32) {
        let c = control.clamped();
        let max_ds = params.steer_rate_per_s * dt_s;
        self.steer_command += (c.steer - self.steer_command).clamp(-max_ds, max_ds);
        self.steer_actual +=
            (self.steer_command - self.steer_actual) * dt_s / (params.steer_lag_s + dt_s);
        let accel_cmd = if c.brake > 0.0 {
            -c.brake * params.brake_decel_mps2
        } else {
            c.throttle * params.throttle_accel_mps2
        };
        self.accel_actual += (accel_cmd - self.accel_actual) * dt_s / (params.accel_lag_s + dt_s);

        let wheel = -params.steer_gain_rad * self.steer_actual;
        let beta = (params.rear_wb_m / (params.front_wb_m + params.rear_wb_m) * wheel.tan()).atan();
        let v = self.speed_mps;
        let dir = self.yaw + beta;
        self.position += Vec2::new(dir.cos(), dir.sin()) * (v * dt_s);
        self.yaw = wrap_angle(self.yaw + v / params.rear_wb_m * beta.sin() * dt_s);
        let resist = params.drag_per_m * v * v + if v > 0.0 { params.rolling_mps2 } else { 0.0 };
        self.speed_mps = (v + (self.accel_actual - resist) * dt_s).max(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f32 = 0.025;

    fn drive(params: &VehicleParams, s: &mut VehicleState, c: VehicleControl, ticks: usize) {
        for _ in 0..ticks {
            s.step(params, c, DT);
        }
    }

    #[test]
    fn full_brake_from_10_mps_stops_within_the_expected_distance() {
        let p = VehicleParams::default();
        let mut s = VehicleState::at_rest(Vec2::ZERO, 0.0);
        s.speed_mps = 10.0;
        let mut ticks = 0;
        while s.speed_mps > 0.0 && ticks < 400 {
            s.step(&p, VehicleControl::BRAKE, DT);
            ticks += 1;
        }
        let dist = s.position.x;
        // Ideal: v^2 / (2 a) = 6.25 m at 8 m/s^2; the 0.1 s lag adds about v * tau = 1 m.
        assert!(dist > 6.25 && dist < 7.6, "stopped after {dist} m");
        assert!(s.speed_mps == 0.0 && s.position.y.abs() < 1e-6);
        // Stays stopped (no reverse).
        drive(&p, &mut s, VehicleControl::BRAKE, 40);
        assert!((s.position.x - dist).abs() < 1e-6);
    }

    #[test]
    fn constant_steer_gives_the_expected_turning_radius() {
        let p = VehicleParams::default();
        for steer in [0.5f32, -1.0] {
            let mut s = VehicleState::at_rest(Vec2::ZERO, 0.0);
            s.speed_mps = 5.0;
            // Hold speed by cancelling the resistance, steer constant.
            let (throttle, _) = p.pedals_for_accel(0.0, 5.0);
            let c = VehicleControl {
                steer,
                throttle,
                brake: 0.0,
            };
            drive(&p, &mut s, c, 80); // settle the actuators
            let mut pts = Vec::new();
            for _ in 0..200 {
                s.step(&p, c, DT);
                pts.push(s.position);
            }
            // Fit the circle through three spread points.
            let (a, b, cc) = (pts[0], pts[60], pts[120]);
            let d = 2.0 * (a.x * (b.y - cc.y) + b.x * (cc.y - a.y) + cc.x * (a.y - b.y));
            let ux = (a.length_squared() * (b.y - cc.y)
                + b.length_squared() * (cc.y - a.y)
                + cc.length_squared() * (a.y - b.y))
                / d;
            let uy = (a.length_squared() * (cc.x - b.x)
                + b.length_squared() * (a.x - cc.x)
                + cc.length_squared() * (b.x - a.x))
                / d;
            let r = (a - Vec2::new(ux, uy)).length();
            let expected = 1.0 / p.curvature_for_steer(steer).abs();
            assert!(
                (r - expected).abs() / expected < 0.02,
                "radius {r} vs {expected}"
            );
            // Positive steer turns right (clockwise): the centre is to the right of travel.
            let left_of_start = uy > 0.0;
            assert_eq!(
                left_of_start,
                steer < 0.0,
                "steer {steer} centre at {ux},{uy}"
            );
        }
        // Full lock of the default car: a turning radius near the Model 3's 5.8 m.
        let r_full = 1.0 / p.curvature_for_steer(1.0).abs();
        assert!(r_full > 5.0 && r_full < 6.0, "{r_full}");
    }

    #[test]
    fn steering_rate_limit_is_respected() {
        let p = VehicleParams::default();
        let mut s = VehicleState::at_rest(Vec2::ZERO, 0.0);
        let c = VehicleControl {
            steer: 1.0,
            throttle: 0.0,
            brake: 0.0,
        };
        let mut prev = 0.0f32;
        for _ in 0..20 {
            s.step(&p, c, DT);
            assert!(s.steer_command - prev <= p.steer_rate_per_s * DT + 1e-6);
            assert!(s.steer_actual <= s.steer_command + 1e-6);
            prev = s.steer_command;
        }
        // 20 ticks = 0.5 s at 3 units/s: the command saturates at 1 after 1/3 s.
        assert_eq!(s.steer_command, 1.0);
        let mut s2 = VehicleState::at_rest(Vec2::ZERO, 0.0);
        s2.step(&p, c, DT);
        assert!((s2.steer_command - 0.075).abs() < 1e-6);
    }

    #[test]
    fn steer_for_curvature_inverts_curvature_for_steer() {
        let p = VehicleParams::default();
        for steer in [-0.8f32, -0.2, 0.0, 0.3, 0.9] {
            let k = p.curvature_for_steer(steer);
            assert!((p.steer_for_curvature(k) - steer).abs() < 1e-4);
        }
    }

    #[test]
    fn throttle_accelerates_and_drag_limits_speed() {
        let p = VehicleParams::default();
        let mut s = VehicleState::at_rest(Vec2::ZERO, 0.0);
        let c = VehicleControl {
            steer: 0.0,
            throttle: 1.0,
            brake: 0.0,
        };
        drive(&p, &mut s, c, 40);
        assert!(s.speed_mps > 3.0 && s.speed_mps < 4.0, "{}", s.speed_mps);
        drive(&p, &mut s, c, 40 * 120);
        let v_max = ((p.throttle_accel_mps2 - p.rolling_mps2) / p.drag_per_m).sqrt();
        assert!(
            (s.speed_mps - v_max).abs() < 0.5,
            "{} vs {v_max}",
            s.speed_mps
        );
    }
}
