//! The ResNet backbone (BasicBlock; ResNet-18/34 layouts, any widths) with every BatchNorm a bank.
//!
//! Field names follow torchvision's ResNet (`conv1`, `bn1`, `layer1.0.conv1`,
//! `layer2.0.downsample`, ...) so a torchvision state dict maps onto it with
//! few renames (see `checkpoint.rs`). The average pool and `fc` are not part
//! of it: `forward` returns the stride-32 feature map.

use crate::bn_bank::{BnBank, BnBankConfig};
use crate::conv::conv2d;
use burn::module::Module;
use burn::nn::PaddingConfig2d;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::pool::{MaxPool2d, MaxPool2dConfig};
use burn::prelude::*;
use burn::tensor::activation::relu;
use serde::{Deserialize, Serialize};

/// Which ResNet layout (blocks per stage).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Depth {
    /// ResNet-18: 2-2-2-2 basic blocks.
    Resnet18,
    /// ResNet-34: 3-4-6-3 basic blocks.
    Resnet34,
}

impl Depth {
    /// Basic blocks in each of the four stages.
    pub fn blocks(self) -> [usize; 4] {
        match self {
            Depth::Resnet18 => [2, 2, 2, 2],
            Depth::Resnet34 => [3, 4, 6, 3],
        }
    }

    /// Name as written in configs and reports.
    pub fn name(self) -> &'static str {
        match self {
            Depth::Resnet18 => "resnet18",
            Depth::Resnet34 => "resnet34",
        }
    }
}

/// Configuration of the backbone.
#[derive(Config, Debug)]
pub struct BackboneConfig {
    /// The layout.
    pub depth: Depth,
    /// Channels of the four stages (torchvision: 64-128-256-512); the stem has `widths[0]`.
    pub widths: [usize; 4],
    /// BN branches (one per scale in R; 1 = the NRA model).
    pub num_branches: usize,
}

impl BackboneConfig {
    /// Builds the backbone.
    pub fn init(&self, device: &Device) -> Backbone {
        let w = self.widths;
        let nb = self.num_branches;
        let bank = |c| BnBankConfig::new(c, nb).init(device);
        let blocks = self.depth.blocks();
        let stage = |i: usize| -> Vec<BasicBlock> {
            let c_in = if i == 0 { w[0] } else { w[i - 1] };
            (0..blocks[i])
                .map(|b| {
                    let (cin, stride) = if b == 0 {
                        (c_in, if i == 0 { 1 } else { 2 })
                    } else {
                        (w[i], 1)
                    };
                    BasicBlock::new(cin, w[i], stride, nb, device)
                })
                .collect()
        };
        Backbone {
            conv1: Conv2dConfig::new([3, w[0]], [7, 7])
                .with_stride([2, 2])
                .with_padding(PaddingConfig2d::Explicit(3, 3, 3, 3))
                .with_bias(false)
                .init(device),
            bn1: bank(w[0]),
            maxpool: MaxPool2dConfig::new([3, 3])
                .with_strides([2, 2])
                .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
                .init(),
            layer1: stage(0),
            layer2: stage(1),
            layer3: stage(2),
            layer4: stage(3),
        }
    }

    /// Channels of the output feature map.
    pub fn feature_dim(&self) -> usize {
        self.widths[3]
    }
}

/// The 1x1 strided projection of a block whose shape changes (torchvision's `downsample`).
#[derive(Module, Debug)]
pub struct Downsample {
    /// 1x1 convolution (torchvision `downsample.0`).
    pub conv: Conv2d,
    /// Its BN bank (torchvision `downsample.1`).
    pub bn: BnBank,
}

/// A ResNet basic block: two 3x3 convolutions, BN banks, identity or projected shortcut.
#[derive(Module, Debug)]
pub struct BasicBlock {
    /// First 3x3 convolution (carries the stride).
    pub conv1: Conv2d,
    /// BN bank after `conv1`.
    pub bn1: BnBank,
    /// Second 3x3 convolution.
    pub conv2: Conv2d,
    /// BN bank after `conv2`.
    pub bn2: BnBank,
    /// Shortcut projection when stride or width changes.
    pub downsample: Option<Downsample>,
}

fn conv3x3(cin: usize, cout: usize, stride: usize, device: &Device) -> Conv2d {
    Conv2dConfig::new([cin, cout], [3, 3])
        .with_stride([stride, stride])
        .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
        .with_bias(false)
        .init(device)
}

impl BasicBlock {
    /// A block from `cin` to `cout` channels with the given stride and BN branches.
    pub fn new(cin: usize, cout: usize, stride: usize, branches: usize, device: &Device) -> Self {
        let downsample = (stride != 1 || cin != cout).then(|| Downsample {
            conv: Conv2dConfig::new([cin, cout], [1, 1])
                .with_stride([stride, stride])
                .with_bias(false)
                .init(device),
            bn: BnBankConfig::new(cout, branches).init(device),
        });
        BasicBlock {
            conv1: conv3x3(cin, cout, stride, device),
            bn1: BnBankConfig::new(cout, branches).init(device),
            conv2: conv3x3(cout, cout, 1, device),
            bn2: BnBankConfig::new(cout, branches).init(device),
            downsample,
        }
    }

