//! Training: the loader over dataset shards and its augmentations, the network
//! presets, the losses, the batch resize, the multi-resolution step, BN
//! recalibration (on batches, or on frames rendered along scenarios), and a
//! synthetic toy batch with the smoke run that trains on it.

pub mod augment;
pub mod fit;
pub mod loader;
pub mod losses;
pub mod multires;
pub mod presets;
pub mod recalibrate;
pub mod recalibrate_scenes;
pub mod resize;
pub mod stage;
pub mod synthetic;

pub use multires::{Batch, MultiResTrainer, TrainConfig};
pub use presets::Preset;
pub use stage::{StageSpec, run_stage};
