//! The training loader: streams (frame, view) samples of a labelled dataset
//! (`dataset::format`) into [`Batch`]es.
//!
//! - Samples: every camera view of every frame whose label is valid (its
//!   future was driven), over the episodes whose shard and labels are
//!   usable. A bad episode (truncated shard, another S0, labels of another
//!   version, no labels) is skipped and listed in [`TrainSet::skipped`] with
//!   the reason and the fix; the rest is used.
//! - Order: epoch `e` visits the samples in a ChaCha8 shuffle seeded from
//!   `(seed, e)`; with `balanced`, each draw first picks a command uniformly
//!   among those present, then a sample of that command (TimeParam's
//!   command-balanced retargeting data). Batches are whole (the epoch's
//!   remainder is dropped).
//! - Per sample: the view's RGB image, augmented ([`super::augment`], seeded
//!   from `(epoch seed, position in the epoch)`), normalised like the
//!   policy's input (`PolicyConfig::normalize_rgb8`: RGB / 255, ImageNet
//!   mean and std) into `[3, H0, W0]`; `q` `[6, 4, 28]` from the label file;
//!   `seg` `[H0, W0]` the WoR class ids (warped with the image).
//! - Worker threads (one by default) read, augment and normalise, and hand
//!   batches over bounded channels, batch `g` from worker `g mod workers`;
//!   the training step converts them to tensors. Every number depends only
//!   on the dataset, the seed and the configuration, not on the number of
//!   workers or their timing.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use burn::prelude::*;
use dataset::action::{BRAKE, NUM_ACTIONS, NUM_COMMANDS, NUM_SPEED_BINS};
use dataset::decode::{BRAKE_THRESHOLD, interpolate_speed, softmax};
use dataset::format::{DataError, INDEX_FILE, Index, MappedLabels, MappedShard, Q_PER_VIEW};
use dataset::labels::LABEL_VERSION;
use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::augment::{AugmentConfig, Sample as Pixels, augment, mix, sample_rng};
use super::losses::{TEMPERATURE, command_weights};
use super::multires::Batch;
use crate::model::PolicyConfig;

/// Below this speed a frame counts as standing (metres per second).
pub const STANDING_MPS: f32 = 0.5;

/// Which samples an epoch draws and how often: one struct for a stage's spec, the
/// loader and the checkpoint's card (flattened into their JSON). The default is WoR's:
/// every sample once per epoch. A frame that is of several repeated kinds appears the
/// largest of their numbers of times.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Sampling {
    /// Draw commands evenly instead of visiting every sample once per epoch.
    pub balanced: bool,
    /// The share of standing frames (ego below [`STANDING_MPS`]) kept, in [0, 1]: a
    /// fixed subset chosen by the seed (1 keeps all). Waiting at red lights fills a third
    /// of our data; fewer of those frames weaken the "junction ahead: brake" prior.
    pub standing_keep: f64,
    /// How many times each kept starting frame ([`TrainSet::starts`]: standing, and
    /// the target goes, as when the light has just turned green) appears per epoch (1:
    /// once). They are about one standing frame in 25.
    pub start_repeat: usize,
    /// How many times each kept frame with a pedestrian ahead
    /// ([`TrainSet::pedestrian_ahead`]) appears per epoch (1: once).
    pub pedestrian_repeat: usize,
    /// How many times each kept frame with a stopped vehicle ahead
    /// ([`TrainSet::stopped_vehicle_ahead`]: a queue at a light, a car waiting) appears
    /// per epoch (1: once). At the paper's densities they are under 1 % of the frames.
    pub stopped_vehicle_repeat: usize,
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling {
            balanced: false,
            standing_keep: 1.0,
            start_repeat: 1,
            pedestrian_repeat: 1,
            stopped_vehicle_repeat: 1,
        }
    }
}

