//! BatchNorm in training mode on the CPU as one operation, forward and backward.
//!
//! burn computes a training-mode BatchNorm out of tensor operations (its default
//! `batch_norm_train` and `batch_norm_train_backward`): each statistic swaps the batch
//! and channel axes and copies the activation into that layout, and the backward makes
//! a dozen full passes. After the convolutions moved to [`crate::conv`], those copies
//! were the largest cost left outside the matrix products (docs/training.md). Here the
//! statistics are two passes per channel over burn's NCHW tensor, and the backward is
//! two more: the sums per channel, then the input gradient per plane.
//!
//! [`batch_norm`] is what the BN banks call. On the CPU in training mode it computes
//! what `BatchNorm::forward` computes there (batch mean and biased variance, the same
//! running-statistics update), and everywhere else it calls `BatchNorm::forward`.
//! Sums run in 16 f32 lanes per plane, added in f64, one channel at a time in a fixed
//! order, so the result does not depend on the thread count.

use crate::conv::{contiguous, f32s, flex, on_flex};
use burn::backend::autodiff::checkpoint::base::Checkpointer;
use burn::backend::autodiff::checkpoint::strategy::CheckpointStrategy;
use burn::backend::autodiff::grads::Gradients;
use burn::backend::autodiff::ops::{Backward, Ops, OpsKind};
use burn::backend::flex::FlexTensor;
use burn::backend::tensor::FloatTensor;
use burn::backend::{Autodiff, Backend, Dispatch, Flex, backend_extension};
use burn::nn::BatchNorm;
use burn::prelude::*;
pub use kernels::batch_norm::{Planes, backward, normalize, statistics};

/// Two custom operations for burn: the batch statistics, and training-mode BatchNorm
/// with them (computed once, for the normalisation and the running averages alike).
#[backend_extension(Autodiff, Flex)]
pub trait NormOps: Backend {
    /// `x [batch, channels, ...]` normalised with its own per-channel mean and biased
    /// variance, `stats` as [`NormOps::batch_statistics`] returns them for this `x`,
    /// scaled by `gamma` and shifted by `beta`; its gradient treats the statistics as
    /// functions of `x`, as training-mode BatchNorm does (`stats` itself gets none).
    fn batch_norm_train(
        x: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        beta: FloatTensor<Self>,
        stats: FloatTensor<Self>,
        eps: f64,
    ) -> FloatTensor<Self>;

    /// The per-channel mean and biased variance of `x` as `[2, channels]` (the mean's
    /// row, then the variance's), without a gradient.
    fn batch_statistics(x: FloatTensor<Self>) -> FloatTensor<Self>;
}

fn shape_of(t: &FlexTensor) -> Vec<usize> {
    t.layout().shape().as_slice().to_vec()
}

/// A `[channels]` CPU tensor.
fn channel_tensor(values: Vec<f32>) -> FlexTensor {
    let n = values.len();
    flex(values, [n])
}

/// The mean's and the variance's rows of a contiguous `[2, channels]` statistics tensor.
fn mean_var(stats: &FlexTensor) -> (&[f32], &[f32]) {
    let v = f32s(stats);
    v.split_at(v.len() / 2)
}

/// The forward on contiguous primitives.
fn train_forward(
    x: &FlexTensor,
    gamma: &FlexTensor,
    beta: &FlexTensor,
    stats: &FlexTensor,
    eps: f64,
) -> FlexTensor {
    let dims = shape_of(x);
    let (mean, var) = mean_var(stats);
    let y = normalize(
        f32s(x),
        Planes::of(&dims),
        [f32s(gamma), f32s(beta), mean, var],
        eps,
    );
    flex(y, dims)
}

impl NormOps for Flex {
    fn batch_norm_train(
        x: FlexTensor,
        gamma: FlexTensor,
        beta: FlexTensor,
        stats: FlexTensor,
        eps: f64,
    ) -> FlexTensor {
        let [x, gamma, beta, stats] = [x, gamma, beta, stats].map(|t| contiguous(&t));
        train_forward(&x, &gamma, &beta, &stats, eps)
    }

    fn batch_statistics(x: FlexTensor) -> FlexTensor {
        let x = contiguous(&x);
        let dims = shape_of(&x);
        let (mut mean, var) = statistics(f32s(&x), Planes::of(&dims));
        let channels = mean.len();
        mean.extend(var);
        flex(mean, [2, channels])
    }
}

/// The backward step of [`NormOps::batch_norm_train`] on `Autodiff<Flex>`.
#[derive(Debug)]
struct NormBackward;

