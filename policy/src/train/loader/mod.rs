//! The training loader: streams (frame, view) samples of a labelled dataset
//! (`dataset::format`) into [`Batch`](crate::train::Batch)es.
//!
//! - Samples: every camera view of every frame whose label is valid (its
//!   future was driven), over the episodes whose shard and labels are
//!   usable. A bad episode (truncated shard, another S0, labels of another
//!   version, no labels) is skipped and listed in [`TrainSet::skipped`] with
//!   the reason and the fix; the rest is used.
//! - Order: epoch `e` visits the samples in a ChaCha8 shuffle seeded from
//!   `(seed, e)`; with `balanced`, each draw first picks a command uniformly
//!   among those present, then a sample of that command (TimeParam's
//!   command-balanced retargeting data). Batches are whole (the epoch's
//!   remainder is dropped).
//! - Per sample: the view's RGB image, augmented ([`crate::train::augment`], seeded
//!   from `(epoch seed, position in the epoch)`), normalised like the
//!   policy's input (`PolicyConfig::normalize_rgb8`: RGB / 255, ImageNet
//!   mean and std) into `[3, H0, W0]`; `q` `[6, 4, 28]` from the label file;
//!   `seg` `[H0, W0]` the WoR class ids (warped with the image).
//! - Worker threads (one by default) read, augment and normalise, and hand
//!   batches over bounded channels, batch `g` from worker `g mod workers`;
//!   the training step converts them to tensors. Every number depends only
//!   on the dataset, the seed and the configuration, not on the number of
//!   workers or their timing.
//!
//! | file | concern |
//! | --- | --- |
//! | [`sampling`] | [`Sampling`]: which samples an epoch draws and how often (shared with the stage spec and the checkpoint card), and what counts as standing |
//! | [`config`] | [`LoaderConfig`]: batch, seed, augmentations, sampling, where to resume, queue and workers |
//! | [`error`] | [`LoadError`]: why a dataset cannot feed training, and what to run |
//! | [`set`] | [`TrainSet`]: the dataset opened, its samples listed, bad episodes [`Skipped`] |
//! | [`epoch`] | the kinds of frame repeated, the standing frames kept, and each epoch's order |
//! | [`batch`] | [`HostBatch`]: a batch read, augmented and normalised on the host, and its tensors |
//! | [`stream`] | [`Loader`]: the worker threads that prepare batches ahead of the training step |

pub mod batch;
pub mod config;
pub mod epoch;
pub mod error;
pub mod sampling;
pub mod set;
pub mod stream;

pub use batch::HostBatch;
pub use config::LoaderConfig;
pub use error::LoadError;
pub use sampling::{STANDING_MPS, Sampling};
pub use set::{SampleRef, Skipped, TrainSet};
pub use stream::Loader;

#[cfg(test)]
mod fixtures;
