//! The training loop: a batch, a step, a row of the loss log, and a checkpoint of
//! the run state (with `latest.safetensors`) when one is due, to the last step.

use std::io::Write;
use std::time::{Instant, SystemTime};

use burn::prelude::*;

use super::cards::latest_card;
use super::error::{StageError, io_err};
use super::run_folder::{LATEST_FILE, Progress, save_state};
use super::start::Session;
use crate::checkpoint;
use crate::train::loader::{LoadError, Loader, LoaderConfig, Skipped};
use crate::train::multires::StepReport;

/// What a stage reports while it runs.
#[derive(Debug, Clone)]
pub struct StepUpdate<'a> {
    /// The step's losses.
    pub report: &'a StepReport,
    /// Steps in the stage.
    pub steps: usize,
    /// Samples per second since this process started or resumed the stage.
    pub samples_per_s: f64,
    /// Whether the state was just checkpointed.
    pub checkpointed: bool,
    /// The dataset's episodes left out because their files are unreadable
    /// (the same list at every step: say it once).
    pub skipped: &'a [Skipped],
}

impl Session<'_> {
    /// Trains from the steps done to the spec's last, or until `stop_at` has passed
    /// (then it checkpoints after the step in progress and stops); `on_step` sees
    /// every step. Returns the training wall time over every session (seconds) and,
    /// when it stopped early, the steps done.
    pub(super) fn train(
        &mut self,
        device: &Device,
        stop_at: Option<SystemTime>,
        on_step: &mut impl FnMut(&StepUpdate<'_>),
    ) -> Result<(f64, Option<usize>), StageError> {
        let spec = self.spec;
        let (mut loader, per_epoch) = self.start_loader();
        let started = Instant::now();
        for step in self.done..spec.steps {
            let Some(batch) = loader.next_batch(device) else {
                if let Some(e) = loader.failure() {
                    return Err(LoadError::from(e).into());
                }
                break;
            };
            let report = self.trainer.step(&batch);
            let elapsed = started.elapsed().as_secs_f64();
            let samples_per_s = ((step + 1 - self.done) * spec.batch) as f64 / elapsed.max(1e-9);
            let wall_s = self.wall_before_s + elapsed;
            self.log(step, step / per_epoch, &report, samples_per_s, wall_s)?;
            let last = step + 1 == spec.steps;
            let due = spec.checkpoint_every > 0 && (step + 1) % spec.checkpoint_every == 0;
            let out_of_time = !last && stop_at.is_some_and(|t| SystemTime::now() >= t);
            if last || due || out_of_time {
                self.checkpoint(step + 1, wall_s)?;
            }
            on_step(&StepUpdate {
                report: &report,
                steps: spec.steps,
                samples_per_s,
                checkpointed: last || due || out_of_time,
                skipped: &self.set.skipped,
            });
            if out_of_time {
                drop(loader);
                return Ok((wall_s, Some(step + 1)));
            }
        }
        drop(loader);
        Ok((self.wall_before_s + started.elapsed().as_secs_f64(), None))
    }

    /// The loader of the stage's batches from the steps done on (the same batches
    /// as an uninterrupted run's), and its batches per epoch.
    fn start_loader(&self) -> (Loader, usize) {
        let spec = self.spec;
        let cfg = LoaderConfig {
            batch: spec.batch,
            seed: spec.seed,
            augment: spec.augment.then(Default::default),
            sampling: spec.sampling.clone(),
            ..LoaderConfig::new(spec.batch, spec.seed)
        };
        let per_epoch = (self.set.epoch_len(&cfg) / spec.batch.max(1)).max(1);
        let loader = Loader::start(
            self.set.clone(),
            &self.config,
            LoaderConfig {
                first_epoch: (self.done / per_epoch) as u64,
                first_batch: self.done % per_epoch,
                ..cfg
            },
        );
        (loader, per_epoch)
    }

    /// Appends step `step`'s row to the loss log (`losses.csv`).
    fn log(
        &mut self,
        step: usize,
        epoch: usize,
        report: &StepReport,
        samples_per_s: f64,
        wall_s: f64,
    ) -> Result<(), StageError> {
        let per: Vec<String> = report.per_scale.iter().map(|l| format!("{l}")).collect();
        writeln!(
            self.losses,
            "{},{},{},{},{},{},{},{},{},{:.2},{:.1}",
            step,
            epoch,
            report.loss,
            report.parts.act,
            report.parts.seg,
            report.parts.kd,
            report.parts.feat,
            per.join(","),
            report.unfrozen_stages,
            samples_per_s,
            wall_s
        )
        .map_err(|e| io_err(&self.losses_path, e, "check the disk has room"))
    }

    /// Checkpoints the run state after `steps` steps and `wall_s` seconds of training,
    /// and writes the network so far as `latest.safetensors`: loadable by every tool
    /// (e.g. `mrdrive run --checkpoint`) to look at a run before it ends, without the
    /// final recalibration.
    fn checkpoint(&mut self, steps: usize, wall_s: f64) -> Result<(), StageError> {
        self.losses
            .flush()
            .map_err(|e| io_err(&self.losses_path, e, "check the disk has room"))?;
        save_state(
            &self.trainer,
            &self.state_dir,
            Progress {
                step: steps,
                wall_s,
            },
        )?;
        let card = latest_card(self.spec, self.run_dir, steps);
        checkpoint::save(
            &self.trainer.net.valid(),
            &card,
            &self.run_dir.join(LATEST_FILE),
        )?;
        Ok(())
    }
}