impl Backward<Flex, 3> for NormBackward {
    /// The forward's contiguous input, gamma and `[2, channels]` statistics, epsilon.
    type State = (FlexTensor, FlexTensor, FlexTensor, f64);

    fn backward(self, ops: Ops<Self::State, 3>, grads: &mut Gradients, _: &mut Checkpointer) {
        let [node_x, node_gamma, node_beta] = ops.parents;
        let dy = contiguous(&grads.consume::<Flex>(&ops.node));
        let (x, gamma, stats, eps) = ops.state;
        let dims = shape_of(&x);
        let (mean, var) = mean_var(&stats);
        let (dx, dgamma, dbeta) = backward(
            f32s(&x),
            f32s(&dy),
            Planes::of(&dims),
            [f32s(&gamma), mean, var],
            eps,
        );
        if let Some(node) = node_x {
            grads.register::<Flex>(node.id, flex(dx, dims));
        }
        if let Some(node) = node_gamma {
            grads.register::<Flex>(node.id, channel_tensor(dgamma));
        }
        if let Some(node) = node_beta {
            grads.register::<Flex>(node.id, channel_tensor(dbeta));
        }
    }
}

impl<C: CheckpointStrategy> NormOps for Autodiff<Flex, C> {
    fn batch_norm_train(
        x: FloatTensor<Self>,
        gamma: FloatTensor<Self>,
        beta: FloatTensor<Self>,
        stats: FloatTensor<Self>,
        eps: f64,
    ) -> FloatTensor<Self> {
        match NormBackward
            .prepare::<C>([x.node(), gamma.node(), beta.node()])
            .compute_bound()
            .stateful()
        {
            OpsKind::Tracked(prep) => {
                let [x, gamma, beta, stats] = [
                    x.primitive(),
                    gamma.primitive(),
                    beta.primitive(),
                    stats.primitive(),
                ]
                .map(contiguous);
                let y = train_forward(&x, &gamma, &beta, &stats, eps);
                prep.finish((x, gamma, stats, eps), y)
            }
            OpsKind::UnTracked(prep) => prep.finish(Flex::batch_norm_train(
                x.into_primitive(),
                gamma.into_primitive(),
                beta.into_primitive(),
                stats.into_primitive(),
                eps,
            )),
        }
    }

    fn batch_statistics(x: FloatTensor<Self>) -> FloatTensor<Self> {
        FloatTensor::<Self>::new(Flex::batch_statistics(x.into_primitive()))
    }
}

