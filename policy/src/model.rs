//! The whole network: normalise -> ResNet with BN banks -> pooled feature -> action head
//! (and the segmentation decoder when training), one BN branch per input scale.

use crate::backbone::{Backbone, BackboneConfig, Depth};
use crate::bn_bank::BnBank;
use crate::heads::{ActionHead, ActionHeadConfig, SegHead, SegHeadConfig};
use burn::module::Module;
use burn::prelude::*;

/// Everything that fixes the network's shape and its input; saved beside every checkpoint.
#[derive(Config, Debug, PartialEq)]
pub struct PolicyConfig {
    /// Backbone layout.
    pub depth: Depth,
    /// Stage widths (64-128-256-512 as torchvision; 32-64-128-256 half width).
    pub widths: [usize; 4],
    /// The scale set R (fractions of S0); one BN branch each, in this order.
    #[config(default = "vec![0.75, 1.0]")]
    pub scales: Vec<f32>,
    /// Input height at scale 1.0 (pixels; S0's height).
    #[config(default = 96)]
    pub input_height: usize,
    /// Input width at scale 1.0 (pixels; S0's width).
    #[config(default = 240)]
    pub input_width: usize,
    /// Route commands.
    #[config(default = 6)]
    pub num_commands: usize,
    /// Speed bins of the action head.
    #[config(default = 4)]
    pub num_speed_bins: usize,
    /// Segmentation classes.
    #[config(default = 6)]
    pub num_seg_classes: usize,
    /// WoR's factorised action logits (13 raw outputs per cell) or 28 free logits.
    #[config(default = true)]
    pub factorised_actions: bool,
    /// Per-channel mean subtracted after dividing RGB by 255 (ImageNet).
    #[config(default = "[0.485, 0.456, 0.406]")]
    pub mean: [f32; 3],
    /// Per-channel std divided by after the mean (ImageNet).
    #[config(default = "[0.229, 0.224, 0.225]")]
    pub std: [f32; 3],
}

/// Why a [`PolicyConfig`] cannot build a network.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// A field has a value the network cannot use.
    #[error("policy config field `{field}`: {problem}; fix: {fix}")]
    Field {
        /// The field.
        field: &'static str,
        /// What is wrong.
        problem: String,
        /// What would fix it.
        fix: &'static str,
    },
}

/// `floor(r * n)` pixels, with a 1e-4 pixel allowance for f32 rounding (0.7 * 100 gives 70).
pub fn scaled_len(n: usize, r: f32) -> usize {
    (r as f64 * n as f64 + 1e-4).floor() as usize
}

/// Scales closer than this are the same scale.
pub const SCALE_TOLERANCE: f32 = 1e-4;

impl PolicyConfig {
    /// The CPU default: half-width ResNet-18 at 240 x 96, R = {0.75, 1.0}.
    pub fn cpu_default() -> Self {
        PolicyConfig::new(Depth::Resnet18, [32, 64, 128, 256])
    }

    /// The paper's network: ResNet-34 at 480 x 192, R = {0.75, 1.0}.
    pub fn paper() -> Self {
        PolicyConfig::new(Depth::Resnet34, [64, 128, 256, 512])
            .with_input_height(192)
            .with_input_width(480)
    }

