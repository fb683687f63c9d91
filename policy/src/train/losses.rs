//! The training losses (PROTOCOL §4 and §6).

use burn::prelude::*;
use burn::tensor::activation::{log_softmax, softmax};
use burn::tensor::module::interpolate;
use burn::tensor::ops::{InterpolateMode, InterpolateOptions};

/// WoR's temperature for the Boltzmann targets `softmax(Q / T)`.
pub const TEMPERATURE: f32 = 0.01;

/// `KL(p || softmax(z))` summed over the last dim for target log-probabilities `log_p`,
/// averaged over every other dim.
fn kl_last_dim(log_p: Tensor<4>, z: Tensor<4>) -> Tensor<1> {
    let log_q = log_softmax(z, 3);
    let p = log_p.clone().exp();
    (p * (log_p - log_q)).sum_dim(3).mean()
}

/// Action loss: `KL(softmax(Q / T) || softmax(z))` over the 28 actions, for every command and
/// speed bin, averaged over batch, commands and bins. `q`, `z`: `[B, commands, bins, 28]`.
pub fn action_kl(z: Tensor<4>, q: Tensor<4>, temperature: f32) -> Tensor<1> {
    kl_last_dim(log_softmax(q.div_scalar(temperature), 3), z)
}

/// Teacher knowledge distillation: `KL(softmax(zT) || softmax(z))` over the 28 actions,
/// averaged like [`action_kl`]; the teacher's logits carry no gradient.
pub fn kd_kl(z: Tensor<4>, teacher_z: Tensor<4>) -> Tensor<1> {
    kl_last_dim(log_softmax(teacher_z.detach(), 3), z)
}

/// Feature matching: `||f - fT||^2 / D`, averaged over the batch (`[B, D]`).
pub fn feature_mse(f: Tensor<2>, teacher_f: Tensor<2>) -> Tensor<1> {
    (f - teacher_f.detach()).powi_scalar(2).mean()
}

/// Segmentation cross-entropy: logits `[B, K, h, w]` upsampled (nearest, as WoR) to the
/// label size `[B, H, W]`, averaged over pixels.
pub fn seg_ce(logits: Tensor<4>, labels: Tensor<3, Int>) -> Tensor<1> {
    let [b, h, w] = labels.dims();
    let mut options = InterpolateOptions::new(InterpolateMode::Nearest);
    options.output_size = Some([h, w]);
    let logits = interpolate(logits, options);
    let log_p = log_softmax(logits, 1);
    let picked = log_p.gather(1, labels.reshape([b, 1, h, w]));
    picked.mean().neg()
}

/// Softmax probabilities over the last dim (for reports).
pub fn probs(z: Tensor<4>) -> Tensor<4> {
    softmax(z, 3)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scalar(t: Tensor<1>) -> f32 {
        t.into_data().try_to_vec::<f32>().unwrap()[0]
    }

    #[test]
    fn action_kl_is_zero_at_the_target_and_matches_a_hand_computation() {
        let device = Device::flex();
        let q = Tensor::<4>::random(
            [2, 6, 4, 28],
            burn::tensor::Distribution::Normal(0.0, 0.02),
            &device,
        );
        // z = Q / T gives exactly the target distribution.
        assert!(
            scalar(action_kl(
                q.clone().div_scalar(TEMPERATURE),
                q.clone(),
                TEMPERATURE
            ))
            .abs()
                < 1e-5
        );
        // One cell by hand: target one-hot-ish (Q/T = [0, ln 3]) over 2 of 28 actions...
        let mut qv = vec![-1e3f32; 28];
        qv[0] = 0.0;
        qv[1] = 3f32.ln() * TEMPERATURE;
        let zv = vec![0.0f32; 28];
        let q = Tensor::<4>::from_data(TensorData::new(qv, [1, 1, 1, 28]), &device);
        let z = Tensor::<4>::from_data(TensorData::new(zv, [1, 1, 1, 28]), &device);
        // p = (1/4, 3/4), q = 1/28 each: KL = 1/4 ln(28/4) + 3/4 ln(3*28/4).
        let expected = 0.25 * (7.0f32).ln() + 0.75 * (21.0f32).ln();
        assert!((scalar(action_kl(z, q, TEMPERATURE)) - expected).abs() < 1e-4);
    }

    #[test]
    fn kd_and_feature_losses() {
        let device = Device::flex();
        let z = Tensor::<4>::random(
            [1, 6, 4, 28],
            burn::tensor::Distribution::Normal(0.0, 1.0),
            &device,
        );
        assert!(scalar(kd_kl(z.clone(), z.clone())).abs() < 1e-5);
        assert!(scalar(kd_kl(z.clone(), z.mul_scalar(2.0))) > 1e-3);
        let f = Tensor::<2>::from_data(
            TensorData::new(vec![1.0f32, 2.0, 3.0, 4.0], [1, 4]),
            &device,
        );
        let g = Tensor::<2>::zeros([1, 4], &device);
        assert!((scalar(feature_mse(f, g)) - 30.0 / 4.0).abs() < 1e-5);
    }

    #[test]
    fn seg_ce_upsamples_and_picks_the_label() {
        let device = Device::flex();
        // 2 classes, 1x1 logits favouring class 1 by ln 3: p(1) = 3/4 everywhere.
        let logits = Tensor::<4>::from_data(
            TensorData::new(vec![0.0f32, 3f32.ln()], [1, 2, 1, 1]),
            &device,
        );
        let ones = Tensor::<3, Int>::ones([1, 4, 4], &device);
        assert!((scalar(seg_ce(logits.clone(), ones)) + 0.75f32.ln()).abs() < 1e-5);
        let zeros = Tensor::<3, Int>::zeros([1, 4, 4], &device);
        assert!((scalar(seg_ce(logits, zeros)) + 0.25f32.ln()).abs() < 1e-5);
    }
}
