//! Training: the network presets, the losses, the batch resize, the
//! multi-resolution step, BN recalibration, and a synthetic toy batch with the
//! smoke run that trains on it.

pub mod losses;
pub mod multires;
pub mod presets;
pub mod recalibrate;
pub mod resize;
pub mod synthetic;

pub use multires::{Batch, MultiResTrainer, TrainConfig};
pub use presets::Preset;
