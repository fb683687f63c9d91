//! A batch's samples read, augmented and normalised on the host
//! ([`TrainSet::host_batch`] into a [`HostBatch`]), then made tensors.

use burn::prelude::*;
use dataset::action::{NUM_ACTIONS, NUM_COMMANDS, NUM_SPEED_BINS};
use dataset::format::{DataError, Q_PER_VIEW};

use super::config::LoaderConfig;
use super::set::{SampleRef, TrainSet};
use crate::model::PolicyConfig;
use crate::train::augment::{Sample as Pixels, augment, mix, sample_rng};
use crate::train::losses::command_weights;
use crate::train::multires::Batch;

impl TrainSet {
    /// The host-side batch of the samples at `order` positions `at`, the
    /// `k`-th sample of the epoch seeded from `(epoch seed, first_k + i)`.
    pub fn host_batch(
        &self,
        config: &PolicyConfig,
        cfg: &LoaderConfig,
        epoch: u64,
        first_k: u64,
        at: &[usize],
    ) -> Result<HostBatch, DataError> {
        let [h, w] = self.size;
        let epoch_seed = mix(cfg.seed, epoch);
        let mut out = HostBatch {
            images: Vec::with_capacity(at.len() * 3 * h * w),
            q: vec![0.0; at.len() * Q_PER_VIEW],
            seg: Vec::with_capacity(at.len() * h * w),
            samples: Vec::with_capacity(at.len()),
            size: [h, w],
        };
        for (i, &pos) in at.iter().enumerate() {
            let s = self.samples[pos];
            let part = &self.parts[s.episode as usize];
            let (f, v) = (s.frame as usize, usize::from(s.view));
            let (mut rgb, mut classes) = part.shard.view_images(f, v)?;
            if let Some(aug) = &cfg.augment {
                let mut rng = sample_rng(epoch_seed, first_k + i as u64);
                let mut px = Pixels {
                    rgb: &mut rgb,
                    classes: &mut classes,
                    width: w,
                    height: h,
                };
                augment(&mut px, aug, &mut rng);
            }
            out.images.extend(config.normalize_rgb8(&rgb, h, w));
            part.labels
                .q_into(f, v, &mut out.q[i * Q_PER_VIEW..(i + 1) * Q_PER_VIEW]);
            out.seg.extend(classes.iter().map(|&c| i64::from(c)));
            out.samples.push(s);
        }
        Ok(out)
    }
}

/// A batch on the host, before it becomes tensors.
#[derive(Debug, Clone, PartialEq)]
pub struct HostBatch {
    /// Normalised images `[B, 3, H0, W0]`.
    pub images: Vec<f32>,
    /// Action values `[B, 6, 4, 28]`.
    pub q: Vec<f32>,
    /// WoR class ids `[B, H0, W0]`.
    pub seg: Vec<i64>,
    /// Which samples, in batch order.
    pub samples: Vec<SampleRef>,
    /// H0, W0 (pixels).
    pub size: [usize; 2],
}

impl HostBatch {
    /// Samples in the batch.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether it holds no sample.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The batch as tensors on `device`.
    pub fn to_batch(&self, device: &Device) -> Batch {
        let (n, [h, w]) = (self.len(), self.size);
        Batch {
            images: Tensor::from_data(TensorData::new(self.images.clone(), [n, 3, h, w]), device),
            q: Tensor::from_data(
                TensorData::new(
                    self.q.clone(),
                    [n, NUM_COMMANDS, NUM_SPEED_BINS, NUM_ACTIONS],
                ),
                device,
            ),
            seg: Tensor::from_data(TensorData::new(self.seg.clone(), [n, h, w]), device),
            cmd_weights: Tensor::from_data(
                TensorData::new(
                    self.samples
                        .iter()
                        .flat_map(|s| command_weights(s.command))
                        .collect::<Vec<f32>>(),
                    [n, NUM_COMMANDS],
                ),
                device,
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::loader::fixtures::{config, write};
    use dataset::synthetic;

    #[test]
    fn a_batch_holds_the_normalised_image_its_label_and_its_classes() {
        let dir = write(1, 8);
        let set = TrainSet::open(dir.path(), &config()).unwrap();
        let cfg = LoaderConfig {
            augment: None,
            ..LoaderConfig::new(4, 1)
        };
        let k = set
            .samples
            .iter()
            .position(|s| (s.frame, s.view) == (2, 1))
            .unwrap();
        let b = set.host_batch(&config(), &cfg, 0, 0, &[k]).unwrap();
        let (h, w) = (8, 24);
        let c = config();
        for (ch, y, x) in [(0, 0, 0), (1, 3, 5), (2, 7, 23)] {
            let byte = synthetic::rgb_byte(x, y, ch, 2, 1, 0);
            let want = (f32::from(byte) / 255.0 - c.mean[ch]) / c.std[ch];
            assert_eq!(b.images[ch * h * w + y * w + x], want);
        }
        for (cmd, bin, a) in [(0, 0, 0), (3, 2, 10), (5, 3, 27)] {
            let at = (cmd * NUM_SPEED_BINS + bin) * NUM_ACTIONS + a;
            assert_eq!(b.q[at], synthetic::q_value(2, 1, cmd, bin, a));
        }
        assert_eq!(b.seg[5], i64::from(synthetic::class_id(5, w, 2, 1)));
        let t = b.to_batch(&Device::flex());
        assert_eq!(t.images.dims(), [1, 3, h, w]);
        assert_eq!(t.q.dims(), [1, 6, 4, 28]);
        assert_eq!(t.seg.dims(), [1, h, w]);
    }
}