    /// Checks the fields; every error names the field and the fix.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let err = |field, problem: String, fix| {
            Err(ConfigError::Field {
                field,
                problem,
                fix,
            })
        };
        if self.widths.contains(&0) || !self.widths[3].is_multiple_of(8) {
            return err(
                "widths",
                format!("{:?}", self.widths),
                "four positive widths, the last a multiple of 8 (e.g. [32, 64, 128, 256])",
            );
        }
        if self.scales.is_empty() {
            return err(
                "scales",
                "empty".into(),
                "give at least one scale, e.g. [0.75, 1.0]",
            );
        }
        for (i, r) in self.scales.iter().enumerate() {
            if !(*r > 0.0 && *r <= 4.0) {
                return err(
                    "scales",
                    format!("scale {r} is not in (0, 4]"),
                    "use fractions of S0 such as 0.5 or 1.0",
                );
            }
            if self.scales[..i]
                .iter()
                .any(|q| (q - r).abs() < SCALE_TOLERANCE)
            {
                return err(
                    "scales",
                    format!("scale {r} appears twice"),
                    "list each scale once",
                );
            }
            let [h, w] = self.input_size(*r);
            if h < 32 || w < 32 {
                return err(
                    "scales",
                    format!("scale {r} gives a {w} x {h} input"),
                    "keep every scaled input at least 32 x 32 pixels",
                );
            }
        }
        if self.input_height == 0 || self.input_width == 0 {
            return err(
                "input_height/input_width",
                "zero".into(),
                "give S0, e.g. 96 x 240",
            );
        }
        if self.num_commands == 0 || self.num_speed_bins == 0 || self.num_seg_classes == 0 {
            return err(
                "num_commands/num_speed_bins/num_seg_classes",
                "zero".into(),
                "use 6 / 4 / 6 as WoR",
            );
        }
        if self.std.iter().any(|s| s.is_nan() || *s <= 0.0) {
            return err(
                "std",
                format!("{:?}", self.std),
                "positive values, e.g. ImageNet's [0.229, 0.224, 0.225]",
            );
        }
        Ok(())
    }

    /// Input size `[height, width]` at scale `r`: `floor(r H0) x floor(r W0)`.
    ///
    /// A 1e-4 pixel allowance absorbs f32 rounding (0.7 * 100 gives 70, as in decimal).
    pub fn input_size(&self, r: f32) -> [usize; 2] {
        [
            scaled_len(self.input_height, r),
            scaled_len(self.input_width, r),
        ]
    }

    /// The BN branch for scale `r`, if `r` is in R.
    pub fn branch_of(&self, r: f32) -> Option<usize> {
        self.scales
            .iter()
            .position(|q| (q - r).abs() < SCALE_TOLERANCE)
    }

    /// The backbone part of the config.
    pub fn backbone(&self) -> BackboneConfig {
        BackboneConfig::new(self.depth, self.widths, self.scales.len())
    }

    /// Builds a randomly initialised network (panics on an invalid config: call `validate` on user input).
    pub fn init(&self, device: &Device) -> PolicyNet {
        if let Err(e) = self.validate() {
            panic!("{e}");
        }
        let d = self.widths[3];
        PolicyNet {
            backbone: self.backbone().init(device),
            action_head: ActionHeadConfig::new(d)
                .with_num_commands(self.num_commands)
                .with_num_speed_bins(self.num_speed_bins)
                .with_factorised(self.factorised_actions)
                .init(device),
            seg_head: SegHeadConfig::new(d, self.scales.len())
                .with_num_classes(self.num_seg_classes)
                .init(device),
            config: self.clone(),
        }
    }

    /// Normalises an RGB8 image (row-major, 3 bytes a pixel) into CHW floats.
    pub fn normalize_rgb8(&self, data: &[u8], height: usize, width: usize) -> Vec<f32> {
        let n = height * width;
        let mut out = vec![0.0f32; 3 * n];
        for c in 0..3 {
            let (m, s) = (self.mean[c], self.std[c]);
            for (i, px) in data.chunks_exact(3).take(n).enumerate() {
                out[c * n + i] = (px[c] as f32 / 255.0 - m) / s;
            }
        }
        out
    }
}

/// What one forward pass gives.
#[derive(Debug, Clone)]
pub struct PolicyOutput {
    /// Action logits `[B, commands, speed bins, 28]`.
    pub action_logits: Tensor<4>,
    /// Globally pooled feature `[B, D]`.
    pub features: Tensor<2>,
    /// Segmentation logits `[B, classes, H/4, W/4]` when asked for.
    pub seg_logits: Option<Tensor<4>>,
}

/// The multi-resolution policy network (one BN branch per scale; one branch = NRA).
#[derive(Module, Debug)]
pub struct PolicyNet {
    /// ResNet trunk.
    pub backbone: Backbone,
    /// WoR action head.
    pub action_head: ActionHead,
    /// Segmentation decoder (training only).
    pub seg_head: SegHead,
    /// The config it was built from.
    #[module(skip)]
    pub config: PolicyConfig,
}

impl PolicyNet {
    /// Forward pass of normalised images `[B, 3, H, W]` through BN branch `branch`.
    pub fn forward(&self, images: Tensor<4>, branch: usize, with_seg: bool) -> PolicyOutput {
        let fmap = self.backbone.forward(images, branch);
        let [b, c, _, _] = fmap.dims();
        let features = fmap.clone().mean_dims(&[2, 3]).reshape([b, c]);
        let seg_logits = with_seg.then(|| self.seg_head.forward(fmap, branch));
        PolicyOutput {
            action_logits: self.action_head.forward(features.clone()),
            features,
            seg_logits,
        }
    }

    /// Every BN bank (backbone then decoder).
    pub fn banks_mut(&mut self) -> Vec<&mut BnBank> {
        let mut v = self.backbone.banks_mut();
        v.extend(self.seg_head.banks_mut());
        v
    }

    /// Folds pending BN running-statistics updates in (call before `valid()`, saving or copying).
    pub fn sync_running_stats(&self) {
        for bank in self.clone().banks_mut() {
            bank.sync();
        }
    }

    /// A multi-resolution network for `scales` from this single-branch one: every BN copied into
    /// every branch, convolutions and heads shared (docs/protocol.md §6 init).
    pub fn to_multires(&self, scales: Vec<f32>) -> Result<PolicyNet, ConfigError> {
        if self.config.scales.len() != 1 {
            return Err(ConfigError::Field {
                field: "scales",
                problem: format!(
                    "the source network has {} branches",
                    self.config.scales.len()
                ),
                fix: "start from a single-resolution (one-scale) checkpoint",
            });
        }
        let config = self.config.clone().with_scales(scales);
        config.validate()?;
        let n = config.scales.len();
        let mut net = self.clone();
        net.config = config;
        for bank in net.banks_mut() {
            *bank = bank.replicate(0, n);
        }
        Ok(net)
    }
}

