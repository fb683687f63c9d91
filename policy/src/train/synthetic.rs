//! A synthetic batch for smoke runs and tests (random images, action values and
//! labels from a seeded ChaCha8 generator), and the smoke run itself
//! (`mrdrive train --synthetic`): a fresh network must fit one toy batch.

use super::losses::command_weights;
use super::multires::{Batch, MultiResTrainer, StepReport, TrainConfig};
use crate::model::{ConfigError, PolicyConfig};
use burn::prelude::*;
use dataset::action::{NUM_ACTIONS, NUM_COMMANDS};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A batch of `n` samples at S0 for `config`, fully determined by `seed`.
///
/// Images are smooth random colour fields (normalised as the config says); the
/// action values favour one action per (sample, command, speed bin) by 0.05,
/// so the Boltzmann target is sharp; labels are vertical bands of classes.
pub fn toy_batch(config: &PolicyConfig, n: usize, seed: u64, device: &Device) -> Batch {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (h, w) = (config.input_height, config.input_width);
    let mut images = Vec::with_capacity(n * 3 * h * w);
    for _ in 0..n {
        let base: [f32; 3] = std::array::from_fn(|_| rng.random_range(0.0..1.0));
        let slope: [f32; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        for c in 0..3 {
            for y in 0..h {
                for x in 0..w {
                    let v = (base[c]
                        + slope[c] * (x as f32 / w as f32 - 0.5) * (1.0 + y as f32 / h as f32))
                        .clamp(0.0, 1.0);
                    images.push((v - config.mean[c]) / config.std[c]);
                }
            }
        }
    }
    let cells = n * config.num_commands * config.num_speed_bins;
    let mut q = Vec::with_capacity(cells * NUM_ACTIONS);
    for _ in 0..cells {
        let best = rng.random_range(0..NUM_ACTIONS);
        for j in 0..NUM_ACTIONS {
            q.push(if j == best {
                0.05
            } else {
                rng.random_range(0.0..0.01)
            });
        }
    }
    let mut seg = Vec::with_capacity(n * h * w);
    for _ in 0..n {
        let offset = rng.random_range(0..config.num_seg_classes as i64);
        for _y in 0..h {
            for x in 0..w {
                seg.push(
                    (offset + (x * config.num_seg_classes / w) as i64)
                        % config.num_seg_classes as i64,
                );
            }
        }
    }
    // Mostly LANEFOLLOW, as in the datasets, with a turn now and then.
    let cmd_weights: Vec<f32> = (0..n)
        .flat_map(|_| {
            command_weights(if rng.random_bool(0.25) {
                rng.random_range(0..3)
            } else {
                3
            })
        })
        .collect();
    Batch {
        images: Tensor::from_data(TensorData::new(images, [n, 3, h, w]), device),
        q: Tensor::from_data(
            TensorData::new(
                q,
                [n, config.num_commands, config.num_speed_bins, NUM_ACTIONS],
            ),
            device,
        ),
        seg: Tensor::from_data(TensorData::new(seg, [n, h, w]), device),
        cmd_weights: Tensor::from_data(TensorData::new(cmd_weights, [n, NUM_COMMANDS]), device),
    }
}

/// Settings of a smoke run on one fixed toy batch.
#[derive(Debug, Clone)]
pub struct SmokeRun {
    /// The network to train from a fresh initialisation.
    pub config: PolicyConfig,
    /// Samples in the toy batch.
    pub batch: usize,
    /// Training steps.
    pub steps: usize,
    /// Adam learning rate.
    pub lr: f64,
    /// Seed of the initialisation and of the toy batch.
    pub seed: u64,
}

impl SmokeRun {
    /// What the run does, in one line (`mrdrive train --synthetic`).
    pub fn describe(&self) -> String {
        format!(
            "synthetic multi-resolution training: {} scales {:?}, batch {}, {} steps (one fixed toy batch)",
            self.config.depth.name(),
            self.config.scales,
            self.batch,
            self.steps
        )
    }

    /// A step's losses in one line: the mean, then each scale's.
    pub fn step_line(&self, r: &StepReport) -> String {
        let per: Vec<String> = r
            .per_scale
            .iter()
            .zip(&self.config.scales)
            .map(|(l, s)| format!("{s}x {l:.4}"))
            .collect();
        format!(
            "step {:>4}  loss {:.4}  ({})",
            r.step,
            r.loss,
            per.join(", ")
        )
    }
}

/// The losses at the ends of a smoke run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmokeOutcome {
    /// Loss of the first step.
    pub first_loss: f32,
    /// Loss of the last step.
    pub last_loss: f32,
}

