//! How the loader samples and augments: [`LoaderConfig`].

use super::sampling::Sampling;
use crate::train::augment::AugmentConfig;

/// How the loader samples and augments.
#[derive(Debug, Clone, PartialEq)]
pub struct LoaderConfig {
    /// Samples per batch.
    pub batch: usize,
    /// Seed of the sample order and the augmentations.
    pub seed: u64,
    /// Augment (WoR's ops); `None` feeds the images as stored (BN recalibration, evaluation).
    pub augment: Option<AugmentConfig>,
    /// Which samples an epoch draws and how often.
    pub sampling: Sampling,
    /// The first epoch (to resume a run where it stopped).
    pub first_epoch: u64,
    /// Batches of the first epoch to leave out (to resume a run mid-epoch); the
    /// batches that follow are the same as in an uninterrupted stream.
    pub first_batch: usize,
    /// Epochs to stream; `None` streams until the loader is dropped.
    pub epochs: Option<u64>,
    /// Batches prepared ahead of the training step (over all workers).
    pub queue: usize,
    /// Worker threads (1 keeps one core for the loader on a 2-core CPU;
    /// more for a GPU step, which wants more samples per second). The
    /// batches are the same for any number.
    pub workers: usize,
}

impl LoaderConfig {
    /// Batches of `batch`, seed `seed`, WoR's augmentations, every sample
    /// once per epoch, forever, 4 batches ahead, one worker thread.
    pub fn new(batch: usize, seed: u64) -> LoaderConfig {
        LoaderConfig {
            batch,
            seed,
            augment: Some(AugmentConfig::default()),
            sampling: Sampling::default(),
            first_epoch: 0,
            first_batch: 0,
            epochs: None,
            queue: 4,
            workers: 1,
        }
    }
}
