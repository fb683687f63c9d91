//! The two heads on the backbone: WoR's action head and the segmentation decoder.

use crate::bn_bank::{BnBank, BnBankConfig};
use crate::conv::{conv_transpose2d, conv2d};
use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig, ConvTranspose2d, ConvTranspose2dConfig};
use burn::nn::{Linear, LinearConfig};
use burn::prelude::*;
use burn::tensor::activation::relu;
use dataset::action::{NUM_ACTIONS, NUM_STEERS, NUM_THROTTLES};

/// Configuration of the action head.
#[derive(Config, Debug)]
pub struct ActionHeadConfig {
    /// Input feature size (the backbone's last width; 512 in the paper).
    pub d_input: usize,
    /// Hidden width of both hidden layers.
    #[config(default = 256)]
    pub d_hidden: usize,
    /// Route commands.
    #[config(default = 6)]
    pub num_commands: usize,
    /// Speed bins.
    #[config(default = 4)]
    pub num_speed_bins: usize,
    /// WoR's factorised output: 9 steer + 3 throttle + 1 brake logits per
    /// (command, speed), expanded to 28 as `steer + throttle` (true, as WoR's
    /// `main_model.py`), or 28 free logits (false).
    #[config(default = true)]
    pub factorised: bool,
}

impl ActionHeadConfig {
    /// Raw outputs per (command, speed bin).
    pub fn raw_per_cell(&self) -> usize {
        if self.factorised {
            NUM_STEERS + NUM_THROTTLES + 1
        } else {
            NUM_ACTIONS
        }
    }

    /// Builds the head.
    pub fn init(&self, device: &Device) -> ActionHead {
        let out = self.num_commands * self.num_speed_bins * self.raw_per_cell();
        ActionHead {
            fc1: LinearConfig::new(self.d_input, self.d_hidden).init(device),
            fc2: LinearConfig::new(self.d_hidden, self.d_hidden).init(device),
            fc3: LinearConfig::new(self.d_hidden, out).init(device),
            num_commands: self.num_commands,
            num_speed_bins: self.num_speed_bins,
            factorised: self.factorised,
        }
    }
}

/// MLP `d -> 256 -> 256 -> commands x speed bins x (13 or 28)`, giving 28 logits per cell.
#[derive(Module, Debug)]
pub struct ActionHead {
    /// First layer.
    pub fc1: Linear,
    /// Second layer.
    pub fc2: Linear,
    /// Output layer.
    pub fc3: Linear,
    /// Route commands.
    pub num_commands: usize,
    /// Speed bins.
    pub num_speed_bins: usize,
    /// Factorised output (see [`ActionHeadConfig::factorised`]).
    pub factorised: bool,
}

impl ActionHead {
    /// Action logits `[B, commands, speed bins, 28]` from pooled features `[B, d]`.
    pub fn forward(&self, features: Tensor<2>) -> Tensor<4> {
        let [b, _] = features.dims();
        let h = relu(self.fc1.forward(features));
        let h = relu(self.fc2.forward(h));
        let raw = self.fc3.forward(h);
        let (c, s) = (self.num_commands, self.num_speed_bins);
        if !self.factorised {
            return raw.reshape([b, c, s, NUM_ACTIONS]);
        }
        let raw = raw.reshape([b, c, s, NUM_STEERS + NUM_THROTTLES + 1]);
        let steer = raw.clone().narrow(3, 0, NUM_STEERS);
        let throttle = raw.clone().narrow(3, NUM_STEERS, NUM_THROTTLES);
        let brake = raw.narrow(3, NUM_STEERS + NUM_THROTTLES, 1);
        // Action t * 9 + s has logit steer[s] + throttle[t] (WoR's `action_logits`).
        let steer = steer.repeat_dim(3, NUM_THROTTLES);
        let throttle = throttle
            .reshape([b, c, s, NUM_THROTTLES, 1])
            .repeat_dim(4, NUM_STEERS)
            .reshape([b, c, s, NUM_THROTTLES * NUM_STEERS]);
        Tensor::cat(vec![steer + throttle, brake], 3)
    }
}

