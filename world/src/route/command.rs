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

impl Command {
    /// Every command, in index order.
    pub const ALL: [Command; 6] = [
        Command::Left,
        Command::Right,
        Command::Straight,
        Command::LaneFollow,
        Command::ChangeLaneLeft,
        Command::ChangeLaneRight,
    ];

    /// The command with index `i` (`Command as u8`), or `None` past 5.
    pub fn from_index(i: usize) -> Option<Command> {
        Command::ALL.get(i).copied()
    }

    /// CARLA's name of the command (`RoadOption`).
    pub fn name(self) -> &'static str {
        match self {
            Command::Left => "LEFT",
            Command::Right => "RIGHT",
            Command::Straight => "STRAIGHT",
            Command::LaneFollow => "LANEFOLLOW",
            Command::ChangeLaneLeft => "CHANGELANELEFT",
            Command::ChangeLaneRight => "CHANGELANERIGHT",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_are_listed_in_index_order() {
        for (i, c) in Command::ALL.iter().enumerate() {
            assert_eq!(*c as usize, i);
            assert_eq!(Command::from_index(i), Some(*c));
        }
        assert_eq!(Command::from_index(6), None);
        assert_eq!(Command::ChangeLaneLeft.name(), "CHANGELANELEFT");
    }
}