/// Counts of one network's parameters and of its BN banks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParamCounts {
    /// Learnable parameters (weights, biases, BN gamma/beta) of the whole network.
    pub learnable: usize,
    /// Learnable BN parameters (gamma, beta) over all branches.
    pub bn_learnable: usize,
    /// BN running statistics (mean, var) over all branches (buffers, not learned).
    pub bn_buffers: usize,
}

impl ParamCounts {
    /// Counts the parameters of `net`.
    pub fn of(net: &PolicyNet) -> Self {
        let mut net = net.clone();
        let mut bn_learnable = 0;
        for bank in net.banks_mut() {
            for bn in &bank.branches {
                bn_learnable += 2 * bn.gamma.dims()[0];
            }
        }
        // burn's `num_params` counts running statistics too; they equal the BN learnables.
        let bn_buffers = bn_learnable;
        ParamCounts {
            learnable: net.num_params() - bn_buffers,
            bn_learnable,
            bn_buffers,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn tiny(scales: Vec<f32>) -> PolicyConfig {
        PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_scales(scales)
            .with_input_height(64)
            .with_input_width(96)
    }

    #[test]
    fn input_sizes_floor_the_scaled_s0() {
        let c = PolicyConfig::cpu_default();
        assert_eq!(c.input_size(1.0), [96, 240]);
        assert_eq!(c.input_size(0.75), [72, 180]);
        assert_eq!(c.input_size(0.625), [60, 150]);
        assert_eq!(PolicyConfig::paper().input_size(0.75), [144, 360]);
        assert_eq!(c.clone().with_input_height(100).input_size(0.7), [70, 168]);
        assert_eq!(c.input_size(0.55), [52, 132]);
    }

    #[test]
    fn bad_configs_name_the_field() {
        let e = tiny(vec![]).validate().unwrap_err().to_string();
        assert!(e.contains("`scales`") && e.contains("fix"), "{e}");
        let e = tiny(vec![0.5, 0.5]).validate().unwrap_err().to_string();
        assert!(e.contains("twice"), "{e}");
        let e = tiny(vec![0.1]).validate().unwrap_err().to_string();
        assert!(e.contains("32 x 32"), "{e}");
        assert!(tiny(vec![0.5, 0.625, 0.75, 0.875, 1.0]).validate().is_ok());
    }

    #[test]
    fn any_scale_set_runs_each_branch() {
        let device = Device::flex();
        let cfg = tiny(vec![0.5, 0.625, 0.75, 0.875, 1.0]);
        let net = cfg.init(&device);
        for (b, r) in cfg.scales.iter().enumerate() {
            let [h, w] = cfg.input_size(*r);
            let out = net.forward(Tensor::zeros([1, 3, h, w], &device), b, true);
            assert_eq!(out.action_logits.dims(), [1, 6, 4, 28]);
            assert_eq!(out.features.dims(), [1, 16]);
        }
    }

    #[test]
    fn multires_from_single_res_is_identical_at_full_scale() {
        let device = Device::flex();
        device.seed(11);
        let single = tiny(vec![1.0]).init(&device);
        // Give the single model non-trivial BN statistics and affine parameters.
        let mut single = single;
        for bank in single.banks_mut() {
            let bn = &mut bank.branches[0];
            let c = bn.gamma.dims()[0];
            let r = |m: f64| {
                Tensor::<1>::random(
                    [c],
                    burn::tensor::Distribution::Uniform(m, m + 1.0),
                    &device,
                )
            };
            bn.gamma = burn::module::Param::from_tensor(r(0.5));
            bn.beta = burn::module::Param::from_tensor(r(-0.5));
            bn.running_mean = burn::module::RunningState::new(r(-0.5));
            bn.running_var = burn::module::RunningState::new(r(0.5));
        }
        let single = single.valid();
        let multi = single.to_multires(vec![0.75, 1.0]).unwrap().valid();
        let x = Tensor::<4>::random(
            [2, 3, 64, 96],
            burn::tensor::Distribution::Normal(0.0, 1.0),
            &device,
        );
        let a = single.forward(x.clone(), 0, true);
        let b = multi.forward(x, 1, true);
        assert_eq!(a.action_logits.into_data(), b.action_logits.into_data());
        assert_eq!(
            a.seg_logits.unwrap().into_data(),
            b.seg_logits.unwrap().into_data()
        );
        assert_eq!(multi.banks_count(), single.banks_count());
    }

    #[test]
    fn bank_overhead_is_the_extra_bn_affine_parameters() {
        let device = Device::flex();
        let one = ParamCounts::of(&tiny(vec![1.0]).init(&device));
        let two = ParamCounts::of(&tiny(vec![0.75, 1.0]).init(&device));
        assert_eq!(two.bn_learnable, 2 * one.bn_learnable);
        assert_eq!(two.learnable - one.learnable, one.bn_learnable);
    }

    impl PolicyNet {
        fn banks_count(&self) -> usize {
            self.clone().banks_mut().len()
        }
    }
}