/// Configuration of the segmentation decoder.
#[derive(Config, Debug)]
pub struct SegHeadConfig {
    /// Input channels (the backbone's last width).
    pub d_input: usize,
    /// Output classes.
    #[config(default = 6)]
    pub num_classes: usize,
    /// BN branches (one per scale).
    pub num_branches: usize,
}

impl SegHeadConfig {
    /// Builds the decoder: channels halve at each of the three upsamplings.
    pub fn init(&self, device: &Device) -> SegHead {
        let c = [
            self.d_input,
            self.d_input / 2,
            self.d_input / 4,
            self.d_input / 8,
        ];
        let up = |i: usize| {
            ConvTranspose2dConfig::new([c[i], c[i + 1]], [3, 3])
                .with_stride([2, 2])
                .with_padding([1, 1])
                .with_padding_out([1, 1])
                .init(device)
        };
        let bank = |i: usize| BnBankConfig::new(c[i + 1], self.num_branches).init(device);
        SegHead {
            up1: up(0),
            bn1: bank(0),
            up2: up(1),
            bn2: bank(1),
            up3: up(2),
            bn3: bank(2),
            classifier: Conv2dConfig::new([c[3], self.num_classes], [1, 1]).init(device),
        }
    }
}

/// Three `ConvTranspose2d(stride 2) + BN bank + ReLU`, then a 1x1 convolution to the classes.
#[derive(Module, Debug)]
pub struct SegHead {
    /// Upsampling 1 (stride 32 -> 16).
    pub up1: ConvTranspose2d,
    /// BN bank after `up1`.
    pub bn1: BnBank,
    /// Upsampling 2 (stride 16 -> 8).
    pub up2: ConvTranspose2d,
    /// BN bank after `up2`.
    pub bn2: BnBank,
    /// Upsampling 3 (stride 8 -> 4).
    pub up3: ConvTranspose2d,
    /// BN bank after `up3`.
    pub bn3: BnBank,
    /// 1x1 classifier.
    pub classifier: Conv2d,
}

impl SegHead {
    /// Class logits at stride 4 from the stride-32 feature map.
    pub fn forward(&self, features: Tensor<4>, branch: usize) -> Tensor<4> {
        let x = relu(
            self.bn1
                .forward(conv_transpose2d(&self.up1, features), branch),
        );
        let x = relu(self.bn2.forward(conv_transpose2d(&self.up2, x), branch));
        let x = relu(self.bn3.forward(conv_transpose2d(&self.up3, x), branch));
        conv2d(&self.classifier, x)
    }

    /// Every BN bank of the decoder.
    pub fn banks_mut(&mut self) -> Vec<&mut BnBank> {
        vec![&mut self.bn1, &mut self.bn2, &mut self.bn3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dataset::action::{BRAKE, index};

    #[test]
    fn factorised_logits_are_steer_plus_throttle() {
        let device = Device::flex();
        device.seed(3);
        let head = ActionHeadConfig::new(8).with_d_hidden(16).init(&device);
        let f = Tensor::<2>::random(
            [2, 8],
            burn::tensor::Distribution::Normal(0.0, 1.0),
            &device,
        );
        let z = head.forward(f.clone());
        assert_eq!(z.dims(), [2, 6, 4, 28]);
        // Recompute the raw 13 outputs and check the expansion cell by cell.
        let h = relu(head.fc2.forward(relu(head.fc1.forward(f))));
        let raw = head
            .fc3
            .forward(h)
            .reshape([2, 6, 4, 13])
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        let z = z.into_data().try_to_vec::<f32>().unwrap();
        for cell in 0..2 * 6 * 4 {
            let r = &raw[cell * 13..cell * 13 + 13];
            let zz = &z[cell * 28..cell * 28 + 28];
            for t in 0..3 {
                for s in 0..9 {
                    assert!((zz[index(s, t)] - (r[s] + r[9 + t])).abs() < 1e-5);
                }
            }
            assert_eq!(zz[BRAKE], r[12]);
        }
    }

    #[test]
    fn segmentation_is_at_stride_4() {
        let device = Device::flex();
        let head = SegHeadConfig::new(16, 2).init(&device);
        let y = head.forward(Tensor::zeros([1, 16, 3, 7], &device), 1);
        assert_eq!(y.dims(), [1, 6, 24, 56]);
    }
}
