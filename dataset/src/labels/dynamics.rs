//! The ego's motion over one label step, from the simulator's own vehicle model.
//!
//! World on Rails fits a kinematic bicycle to CARLA; mrdrive knows its vehicle
//! exactly, so a label step integrates `world::agents::vehicle::VehicleState::step`
//! (the equations the loop integrates: bicycle, drag, rolling resistance) at
//! the loop's 40 Hz for one label step (0.25 s). The grid has no actuator
//! state, so the steering rate limit and the actuator lags are left out: the
//! action is in force for the whole step, as in WoR's model.
//!
//! The model is invariant to where the car is and where it points, so one
//! table per start speed and action (in the car's own frame) serves every
//! grid state: the move of a car at yaw `t` is the table's move rotated by `t`.

use glam::Vec2;
use world::agents::{VehicleControl, VehicleParams, VehicleState};

use crate::action::{BRAKE, NUM_ACTIONS, NUM_STEERS, STEERS, THROTTLES};

/// Where one action takes the car in one step, in its frame at the start.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Move {
    /// Displacement: forward, left (metres).
    pub delta: Vec2,
    /// Change of heading (radians, counter-clockwise).
    pub dyaw: f32,
    /// Speed at the end (metres per second).
    pub speed_mps: f32,
}

/// The control of action `a` (WoR's 28: steers tiled over throttles, then brake).
pub fn control_of(a: usize) -> VehicleControl {
    if a == BRAKE {
        VehicleControl::BRAKE
    } else {
        VehicleControl {
            steer: STEERS[a % NUM_STEERS],
            throttle: THROTTLES[a / NUM_STEERS],
            brake: 0.0,
        }
    }
}

/// The vehicle model without actuator dynamics (see the module docs).
pub fn label_vehicle(params: &VehicleParams) -> VehicleParams {
    VehicleParams {
        steer_lag_s: 0.0,
        accel_lag_s: 0.0,
        steer_rate_per_s: f32::MAX,
        ..*params
    }
}

/// The move of action `a` from speed `speed_mps` over `step_s` seconds,
/// integrated in ticks of `tick_s`.
pub fn move_of(params: &VehicleParams, speed_mps: f32, a: usize, step_s: f32, tick_s: f32) -> Move {
    let p = label_vehicle(params);
    let mut s = VehicleState {
        speed_mps,
        ..VehicleState::default()
    };
    let control = control_of(a);
    // The actuators start where the action puts them (no lag in the label model).
    s.steer_command = control.steer;
    s.steer_actual = control.steer;
    let ticks = (step_s / tick_s).round().max(1.0) as usize;
    let dt = step_s / ticks as f32;
    for _ in 0..ticks {
        s.step(&p, control, dt);
    }
    Move {
        delta: s.position,
        dyaw: s.yaw,
        speed_mps: s.speed_mps,
    }
}

/// Moves of every action from each of `speeds` (metres per second): `[speed][action]`.
pub fn move_table(
    params: &VehicleParams,
    speeds: &[f32],
    step_s: f32,
    tick_s: f32,
) -> Vec<[Move; NUM_ACTIONS]> {
    speeds
        .iter()
        .map(|&v| std::array::from_fn(|a| move_of(params, v, a, step_s, tick_s)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::action::index;

    #[test]
    fn straight_full_throttle_speeds_up_and_brake_slows_down() {
        let p = VehicleParams::default();
        let go = move_of(&p, 4.0, index(4, 2), 0.25, 0.025);
        assert!(
            go.speed_mps > 4.5
                && go.delta.x > 1.0
                && go.delta.y.abs() < 1e-4
                && go.dyaw.abs() < 1e-5
        );
        let stop = move_of(&p, 4.0, BRAKE, 0.25, 0.025);
        assert!(stop.speed_mps < 2.5 && stop.delta.x < go.delta.x);
        let still = move_of(&p, 0.0, BRAKE, 0.25, 0.025);
        assert_eq!(still.delta, Vec2::ZERO);
    }

    #[test]
    fn positive_steer_turns_right_as_in_carla() {
        let p = VehicleParams::default();
        let right = move_of(&p, 5.0, index(8, 1), 0.25, 0.025);
        let left = move_of(&p, 5.0, index(0, 1), 0.25, 0.025);
        assert!(right.dyaw < -0.05 && right.delta.y < 0.0, "{right:?}");
        assert!(left.dyaw > 0.05 && left.delta.y > 0.0, "{left:?}");
        assert!((right.dyaw + left.dyaw).abs() < 1e-5);
    }
}