/// `bn.forward(x)`: in training mode on the CPU through [`NormOps`] (with the same
/// running-statistics update as burn's), otherwise burn's own.
pub fn batch_norm(bn: &BatchNorm, x: Tensor<4>) -> Tensor<4> {
    let device = x.device();
    if !(device.is_autodiff() && bn.training.is_enabled() && on_flex(&device)) {
        return bn.forward(x);
    }
    let channels = x.dims()[1];
    let stats = Tensor::<2>::from_dispatch(<Dispatch as NormOps>::batch_statistics(
        x.clone().detach().into_dispatch(),
    ));
    let y = Tensor::from_dispatch(<Dispatch as NormOps>::batch_norm_train(
        x.into_dispatch(),
        bn.gamma.val().into_dispatch(),
        bn.beta.val().into_dispatch(),
        stats.clone().into_dispatch(),
        bn.epsilon,
    ));

    // The running statistics, updated as `BatchNorm::forward` does in training.
    let mean = stats.clone().slice([0..1, 0..channels]).reshape([channels]);
    let var = stats.slice([1..2, 0..channels]).reshape([channels]);
    let m = bn.momentum;
    let running_mean = bn.running_mean.value_sync().to_device(&device);
    let running_var = bn.running_var.value_sync().to_device(&device);
    bn.running_mean
        .update((running_mean.mul_scalar(1.0 - m) + mean.mul_scalar(m)).detach());
    bn.running_var
        .update((running_var.mul_scalar(1.0 - m) + var.mul_scalar(m)).detach());
    y
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conv::tests::{close, pool};
    use crate::fused::values;
    use burn::module::{Param, RunningState};
    use burn::nn::BatchNormConfig;
    use burn::tensor::Distribution;
    use burn::tensor::TensorData;

    /// A BatchNorm with gamma, beta and running statistics away from the identity; each
    /// call makes a new one (its own running-state cells: clones would share them).
    fn perturbed(channels: usize, device: &Device) -> BatchNorm {
        let mut bn = BatchNormConfig::new(channels).init(device);
        let r = |lo: f32, hi: f32, k: usize| {
            let v: Vec<f32> = (0..channels)
                .map(|i| lo + (hi - lo) * (((i * k + 1) % 7) as f32 / 6.0))
                .collect();
            Tensor::<1>::from_data(TensorData::new(v, [channels]), device)
        };
        bn.gamma = Param::from_tensor(r(0.5, 1.5, 3));
        bn.beta = Param::from_tensor(r(-0.5, 0.5, 5));
        bn.running_mean = RunningState::new(r(-1.0, 1.0, 2));
        bn.running_var = RunningState::new(r(0.5, 2.0, 4));
        bn
    }

    /// Output, input/gamma/beta gradients and the updated running statistics against
    /// burn's `BatchNorm::forward` in training mode, over two steps (so the running
    /// update compounds), with a loss `sum(y * r)` whose weights differ per value.
    #[test]
    fn training_mode_matches_burns_batch_norm() {
        let device = Device::flex().autodiff();
        for (b, c, h, w) in [(4, 3, 5, 6), (1, 2, 3, 3), (7, 5, 2, 1)] {
            let ours_bn = perturbed(c, &device);
            let burn_bn = perturbed(c, &device);
            for step in 0..2 {
                let x0 = Tensor::<4>::random([b, c, h, w], Distribution::Normal(0.3, 2.0), &device);
                let r: Vec<f32> = (0..b * c * h * w)
                    .map(|i| ((i * 7 + 3) % 11) as f32 / 5.0 - 1.0)
                    .collect();
                let r = Tensor::<4>::from_data(TensorData::new(r, [b, c, h, w]), &device);
                let run = |bn: &BatchNorm, ours: bool| {
                    let x = x0.clone().detach().require_grad();
                    let y = if ours {
                        batch_norm(bn, x.clone())
                    } else {
                        bn.forward(x.clone())
                    };
                    let grads = (y.clone() * r.clone()).sum().backward();
                    [
                        values(y.inner()),
                        values(x.grad(&grads).expect("dx")),
                        values(bn.gamma.val().grad(&grads).expect("dgamma")),
                        values(bn.beta.val().grad(&grads).expect("dbeta")),
                        values(bn.running_mean.value_sync()),
                        values(bn.running_var.value_sync()),
                    ]
                };
                let ours = run(&ours_bn, true);
                let burn = run(&burn_bn, false);
                let names = ["y", "dx", "dgamma", "dbeta", "running mean", "running var"];
                for ((name, a), z) in names.iter().zip(&ours).zip(&burn) {
                    close(&format!("{b}x{c}x{h}x{w} step {step} {name}"), a, z, 2e-5);
                }
            }
        }
    }

    /// Off the autodiff device (inference) it is burn's forward and updates nothing.
    #[test]
    fn inference_uses_burns_forward() {
        let device = Device::flex();
        let bn = perturbed(3, &device);
        let x = Tensor::<4>::random([2, 3, 4, 4], Distribution::Normal(0.0, 1.0), &device);
        assert_eq!(
            values(batch_norm(&bn, x.clone())),
            values(bn.forward(x.clone()))
        );
        let before = values(bn.running_mean.value_sync());
        let _ = batch_norm(&bn, x);
        assert_eq!(
            values(bn.running_mean.value_sync()),
            before,
            "inference updates nothing"
        );
    }

    #[test]
    fn results_are_bit_identical_for_any_thread_count() {
        let p = Planes {
            batch: 5,
            channels: 6,
            pixels: 37,
        };
        let len = 5 * 6 * 37;
        let x: Vec<f32> = (0..len)
            .map(|i| ((i * 37) % 101) as f32 / 50.0 - 1.0)
            .collect();
        let dy: Vec<f32> = (0..len)
            .map(|i| ((i * 29) % 89) as f32 / 44.0 - 1.0)
            .collect();
        let gamma = vec![0.9, 1.1, 1.0, 0.7, 1.3, 1.2];
        let run = |threads| {
            pool(threads).install(|| {
                let (mean, var) = statistics(&x, p);
                let y = normalize(&x, p, [&gamma, &gamma, &mean, &var], 1e-5);
                let (dx, dg, db) = backward(&x, &dy, p, [&gamma, &mean, &var], 1e-5);
                [mean, var, y, dx, dg, db]
                    .map(|v| v.iter().map(|f| f.to_bits()).collect::<Vec<u32>>())
            })
        };
        assert_eq!(run(1), run(2));
        assert_eq!(run(1), run(3));
    }
}