impl Sampling {
    /// A phrase for a model card: how the samples were drawn (", commands drawn
    /// evenly, starting frames 8 times").
    pub fn describe(&self) -> String {
        let mut s = String::from(if self.balanced {
            ", commands drawn evenly"
        } else {
            ", every sample once per epoch"
        });
        if self.standing_keep < 1.0 {
            s += &format!(", {} of the standing frames", self.standing_keep);
        }
        for (n, what) in [
            (self.start_repeat, "starting frames"),
            (self.pedestrian_repeat, "frames with a pedestrian ahead"),
            (
                self.stopped_vehicle_repeat,
                "frames with a stopped vehicle ahead",
            ),
        ] {
            if n > 1 {
                s += &format!(", {what} {n} times");
            }
        }
        s
    }
}

/// How the loader samples and augments.
#[derive(Debug, Clone, PartialEq)]
pub struct LoaderConfig {
    /// Samples per batch.
    pub batch: usize,
    /// Seed of the sample order and the augmentations.
    pub seed: u64,
    /// Augment (WoR's ops); `None` feeds the images as stored (BN recalibration, evaluation).
    pub augment: Option<AugmentConfig>,
    /// Which samples an epoch draws and how often.
    pub sampling: Sampling,
    /// The first epoch (to resume a run where it stopped).
    pub first_epoch: u64,
    /// Batches of the first epoch to leave out (to resume a run mid-epoch); the
    /// batches that follow are the same as in an uninterrupted stream.
    pub first_batch: usize,
    /// Epochs to stream; `None` streams until the loader is dropped.
    pub epochs: Option<u64>,
    /// Batches prepared ahead of the training step (over all workers).
    pub queue: usize,
    /// Worker threads (1 keeps one core for the loader on a 2-core CPU;
    /// more for a GPU step, which wants more samples per second). The
    /// batches are the same for any number.
    pub workers: usize,
}

impl LoaderConfig {
    /// Batches of `batch`, seed `seed`, WoR's augmentations, every sample
    /// once per epoch, forever, 4 batches ahead, one worker thread.
    pub fn new(batch: usize, seed: u64) -> LoaderConfig {
        LoaderConfig {
            batch,
            seed,
            augment: Some(AugmentConfig::default()),
            sampling: Sampling::default(),
            first_epoch: 0,
            first_batch: 0,
            epochs: None,
            queue: 4,
            workers: 1,
        }
    }
}

/// Why a dataset cannot feed training.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The index is missing or unreadable.
    #[error(transparent)]
    Data(#[from] DataError),
    /// The directory has nothing in it.
    #[error(
        "{0}: the dataset directory is empty; collect into it with `mrdrive collect --out {0}`, then label it with `mrdrive label {0}`"
    )]
    EmptyDir(PathBuf),
    /// No episode gave a labelled frame.
    #[error(
        "{dir}: no labelled frame to train on ({episodes} episodes in the index{skipped}); label the dataset with `mrdrive label {dir}`"
    )]
    NoSamples {
        /// The dataset directory.
        dir: PathBuf,
        /// Episodes in the index.
        episodes: usize,
        /// The skipped files, as text.
        skipped: String,
    },
    /// The dataset's images are not the size the policy takes.
    #[error(
        "{index}: s0 is {w} x {h} but the policy takes {pw} x {ph}; train a policy config with input_width {w} and input_height {h}, or collect at the policy's size"
    )]
    Size {
        /// The index file.
        index: PathBuf,
        /// The dataset's width.
        w: u32,
        /// The dataset's height.
        h: u32,
        /// The policy's width.
        pw: usize,
        /// The policy's height.
        ph: usize,
    },
    /// The policy's head does not have WoR's commands and speed bins.
    #[error(
        "policy config num_commands {commands} and num_speed_bins {bins}: the labels have {NUM_COMMANDS} and {NUM_SPEED_BINS}; use those"
    )]
    Head {
        /// The config's commands.
        commands: usize,
        /// The config's speed bins.
        bins: usize,
    },
}

/// An episode the loader could not use, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Skipped {
    /// The file at fault.
    pub path: PathBuf,
    /// What is wrong and how to fix it.
    pub why: String,
}

/// One training sample: a view of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleRef {
    /// The episode's position among the usable episodes.
    pub episode: u32,
    /// The frame in its shard.
    pub frame: u32,
    /// The camera view.
    pub view: u8,
    /// The frame's command (`world::Command` as u8).
    pub command: u8,
}

struct Part {
    shard: MappedShard,
    labels: MappedLabels,
}

