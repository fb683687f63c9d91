//! Training: the losses, the batch resize, the multi-resolution step, BN recalibration,
//! and a synthetic toy batch for smoke runs and tests.

pub mod losses;
pub mod multires;
pub mod recalibrate;
pub mod resize;
pub mod synthetic;

pub use multires::{Batch, MultiResTrainer, TrainConfig};
