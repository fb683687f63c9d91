//! The policy fingerprint: the CPU paths' arithmetic on fixed inputs, hashed.
//!
//! The matrix kernel dispatches on the CPU at run time (AVX-512 where there is
//! one, AVX2 and FMA otherwise), and a sum's order decides its last bits. This
//! module runs the CPU paths a study uses on fixed inputs and hashes every
//! output bit: fused inference ([`crate::fused`]) of a seeded network at both
//! scales, a few retargeting steps (student with BN banks, frozen teacher,
//! segmentation, Adam; [`crate::train::multires`]) on a seeded toy batch, and
//! inference again with the trained weights. Two machines whose fingerprints
//! agree compute these bit for bit alike; `mrdrive policy fingerprint` prints it
//! and `tests/cross_cpu.rs` compares it with an emulated CPU without AVX-512.

use std::fmt::Write as _;

use burn::prelude::*;
use sim::record::sha256_hex;
use sim::render::image::test_pattern;

use crate::fused::FusedPolicy;
use crate::model::{PolicyConfig, PolicyNet};
use crate::train::multires::{MultiResTrainer, TrainConfig};
use crate::train::synthetic::toy_batch;

/// Retargeting steps the fingerprint takes.
pub const TRAIN_STEPS: usize = 2;
/// Samples in the toy batch.
pub const BATCH: usize = 2;

/// One hashed output: what it is and the SHA-256 of its `f32` bits (little-endian).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Hashed {
    /// e.g. `infer@0.75`, `train step 1 losses`.
    pub name: String,
    /// Lower-case hex.
    pub sha256: String,
}

/// Every hashed output, in a fixed order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PolicyFingerprint {
    /// The outputs.
    pub outputs: Vec<Hashed>,
}

impl PolicyFingerprint {
    /// SHA-256 over every output's line: the one value to compare between machines.
    pub fn digest(&self) -> String {
        let lines: String = self
            .outputs
            .iter()
            .map(|h| format!("{} {}\n", h.name, h.sha256))
            .collect();
        sha256_hex(lines.as_bytes())
    }

    /// A table: one line per output, then the digest.
    pub fn report(&self) -> String {
        let mut s = String::new();
        for h in &self.outputs {
            let _ = writeln!(s, "{:<28} {}", h.name, &h.sha256[..16]);
        }
        let _ = writeln!(s, "digest   {}", self.digest());
        s
    }
}

fn hashed(name: String, values: &[f32]) -> Hashed {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    Hashed {
        name,
        sha256: sha256_hex(&bytes),
    }
}

/// Fused inference of `net` on a fixed picture at each of its scales.
fn infer(net: &PolicyNet, tag: &str, out: &mut Vec<Hashed>) {
    let fused = FusedPolicy::from_net(net);
    for (branch, &scale) in net.config.scales.iter().enumerate() {
        let [h, w] = net.config.input_size(scale);
        let picture = test_pattern(w as u32, h as u32, branch as u64 + 1);
        let logits = fused.forward_rgb8(&picture.data, h, w, branch);
        out.push(hashed(format!("{tag}@{scale:.2}"), &logits));
    }
}

/// The network the fingerprint uses: the CPU default (half-width ResNet-18 at 240 x 96,
/// R = {0.75, 1.0}), or with `quick` the same widths at 120 x 48 (the least whose 0.75x input
/// is 32 pixels high), for an emulated CPU: 4 times less arithmetic, the same kernels.
pub fn config(quick: bool) -> PolicyConfig {
    let config = PolicyConfig::cpu_default();
    if quick {
        config.with_input_height(48).with_input_width(120)
    } else {
        config
    }
}

/// Computes the fingerprint on [`config`]`(quick)`: under a second natively.
pub fn fingerprint(quick: bool) -> PolicyFingerprint {
    let device = Device::flex().autodiff();
    device.seed(2026);
    let config = config(quick);
    let teacher = config.clone().with_scales(vec![1.0]).init(&device);
    let student = config.init(&device);
    let mut outputs = Vec::new();
    infer(&student, "infer", &mut outputs);
    let batch = toy_batch(&config, BATCH, 7, &device);
    let mut trainer = MultiResTrainer::new(
        student,
        Some(teacher),
        TrainConfig::new().with_lr(1e-3),
        &device,
    );
    for step in 1..=TRAIN_STEPS {
        let r = trainer.step(&batch);
        let mut losses = r.per_scale.clone();
        losses.extend([r.loss, r.parts.act, r.parts.seg, r.parts.kd, r.parts.feat]);
        outputs.push(hashed(format!("train step {step} losses"), &losses));
    }
    infer(&trainer.net.valid(), "trained infer", &mut outputs);
    PolicyFingerprint { outputs }
}
