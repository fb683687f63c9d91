//! The multi-resolution driving policy: a ResNet whose every BatchNorm is a bank
//! (one branch per input scale), WoR's action head and decoding, checkpoints,
//! training (presets, the multi-resolution step, BN recalibration), and the
//! `Driver` the loop calls with the factory that builds it from a scenario.
//! The resolution selectors that pick the scale live in `sim::selector`.
//!
//! Read in this order: [`bn_bank`], [`backbone`], [`heads`], [`model`],
//! `dataset::action` and `dataset::decode` (the 28 actions and WoR's decoding, shared with the labels), [`device`], [`checkpoint`], [`fused`], [`conv`] and [`batch_norm`] (the CPU convolutions and BatchNorms training runs through; their arithmetic is the `kernels` crate's), [`driver`], [`train`], [`bench`](mod@bench).

pub mod backbone;
pub mod batch_norm;
pub mod bench;
pub mod bn_bank;
pub mod checkpoint;
pub mod conv;

pub mod device;
pub mod driver;
pub mod fingerprint;
pub mod fused;
pub mod heads;
pub mod model;
pub mod train;
pub mod trigger;

pub use checkpoint::ModelCard;
pub use driver::{PolicyDriver, PolicyFactory};
pub use model::{PolicyConfig, PolicyNet};

/// The burn version this crate is built on, for callers that need devices or tensors.
pub use burn;

/// Worker threads burn's CPU backend uses (rayon's global pool; set `RAYON_NUM_THREADS`).
pub fn cpu_threads() -> usize {
    rayon::current_num_threads()
}
