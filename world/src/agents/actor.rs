//! A snapshot of a moving thing, as the camera, the monitors and the logs see it.

use glam::{Vec2, Vec3};

/// What kind of actor a snapshot is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ActorKind {
    /// The vehicle under test.
    Ego,
    /// A traffic (NPC) vehicle.
    Vehicle,
    /// A pedestrian.
    Pedestrian,
}

/// Where an actor is and how big it is at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActorSnapshot {
    /// Stable id for the run (the ego is 0).
    pub id: u32,
    /// Ego, vehicle or pedestrian.
    pub kind: ActorKind,
    /// Centre of the footprint on the ground (metres, world frame).
    pub position: Vec3,
    /// Heading (radians, counter-clockwise from +x).
    pub heading: f32,
    /// Length, width, height (metres).
    pub extent: Vec3,
    /// Speed along the heading (metres per second).
    pub speed_mps: f32,
    /// A paint index, for drawing vehicles in several colours.
    pub color: u8,
}

/// The pose of the ego (or any vehicle): where the camera rig is mounted and
/// what the monitors compare tick to tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EgoPose {
    /// Centre of the footprint on the ground (metres, world frame).
    pub position: Vec3,
    /// Heading (radians, counter-clockwise from +x).
    pub heading: f32,
}

impl EgoPose {
    /// The footprint's centre on the ground plane (metres).
    pub fn ground(&self) -> Vec2 {
        self.position.truncate()
    }
}

impl From<&ActorSnapshot> for EgoPose {
    fn from(a: &ActorSnapshot) -> EgoPose {
        EgoPose {
            position: a.position,
            heading: a.heading,
        }
    }
}
