//! The end of a stage: the BN recalibration, then the trained checkpoint
//! (`final.safetensors`) with its card and training record.

use std::path::PathBuf;

use burn::prelude::*;

use super::cards::final_card;
use super::error::StageError;
use super::run_folder::FINAL_FILE;
use super::start::Session;
use crate::checkpoint;
use crate::model::PolicyNet;
use crate::train::loader::{Loader, LoaderConfig};
use crate::train::recalibrate::recalibrate_with;
use crate::train::resize::resize_to_scale;

/// How a stage ended.
#[derive(Debug, Clone, PartialEq)]
pub struct StageOutcome {
    /// The trained checkpoint (`final.safetensors` in the run folder).
    pub checkpoint: PathBuf,
    /// Steps taken in this call (0 when the stage was already done).
    pub steps_now: usize,
    /// Training wall time over every session (seconds).
    pub wall_s: f64,
    /// Stopped at the time limit before its last step (`Some(steps done)`): the state
    /// is checkpointed, nothing is published, and running the stage again goes on.
    pub stopped_at: Option<usize>,
}

impl Session<'_> {
    /// Recalibrates the trained network's BN (when the spec asks for it) and writes it
    /// with its card; `wall_s` is the training wall time over every session (seconds).
    pub(super) fn finish(self, device: &Device, wall_s: f64) -> Result<StageOutcome, StageError> {
        let steps = self.trainer.steps_done();
        let mut net = self.trainer.net.valid();
        if self.spec.recalibrate_batches > 0 {
            net = self.recalibrate(net, device);
        }
        let card = final_card(self.spec, &self.set, steps, wall_s);
        let checkpoint = self.run_dir.join(FINAL_FILE);
        checkpoint::save(&net, &card, &checkpoint)?;
        Ok(StageOutcome {
            stopped_at: None,
            checkpoint,
            steps_now: steps - self.done,
            wall_s,
        })
    }

    /// BN recalibration on `spec.recalibrate_batches` unaugmented batches per scale.
    fn recalibrate(&self, net: PolicyNet, device: &Device) -> PolicyNet {
        let spec = self.spec;
        let cfg = LoaderConfig {
            augment: None,
            sampling: spec.sampling.clone(),
            epochs: None,
            ..LoaderConfig::new(spec.batch, spec.seed ^ 0x5ca1e)
        };
        let mut loader = Loader::start(self.set.clone(), &self.config, cfg);
        let batches: Vec<Tensor<4>> = (0..spec.recalibrate_batches)
            .filter_map(|_| loader.next_batch(device).map(|b| b.images))
            .collect();
        drop(loader);
        let n = batches.len();
        let scales = self.config.scales.clone();
        recalibrate_with(net, n, device, |branch, k| {
            resize_to_scale(batches[k].clone(), scales[branch])
        })
        .valid()
    }
}
