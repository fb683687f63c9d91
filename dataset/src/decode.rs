//! From the head's logits to a control: speed interpolation, then WoR's decoding.
//!
//! docs/protocol.md §4. The head gives, for each command, 28 logits at each of 4 speed
//! bins. The logits at the measured speed are the linear interpolation between
//! the two nearest bin centres (clamped at the end bins). Then, with
//! `p = softmax(logits)`: if `p[brake] > 0.5` the car brakes fully (steer 0,
//! throttle 0); otherwise steer and throttle are their expectations under `p`
//! conditioned on not braking, throttle is raised to at least 0.4, and cut to 0
//! above 10 km/h on turns (commands LEFT, RIGHT) and 20 km/h otherwise.
//!
//! For WoR's factorised head (steer logit + throttle logit) the conditional
//! expectations equal WoR's `steers @ softmax(steer_logit)`; WoR's agent takes
//! the speed bins at `linspace(0, 8, 4)` while its labeller uses the centres of
//! `linspace(0, 8, 5)`: we follow the labeller (the bins the targets were made on).

use crate::action::{BRAKE, NUM_ACTIONS, NUM_SPEED_BINS, NUM_STEERS, STEERS, THROTTLES};
use sim::driver::{Command, VehicleControl};

/// Centres of the speed bins (metres per second): centres of `linspace(0, 8, 5)`.
pub const SPEED_BIN_CENTRES_MPS: [f32; NUM_SPEED_BINS] = [1.0, 3.0, 5.0, 7.0];
/// Minimum throttle when not braking.
pub const MIN_THROTTLE: f32 = 0.4;
/// Brake when the brake probability exceeds this.
pub const BRAKE_THRESHOLD: f32 = 0.5;
/// Throttle is cut above this speed on turns (metres per second; 10 km/h).
pub const TURN_SPEED_LIMIT_MPS: f32 = 10.0 / 3.6;
/// Throttle is cut above this speed otherwise (metres per second; 20 km/h).
pub const SPEED_LIMIT_MPS: f32 = 20.0 / 3.6;

/// The decoded control and the probabilities it came from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decoded {
    /// The control to apply.
    pub control: VehicleControl,
    /// Probability of the brake action.
    pub brake_prob: f32,
    /// Expected steer given no brake (before post-processing).
    pub expected_steer: f32,
    /// Expected throttle given no brake (before post-processing).
    pub expected_throttle: f32,
}

/// Linear interpolation of per-speed-bin logits at `speed_mps`.
///
/// `logits[b]` are the 28 logits of speed bin `b`; speeds below the first or
/// above the last bin centre take that bin's logits.
pub fn interpolate_speed(
    logits: &[[f32; NUM_ACTIONS]; NUM_SPEED_BINS],
    speed_mps: f32,
) -> [f32; NUM_ACTIONS] {
    let c = &SPEED_BIN_CENTRES_MPS;
    let (b0, b1, w) = if speed_mps.is_nan() || speed_mps <= c[0] {
        // Also catches NaN: a missing speed reads as standing still.
        (0, 0, 0.0)
    } else if speed_mps >= c[NUM_SPEED_BINS - 1] {
        (NUM_SPEED_BINS - 1, NUM_SPEED_BINS - 1, 0.0)
    } else {
        let b0 = (1..NUM_SPEED_BINS).find(|&b| speed_mps < c[b]).unwrap() - 1;
        (b0, b0 + 1, (speed_mps - c[b0]) / (c[b0 + 1] - c[b0]))
    };
    std::array::from_fn(|j| (1.0 - w) * logits[b0][j] + w * logits[b1][j])
}

/// Softmax of a logit vector (stable).
pub fn softmax(logits: &[f32; NUM_ACTIONS]) -> [f32; NUM_ACTIONS] {
    let m = logits.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let e: [f32; NUM_ACTIONS] = std::array::from_fn(|j| (logits[j] - m).exp());
    let s: f32 = e.iter().sum();
    std::array::from_fn(|j| e[j] / s)
}

