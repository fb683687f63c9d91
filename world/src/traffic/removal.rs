//! When an NPC is taken off the road: as CARLA's Traffic Manager removes a
//! vehicle (`carla::traffic_manager::constants::VehicleRemoval`, used by its
//! `ALSM::IsVehicleStuck`). A vehicle is idle while slower than
//! [`STOPPED_MPS`]; the most idle one is removed once it has been idle
//! [`BLOCKED_S`], or [`RED_LIGHT_BLOCKED_S`] while its light is red, and no
//! vehicle is removed within [`BETWEEN_REMOVALS_S`] of the last removal. CARLA
//! destroys it; we put it back at a free spot on a random lane (the same
//! placement as the first spawn), so the town keeps its count, and the
//! incident list says which rule it was.
//!
//! The paper's own watchdog (docs/protocol.md §2: a car below 0.1 m/s for 40
//! ticks has its autopilot switched off and throttle 0.3 applied) is not
//! reproduced: it catches cars waiting at red lights and in queues and never
//! gives the autopilot back. Until 2026-12-06 an NPC stopped 40 ticks while
//! wanting to move was respawned in its place (issue 49, item 4).

use super::incidents::RespawnCause;

/// Below this speed a vehicle is idle (m/s; CARLA's `STOPPED_VELOCITY_THRESHOLD`).
pub const STOPPED_MPS: f32 = 0.8;
/// Idle this long, its light not red, and it is removed (seconds; `BLOCKED_TIME_THRESHOLD`).
pub const BLOCKED_S: f32 = 90.0;
/// Idle this long whatever its light (seconds; `RED_TL_BLOCKED_TIME_THRESHOLD`).
pub const RED_LIGHT_BLOCKED_S: f32 = 180.0;
/// At most one removal in this long (seconds; `DELTA_TIME_BETWEEN_DESTRUCTIONS`).
pub const BETWEEN_REMOVALS_S: f32 = 10.0;

/// Why a vehicle idle for `idle_s` seconds is removed, `at_red` when the
/// light of its next stop line is red; `None` while it may stay.
pub fn cause(idle_s: f32, at_red: bool) -> Option<RespawnCause> {
    match at_red {
        true if idle_s >= RED_LIGHT_BLOCKED_S => Some(RespawnCause::BlockedAtRed),
        false if idle_s >= BLOCKED_S => Some(RespawnCause::Blocked),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vehicle_goes_after_90_s_or_180_s_at_a_red_light() {
        assert_eq!(cause(89.9, false), None);
        assert_eq!(cause(90.0, false), Some(RespawnCause::Blocked));
        assert_eq!(cause(179.9, true), None);
        assert_eq!(cause(180.0, true), Some(RespawnCause::BlockedAtRed));
    }
}