impl SmokeOutcome {
    /// Whether the loss fell (and stayed a number).
    pub fn fell(&self) -> bool {
        self.last_loss.is_finite() && self.last_loss < self.first_loss
    }
}

impl std::fmt::Display for SmokeOutcome {
    /// `loss FIRST -> LAST (falling)`, or `(NOT falling)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "loss {:.4} -> {:.4} ({})",
            self.first_loss,
            self.last_loss,
            if self.fell() {
                "falling"
            } else {
                "NOT falling"
            }
        )
    }
}

/// A smoke run could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SmokeError {
    /// The network config is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// Nothing to train.
    #[error(
        "steps = {steps}, batch = {batch}: both must be at least 1; fix: e.g. --steps 30 --batch 8"
    )]
    Empty {
        /// Steps asked for.
        steps: usize,
        /// Batch size asked for.
        batch: usize,
    },
}

/// Trains a fresh network of `run.config` on one fixed toy batch with the
/// multi-resolution step (every scale, action head trainable) on `device`
/// (an autodiff device, seeded here); `on_step` sees each step's losses.
pub fn train_on_toy_batch(
    run: &SmokeRun,
    device: &Device,
    mut on_step: impl FnMut(&StepReport),
) -> Result<SmokeOutcome, SmokeError> {
    run.config.validate()?;
    if run.steps == 0 || run.batch == 0 {
        return Err(SmokeError::Empty {
            steps: run.steps,
            batch: run.batch,
        });
    }
    device.seed(run.seed);
    let batch = toy_batch(&run.config, run.batch, run.seed, device);
    let tc = TrainConfig::new()
        .with_lr(run.lr)
        .with_freeze_action_head(false);
    let mut trainer = MultiResTrainer::new(run.config.init(device), None, tc, device);
    let mut first = None;
    let mut last = f32::NAN;
    for _ in 0..run.steps {
        let report = trainer.step(&batch);
        on_step(&report);
        first.get_or_insert(report.loss);
        last = report.loss;
    }
    Ok(SmokeOutcome {
        first_loss: first.unwrap_or(f32::NAN),
        last_loss: last,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::presets::Preset;

    #[test]
    fn a_smoke_run_fits_the_toy_batch_and_refuses_zero_steps() {
        let device = Device::flex().autodiff();
        let run = SmokeRun {
            config: Preset::Tiny.config(&[0.75, 1.0]),
            batch: 2,
            steps: 4,
            lr: 1e-3,
            seed: 0,
        };
        assert_eq!(
            run.describe(),
            "synthetic multi-resolution training: resnet18 scales [0.75, 1.0], batch 2, 4 steps (one fixed toy batch)"
        );
        let mut steps = Vec::new();
        let mut lines = Vec::new();
        let outcome = train_on_toy_batch(&run, &device, |r| {
            steps.push(r.step);
            lines.push(run.step_line(r));
        })
        .unwrap();
        assert_eq!(steps, vec![0, 1, 2, 3]);
        assert!(lines[3].starts_with("step    3  loss "), "{lines:?}");
        assert!(lines[3].contains("(0.75x "), "{lines:?}");
        assert!(outcome.fell(), "{outcome:?}");
        assert!(outcome.to_string().ends_with(" (falling)"), "{outcome}");
        let none = SmokeRun { steps: 0, ..run };
        let e = train_on_toy_batch(&none, &device, |_| {}).unwrap_err();
        assert!(e.to_string().contains("--steps"), "{e}");
    }
}
