//! The multi-resolution training step (docs/protocol.md §6).
//!
//! For each scale r in R: resize the micro-batch to r, activate BN branch r,
//! forward, compute the loss; average the losses over R; one backward pass and
//! one Adam step. Optionally: the action head frozen, a frozen teacher (the
//! 1.0x original model on the same images) for KD and feature matching, and
//! progressive unfreezing of the backbone's convolutions layer4 -> layer1 with
//! a new Adam per unfreezing stage (TimeParam's recipe, WOR.md §5).
//!
//! The trainer's state (network with its parameter ids, Adam's moments, the
//! step) saves to and resumes from a folder, and a resumed run continues bit
//! for bit (see the tests).

use super::losses::{TEMPERATURE, action_kl, feature_mse, kd_kl, seg_ce};
use super::resize::resize_to_scale;
use crate::model::PolicyNet;
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer, OptimizerRecord};
use burn::prelude::*;
use burn::store::{BurnpackStore, ModuleSnapshot};
use std::path::{Path, PathBuf};

/// One training batch at scale 1.0.
#[derive(Debug, Clone)]
pub struct Batch {
    /// Normalised images `[B, 3, H0, W0]`.
    pub images: Tensor<4>,
    /// Action values `Q` `[B, commands, speed bins, 28]`.
    pub q: Tensor<4>,
    /// Segmentation labels `[B, H0, W0]` (class ids).
    pub seg: Tensor<3, Int>,
    /// Per-sample weight of each command's action loss `[B, commands]`
    /// ([`super::losses::command_weights`] of the frame's route command).
    pub cmd_weights: Tensor<2>,
}

/// Settings of the multi-resolution step.
#[derive(Config, Debug, PartialEq)]
pub struct TrainConfig {
    /// Adam learning rate (TimeParam retargeting: 1.5e-4; WoR training: 3e-4).
    #[config(default = 1.5e-4)]
    pub lr: f64,
    /// Weight of the segmentation loss (WoR: 0.05; 0 skips the decoder).
    #[config(default = 0.05)]
    pub seg_weight: f32,
    /// Weight of the teacher KD loss (used only with a teacher).
    #[config(default = 1.0)]
    pub kd_weight: f32,
    /// Weight of the feature loss (used only with a teacher).
    #[config(default = 1.0)]
    pub feat_weight: f32,
    /// Temperature of the Boltzmann targets.
    #[config(default = 0.01)]
    pub temperature: f32,
    /// Keep the action head frozen.
    #[config(default = true)]
    pub freeze_action_head: bool,
    /// Progressive unfreezing: every this many steps one more backbone stage (layer4 first,
    /// then layer3, layer2, layer1) gets trainable convolutions, with a new Adam each time;
    /// the stem stays frozen (TimeParam). None: everything trainable, one Adam.
    #[config(default = "None")]
    pub unfreeze_every: Option<usize>,
}

impl Default for TrainConfig {
    fn default() -> Self {
        TrainConfig::new()
    }
}

/// The terms of a step's loss, each averaged over the scales trained (unweighted).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LossParts {
    /// Action KL against the Boltzmann targets.
    pub act: f32,
    /// Segmentation cross-entropy (0 when the decoder is off).
    pub seg: f32,
    /// KL to the teacher's actions (0 without a teacher).
    pub kd: f32,
    /// Feature MSE to the teacher (0 without a teacher).
    pub feat: f32,
}

/// Losses of one step.
#[derive(Debug, Clone, PartialEq)]
pub struct StepReport {
    /// Step index (0-based).
    pub step: usize,
    /// Loss at each scale trained, in the order given.
    pub per_scale: Vec<f32>,
    /// The averaged loss that was back-propagated.
    pub loss: f32,
    /// Its terms, averaged over the scales.
    pub parts: LossParts,
    /// Backbone stages with trainable convolutions (4 = all).
    pub unfrozen_stages: usize,
}

/// The trainer's state could not be saved or restored.
#[derive(Debug, thiserror::Error)]
pub enum StateError {
    /// A state file could not be written or read.
    #[error("{path}: {problem}; fix: {fix}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        problem: String,
        /// What would fix it.
        fix: &'static str,
    },
}

