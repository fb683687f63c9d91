//! Which samples an epoch draws, and in which order: the kinds of frame
//! [`Sampling`](super::sampling::Sampling) repeats (starting, pedestrian ahead, stopped vehicle ahead), the
//! standing frames it keeps, and the epoch's shuffle or command-balanced draw.

use dataset::action::{BRAKE, NUM_ACTIONS, NUM_COMMANDS, NUM_SPEED_BINS};
use dataset::decode::{BRAKE_THRESHOLD, interpolate_speed, softmax};
use dataset::format::Q_PER_VIEW;
use rand::RngExt;

use super::config::LoaderConfig;
use super::sampling::STANDING_MPS;
use super::set::{SampleRef, TrainSet};
use crate::train::augment::{mix, sample_rng};
use crate::train::losses::TEMPERATURE;

impl TrainSet {
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
    /// (starting, pedestrian ahead, stopped vehicle ahead) as often as [`Sampling`](super::sampling::Sampling) says.
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::loader::fixtures::{config, write};
    use crate::train::loader::sampling::Sampling;

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
}