/// A labelled dataset opened for training: its usable episodes mapped.
pub struct TrainSet {
    /// The dataset directory.
    pub dir: PathBuf,
    /// Its index.
    pub index: Index,
    /// Every usable sample, in index order.
    pub samples: Vec<SampleRef>,
    /// Episodes left out, and why.
    pub skipped: Vec<Skipped>,
    parts: Vec<Part>,
    size: [usize; 2],
}

impl TrainSet {
    /// Opens the dataset in `dir` for a policy of `config`; unusable
    /// episodes are skipped (see [`TrainSet::skipped`]).
    pub fn open(dir: &Path, config: &PolicyConfig) -> Result<TrainSet, LoadError> {
        if config.num_commands != NUM_COMMANDS || config.num_speed_bins != NUM_SPEED_BINS {
            return Err(LoadError::Head {
                commands: config.num_commands,
                bins: config.num_speed_bins,
            });
        }
        if dir.is_dir()
            && std::fs::read_dir(dir)
                .map(|mut d| d.next().is_none())
                .unwrap_or(false)
        {
            return Err(LoadError::EmptyDir(dir.to_path_buf()));
        }
        let index = Index::load(dir)?;
        let [w, h] = index.s0;
        if (w as usize, h as usize) != (config.input_width, config.input_height) {
            return Err(LoadError::Size {
                index: dir.join(INDEX_FILE),
                w,
                h,
                pw: config.input_width,
                ph: config.input_height,
            });
        }
        let views = index.view_yaws_deg.len();
        let mut parts = Vec::new();
        let mut skipped = Vec::new();
        let mut samples = Vec::new();
        for e in &index.episodes {
            let shard_path = dir.join(&e.shard);
            let Some(labels_name) = &e.labels else {
                skipped.push(Skipped {
                    path: shard_path,
                    why: format!("no labels; run `mrdrive label {}`", dir.display()),
                });
                continue;
            };
            let opened = MappedShard::open(&shard_path, index.s0, views).and_then(|shard| {
                let labels =
                    MappedLabels::open(&dir.join(labels_name), LABEL_VERSION, shard.len(), views)?;
                Ok(Part { shard, labels })
            });
            let part = match opened {
                Ok(p) => p,
                Err(err) => {
                    let path = match &err {
                        DataError::Io { path, .. }
                        | DataError::Index { path, .. }
                        | DataError::Shard { path, .. } => path.clone(),
                    };
                    skipped.push(Skipped {
                        path,
                        why: err.to_string(),
                    });
                    continue;
                }
            };
            let episode = parts.len() as u32;
            for (f, &valid) in part.labels.valid.iter().enumerate() {
                if valid {
                    for v in 0..views {
                        samples.push(SampleRef {
                            episode,
                            frame: f as u32,
                            view: v as u8,
                            command: part.shard.state.command[f],
                        });
                    }
                }
            }
            parts.push(part);
        }
        if samples.is_empty() {
            let skipped = skipped
                .iter()
                .map(|s| format!("; skipped {}: {}", s.path.display(), s.why))
                .collect();
            return Err(LoadError::NoSamples {
                dir: dir.to_path_buf(),
                episodes: index.episodes.len(),
                skipped,
            });
        }
        Ok(TrainSet {
            dir: dir.to_path_buf(),
            index,
            samples,
            skipped,
            parts,
            size: [h as usize, w as usize],
        })
    }

    /// The ego's speed at a sample's frame (metres per second).
    pub fn speed_mps(&self, s: &SampleRef) -> f32 {
        self.parts[s.episode as usize].shard.state.ego[s.frame as usize].speed
    }

    /// Samples per command (`world::Command` as index).
    pub fn per_command(&self) -> [usize; NUM_COMMANDS] {
        let mut n = [0; NUM_COMMANDS];
        for s in &self.samples {
            n[usize::from(s.command)] += 1;
        }
        n
    }

