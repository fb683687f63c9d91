//! Must a vehicle stop for a light? One rule for the NPCs and the expert
//! (and the labels that come from the expert's world).
//!
//! - **Red**: always.
//! - **Yellow**: when it can still stop before the line braking at its
//!   comfortable deceleration `a`: the distance from its front bumper to the
//!   stop line is more than the braking distance `v^2 / (2 a)` less a slack
//!   of [`YELLOW_SLACK_M`] (the last half metre it may brake a little
//!   harder than comfortable). Closer than that it drives on: braking would
//!   leave it standing on the line or in the junction.
//! - **Green**: never.
//!
//! A light missing from a state slice counts as green (a town's state vector
//! may end before an unsignalled light).

use crate::map::town::{LightIdx, LightState};

/// The slack of the yellow-light decision (metres).
pub const YELLOW_SLACK_M: f32 = 0.5;

/// The state of a light in a state slice indexed by [`LightIdx`]; a light
/// beyond the slice's end is green.
pub fn light_state(lights: &[LightState], light: LightIdx) -> LightState {
    lights
        .get(light.0 as usize)
        .copied()
        .unwrap_or(LightState::Green)
}

/// Whether a vehicle whose front bumper is `distance_m` metres before a
/// stop line, moving at `speed_mps` (m/s), must stop for a light in `state`,
/// braking at `decel_mps2` (m/s^2; see the module docs).
pub fn must_stop(state: LightState, distance_m: f32, speed_mps: f32, decel_mps2: f32) -> bool {
    match state {
        LightState::Red => true,
        LightState::Yellow => {
            distance_m > speed_mps * speed_mps / (2.0 * decel_mps2) - YELLOW_SLACK_M
        }
        LightState::Green => false,
    }
}

/// A driver's perception-reaction time in the yellow-interval formula (seconds;
/// ITE, *Traffic Engineering Handbook*: 1.0).
pub const CHANGE_REACTION_S: f32 = 1.0;
/// The deceleration the yellow-interval formula assumes (metres per second
/// squared; ITE: 10 ft/s^2).
pub const CHANGE_DECEL_MPS2: f32 = 3.05;

/// How long a light must stay yellow for traffic approaching at
/// `approach_mps` (m/s) on level ground: the Institute of Transportation
/// Engineers' change interval `t + v / (2 a)` ([`CHANGE_REACTION_S`],
/// [`CHANGE_DECEL_MPS2`]), in seconds, rounded up to a tenth. A vehicle the
/// yellow rule above lets drive on (it cannot stop braking at 3 m/s^2 or
/// less) is at most `v / (2 a)` seconds from the line at constant speed, so
/// it crosses before red. Used for lights generated where a map has none;
/// a map's own lights keep their controller's timing.
pub fn change_interval_s(approach_mps: f32) -> f32 {
    let y = CHANGE_REACTION_S + approach_mps.max(0.0) / (2.0 * CHANGE_DECEL_MPS2);
    (y * 10.0).ceil() / 10.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_change_interval_covers_the_drive_on_distance() {
        // 65 mph (Town06's highways): 1 + 29.06 / 6.1 = 5.76 -> 5.8 s; 30 km/h: 2.37 -> 2.4 s.
        assert_eq!(change_interval_s(29.06), 5.8);
        assert_eq!(change_interval_s(30.0 / 3.6), 2.4);
        // A car the yellow rule lets drive on (at the NPCs' 3.0 m/s^2) reaches the line
        // before the interval ends, at every speed.
        for v in [5.0_f32, 10.0, 15.0, 20.0, 25.0, 30.0] {
            let d = v * v / (2.0 * 3.0) - YELLOW_SLACK_M;
            assert!(!must_stop(LightState::Yellow, d - 0.01, v, 3.0));
            assert!(d / v < change_interval_s(v), "{v} m/s");
        }
    }

    #[test]
    fn red_always_green_never() {
        for d in [-1.0, 0.0, 3.0, 100.0] {
            assert!(must_stop(LightState::Red, d, 10.0, 3.0));
            assert!(!must_stop(LightState::Green, d, 0.0, 3.0));
        }
    }

    #[test]
    fn yellow_stops_only_with_room_to_brake_less_the_slack() {
        // 6 m/s at 3 m/s^2: 6 m of braking distance, 5.5 m with the slack.
        assert!(must_stop(LightState::Yellow, 5.6, 6.0, 3.0));
        assert!(!must_stop(LightState::Yellow, 5.4, 6.0, 3.0));
        assert!(!must_stop(LightState::Yellow, 1.0, 6.0, 3.0));
        // Standing (or creeping) before the line, it stays.
        assert!(must_stop(LightState::Yellow, 0.0, 0.0, 3.0));
        assert!(!must_stop(LightState::Yellow, -0.6, 0.0, 3.0));
    }

    #[test]
    fn a_light_beyond_the_states_is_green() {
        let s = [LightState::Red, LightState::Yellow];
        assert_eq!(light_state(&s, LightIdx(1)), LightState::Yellow);
        assert_eq!(light_state(&s, LightIdx(2)), LightState::Green);
    }
}