/// The network's state file in a state folder (weights with their parameter ids).
pub const NET_FILE: &str = "net.bpk";
/// Adam's state file in a state folder.
pub const OPTIM_FILE: &str = "adam.bpk";

/// Holds the student, the optional frozen teacher and the optimizer state.
pub struct MultiResTrainer {
    /// The network being trained (on an autodiff device).
    pub net: PolicyNet,
    /// The frozen teacher and the BN branch it runs at.
    pub teacher: Option<(PolicyNet, usize)>,
    /// Settings.
    pub config: TrainConfig,
    optim: ModuleOptimizer,
    step: usize,
    unfrozen: usize,
}

impl MultiResTrainer {
    /// A trainer for `net` (moved to `device`, an autodiff device), with an optional teacher
    /// whose scale-1.0 branch is used.
    pub fn new(
        net: PolicyNet,
        teacher: Option<PolicyNet>,
        config: TrainConfig,
        device: &Device,
    ) -> Self {
        let mut net = net.fork(device).train();
        if config.freeze_action_head {
            net.action_head = net.action_head.freeze();
        }
        let teacher = teacher.map(|t| {
            let branch = t.config.branch_of(1.0).unwrap_or(t.config.scales.len() - 1);
            (t.fork(device).freeze(), branch)
        });
        let mut trainer = MultiResTrainer {
            net,
            teacher,
            optim: AdamConfig::new().init(),
            step: 0,
            unfrozen: usize::MAX,
            config,
        };
        trainer.apply_unfreezing();
        trainer
    }

    /// Steps taken so far (the index of the next step).
    pub fn steps_done(&self) -> usize {
        self.step
    }

    /// Backbone stages with trainable convolutions at step `step`.
    pub fn unfrozen_at(&self, step: usize) -> usize {
        match self.config.unfreeze_every {
            Some(every) if every > 0 => (1 + step / every).min(4),
            _ => 4,
        }
    }

    /// Sets the trainable stages for the current step; a new stage gets a new Adam.
    fn apply_unfreezing(&mut self) {
        let want = self.unfrozen_at(self.step);
        if want == self.unfrozen {
            return;
        }
        let progressive = self.config.unfreeze_every.is_some_and(|e| e > 0);
        let mut backbone = self.net.backbone.clone();
        for stage in 1..=4 {
            backbone = backbone.set_stage_trainable(stage, stage > 4 - want);
        }
        backbone = backbone.set_stage_trainable(0, !progressive);
        self.net.backbone = backbone;
        self.unfrozen = want;
        self.optim = AdamConfig::new().init();
    }

    /// Saves the network (with its parameter ids) and Adam's state into `dir`.
    pub fn save_state(&self, dir: &Path) -> Result<(), StateError> {
        self.net.sync_running_stats();
        let path = dir.join(NET_FILE);
        let mut store = BurnpackStore::from_file(&path).overwrite(true);
        self.net
            .save_into(&mut store)
            .map_err(|e| StateError::File {
                path: path.clone(),
                problem: format!("could not write: {e}"),
                fix: "check the folder exists, is writable and the disk has room",
            })?;
        let path = dir.join(OPTIM_FILE);
        self.optim
            .to_record()
            .save(&path)
            .map_err(|e| StateError::File {
                path,
                problem: format!("could not write: {e}"),
                fix: "check the folder exists, is writable and the disk has room",
            })
    }

    /// A trainer that continues where [`MultiResTrainer::save_state`] left off after `step`
    /// steps: `net` must have the saved network's architecture (its weights and parameter
    /// ids are read from `dir`).
    pub fn resume(
        net: PolicyNet,
        teacher: Option<PolicyNet>,
        config: TrainConfig,
        device: &Device,
        dir: &Path,
        step: usize,
    ) -> Result<Self, StateError> {
        let mut net = net;
        let path = dir.join(NET_FILE);
        let mut store = BurnpackStore::from_file(&path);
        net.load_from(&mut store).map_err(|e| StateError::File {
            path: path.clone(),
            problem: format!("does not fit the network: {e}"),
            fix: "delete the run folder to start the stage again",
        })?;
        let mut trainer = MultiResTrainer::new(net, teacher, config, device);
        trainer.step = step;
        trainer.apply_unfreezing();
        let path = dir.join(OPTIM_FILE);
        let record = OptimizerRecord::load(&path).map_err(|e| StateError::File {
            path,
            problem: format!("unreadable optimizer state: {e}"),
            fix: "delete the run folder to start the stage again",
        })?;
        trainer.optim = AdamConfig::new().init().load_record(record);
        Ok(trainer)
    }

