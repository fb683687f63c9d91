//! The training losses (docs/protocol.md §4 and §6).

use burn::prelude::*;
use burn::tensor::activation::{log_softmax, softmax};
use burn::tensor::module::interpolate;
use burn::tensor::ops::{InterpolateMode, InterpolateOptions};

/// WoR's temperature for the Boltzmann targets `softmax(Q / T)`.
pub const TEMPERATURE: f32 = 0.01;

/// WoR's command grouping (`rails/rails.py`, `train_main`): the weight of each
/// command's KL for a frame whose route command is `command` (`world::Command` as u8:
/// 0 LEFT, 1 RIGHT, 2 STRAIGHT, 3 LANEFOLLOW, 4/5 CHANGELANE).
///
/// WoR adds two terms per frame: `turn` (mean of the KLs of commands 0-3) on turn
/// frames, else `follow` (command 3); plus `lane` (mean of commands 3-5) on lane-change
/// frames, else `follow`. A follow frame therefore weighs command 3 twice.
pub fn command_weights(command: u8) -> [f32; 6] {
    let mut w = [0.0f32; 6];
    match command {
        0..=2 => {
            for c in w.iter_mut().take(4) {
                *c += 0.25;
            }
        }
        _ => w[3] += 1.0,
    }
    match command {
        4 | 5 => {
            for c in &mut w[3..6] {
                *c += 1.0 / 3.0;
            }
        }
        _ => w[3] += 1.0,
    }
    w
}

/// `KL(p || softmax(z))` for target log-probabilities `log_p` `[B, C, S, A]`, averaged
/// over the speed bins and the actions as WoR's `kl_div(...).mean(dim=[2, 3])`: `[B, C]`.
fn kl_per_command(log_p: Tensor<4>, z: Tensor<4>) -> Tensor<2> {
    let [b, c, _, _] = z.dims();
    kl_terms(log_p, z).mean_dim(3).mean_dim(2).reshape([b, c])
}

/// The terms `p (log p - log softmax(z))` of `KL(p || softmax(z))` over the last dim.
fn kl_terms(log_p: Tensor<4>, z: Tensor<4>) -> Tensor<4> {
    let log_q = log_softmax(z, 3);
    let p = log_p.clone().exp();
    p * (log_p - log_q)
}

/// Action loss: `KL(softmax(Q / T) || softmax(z))` per command (averaged over speed bins
/// and the 28 actions), weighted per sample by `weights` `[B, commands]` (see
/// [`command_weights`]), summed over commands and averaged over the batch.
/// `q`, `z`: `[B, commands, bins, 28]`.
pub fn action_kl(z: Tensor<4>, q: Tensor<4>, weights: Tensor<2>, temperature: f32) -> Tensor<1> {
    let kl = kl_per_command(log_softmax(q.div_scalar(temperature), 3), z);
    (kl * weights).sum_dim(1).mean()
}

/// Teacher knowledge distillation: `KL(softmax(zT) || softmax(z))` summed over commands,
/// speed bins and actions and divided by the batch, as TimeParam does (WOR.md §5: much
/// larger than the action term); the teacher's logits carry no gradient.
pub fn kd_kl(z: Tensor<4>, teacher_z: Tensor<4>) -> Tensor<1> {
    let [b, _, _, _] = z.dims();
    kl_terms(log_softmax(teacher_z.detach(), 3), z)
        .sum()
        .div_scalar(b as f32)
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

    fn follow_weights(n: usize, device: &Device) -> Tensor<2> {
        let w: Vec<f32> = (0..n).flat_map(|_| command_weights(3)).collect();
        Tensor::from_data(TensorData::new(w, [n, 6]), device)
    }

    #[test]
    fn command_weights_follow_wor() {
        assert_eq!(command_weights(3), [0.0, 0.0, 0.0, 2.0, 0.0, 0.0]);
        assert_eq!(command_weights(0), [0.25, 0.25, 0.25, 1.25, 0.0, 0.0]);
        let lane = command_weights(5);
        assert!((lane[3] - 4.0 / 3.0).abs() < 1e-6 && (lane[4] - 1.0 / 3.0).abs() < 1e-6);
        for c in 0..6 {
            assert!((command_weights(c).iter().sum::<f32>() - 2.0).abs() < 1e-6);
        }
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
        let z = q.clone().div_scalar(TEMPERATURE);
        assert!(scalar(action_kl(z, q, follow_weights(2, &device), TEMPERATURE)).abs() < 1e-5);
        // One cell by hand: target (Q/T = [0, ln 3]) over 2 of 28 actions, in command 3
        // and speed bin 0 of a follow frame; every other cell has target = output.
        let mut qv = vec![0.0f32; 6 * 4 * 28];
        for (i, v) in qv.iter_mut().enumerate() {
            let (cell, a) = (i / 28, i % 28);
            if cell == 3 * 4 && a >= 2 {
                *v = -1e3;
            }
        }
        qv[3 * 4 * 28 + 1] = 3f32.ln() * TEMPERATURE;
        let zv: Vec<f32> = qv
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                if i / 28 == 3 * 4 {
                    0.0
                } else {
                    v / TEMPERATURE
                }
            })
            .collect();
        let q = Tensor::<4>::from_data(TensorData::new(qv, [1, 6, 4, 28]), &device);
        let z = Tensor::<4>::from_data(TensorData::new(zv, [1, 6, 4, 28]), &device);
        // p = (1/4, 3/4), q = 1/28 each: KL = 1/4 ln(28/4) + 3/4 ln(3*28/4), averaged over
        // 28 actions and 4 bins, weighted 2 (a follow frame).
        let cell = 0.25 * (7.0f32).ln() + 0.75 * (21.0f32).ln();
        let expected = 2.0 * cell / (28.0 * 4.0);
        let got = scalar(action_kl(z, q, follow_weights(1, &device), TEMPERATURE));
        assert!((got - expected).abs() < 1e-5, "{got} vs {expected}");
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
        assert!(scalar(kd_kl(z.clone(), z.clone().mul_scalar(2.0))) > 1e-3);
        // Summed over cells, divided by the batch: two copies of a sample give the same loss.
        let one = scalar(kd_kl(z.clone(), z.clone().mul_scalar(2.0)));
        let two = scalar(kd_kl(
            Tensor::cat(vec![z.clone(), z.clone()], 0),
            Tensor::cat(vec![z.clone().mul_scalar(2.0), z.mul_scalar(2.0)], 0),
        ));
        assert!((one - two).abs() < 1e-4 * one.max(1.0));
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