    /// Whether sample `s` is a starting frame: the ego stands (below
    /// [`STANDING_MPS`]) and its target, softmax(Q / T) at its command and speed, puts
    /// at most [`BRAKE_THRESHOLD`] on the brake (`policy fit`'s rule).
    pub fn starts(&self, s: &SampleRef) -> bool {
        let speed = self.speed_mps(s);
        if speed >= STANDING_MPS {
            return false;
        }
        let mut q = [0.0; Q_PER_VIEW];
        let part = &self.parts[s.episode as usize];
        part.labels
            .q_into(s.frame as usize, usize::from(s.view), &mut q);
        let c = usize::from(s.command);
        let bins: [[f32; NUM_ACTIONS]; NUM_SPEED_BINS] = std::array::from_fn(|k| {
            std::array::from_fn(|j| q[(c * NUM_SPEED_BINS + k) * NUM_ACTIONS + j] / TEMPERATURE)
        });
        softmax(&interpolate_speed(&bins, speed))[BRAKE] <= BRAKE_THRESHOLD
    }

    /// Whether a pedestrian stands or walks in the ego's corridor straight
    /// ahead at sample `s`'s frame, within
    /// [`dataset::format::PEDESTRIAN_AHEAD_M`] (the rule book's "ahead").
    pub fn pedestrian_ahead(&self, s: &SampleRef) -> bool {
        let state = &self.parts[s.episode as usize].shard.state;
        let f = s.frame as usize;
        dataset::format::pedestrian_ahead(&state.ego[f], &state.actors[f]).is_some()
    }

    /// Whether a stopped vehicle stands in the ego's corridor straight ahead at sample
    /// `s`'s frame ([`dataset::format::stopped_vehicle_ahead`]).
    pub fn stopped_vehicle_ahead(&self, s: &SampleRef) -> bool {
        let state = &self.parts[s.episode as usize].shard.state;
        let f = s.frame as usize;
        dataset::format::stopped_vehicle_ahead(&state.ego[f], &state.actors[f]).is_some()
    }

    /// Whether sample `s` is used under `cfg`'s `standing_keep` (the same answer for every
    /// view of a frame and every epoch).
    pub fn kept(&self, cfg: &LoaderConfig, s: &SampleRef) -> bool {
        let keep = cfg.sampling.standing_keep;
        if keep >= 1.0 || self.speed_mps(s) >= STANDING_MPS {
            return true;
        }
        let frame = (u64::from(s.episode) << 32) | u64::from(s.frame);
        let u = (mix(cfg.seed ^ 0x57a4d, frame) >> 11) as f64 / (1u64 << 53) as f64;
        u < keep
    }

    /// Samples per epoch under `cfg`: those [`TrainSet::kept`], each of a repeated kind
    /// (starting, pedestrian ahead, stopped vehicle ahead) as often as [`Sampling`] says.
    pub fn epoch_len(&self, cfg: &LoaderConfig) -> usize {
        self.pool(cfg).len()
    }

    /// The positions in [`TrainSet::samples`] one epoch draws from, in sample order.
    fn pool(&self, cfg: &LoaderConfig) -> Vec<usize> {
        let mut pool = Vec::with_capacity(self.samples.len());
        for (i, s) in self.samples.iter().enumerate() {
            if !self.kept(cfg, s) {
                continue;
            }
            let sampling = &cfg.sampling;
            let mut copies = 1;
            if sampling.start_repeat > copies && self.starts(s) {
                copies = sampling.start_repeat;
            }
            if sampling.pedestrian_repeat > copies && self.pedestrian_ahead(s) {
                copies = sampling.pedestrian_repeat;
            }
            if sampling.stopped_vehicle_repeat > copies && self.stopped_vehicle_ahead(s) {
                copies = sampling.stopped_vehicle_repeat;
            }
            pool.extend(std::iter::repeat_n(i, copies));
        }
        pool
    }

