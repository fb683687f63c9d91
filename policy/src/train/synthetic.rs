//! A synthetic batch for smoke runs and tests: random images, action values and labels
//! from a seeded ChaCha8 generator.

use super::multires::Batch;
use crate::model::PolicyConfig;
use burn::prelude::*;
use dataset::action::NUM_ACTIONS;
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
    }
}
