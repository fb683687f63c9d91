//! The prefetch threads: [`Loader`] streams the batches of a [`TrainSet`] from
//! worker threads over bounded channels, batch `g` from worker `g mod workers`.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

use burn::prelude::*;
use dataset::format::DataError;

use super::batch::HostBatch;
use super::config::LoaderConfig;
use super::set::TrainSet;
use crate::model::PolicyConfig;
use crate::train::multires::Batch;

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
    use crate::train::loader::fixtures::{config, write};
    use crate::train::loader::set::SampleRef;

    fn all(set: TrainSet, cfg: LoaderConfig) -> Vec<HostBatch> {
        let mut l = Loader::start(Arc::new(set), &config(), cfg);
        std::iter::from_fn(|| l.next_host()).collect()
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
}
