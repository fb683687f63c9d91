//! A labelled dataset opened for training: [`TrainSet`], its usable episodes
//! mapped and every sample listed; a bad episode is [`Skipped`] with the reason.

use std::path::{Path, PathBuf};

use dataset::action::{NUM_COMMANDS, NUM_SPEED_BINS};
use dataset::format::{DataError, INDEX_FILE, Index, MappedLabels, MappedShard};
use dataset::labels::LABEL_VERSION;

use super::error::LoadError;
use crate::model::PolicyConfig;

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

pub(super) struct Part {
    pub(super) shard: MappedShard,
    pub(super) labels: MappedLabels,
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
    /// Further datasets trained on with it, every episode of each (a DAgger round's
    /// `mrdrive train --also`): each folder and its index, in the order given.
    pub also: Vec<(PathBuf, Index)>,
    pub(super) parts: Vec<Part>,
    pub(super) size: [usize; 2],
}

impl TrainSet {
    /// Opens the dataset in `dir` for a policy of `config`; unusable
    /// episodes are skipped (see [`TrainSet::skipped`]).
    pub fn open(dir: &Path, config: &PolicyConfig) -> Result<TrainSet, LoadError> {
        Self::open_first(dir, config, None)
    }

    /// [`TrainSet::open`] on the first `first` episodes of the index only (every
    /// episode when `None`); refuses when any of them is not collected, labelled and
    /// readable, so that a run pinned to them trains on the same samples however
    /// the dataset grows.
    pub fn open_first(
        dir: &Path,
        config: &PolicyConfig,
        first: Option<usize>,
    ) -> Result<TrainSet, LoadError> {
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
        let wanted = first.unwrap_or(index.episodes.len());
        for e in index.episodes.iter().take(wanted) {
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
        let usable = parts.len();
        if first.is_some() && usable < wanted {
            return Err(LoadError::Short {
                dir: dir.to_path_buf(),
                wanted,
                usable,
                first_problem: skipped
                    .first()
                    .map(|s| format!("; {}: {}", s.path.display(), s.why))
                    .unwrap_or_default(),
            });
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
            also: Vec::new(),
            parts,
            size: [h as usize, w as usize],
        })
    }

    /// This set and every labelled episode of each of `dirs`, as one: their samples
    /// after this set's, in the order given. Each must have this set's S0 and camera
    /// views (the same collection settings); an unusable episode is skipped as in
    /// [`TrainSet::open`].
    pub fn with_also(mut self, dirs: &[PathBuf], config: &PolicyConfig) -> Result<Self, LoadError> {
        for dir in dirs {
            let other = Self::open_first(dir, config, None)?;
            if other.index.view_yaws_deg != self.index.view_yaws_deg
                || other.index.frame_every_ticks != self.index.frame_every_ticks
            {
                return Err(LoadError::Mismatch {
                    index: dir.join(INDEX_FILE),
                    found: format!(
                        "views {:?} every {} ticks",
                        other.index.view_yaws_deg, other.index.frame_every_ticks
                    ),
                    want: format!(
                        "views {:?} every {} ticks as {}",
                        self.index.view_yaws_deg,
                        self.index.frame_every_ticks,
                        self.dir.display()
                    ),
                });
            }
            let offset = self.parts.len() as u32;
            self.samples.extend(other.samples.iter().map(|s| SampleRef {
                episode: s.episode + offset,
                ..*s
            }));
            self.parts.extend(other.parts);
            self.skipped.extend(other.skipped);
            self.also.push((dir.clone(), other.index));
        }
        Ok(self)
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::loader::fixtures::{config, write};
    use dataset::synthetic::{self, SyntheticSpec};

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
    fn a_set_pinned_to_its_first_episodes_ignores_later_ones_and_refuses_a_gap() {
        let dir = write(4, 12);
        let all = TrainSet::open(dir.path(), &config()).unwrap();
        let first = TrainSet::open_first(dir.path(), &config(), Some(2)).unwrap();
        // The first two episodes' samples, the same as the whole set's first half.
        assert_eq!(first.samples.len() * 2, all.samples.len());
        assert_eq!(first.samples[..], all.samples[..first.samples.len()]);
        // Episode 1 unlabelled: the pinned set refuses, naming it and the fix; a
        // set pinned to episode 0 alone does not need it.
        let index = Index::load(dir.path()).unwrap();
        std::fs::remove_file(dir.path().join(index.episodes[1].labels.as_ref().unwrap())).unwrap();
        let err = TrainSet::open_first(dir.path(), &config(), Some(2))
            .err()
            .unwrap()
            .to_string();
        assert!(
            err.contains("first 2 episodes")
                && err.contains("1 of them")
                && err.contains("labels-00001")
                && err.contains("mrdrive data study"),
            "{err}"
        );
        assert!(TrainSet::open_first(dir.path(), &config(), Some(1)).is_ok());
        // More than the index holds: refused the same way.
        let err = TrainSet::open_first(dir.path(), &config(), Some(9))
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("first 9 episodes"), "{err}");
    }

    #[test]
    fn a_set_with_others_trains_on_theirs_after_its_own_and_refuses_other_views() {
        let (a, b) = (write(2, 12), write(3, 10));
        let alone = TrainSet::open(a.path(), &config()).unwrap();
        let other = TrainSet::open(b.path(), &config()).unwrap();
        let both = TrainSet::open(a.path(), &config())
            .unwrap()
            .with_also(&[b.path().to_path_buf()], &config())
            .unwrap();
        assert_eq!(
            both.samples.len(),
            alone.samples.len() + other.samples.len()
        );
        assert_eq!(both.samples[..alone.samples.len()], alone.samples[..]);
        // The other set's samples follow, their episodes counted after this set's two.
        let theirs = &both.samples[alone.samples.len()..];
        assert!(theirs.iter().zip(&other.samples).all(|(t, o)| {
            t.episode == o.episode + 2
                && (t.frame, t.view, t.command) == (o.frame, o.view, o.command)
        }));
        // The frames are theirs: the speed of a sample is read from the other shard.
        let (t, o) = (
            theirs[theirs.len() - 1],
            other.samples[other.samples.len() - 1],
        );
        assert_eq!(both.speed_mps(&t), other.speed_mps(&o));
        assert_eq!(both.also.len(), 1);
        assert_eq!(both.also[0].1.episodes.len(), 3);
        // Frames at another spacing: refused, naming the file and both settings.
        let odd = write(1, 10);
        let mut index = Index::load(odd.path()).unwrap();
        index.frame_every_ticks = 5;
        index.save(odd.path()).unwrap();
        let err = TrainSet::open(a.path(), &config())
            .unwrap()
            .with_also(&[odd.path().to_path_buf()], &config());
        let err = err.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(
            err.contains(INDEX_FILE) && err.contains("every 5 ticks"),
            "{err}"
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
