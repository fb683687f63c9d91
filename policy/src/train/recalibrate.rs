//! BN recalibration: re-estimate each branch's running statistics on training data.
//!
//! For each scale, the branch's running mean/var are reset and then set to the
//! cumulative average of the batch statistics over the batches given (momentum
//! 1/(k+1) at batch k), with no parameter update (docs/protocol.md §6: 200 batches).

use super::multires::Batch;
use super::resize::resize_to_scale;
use crate::model::PolicyNet;
use burn::module::Module;
use burn::prelude::*;

/// Recalibrates every branch of `net` on `batches` (at S0, resized per scale), on `device`
/// (an autodiff device: BatchNorm updates statistics only in training mode there).
pub fn recalibrate(net: PolicyNet, batches: &[Batch], device: &Device) -> PolicyNet {
    let scales = net.config.scales.clone();
    recalibrate_with(net, batches.len(), device, |branch, k| {
        resize_to_scale(batches[k].images.clone(), scales[branch])
    })
}

/// Recalibrates every branch of `net` on `n_batches` normalised image batches per branch:
/// `images(branch, k)` gives batch `k` at branch `branch`'s scale, on `device` (autodiff).
///
/// Use this when the images come at each scale directly (rendered at that scale, as the
/// policy sees them in the loop) rather than resized from S0.
pub fn recalibrate_with(
    net: PolicyNet,
    n_batches: usize,
    device: &Device,
    mut images: impl FnMut(usize, usize) -> Tensor<4>,
) -> PolicyNet {
    // Statistics only: no parameter needs a gradient.
    let mut net = net.fork(device).train().no_grad();
    let momentum: Vec<f64> = net
        .banks_mut()
        .iter()
        .map(|b| b.branches[0].momentum)
        .collect();
    for branch in 0..net.config.scales.len() {
        for bank in net.banks_mut() {
            bank.reset_running_stats(branch);
        }
        for k in 0..n_batches {
            for bank in net.banks_mut() {
                bank.set_momentum(1.0 / (k as f64 + 1.0));
            }
            let _ = net.forward(images(branch, k), branch, true);
        }
    }
    for (bank, m) in net.banks_mut().into_iter().zip(momentum) {
        bank.set_momentum(m);
    }
    net.sync_running_stats();
    net
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backbone::Depth;
    use crate::model::PolicyConfig;
    use crate::train::synthetic::toy_batch;

    #[test]
    fn recalibration_gives_the_mean_of_the_batch_statistics() {
        let device = Device::flex().autodiff();
        device.seed(31);
        let cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(48)
            .with_input_width(64);
        let net = cfg.init(&device);
        let batches: Vec<Batch> = (0..3).map(|s| toy_batch(&cfg, 2, s, &device)).collect();
        let net = recalibrate(net, &batches, &device);
        // The stem BN sees conv1(x) directly: its running mean is the average of the
        // per-batch channel means of conv1's output at that scale.
        for (branch, r) in cfg.scales.iter().enumerate() {
            let mut expected = vec![0.0f32; 4];
            for b in &batches {
                let y = net
                    .backbone
                    .conv1
                    .forward(resize_to_scale(b.images.clone(), *r));
                let m = y
                    .mean_dims(&[0, 2, 3])
                    .into_data()
                    .try_to_vec::<f32>()
                    .unwrap();
                for c in 0..4 {
                    expected[c] += m[c] / batches.len() as f32;
                }
            }
            let got = net.backbone.bn1.branches[branch]
                .running_mean
                .value_sync()
                .into_data()
                .try_to_vec::<f32>()
                .unwrap();
            for c in 0..4 {
                assert!(
                    (got[c] - expected[c]).abs() < 1e-4,
                    "branch {branch}: {got:?} vs {expected:?}"
                );
            }
            assert_eq!(net.backbone.bn1.branches[branch].momentum, 0.1);
        }
    }
}
