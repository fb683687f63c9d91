//! The discrete action space of World on Rails: 9 steers x 3 throttles + brake.
//!
//! Action `j < 27` is steer `STEERS[j % 9]` with throttle `THROTTLES[j / 9]`
//! (WoR's `BellmanUpdater._actions`: steers tiled, throttles repeated);
//! action 27 is the brake.

/// Number of steering bins.
pub const NUM_STEERS: usize = 9;
/// Number of throttle bins.
pub const NUM_THROTTLES: usize = 3;
/// Number of actions: every steer x throttle pair plus one brake action.
pub const NUM_ACTIONS: usize = NUM_STEERS * NUM_THROTTLES + 1;
/// Index of the brake action.
pub const BRAKE: usize = NUM_ACTIONS - 1;
/// Number of route commands the head predicts for (CARLA RoadOption - 1).
pub const NUM_COMMANDS: usize = 6;
/// Number of speed bins the head predicts for.
pub const NUM_SPEED_BINS: usize = 4;

/// Steering values of the bins: `linspace(-1, 1, 9)`.
pub const STEERS: [f32; NUM_STEERS] = [-1.0, -0.75, -0.5, -0.25, 0.0, 0.25, 0.5, 0.75, 1.0];
/// Throttle values of the bins: `linspace(0, 1, 3)`.
pub const THROTTLES: [f32; NUM_THROTTLES] = [0.0, 0.5, 1.0];

/// One of the 28 discrete actions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Action {
    /// Steer and throttle, no brake.
    Drive {
        /// Steering in [-1, 1].
        steer: f32,
        /// Throttle in [0, 1].
        throttle: f32,
    },
    /// Full brake, no steer, no throttle.
    Brake,
}

/// The action with index `j` (panics if `j >= NUM_ACTIONS`: indices are ours, not user input).
pub fn action(j: usize) -> Action {
    assert!(j < NUM_ACTIONS, "action index {j} out of range");
    if j == BRAKE {
        Action::Brake
    } else {
        Action::Drive {
            steer: STEERS[j % NUM_STEERS],
            throttle: THROTTLES[j / NUM_STEERS],
        }
    }
}

/// The index of the (steer bin, throttle bin) action.
pub fn index(steer_bin: usize, throttle_bin: usize) -> usize {
    assert!(steer_bin < NUM_STEERS && throttle_bin < NUM_THROTTLES);
    throttle_bin * NUM_STEERS + steer_bin
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_are_the_linspaces() {
        for (i, s) in STEERS.iter().enumerate() {
            assert_eq!(*s, -1.0 + 2.0 * i as f32 / 8.0);
        }
        assert_eq!(THROTTLES, [0.0, 0.5, 1.0]);
        assert_eq!(NUM_ACTIONS, 28);
    }

    #[test]
    fn layout_tiles_steers_and_repeats_throttles() {
        assert_eq!(
            action(0),
            Action::Drive {
                steer: -1.0,
                throttle: 0.0
            }
        );
        assert_eq!(
            action(8),
            Action::Drive {
                steer: 1.0,
                throttle: 0.0
            }
        );
        assert_eq!(
            action(9),
            Action::Drive {
                steer: -1.0,
                throttle: 0.5
            }
        );
        assert_eq!(
            action(22),
            Action::Drive {
                steer: 0.0,
                throttle: 1.0
            }
        );
        assert_eq!(action(27), Action::Brake);
        for (t, &throttle) in THROTTLES.iter().enumerate() {
            for (s, &steer) in STEERS.iter().enumerate() {
                assert_eq!(action(index(s, t)), Action::Drive { steer, throttle });
            }
        }
    }
}