    /// The order of epoch `epoch`: positions in [`TrainSet::samples`].
    pub fn epoch_order(&self, cfg: &LoaderConfig, epoch: u64) -> Vec<usize> {
        let mut rng = sample_rng(cfg.seed, epoch);
        let pool = self.pool(cfg);
        let n = pool.len();
        if cfg.sampling.balanced {
            let mut by_command: Vec<Vec<usize>> = vec![Vec::new(); NUM_COMMANDS];
            for &i in &pool {
                by_command[usize::from(self.samples[i].command)].push(i);
            }
            by_command.retain(|c| !c.is_empty());
            (0..n)
                .map(|_| {
                    let c = &by_command[rng.random_range(0..by_command.len())];
                    c[rng.random_range(0..c.len())]
                })
                .collect()
        } else {
            let mut order = pool;
            for i in (1..n).rev() {
                order.swap(i, rng.random_range(0..=i));
            }
            order
        }
    }

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

/// Streams batches of a [`TrainSet`] from worker threads.
pub struct Loader {
    /// One channel per worker; batch `g` comes from worker `g mod workers`.
    rx: Vec<Receiver<Result<HostBatch, DataError>>>,
    workers: Vec<JoinHandle<()>>,
    next: usize,
    /// Why the stream ended early (a frame that could not be read), once it has.
    failure: Option<DataError>,
    /// Batches per epoch.
    pub batches_per_epoch: usize,
}

impl Loader {
    /// Starts the workers. `set` is shared with them; `config` says how to normalise.
    pub fn start(set: Arc<TrainSet>, config: &PolicyConfig, cfg: LoaderConfig) -> Loader {
        let batch = cfg.batch.max(1);
        let batches_per_epoch = set.epoch_len(&cfg) / batch;
        let n = cfg.workers.max(1);
        let mut rx = Vec::with_capacity(n);
        let mut workers = Vec::with_capacity(n);
        for w in 0..n {
            let (tx, r) = sync_channel(cfg.queue.div_ceil(n).max(1));
            let (set, config, cfg) = (set.clone(), config.clone(), cfg.clone());
            let worker = std::thread::Builder::new()
                .name(format!("mrdrive-loader-{w}"))
                .spawn(move || produce(&set, &config, &cfg, batch, (w, n), &tx))
                .expect("a loader thread starts");
            rx.push(r);
            workers.push(worker);
        }
        Loader {
            rx,
            workers,
            next: 0,
            batches_per_epoch,
            failure: None,
        }
    }

    /// The next batch on the host, or `None` after the last epoch, or when a frame
    /// could not be read ([`Loader::failure`] then says why).
    pub fn next_host(&mut self) -> Option<HostBatch> {
        if self.failure.is_some() {
            return None;
        }
        let n = self.rx.len();
        match self.rx.get(self.next % n.max(1))?.recv().ok()? {
            Ok(b) => {
                self.next += 1;
                Some(b)
            }
            Err(e) => {
                self.failure = Some(e);
                None
            }
        }
    }

    /// Why the stream ended before its last epoch, if it did: a frame of the dataset
    /// could not be read (a damaged shard). Taken once.
    pub fn failure(&mut self) -> Option<DataError> {
        self.failure.take()
    }