    /// `relu(bn2(conv2(relu(bn1(conv1 x)))) + shortcut(x))` with BN branch `branch`.
    pub fn forward(&self, x: Tensor<4>, branch: usize) -> Tensor<4> {
        let shortcut = match &self.downsample {
            Some(d) => d.bn.forward(conv2d(&d.conv, x.clone()), branch),
            None => x.clone(),
        };
        let y = relu(self.bn1.forward(conv2d(&self.conv1, x), branch));
        let y = self.bn2.forward(conv2d(&self.conv2, y), branch);
        relu(y + shortcut)
    }

    /// Turns gradients of the convolutions on or off (BN banks untouched).
    pub fn set_convs_trainable(mut self, trainable: bool) -> Self {
        self.conv1 = self.conv1.set_require_grad(trainable);
        self.conv2 = self.conv2.set_require_grad(trainable);
        if let Some(d) = self.downsample.as_mut() {
            d.conv = d.conv.clone().set_require_grad(trainable);
        }
        self
    }

    /// Every BN bank of the block.
    pub fn banks_mut(&mut self) -> Vec<&mut BnBank> {
        let mut v = vec![&mut self.bn1, &mut self.bn2];
        if let Some(d) = self.downsample.as_mut() {
            v.push(&mut d.bn);
        }
        v
    }
}

/// The ResNet trunk: stem, max-pool, four stages of basic blocks.
#[derive(Module, Debug)]
pub struct Backbone {
    /// Stem 7x7 stride-2 convolution.
    pub conv1: Conv2d,
    /// Stem BN bank.
    pub bn1: BnBank,
    /// 3x3 stride-2 max-pool.
    pub maxpool: MaxPool2d,
    /// Stage 1 (stride 4).
    pub layer1: Vec<BasicBlock>,
    /// Stage 2 (stride 8).
    pub layer2: Vec<BasicBlock>,
    /// Stage 3 (stride 16).
    pub layer3: Vec<BasicBlock>,
    /// Stage 4 (stride 32).
    pub layer4: Vec<BasicBlock>,
}

impl Backbone {
    /// The stride-32 feature map of a normalised image batch `[B, 3, H, W]`, BN branch `branch`.
    pub fn forward(&self, x: Tensor<4>, branch: usize) -> Tensor<4> {
        let mut x = self
            .maxpool
            .forward(relu(self.bn1.forward(conv2d(&self.conv1, x), branch)));
        for block in self
            .layer1
            .iter()
            .chain(&self.layer2)
            .chain(&self.layer3)
            .chain(&self.layer4)
        {
            x = block.forward(x, branch);
        }
        x
    }

    /// The stages as a mutable array (index 0 = layer1).
    pub fn stages_mut(&mut self) -> [&mut Vec<BasicBlock>; 4] {
        [
            &mut self.layer1,
            &mut self.layer2,
            &mut self.layer3,
            &mut self.layer4,
        ]
    }

    /// Every BN bank, stem first, in forward order.
    pub fn banks_mut(&mut self) -> Vec<&mut BnBank> {
        let mut v = vec![&mut self.bn1];
        for stage in [
            &mut self.layer1,
            &mut self.layer2,
            &mut self.layer3,
            &mut self.layer4,
        ] {
            for block in stage.iter_mut() {
                v.extend(block.banks_mut());
            }
        }
        v
    }

    /// Makes the convolutions of stage `stage` (1..=4; 0 = the stem) trainable or frozen.
    pub fn set_stage_trainable(mut self, stage: usize, trainable: bool) -> Self {
        if stage == 0 {
            self.conv1 = self.conv1.set_require_grad(trainable);
            return self;
        }
        let s = std::mem::take(self.stages_mut()[stage - 1]);
        *self.stages_mut()[stage - 1] = s
            .into_iter()
            .map(|b| b.set_convs_trainable(trainable))
            .collect();
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_is_stride_32_with_the_last_width() {
        let device = Device::flex();
        let cfg = BackboneConfig::new(Depth::Resnet18, [4, 8, 8, 16], 2);
        let net = cfg.init(&device);
        let y = net.forward(Tensor::zeros([2, 3, 64, 96], &device), 1);
        assert_eq!(y.dims(), [2, 16, 2, 3]);
    }

    #[test]
    fn layouts_have_the_torchvision_block_counts() {
        let device = Device::flex();
        let net = BackboneConfig::new(Depth::Resnet34, [2, 2, 4, 4], 1).init(&device);
        assert_eq!(
            [
                net.layer1.len(),
                net.layer2.len(),
                net.layer3.len(),
                net.layer4.len()
            ],
            [3, 4, 6, 3]
        );
        // Projections exactly where torchvision has them.
        assert!(net.layer1[0].downsample.is_none());
        assert!(net.layer2[0].downsample.is_some() && net.layer2[1].downsample.is_none());
        assert!(net.layer4[0].downsample.is_some());
    }

    #[test]
    fn full_width_resnet18_and_34_have_torchvision_parameter_counts() {
        // torchvision: resnet18 11,689,512 and resnet34 21,797,672 parameters, of which fc
        // is 513,000; BN running statistics are buffers there, parameters in burn's count.
        let device = Device::flex();
        for (depth, expected) in [
            (Depth::Resnet18, 11_689_512 - 513_000),
            (Depth::Resnet34, 21_797_672 - 513_000),
        ] {
            let mut net = BackboneConfig::new(depth, [64, 128, 256, 512], 1).init(&device);
            let running: usize = net
                .banks_mut()
                .iter()
                .map(|b| 2 * b.branches[0].gamma.dims()[0])
                .sum();
            assert_eq!(net.num_params() - running, expected, "{depth:?}");
        }
    }
}
