//! Driving data without networks: WoR's action space, the shard format and
//! its reader, world-on-rails action values, and the collection of episodes.
//! It builds and tests without burn.
//!
//! Its part of the data flow (`DESIGN.md`):
//!
//! ```text
//! scenarios + the expert with noise (noise) ─▶ a run of sim's loop, observed (collect):
//!   a frame every 10th tick: rig images per camera yaw, class images, speed,
//!   command, every actor and light
//! ─▶ shards (format) ─▶ the labeller (labels/): Q[command, speed, action] from
//!   world's rules and vehicle model over the recorded future ─▶ label files
//! ─▶ the policy's loader (policy)
//! ```
//!
//! | path | what |
//! | --- | --- |
//! | [`action`] | WoR's 28 actions and the command and speed-bin counts |
//! | [`cache`] | where the study's datasets and the training runs' state live, outside the work tree (`$MRDRIVE_CACHE`) |
//! | [`decode`] | from the head's logits to a control: speed interpolation, then WoR's decoding to steer, throttle and brake |
//! | [`noise`] | the expert with noise, the driver of collection |
//! | [`dagger`] | a policy driving while the expert watches and takes over where it is stuck: a DAgger round's driver |
//! | [`collect`] | planned episodes, the observer that keeps frames, writing shards |
//! | [`hashes`] | the SHA-256 of a dataset's files, and a check against a committed list |
//! | [`format`] | the on-disk dataset: index and safetensors shards, and their reader |
//! | [`labels`] | world-on-rails action values: grid, static and per-step maps, the vehicle model's dynamics, the backward recursion, episodes |
//! | [`label_driver`] | a driver that drives by the action values (do the labels say how to drive?) |

pub mod action;
pub mod cache;
pub mod collect;
pub mod dagger;
pub mod decode;
pub mod format;
pub mod hashes;
pub mod info;
pub mod label_driver;
pub mod labels;
pub mod noise;
pub mod queue;
pub mod show;
pub mod synthetic;