    /// The next batch as tensors on `device`, or `None` after the last epoch.
    pub fn next_batch(&mut self, device: &Device) -> Option<Batch> {
        self.next_host().map(|b| b.to_batch(device))
    }
}

/// Worker `w` of `n`: makes every batch `g` of the stream with `g mod n = w`.
fn produce(
    set: &TrainSet,
    config: &PolicyConfig,
    cfg: &LoaderConfig,
    batch: usize,
    (w, n): (usize, usize),
    tx: &SyncSender<Result<HostBatch, DataError>>,
) {
    let mut epoch = cfg.first_epoch;
    let mut g = 0usize;
    loop {
        if cfg.epochs.is_some_and(|e| epoch >= cfg.first_epoch + e) {
            return;
        }
        let order = set.epoch_order(cfg, epoch);
        let skip = if epoch == cfg.first_epoch {
            cfg.first_batch
        } else {
            0
        };
        for (b, at) in order.chunks_exact(batch).enumerate().skip(skip) {
            if g % n == w {
                let hb = set.host_batch(config, cfg, epoch, (b * batch) as u64, at);
                let failed = hb.is_err();
                if tx.send(hb).is_err() || failed {
                    return; // the loader was dropped, or the stream cannot go on
                }
            }
            g += 1;
        }
        if order.len() < batch {
            return; // not one whole batch: nothing to stream
        }
        epoch += 1;
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        // Closing the channels makes each worker's next send fail, so it ends.
        self.rx.clear();
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backbone::Depth;
    use dataset::synthetic::{self, SyntheticSpec};

    fn config() -> PolicyConfig {
        PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(8)
            .with_input_width(24)
    }

    fn write(episodes: u32, frames: u32) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        synthetic::write(dir.path(), &SyntheticSpec::tiny(episodes, frames)).unwrap();
        dir
    }

    fn all(set: TrainSet, cfg: LoaderConfig) -> Vec<HostBatch> {
        let mut l = Loader::start(Arc::new(set), &config(), cfg);
        std::iter::from_fn(|| l.next_host()).collect()
    }

    #[test]
    fn samples_are_every_view_of_every_labelled_frame() {
        let dir = write(2, 12);
        let set = TrainSet::open(dir.path(), &config()).unwrap();
        // 12 - 5 labelled frames, 3 views, 2 episodes.
        assert_eq!(set.samples.len(), 2 * 7 * 3);
        assert!(set.skipped.is_empty());
        assert!(set.samples.iter().all(|s| (s.frame as usize) < 7));
        // Frames 4 (LEFT) and 0-3, 5, 6 (LANEFOLLOW) of each episode.
        assert_eq!(set.per_command()[0], 2 * 3);
        assert_eq!(set.per_command()[3], 2 * 6 * 3);
    }

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

    #[test]
    fn batches_are_the_same_for_a_seed_and_differ_for_another() {
        let dir = write(2, 12);
        let cfg = |seed| LoaderConfig {
            epochs: Some(2),
            queue: 1,
            ..LoaderConfig::new(5, seed)
        };
        let open = || TrainSet::open(dir.path(), &config()).unwrap();
        let a = all(open(), cfg(7));
        let b = all(open(), cfg(7));
        assert_eq!(a.len(), 2 * (42 / 5));
        assert_eq!(a, b);
        let c = all(open(), cfg(8));
        assert_ne!(a[0].samples, c[0].samples);
        let three = all(
            open(),
            LoaderConfig {
                workers: 3,
                queue: 5,
                ..cfg(7)
            },
        );
        assert_eq!(three, a, "three workers give the same stream");
        // Resuming at epoch 1, batch 3 streams exactly the rest of the stream.
        let resumed = all(
            open(),
            LoaderConfig {
                first_epoch: 1,
                first_batch: 3,
                epochs: Some(1),
                workers: 2,
                ..cfg(7)
            },
        );
        assert_eq!(resumed, a[8 + 3..].to_vec());
        // Each epoch visits each sample at most once, and the epochs differ.
        let first: Vec<SampleRef> = a[..8].iter().flat_map(|b| b.samples.clone()).collect();
        let mut dedup = first.clone();
        dedup.sort_by_key(|s| (s.episode, s.frame, s.view));
        dedup.dedup();
        assert_eq!(dedup.len(), first.len());
        assert_ne!(a[0].samples, a[8].samples);
        // Augmentation changed the images (a fixed seed, so a fixed answer).
        let plain = all(
            open(),
            LoaderConfig {
                augment: None,
                ..cfg(7)
            },
        );
        assert_eq!(plain[0].samples, a[0].samples);
        assert_ne!(plain[0].images, a[0].images);
    }

    #[test]
    fn standing_frames_are_thinned_by_a_fixed_seeded_subset_and_starting_frames_repeat() {
        let dir = write(2, 40);
        let set = TrainSet::open(dir.path(), &config()).unwrap();
        let standing = |s: &SampleRef| set.speed_mps(s) < STANDING_MPS;
        // The synthetic ego stands every 5th frame; its target brakes at red lights
        // (frames 0-9, 20-29) and goes at green (10-19, 30-34).
        for s in &set.samples {
            let green = (s.frame / 10) % 2 == 1;
            assert_eq!(set.starts(s), standing(s) && green, "{s:?}");
        }
        let standing_n = set.samples.iter().filter(|s| standing(s)).count();
        assert!(standing_n > 0 && standing_n < set.samples.len());
        let all = LoaderConfig::new(5, 3);
        assert_eq!(set.epoch_len(&all), set.samples.len());
        let none = LoaderConfig {
            sampling: Sampling {
                standing_keep: 0.0,
                ..Sampling::default()
            },
            ..all.clone()
        };
        assert_eq!(set.epoch_len(&none), set.samples.len() - standing_n);
        assert!(
            set.epoch_order(&none, 0)
                .iter()
                .all(|&i| !standing(&set.samples[i]))
        );
        let half = LoaderConfig {
            sampling: Sampling {
                standing_keep: 0.5,
                ..Sampling::default()
            },
            ..all.clone()
        };
        let kept = set.epoch_len(&half) - (set.samples.len() - standing_n);
        assert!(kept > 0 && kept < standing_n, "{kept} of {standing_n}");
        // The same frames in every epoch, and all views of a frame together.
        let frames = |e| {
            let mut f: Vec<(u32, u32)> = set
                .epoch_order(&half, e)
                .iter()
                .map(|&i| (set.samples[i].episode, set.samples[i].frame))
                .collect();
            f.sort();
            f
        };
        assert_eq!(frames(0), frames(1));
        assert_eq!(kept % 3, 0);
        // Each kept starting frame three times an epoch, in either sampling.
        let starting = set
            .samples
            .iter()
            .filter(|s| set.starts(s) && set.kept(&all, s))
            .count();
        assert!(starting > 0);
        for balanced in [false, true] {
            let thrice = LoaderConfig {
                sampling: Sampling {
                    start_repeat: 3,
                    balanced,
                    ..Sampling::default()
                },
                ..all.clone()
            };
            assert_eq!(set.epoch_len(&thrice), set.samples.len() + 2 * starting);
            let order = set.epoch_order(&thrice, 0);
            assert_eq!(order.len(), set.epoch_len(&thrice));
            if !balanced {
                let starts = order
                    .iter()
                    .filter(|&&i| set.starts(&set.samples[i]))
                    .count();
                assert_eq!(starts, 3 * starting);
            }
        }
    }

    #[test]
    fn frames_with_a_pedestrian_ahead_repeat() {
        let dir = write(2, 40);
        let set = TrainSet::open(dir.path(), &config()).unwrap();
        // The synthetic walker crosses 8 m ahead of the ego when frame mod 7 = 3.
        for s in &set.samples {
            assert_eq!(set.pedestrian_ahead(s), s.frame % 7 == 3, "{s:?}");
        }
        let ahead = set
            .samples
            .iter()
            .filter(|s| set.pedestrian_ahead(s))
            .count();
        let both = set
            .samples
            .iter()
            .filter(|s| set.pedestrian_ahead(s) && set.starts(s))
            .count();
        assert!(ahead > 0);
        let all = LoaderConfig::new(5, 3);
        let four = LoaderConfig {
            sampling: Sampling {
                pedestrian_repeat: 4,
                ..Sampling::default()
            },
            ..all.clone()
        };
        assert_eq!(set.epoch_len(&four), set.samples.len() + 3 * ahead);
        let order = set.epoch_order(&four, 0);
        let drawn = order
            .iter()
            .filter(|&&i| set.pedestrian_ahead(&set.samples[i]))
            .count();
        assert_eq!(drawn, 4 * ahead);
        // With starting frames repeated too, a frame that is both counts once, at the larger.
        let starts = set.samples.iter().filter(|s| set.starts(s)).count();
        let mixed = LoaderConfig {
            sampling: Sampling {
                start_repeat: 2,
                ..four.sampling.clone()
            },
            ..four
        };
        assert_eq!(
            set.epoch_len(&mixed),
            set.samples.len() + 3 * ahead + (starts - both)
        );
    }

    #[test]
    fn frames_with_a_stopped_vehicle_ahead_repeat() {
        let dir = write(2, 40);
        let set = TrainSet::open(dir.path(), &config()).unwrap();
        // The synthetic car 15 m ahead stands when frame mod 6 = 2.
        for s in &set.samples {
            assert_eq!(set.stopped_vehicle_ahead(s), s.frame % 6 == 2, "{s:?}");
        }
        let ahead = set
            .samples
            .iter()
            .filter(|s| set.stopped_vehicle_ahead(s))
            .count();
        assert!(ahead > 0);
        let five = LoaderConfig {
            sampling: Sampling {
                stopped_vehicle_repeat: 5,
                ..Sampling::default()
            },
            ..LoaderConfig::new(5, 3)
        };
        assert_eq!(set.epoch_len(&five), set.samples.len() + 4 * ahead);
        let drawn = set
            .epoch_order(&five, 0)
            .iter()
            .filter(|&&i| set.stopped_vehicle_ahead(&set.samples[i]))
            .count();
        assert_eq!(drawn, 5 * ahead);
    }

    #[test]
    fn balanced_sampling_draws_each_command_about_equally() {
        let dir = write(2, 40);
        let set = TrainSet::open(dir.path(), &config()).unwrap();
        // LEFT is one frame in five.
        let [left, .., follow, _, _] = set.per_command().map(|n| n as f32);
        assert!(follow > 3.0 * left);
        let cfg = LoaderConfig {
            sampling: Sampling {
                balanced: true,
                ..Sampling::default()
            },
            ..LoaderConfig::new(5, 3)
        };
        let mut drawn = [0usize; NUM_COMMANDS];
        for e in 0..5 {
            for k in set.epoch_order(&cfg, e) {
                drawn[usize::from(set.samples[k].command)] += 1;
            }
        }
        let share = drawn[0] as f32 / (drawn[0] + drawn[3]) as f32;
        assert!((0.45..0.55).contains(&share), "{drawn:?}");
    }

    #[test]
    fn a_bad_shard_is_skipped_by_name_and_the_rest_used() {
        let dir = write(4, 10);
        let index = Index::load(dir.path()).unwrap();
        // Episode 0: truncated. Episode 1: another S0. Episode 2: labels of
        // another version. Episode 3: fine.
        let p0 = dir.path().join(&index.episodes[0].shard);
        let bytes = std::fs::read(&p0).unwrap();
        std::fs::write(&p0, &bytes[..bytes.len() - 100]).unwrap();
        let other = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            s0: [12, 4],
            ..SyntheticSpec::tiny(2, 10)
        };
        synthetic::write(other.path(), &spec).unwrap();
        let p1 = dir.path().join(&index.episodes[1].shard);
        std::fs::copy(other.path().join(&index.episodes[1].shard), &p1).unwrap();
        let l2 = dir.path().join(index.episodes[2].labels.as_ref().unwrap());
        std::fs::write(
            &l2,
            synthetic::labels(10, 3).to_bytes(LABEL_VERSION + 1, "x"),
        )
        .unwrap();
        let set = TrainSet::open(dir.path(), &config()).unwrap();
        assert_eq!(set.samples.len(), 5 * 3);
        let why: Vec<String> = set
            .skipped
            .iter()
            .map(|s| format!("{}: {}", s.path.display(), s.why))
            .collect();
        assert_eq!(why.len(), 3, "{why:?}");
        assert!(
            why[0].contains("episode-00000") && why[0].contains("truncated"),
            "{}",
            why[0]
        );
        assert!(
            why[1].contains("episode-00001") && why[1].contains("another dataset or S0"),
            "{}",
            why[1]
        );
        assert!(
            why[2].contains("labels-00002") && why[2].contains("mrdrive label"),
            "{}",
            why[2]
        );
    }

    #[test]
    fn an_empty_or_unindexed_or_unlabelled_dataset_says_what_to_run() {
        let empty = tempfile::tempdir().unwrap();
        let err = TrainSet::open(empty.path(), &config())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("empty") && err.contains("mrdrive collect"),
            "{err}"
        );
        std::fs::write(empty.path().join("notes.txt"), "x").unwrap();
        let err = TrainSet::open(empty.path(), &config())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains(INDEX_FILE) && err.contains("mrdrive collect"),
            "{err}"
        );
        let dir = tempfile::tempdir().unwrap();
        let spec = SyntheticSpec {
            labelled: false,
            ..SyntheticSpec::tiny(1, 10)
        };
        synthetic::write(dir.path(), &spec).unwrap();
        let err = TrainSet::open(dir.path(), &config())
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("no labelled frame") && err.contains("mrdrive label"),
            "{err}"
        );
        let wide = config().with_input_width(48);
        let dir = write(1, 10);
        let err = TrainSet::open(dir.path(), &wide).err().unwrap().to_string();
        assert!(
            err.contains("24 x 8") && err.contains("input_width"),
            "{err}"
        );
    }
}
