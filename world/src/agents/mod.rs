//! What moves in the town: the [`actor`] snapshot every consumer reads, the
//! [`vehicle`] model shared by the ego and the NPCs, how their wheels climb
//! a [`kerb`], the [`npc`] driver and the [`pedestrian`] walkers.

pub mod actor;
pub mod kerb;
pub mod npc;
pub mod pedestrian;
pub mod vehicle;

pub use actor::{ActorKind, ActorSnapshot, EgoPose};
pub use vehicle::{VehicleControl, VehicleParams, VehicleState};