    /// A trainer at `step` with `net`'s weights and fresh Adam moments: a resume
    /// from a snapshot that kept the weights only (`train::stage::snapshot`). The
    /// steps after it see the batches and the unfreezing schedule of an uninterrupted
    /// run; Adam starts over (its moments at zero, its bias correction from step 1).
    pub fn continue_from(
        net: PolicyNet,
        teacher: Option<PolicyNet>,
        config: TrainConfig,
        device: &Device,
        step: usize,
    ) -> Self {
        let mut trainer = MultiResTrainer::new(net, teacher, config, device);
        trainer.step = step;
        trainer.apply_unfreezing();
        trainer
    }

    /// One multi-resolution step over every scale of the network's R.
    pub fn step(&mut self, batch: &Batch) -> StepReport {
        let branches: Vec<usize> = (0..self.net.config.scales.len()).collect();
        self.step_branches(batch, &branches)
    }

    /// One step over the given BN branches only (each at its scale).
    pub fn step_branches(&mut self, batch: &Batch, branches: &[usize]) -> StepReport {
        self.apply_unfreezing();
        let cfg = &self.config;
        let teacher_out = self.teacher.as_ref().map(|(t, b)| {
            let out = t.forward(batch.images.clone(), *b, false);
            (out.action_logits.detach(), out.features.detach())
        });
        let mut total: Option<Tensor<1>> = None;
        let mut per_scale = Vec::with_capacity(branches.len());
        let mut parts = LossParts::default();
        let n = branches.len() as f32;
        let value = |t: &Tensor<1>| t.clone().into_scalar::<f32>();
        for &b in branches {
            let r = self.net.config.scales[b];
            let x = resize_to_scale(batch.images.clone(), r);
            let out = self.net.forward(x, b, cfg.seg_weight > 0.0);
            let act = action_kl(
                out.action_logits.clone(),
                batch.q.clone(),
                batch.cmd_weights.clone(),
                cfg.temperature,
            );
            parts.act += value(&act) / n;
            let mut loss = act;
            if let Some(seg) = out.seg_logits {
                let seg = seg_ce(seg, batch.seg.clone());
                parts.seg += value(&seg) / n;
                loss = loss + seg.mul_scalar(cfg.seg_weight);
            }
            if let Some((tz, tf)) = &teacher_out {
                let kd = kd_kl(out.action_logits, tz.clone());
                let feat = feature_mse(out.features, tf.clone());
                parts.kd += value(&kd) / n;
                parts.feat += value(&feat) / n;
                loss = loss + kd.mul_scalar(cfg.kd_weight) + feat.mul_scalar(cfg.feat_weight);
            }
            per_scale.push(value(&loss));
            total = Some(match total {
                Some(t) => t + loss,
                None => loss,
            });
        }
        let total = total.expect("at least one branch").div_scalar(n);
        let loss = value(&total);
        let grads = GradientsParams::from_grads(total.backward(), &self.net);
        self.net = self.optim.step(self.config.lr, self.net.clone(), grads);
        let report = StepReport {
            step: self.step,
            per_scale,
            loss,
            parts,
            unfrozen_stages: self.unfrozen,
        };
        self.step += 1;
        report
    }
}

