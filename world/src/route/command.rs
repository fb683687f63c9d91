//! High-level route commands, shared by the planner, the expert and the policy.

/// The high-level route command (CARLA's `RoadOption` minus one).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Command {
    /// Turn left at the next junction.
    Left = 0,
    /// Turn right at the next junction.
    Right = 1,
    /// Go straight through the next junction.
    Straight = 2,
    /// Follow the lane.
    LaneFollow = 3,
    /// Change to the left lane.
    ChangeLaneLeft = 4,
    /// Change to the right lane.
    ChangeLaneRight = 5,
}