/// Decodes the 28 logits at the current speed into a control (docs/protocol.md §4).
pub fn decode(logits: &[f32; NUM_ACTIONS], speed_mps: f32, command: Command) -> Decoded {
    let p = softmax(logits);
    let brake_prob = p[BRAKE];
    let drive: f32 = p[..BRAKE].iter().sum();
    let (mut steer, mut throttle) = (0.0f32, 0.0f32);
    for (j, pj) in p[..BRAKE].iter().enumerate() {
        steer += pj * STEERS[j % NUM_STEERS];
        throttle += pj * THROTTLES[j / NUM_STEERS];
    }
    if drive > 0.0 {
        steer /= drive;
        throttle /= drive;
    }
    let (expected_steer, expected_throttle) = (steer, throttle);
    let control = if brake_prob > BRAKE_THRESHOLD {
        VehicleControl {
            steer: 0.0,
            throttle: 0.0,
            brake: 1.0,
        }
    } else {
        let limit = match command {
            Command::Left | Command::Right => TURN_SPEED_LIMIT_MPS,
            _ => SPEED_LIMIT_MPS,
        };
        let throttle = if speed_mps > limit {
            0.0
        } else {
            throttle.max(MIN_THROTTLE)
        };
        VehicleControl {
            steer,
            throttle,
            brake: 0.0,
        }
    };
    Decoded {
        control,
        brake_prob,
        expected_steer,
        expected_throttle,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::action::index;

    fn one_hot(j: usize, hot: f32) -> [f32; NUM_ACTIONS] {
        let mut l = [0.0; NUM_ACTIONS];
        l[j] = hot;
        l
    }

    #[test]
    fn a_confident_brake_brakes() {
        let d = decode(&one_hot(BRAKE, 20.0), 3.0, Command::LaneFollow);
        assert_eq!(
            d.control,
            VehicleControl {
                steer: 0.0,
                throttle: 0.0,
                brake: 1.0
            }
        );
        assert!(d.brake_prob > 0.99);
    }

    #[test]
    fn a_confident_action_gives_its_steer_and_throttle() {
        // Steer bin 6 (+0.5), throttle bin 2 (1.0), standing still.
        let d = decode(&one_hot(index(6, 2), 30.0), 0.0, Command::LaneFollow);
        assert!((d.control.steer - 0.5).abs() < 1e-5, "{d:?}");
        assert!((d.control.throttle - 1.0).abs() < 1e-5);
        assert_eq!(d.control.brake, 0.0);
    }

    #[test]
    fn expectation_is_conditioned_on_not_braking_and_throttle_floored() {
        // Two equally likely drive actions: steer -1 / throttle 0 and steer 0.5 / throttle 0.5,
        // plus brake at 40 %: expectations ignore the brake mass.
        let mut l = [f32::NEG_INFINITY; NUM_ACTIONS];
        l[index(0, 0)] = 0.0;
        l[index(6, 1)] = 0.0;
        l[BRAKE] = (4.0f32 / 3.0).ln(); // p = (1, 1, 4/3) / (10/3) -> brake 0.4
        let d = decode(&l, 2.0, Command::Straight);
        assert!((d.brake_prob - 0.4).abs() < 1e-5, "{d:?}");
        assert!((d.expected_steer - (-0.25)).abs() < 1e-5);
        assert!((d.expected_throttle - 0.25).abs() < 1e-5);
        assert!((d.control.steer - (-0.25)).abs() < 1e-5);
        assert_eq!(d.control.throttle, MIN_THROTTLE);
        assert_eq!(d.control.brake, 0.0);
    }

    #[test]
    fn throttle_is_cut_above_the_speed_limits() {
        let l = one_hot(index(4, 2), 30.0);
        // 12 km/h: above the turn limit, below the straight limit.
        let v = 12.0 / 3.6;
        assert_eq!(decode(&l, v, Command::Left).control.throttle, 0.0);
        assert_eq!(decode(&l, v, Command::Right).control.throttle, 0.0);
        assert!((decode(&l, v, Command::Straight).control.throttle - 1.0).abs() < 1e-5);
        assert_eq!(
            decode(&l, 21.0 / 3.6, Command::LaneFollow).control.throttle,
            0.0
        );
    }

    #[test]
    fn speed_interpolation_between_bin_centres() {
        let bins: [[f32; NUM_ACTIONS]; NUM_SPEED_BINS] =
            std::array::from_fn(|b| [10.0 * b as f32; NUM_ACTIONS]);
        assert_eq!(interpolate_speed(&bins, 0.0)[0], 0.0);
        assert_eq!(interpolate_speed(&bins, 1.0)[0], 0.0);
        assert!((interpolate_speed(&bins, 2.0)[5] - 5.0).abs() < 1e-5);
        assert!((interpolate_speed(&bins, 3.0)[5] - 10.0).abs() < 1e-5);
        assert!((interpolate_speed(&bins, 6.5)[27] - 27.5).abs() < 1e-5);
        assert_eq!(interpolate_speed(&bins, 9.0)[0], 30.0);
        assert_eq!(interpolate_speed(&bins, f32::NAN)[0], 0.0);
    }
}