/// Default temperature, re-exported for callers building a [`TrainConfig`].
pub const DEFAULT_TEMPERATURE: f32 = TEMPERATURE;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backbone::Depth;
    use crate::model::PolicyConfig;
    use crate::train::synthetic::toy_batch;

    fn tiny() -> PolicyConfig {
        PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(48)
            .with_input_width(64)
            .with_scales(vec![0.75, 1.0])
    }

    fn vals<const D: usize>(t: Tensor<D>) -> Vec<f32> {
        t.into_data().try_to_vec::<f32>().unwrap()
    }

    #[test]
    fn training_at_one_scale_changes_only_that_branch() {
        let device = Device::flex().autodiff();
        device.seed(21);
        let cfg = tiny().with_input_height(64).with_input_width(96);
        let net = cfg.init(&device);
        let batch = toy_batch(&cfg, 4, 1, &device);
        let before = net.clone();
        let mut tr = MultiResTrainer::new(net, None, TrainConfig::new().with_lr(1e-2), &device);
        tr.step_branches(&batch, &[1]);
        tr.step_branches(&batch, &[1]);
        let bn = |n: &PolicyNet, b: usize| {
            let bn = &n.backbone.layer2[0].bn1.branches[b];
            (
                vals(bn.running_mean.value_sync()),
                vals(bn.running_var.value_sync()),
                vals(bn.gamma.val()),
                vals(bn.beta.val()),
            )
        };
        assert_eq!(
            bn(&tr.net, 0),
            bn(&before, 0),
            "branch 0 (0.75x) must not move"
        );
        let (m1, v1, g1, b1) = bn(&tr.net, 1);
        let (m0, v0, g0, b0) = bn(&before, 1);
        assert!(
            m1 != m0 && v1 != v0 && g1 != g0 && b1 != b0,
            "branch 1 (1.0x) must move"
        );
        let seg =
            |n: &PolicyNet, b: usize| vals(n.seg_head.bn2.branches[b].running_mean.value_sync());
        assert_eq!(seg(&tr.net, 0), seg(&before, 0));
        assert_ne!(seg(&tr.net, 1), seg(&before, 1));
    }

    #[test]
    fn teacher_and_frozen_head_never_change() {
        let device = Device::flex().autodiff();
        device.seed(22);
        let cfg = tiny();
        let teacher = cfg.clone().with_scales(vec![1.0]).init(&device);
        let student = cfg.init(&device);
        let batch = toy_batch(&cfg, 4, 2, &device);
        let head_before = vals(student.action_head.fc1.weight.val());
        let t_before = (
            vals(teacher.backbone.conv1.weight.val()),
            vals(teacher.backbone.bn1.branches[0].running_mean.value_sync()),
            vals(teacher.action_head.fc3.weight.val()),
        );
        let conv_before = vals(student.backbone.layer1[0].conv1.weight.val());
        let mut tr = MultiResTrainer::new(
            student,
            Some(teacher),
            TrainConfig::new().with_lr(1e-2),
            &device,
        );
        for _ in 0..3 {
            let r = tr.step(&batch);
            assert!(r.loss.is_finite() && r.per_scale.len() == 2);
        }
        assert_eq!(vals(tr.net.action_head.fc1.weight.val()), head_before);
        let (t, _) = tr.teacher.as_ref().unwrap();
        assert_eq!(vals(t.backbone.conv1.weight.val()), t_before.0);
        assert_eq!(
            vals(t.backbone.bn1.branches[0].running_mean.value_sync()),
            t_before.1
        );
        assert_eq!(vals(t.action_head.fc3.weight.val()), t_before.2);
        // The student's backbone did train.
        assert_ne!(
            vals(tr.net.backbone.layer1[0].conv1.weight.val()),
            conv_before
        );
    }

    #[test]
    fn progressive_unfreezing_goes_layer4_to_layer1() {
        let device = Device::flex().autodiff();
        device.seed(23);
        let cfg = tiny();
        let net = cfg.init(&device);
        let batch = toy_batch(&cfg, 2, 3, &device);
        let w = |n: &PolicyNet| {
            [
                vals(n.backbone.layer1[0].conv1.weight.val()),
                vals(n.backbone.layer2[0].conv1.weight.val()),
                vals(n.backbone.layer3[0].conv1.weight.val()),
                vals(n.backbone.layer4[0].conv1.weight.val()),
                vals(n.backbone.conv1.weight.val()),
            ]
        };
        let mut tr = MultiResTrainer::new(
            net,
            None,
            TrainConfig::new()
                .with_lr(1e-2)
                .with_unfreeze_every(Some(2)),
            &device,
        );
        let mut prev = w(&tr.net);
        let mut changed_at = vec![];
        for s in 0..8 {
            let r = tr.step(&batch);
            assert_eq!(r.unfrozen_stages, (1 + s / 2).min(4));
            let now = w(&tr.net);
            changed_at.push((0..5).map(|i| now[i] != prev[i]).collect::<Vec<_>>());
            prev = now;
        }
        // Steps 0-1: layer4 only; 2-3: + layer3; 4-5: + layer2; 6-7: + layer1; the stem never.
        assert_eq!(changed_at[0], vec![false, false, false, true, false]);
        assert_eq!(changed_at[2], vec![false, false, true, true, false]);
        assert_eq!(changed_at[4], vec![false, true, true, true, false]);
        assert_eq!(changed_at[6], vec![true, true, true, true, false]);
    }

    fn fingerprint(n: &PolicyNet) -> Vec<Vec<f32>> {
        n.sync_running_stats();
        vec![
            vals(n.backbone.conv1.weight.val()),
            vals(n.backbone.layer1[0].conv1.weight.val()),
            vals(n.backbone.layer4[0].conv2.weight.val()),
            vals(
                n.backbone.layer3[0].bn1.branches[0]
                    .running_mean
                    .value_sync(),
            ),
            vals(
                n.backbone.layer3[0].bn1.branches[1]
                    .running_var
                    .value_sync(),
            ),
            vals(n.seg_head.bn2.branches[1].gamma.val()),
            vals(n.action_head.fc1.weight.val()),
        ]
    }

    #[test]
    fn a_resumed_trainer_continues_bit_for_bit() {
        let device = Device::flex().autodiff();
        device.seed(25);
        let cfg = tiny();
        let teacher = cfg.clone().with_scales(vec![1.0]).init(&device);
        let student = cfg.init(&device);
        let batches: Vec<Batch> = (0..5)
            .map(|k| toy_batch(&cfg, 3, 40 + k, &device))
            .collect();
        // Unfreezing every 2 steps: the resume point (3) lies inside a stage, and a new
        // Adam starts at step 4 in both runs.
        let tc = TrainConfig::new()
            .with_lr(1e-2)
            .with_unfreeze_every(Some(2));
        let mut straight =
            MultiResTrainer::new(student.clone(), Some(teacher.clone()), tc.clone(), &device);
        let losses: Vec<f32> = batches.iter().map(|b| straight.step(b).loss).collect();

        let dir = tempfile::tempdir().unwrap();
        let mut first =
            MultiResTrainer::new(student.clone(), Some(teacher.clone()), tc.clone(), &device);
        for b in &batches[..3] {
            first.step(b);
        }
        first.save_state(dir.path()).unwrap();
        drop(first);
        let mut resumed =
            MultiResTrainer::resume(cfg.init(&device), Some(teacher), tc, &device, dir.path(), 3)
                .unwrap();
        assert_eq!(resumed.steps_done(), 3);
        let rest: Vec<f32> = batches[3..].iter().map(|b| resumed.step(b).loss).collect();
        assert_eq!(rest, losses[3..].to_vec());
        assert_eq!(fingerprint(&resumed.net), fingerprint(&straight.net));
    }

    #[test]
    fn a_state_of_another_network_is_refused_with_the_file_named() {
        let device = Device::flex().autodiff();
        device.seed(26);
        let dir = tempfile::tempdir().unwrap();
        let tr = MultiResTrainer::new(tiny().init(&device), None, TrainConfig::new(), &device);
        tr.save_state(dir.path()).unwrap();
        let other = tiny().with_scales(vec![1.0]).with_input_width(96);
        let wider = PolicyConfig {
            widths: [8, 8, 16, 16],
            ..other
        };
        let err = MultiResTrainer::resume(
            wider.init(&device),
            None,
            TrainConfig::new(),
            &device,
            dir.path(),
            1,
        )
        .err()
        .expect("a different network is refused");
        assert!(err.to_string().contains(NET_FILE), "{err}");
    }

    #[test]
    fn loss_falls_on_a_fixed_toy_batch() {
        let device = Device::flex().autodiff();
        device.seed(24);
        let cfg = tiny();
        let batch = toy_batch(&cfg, 4, 4, &device);
        let mut tr = MultiResTrainer::new(
            cfg.init(&device),
            None,
            TrainConfig::new()
                .with_lr(3e-3)
                .with_freeze_action_head(false),
            &device,
        );
        let first = tr.step(&batch).loss;
        let mut last = first;
        for _ in 0..25 {
            last = tr.step(&batch).loss;
        }
        assert!(last < 0.7 * first, "loss {first} -> {last}");
    }
}
