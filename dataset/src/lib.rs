//! Driving data without networks: WoR's action space, the shard format and
//! its reader, world-on-rails action values, and the collection of episodes.
//!
//! Data flow (DESIGN.md): the expert drives scenarios with noise -> the
//! collection observer keeps a frame every 10th tick (rig images per camera
//! yaw, class image, speed, command, every actor and light) -> shards
//! ([`format`]) -> the labeller ([`labels`]) computes `Q[command, speed,
//! action]` from the recorded future -> label files -> the policy's loader.

pub mod action;
pub mod collect;
pub mod decode;
pub mod format;
pub mod info;
pub mod label_driver;
pub mod labels;
pub mod noise;
pub mod show;
pub mod synthetic;
