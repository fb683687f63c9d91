//! A learned trigger: a logistic head on the policy's pooled backbone
//! feature that says when the high input scale is needed, so a selector can
//! switch without a map (the paper's future work, §VI-1; the `learned`
//! selector, [`sim::selector::Learned`]).
//!
//! **What it learns.** The shipped multi-resolution policy drives each frame
//! through its low- and high-scale BN branches. Where the two branches'
//! action distributions (softmax of the 28 logits for the frame's command at
//! its speed) differ most, the low scale loses something the high one sees.
//! A frame is a positive when their total-variation distance is in the top
//! `positive_share` of the training frames; the head learns that from the
//! pooled feature of either branch (each frame gives one sample per branch,
//! so the head also works on whichever scale the car is driving at). No
//! label of the dataset is read: only its images, commands and speeds.
//!
//! **Or what the difference costs** ([`Target::Regret`]). Branches also
//! disagree where it does not matter: two steering cells of equal value as
//! the car weaves in its lane. The regret target weighs the disagreement by
//! the frame's world-on-rails action values: the value the high branch's
//! distribution expects, `sum_a p_high(a) Q(a)`, less the low branch's, for
//! the frame's command at its speed. A frame is a positive when that loss is
//! in the top `positive_share` (and above zero). Frames without a label are
//! left out of such a fit.
//!
//! **The fit.** Features are standardised, then a logistic regression is fit
//! by full-batch gradient descent with L2, positives weighted up to balance
//! the classes. Deterministic: the frames are read in dataset order, every
//! sum in a fixed order. Episodes whose plan index is 4 mod 5 are held out.

use std::path::{Path, PathBuf};

use dataset::action::{NUM_ACTIONS, NUM_SPEED_BINS};
use dataset::decode::{interpolate_speed, softmax};
use dataset::format::{Index, MappedLabels, MappedShard, Q_PER_VIEW};
use dataset::labels::LABEL_VERSION;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sim::driver::RgbImage;
use sim::render::resize::{Filter, resize_rgb};

use crate::fused::FusedPolicy;

/// The `format` of a trigger file.
pub const TRIGGER_FORMAT: &str = "mrdrive-trigger/1";

/// A trained trigger: `p = sigmoid(w . (f - mean) / std + b)` on the pooled
/// feature `f` of either BN branch.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trigger {
    /// Always [`TRIGGER_FORMAT`].
    pub format: String,
    /// The scales it chooses between (fractions of S0).
    pub low: f32,
    /// The high scale.
    pub high: f32,
    /// Feature means (the standardisation), one per feature.
    pub mean: Vec<f32>,
    /// Feature standard deviations.
    pub std: Vec<f32>,
    /// Weights on the standardised features.
    pub weights: Vec<f32>,
    /// Bias.
    pub bias: f32,
    /// How it was made and how well it does.
    pub card: TriggerCard,
}

/// Where a trigger came from and what it scores on held-out episodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TriggerCard {
    /// The policy checkpoint whose features and branches it reads.
    pub checkpoint: String,
    /// That checkpoint's SHA-256 when the trigger was fit: a policy driver refuses a
    /// trigger fit on another network (absent in files written before 2026-12-07).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint_sha256: Option<String>,
    /// The dataset it was fit on.
    pub data: String,
    /// Every how many frames one was used.
    pub every: usize,
    /// Frames in the fit and in the held-out episodes.
    pub frames_fit: usize,
    /// Held-out frames.
    pub frames_held_out: usize,
    /// Share of fit frames called positive.
    pub positive_share: f32,
    /// What a positive is (files written before there was a choice: disagreement).
    #[serde(default)]
    pub target: Target,
    /// The target's score at and above which a frame is positive: the
    /// total-variation distance, or the regret (reward units).
    pub tv_threshold: f32,
    /// Gradient-descent epochs.
    pub epochs: usize,
    /// Learning rate.
    pub lr: f32,
    /// L2 weight.
    pub l2: f32,
    /// Held-out scores at p >= 0.5, over both branches' samples.
    pub held_out: Scores,
    /// Fit scores at p >= 0.5.
    pub fit: Scores,
}

impl TriggerCard {
    /// What the fit did, three lines (`mrdrive policy trigger`): the frames and
    /// what a positive is, then the scores on the fit and on the held-out episodes.
    pub fn report(&self) -> String {
        use std::fmt::Write;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{} frames fit, {} held out (episodes 4 mod 5); positive: {} >= {:.3} (top {:.0} %)",
            self.frames_fit,
            self.frames_held_out,
            match self.target {
                Target::Disagreement => "total variation",
                Target::Regret => "regret",
            },
            self.tv_threshold,
            100.0 * self.positive_share
        );
        for (name, s) in [("fit", self.fit), ("held out", self.held_out)] {
            let _ = writeln!(
                out,
                "{name:<9} n {:>6}  positive {:>5.1} %  predicted {:>5.1} %  accuracy {:>5.1} %  recall {:>5.1} %  precision {:>5.1} %",
                s.n,
                100.0 * s.positive_rate,
                100.0 * s.predicted_rate,
                100.0 * s.accuracy,
                100.0 * s.recall,
                100.0 * s.precision
            );
        }
        out
    }

    /// Whether a trigger with this card answers the fit `asked` describes (the same
    /// network by digest, data, frames, target, share and scales): `mrdrive policy
    /// trigger` then leaves the file as it is.
    pub fn fits_the_same(&self, asked: &TriggerCard) -> bool {
        self.checkpoint_sha256.is_some()
            && self.checkpoint_sha256 == asked.checkpoint_sha256
            && self.data == asked.data
            && self.every == asked.every
            && self.target == asked.target
            && self.positive_share == asked.positive_share
    }

    /// A card for a trigger of `checkpoint` fit on every `every`-th frame of
    /// `data`; [`fit`] fills in the rest.
    pub fn new(checkpoint: String, data: String, every: usize) -> Self {
        TriggerCard {
            checkpoint,
            checkpoint_sha256: None,
            data,
            every,
            frames_fit: 0,
            frames_held_out: 0,
            positive_share: 0.0,
            target: Target::default(),
            tv_threshold: 0.0,
            epochs: 0,
            lr: 0.0,
            l2: 0.0,
            held_out: Scores::default(),
            fit: Scores::default(),
        }
    }
}

/// What a trigger learns to call a frame that needs the high scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Target {
    /// The two branches' action distributions differ most (total variation).
    #[default]
    Disagreement,
    /// Acting on the low branch loses the most value by the frame's labels.
    Regret,
}

impl Target {
    /// Its name on the command line and in cards.
    pub fn name(self) -> &'static str {
        match self {
            Target::Disagreement => "disagreement",
            Target::Regret => "regret",
        }
    }

    /// A frame's score under this target (`None`: the frame has no label
    /// and the target needs one).
    pub fn score(self, s: &FrameSample) -> Option<f32> {
        match self {
            Target::Disagreement => Some(s.tv),
            Target::Regret => s.regret,
        }
    }
}

/// Classification scores at p >= 0.5.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Scores {
    /// Samples.
    pub n: usize,
    /// Share of samples that are positive.
    pub positive_rate: f32,
    /// Share predicted positive (how often the high scale would be chosen).
    pub predicted_rate: f32,
    /// Share classified right.
    pub accuracy: f32,
    /// Share of positives predicted positive.
    pub recall: f32,
    /// Share of predicted positives that are positive.
    pub precision: f32,
}

/// A trigger file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum TriggerError {
    /// The file cannot be read.
    #[error(
        "{path}: cannot read the trigger: {source}; fix: make it with `mrdrive policy trigger`"
    )]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not a trigger.
    #[error("{path}: not a trigger file ({why}); fix: make it with `mrdrive policy trigger`")]
    Parse {
        /// The file.
        path: PathBuf,
        /// Why.
        why: String,
    },
    /// The trigger does not fit the policy.
    #[error("{path}: field `{field}`: {why}; fix: {fix}")]
    Misfit {
        /// The file.
        path: PathBuf,
        /// The field.
        field: &'static str,
        /// What is wrong.
        why: String,
        /// What to do.
        fix: String,
    },
    /// The dataset cannot be read.
    #[error(transparent)]
    Data(#[from] dataset::format::DataError),
    /// The dataset gave nothing to fit on.
    #[error("{data}: {why}; fix: {fix}")]
    NoData {
        /// The dataset folder.
        data: PathBuf,
        /// What is missing.
        why: String,
        /// What to do.
        fix: String,
    },
    /// The policy checkpoint cannot be loaded.
    #[error(transparent)]
    Checkpoint(#[from] crate::checkpoint::CheckpointError),
}

impl Trigger {
    /// The probability that the high scale is needed for a pooled feature.
    pub fn p_high(&self, features: &[f32]) -> f32 {
        let z = self
            .weights
            .iter()
            .zip(features)
            .zip(&self.mean)
            .zip(&self.std)
            .fold(self.bias, |z, (((w, f), m), s)| z + w * (f - m) / s);
        sigmoid(z)
    }

    /// Reads a trigger file and checks that it is one.
    pub fn load(path: &Path) -> Result<Trigger, TriggerError> {
        Self::load_identified(path).map(|(t, _)| t)
    }

    /// Like [`Trigger::load`], with the file and the SHA-256 of the bytes
    /// read, which run records carry so that a resumed sweep never mixes two
    /// triggers saved under one name.
    pub fn load_identified(
        path: &Path,
    ) -> Result<(Trigger, sim::record::CheckpointId), TriggerError> {
        let bytes = std::fs::read(path).map_err(|source| TriggerError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let id = sim::record::CheckpointId::of_bytes(path, &bytes);
        let t: Trigger = serde_json::from_slice(&bytes).map_err(|e| TriggerError::Parse {
            path: path.to_path_buf(),
            why: e.to_string(),
        })?;
        if t.format != TRIGGER_FORMAT {
            return Err(TriggerError::Parse {
                path: path.to_path_buf(),
                why: format!("format is {:?}, not {TRIGGER_FORMAT:?}", t.format),
            });
        }
        let d = t.weights.len();
        if t.mean.len() != d || t.std.len() != d {
            return Err(TriggerError::Misfit {
                path: path.to_path_buf(),
                field: "mean",
                why: format!(
                    "{} weights but {} means and {} deviations",
                    d,
                    t.mean.len(),
                    t.std.len()
                ),
                fix: "make the file again with `mrdrive policy trigger`".into(),
            });
        }
        Ok((t, id))
    }

    /// Checks that the trigger reads features of a policy whose pooled
    /// feature has `dim` entries and that has BN branches `scales`.
    pub fn check_fits(&self, path: &Path, dim: usize, scales: &[f32]) -> Result<(), TriggerError> {
        let misfit = |field, why: String| TriggerError::Misfit {
            path: path.to_path_buf(),
            field,
            why,
            fix: "make a trigger for this checkpoint: mrdrive policy trigger --checkpoint <it>"
                .into(),
        };
        if self.weights.len() != dim {
            return Err(misfit(
                "weights",
                format!(
                    "{} weights, but the policy's pooled feature has {dim} entries",
                    self.weights.len()
                ),
            ));
        }
        for (field, s) in [("low", self.low), ("high", self.high)] {
            if !scales.contains(&s) {
                return Err(misfit(
                    field,
                    format!("scale {s}, but the policy has branches {scales:?}"),
                ));
            }
        }
        Ok(())
    }

    /// Scores at p >= 0.5 on features `x` with targets `y`.
    pub fn scores(&self, x: &[&[f32]], y: &[bool]) -> Scores {
        let n = x.len();
        if n == 0 {
            return Scores::default();
        }
        let (mut tp, mut fp, mut fneg, mut tn) = (0usize, 0usize, 0usize, 0usize);
        for (f, &t) in x.iter().zip(y) {
            match (self.p_high(f) >= 0.5, t) {
                (true, true) => tp += 1,
                (true, false) => fp += 1,
                (false, true) => fneg += 1,
                (false, false) => tn += 1,
            }
        }
        let r = |a: usize, b: usize| if b == 0 { 0.0 } else { a as f32 / b as f32 };
        Scores {
            n,
            positive_rate: r(tp + fneg, n),
            predicted_rate: r(tp + fp, n),
            accuracy: r(tp + tn, n),
            recall: r(tp, tp + fneg),
            precision: r(tp, tp + fp),
        }
    }

    /// Writes the trigger as pretty JSON.
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        let text = serde_json::to_string_pretty(self).expect("a trigger serialises");
        std::fs::write(path, text + "\n")
    }
}

/// `b + w . x`, summed from the bias in feature order (on standardised features).
fn linear(w: &[f32], b: f32, x: impl Iterator<Item = f32>) -> f32 {
    w.iter().zip(x).fold(b, |z, (w, x)| z + w * x)
}

fn sigmoid(z: f32) -> f32 {
    1.0 / (1.0 + (-z).exp())
}

/// One frame's features through both branches and how much the branches disagree.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameSample {
    /// Pooled feature through the low-scale branch, on the image at the low scale.
    pub low: Vec<f32>,
    /// Pooled feature through the high-scale branch, on the image at the high scale.
    pub high: Vec<f32>,
    /// Total-variation distance between the two branches' action distributions.
    pub tv: f32,
    /// The value lost by acting on the low branch rather than the high one,
    /// by the frame's labels: `sum_a (p_high(a) - p_low(a)) Q(a)` (reward
    /// units; `None` where the frame has no valid label).
    pub regret: Option<f32>,
    /// Whether the frame's episode is held out.
    pub held_out: bool,
}

/// The 28 logits for `command` at `speed_mps` (the speed bins interpolated)
/// from the flattened `[commands][bins][28]` logits of one image.
pub fn command_logits(all: &[f32], command: usize, speed_mps: f32) -> [f32; NUM_ACTIONS] {
    let per_command = NUM_SPEED_BINS * NUM_ACTIONS;
    let z = &all[command * per_command..(command + 1) * per_command];
    let bins: [[f32; NUM_ACTIONS]; NUM_SPEED_BINS] =
        std::array::from_fn(|b| std::array::from_fn(|j| z[b * NUM_ACTIONS + j]));
    interpolate_speed(&bins, speed_mps)
}

/// The value `p` expects over action values `q`: `sum_a p(a) q(a)`.
pub fn expected_value(p: &[f32; NUM_ACTIONS], q: &[f32; NUM_ACTIONS]) -> f32 {
    p.iter().zip(q).map(|(a, b)| a * b).sum()
}

/// Total-variation distance between two distributions over the actions.
pub fn total_variation(p: &[f32; NUM_ACTIONS], q: &[f32; NUM_ACTIONS]) -> f32 {
    0.5 * p.iter().zip(q).map(|(a, b)| (a - b).abs()).sum::<f32>()
}

/// [`frame_samples`] of the policy checkpoint `weights` (its running
/// statistics synchronised, fused for the CPU).
pub fn checkpoint_samples(
    weights: &Path,
    data: &Path,
    scales: (f32, f32),
    every: usize,
) -> Result<(Vec<FrameSample>, Vec<String>), TriggerError> {
    use burn::prelude::*;
    let (net, _) = crate::checkpoint::load(weights, &Device::flex())?;
    net.sync_running_stats();
    let fused = FusedPolicy::from_net(&net.valid());
    frame_samples(&fused, data, scales, every)
}

/// Runs every `every`-th frame of `data` (the rig as mounted, view 0)
/// through both branches of `policy`: the S0 image shrunk to each scale by
/// area averaging (as the renderer's supersampling does), its pooled
/// feature, and the two action distributions' distance. In dataset order;
/// episodes that cannot be read are skipped and named in the second value.
pub fn frame_samples(
    policy: &FusedPolicy,
    data: &Path,
    (low, high): (f32, f32),
    every: usize,
) -> Result<(Vec<FrameSample>, Vec<String>), TriggerError> {
    let index = Index::load(data)?;
    let cfg = policy.config();
    let branch = |s: f32| {
        cfg.branch_of(s).ok_or_else(|| TriggerError::NoData {
            data: data.to_path_buf(),
            why: format!("the policy has no BN branch for scale {s}"),
            fix: format!("choose scales among {:?}", cfg.scales),
        })
    };
    let (bl, bh) = (branch(low)?, branch(high)?);
    let [s0w, s0h] = index.s0;
    if [s0h as usize, s0w as usize] != cfg.input_size(1.0) {
        return Err(TriggerError::NoData {
            data: data.to_path_buf(),
            why: format!(
                "images are {s0w}x{s0h} but the policy's S0 is {:?} (height, width)",
                cfg.input_size(1.0)
            ),
            fix: "use a dataset collected at the policy's S0".into(),
        });
    }
    let views = index.view_yaws_deg.len();
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    for ep in &index.episodes {
        let path = data.join(&ep.shard);
        let shard = match MappedShard::open(&path, index.s0, views) {
            Ok(s) => s,
            Err(e) => {
                skipped.push(e.to_string());
                continue;
            }
        };
        let held_out = ep.id % 5 == 4;
        // Labels are optional: only the regret target reads them.
        let labels = ep.labels.as_ref().and_then(|name| {
            MappedLabels::open(&data.join(name), LABEL_VERSION, shard.len(), views)
                .map_err(|e| skipped.push(format!("labels left out: {e}")))
                .ok()
        });
        let frames: Vec<usize> = (0..shard.len()).step_by(every.max(1)).collect();
        let samples: Result<Vec<FrameSample>, dataset::format::DataError> = frames
            .par_iter()
            .map(|&i| {
                let src = RgbImage {
                    width: s0w,
                    height: s0h,
                    data: shard.view_images(i, 0)?.0,
                };
                let st = &shard.state;
                let command = usize::from(st.command[i]);
                let speed = st.ego[i].speed;
                let through = |scale: f32, b: usize| {
                    let [h, w] = cfg.input_size(scale);
                    let mut img = RgbImage::default();
                    let img = if [h, w] == [s0h as usize, s0w as usize] {
                        &src
                    } else {
                        resize_rgb(&src, w as u32, h as u32, Filter::Area, &mut img);
                        &img
                    };
                    let f = policy.features(&policy.normalize(&img.data, h, w), b);
                    let z = command_logits(&policy.action_logits(&f), command, speed);
                    (f, softmax(&z))
                };
                let (fl, pl) = through(low, bl);
                let (fh, ph) = through(high, bh);
                let regret = labels.as_ref().filter(|l| l.valid[i]).map(|l| {
                    let mut q = vec![0.0; Q_PER_VIEW];
                    l.q_into(i, 0, &mut q);
                    let q = command_logits(&q, command, speed);
                    expected_value(&ph, &q) - expected_value(&pl, &q)
                });
                Ok(FrameSample {
                    low: fl,
                    high: fh,
                    tv: total_variation(&pl, &ph),
                    regret,
                    held_out,
                })
            })
            .collect();
        match samples {
            Ok(samples) => out.extend(samples),
            Err(e) => skipped.push(e.to_string()),
        }
    }
    if !out.iter().any(|s| !s.held_out) {
        return Err(TriggerError::NoData {
            data: data.to_path_buf(),
            why: "no readable frame outside the held-out episodes (ids 4 mod 5)".into(),
            fix: "collect more episodes (mrdrive collect) or point --data at another dataset"
                .into(),
        });
    }
    Ok((out, skipped))
}

/// How to fit a trigger.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitConfig {
    /// Share of fit frames called positive (top of the target's score).
    pub positive_share: f32,
    /// What a positive is.
    pub target: Target,
    /// Gradient-descent epochs.
    pub epochs: usize,
    /// Learning rate.
    pub lr: f32,
    /// L2 weight.
    pub l2: f32,
}

impl Default for FitConfig {
    fn default() -> Self {
        FitConfig {
            positive_share: 0.25,
            target: Target::Disagreement,
            epochs: 400,
            lr: 0.5,
            l2: 1e-3,
        }
    }
}

/// Fits a trigger on `samples` (see the module docs); `card` gets the scores.
pub fn fit(
    samples: &[FrameSample],
    (low, high): (f32, f32),
    cfg: FitConfig,
    mut card: TriggerCard,
) -> Result<Trigger, TriggerError> {
    // The frames the target can score; the rest take no part.
    let samples: Vec<(&FrameSample, f32)> = samples
        .iter()
        .filter_map(|s| cfg.target.score(s).map(|v| (s, v)))
        .collect();
    let fit_frames: Vec<f32> = samples
        .iter()
        .filter(|(s, _)| !s.held_out)
        .map(|&(_, v)| v)
        .collect();
    if fit_frames.is_empty() {
        return Err(TriggerError::NoData {
            data: PathBuf::from(&card.data),
            why: format!(
                "no frame outside the held-out episodes has a {} score",
                cfg.target.name()
            ),
            fix: "label the dataset (`mrdrive label`) or fit the disagreement target".into(),
        });
    }
    let mut sorted = fit_frames.clone();
    sorted.sort_by(f32::total_cmp);
    let cut = ((1.0 - cfg.positive_share.clamp(0.0, 1.0)) * sorted.len() as f32) as usize;
    let mut threshold = sorted[cut.min(sorted.len() - 1)];
    if cfg.target == Target::Regret {
        // Losing nothing never needs the high scale.
        threshold = threshold.max(1e-6);
    }
    // One sample per branch and frame.
    let expand = |held_out: bool| -> (Vec<&[f32]>, Vec<bool>) {
        samples
            .iter()
            .filter(|(s, _)| s.held_out == held_out)
            .flat_map(|&(s, v)| {
                let y = v >= threshold;
                [(s.low.as_slice(), y), (s.high.as_slice(), y)]
            })
            .unzip()
    };
    let (x, y) = expand(false);
    let d = x[0].len();
    let n = x.len() as f32;
    let mut mean = vec![0.0f32; d];
    for f in &x {
        for (m, v) in mean.iter_mut().zip(*f) {
            *m += v / n;
        }
    }
    let mut std = vec![0.0f32; d];
    for f in &x {
        for ((s, v), m) in std.iter_mut().zip(*f).zip(&mean) {
            *s += (v - m) * (v - m) / n;
        }
    }
    std.iter_mut().for_each(|s| *s = s.sqrt().max(1e-6));
    let z: Vec<Vec<f32>> = x
        .iter()
        .map(|f| (0..d).map(|i| (f[i] - mean[i]) / std[i]).collect())
        .collect();
    let positives = y.iter().filter(|&&p| p).count().max(1) as f32;
    let pos_weight = (n - positives).max(1.0) / positives;
    let total_weight: f32 = y.iter().map(|&p| if p { pos_weight } else { 1.0 }).sum();
    let (mut w, mut b) = (vec![0.0f32; d], 0.0f32);
    let mut grad = vec![0.0f32; d];
    for _ in 0..cfg.epochs {
        grad.iter_mut().for_each(|g| *g = 0.0);
        let mut gb = 0.0f32;
        for (zi, &yi) in z.iter().zip(&y) {
            let p = sigmoid(linear(&w, b, zi.iter().copied()));
            let (t, wt) = if yi { (1.0, pos_weight) } else { (0.0, 1.0) };
            let e = wt * (p - t) / total_weight;
            for (g, v) in grad.iter_mut().zip(zi) {
                *g += e * v;
            }
            gb += e;
        }
        for (wi, g) in w.iter_mut().zip(&grad) {
            *wi -= cfg.lr * (g + cfg.l2 * *wi);
        }
        b -= cfg.lr * gb;
    }
    card.positive_share = cfg.positive_share;
    card.target = cfg.target;
    card.tv_threshold = threshold;
    card.epochs = cfg.epochs;
    card.lr = cfg.lr;
    card.l2 = cfg.l2;
    card.frames_fit = fit_frames.len();
    card.frames_held_out = samples.len() - fit_frames.len();
    let mut t = Trigger {
        format: TRIGGER_FORMAT.into(),
        low,
        high,
        mean,
        std,
        weights: w,
        bias: b,
        card,
    };
    t.card.fit = t.scores(&x, &y);
    let (xh, yh) = expand(true);
    t.card.held_out = t.scores(&xh, &yh);
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_fit_is_the_same_network_by_digest_data_frames_and_target() {
        let asked = TriggerCard {
            checkpoint_sha256: Some("ab".into()),
            positive_share: 0.1,
            target: Target::Regret,
            ..TriggerCard::new("models/ra.safetensors".into(), "data/r".into(), 5)
        };
        // What the fit fills in (frames, scores) does not matter.
        let made = TriggerCard {
            frames_fit: 100,
            ..asked.clone()
        };
        assert!(made.fits_the_same(&asked));
        for other in [
            TriggerCard {
                checkpoint_sha256: Some("cd".into()),
                ..made.clone()
            },
            TriggerCard {
                checkpoint_sha256: None,
                ..made.clone()
            },
            TriggerCard {
                data: "data/o".into(),
                ..made.clone()
            },
            TriggerCard {
                every: 2,
                ..made.clone()
            },
            TriggerCard {
                target: Target::Disagreement,
                ..made.clone()
            },
            TriggerCard {
                positive_share: 0.25,
                ..made.clone()
            },
        ] {
            assert!(!other.fits_the_same(&asked), "{other:?}");
        }
    }

    fn card() -> TriggerCard {
        TriggerCard::new("c".into(), "d".into(), 1)
    }

    /// Frames whose disagreement grows with feature 0 (feature 1 is noise to
    /// it) and whose regret grows with feature 1.
    fn frames(n: usize) -> Vec<FrameSample> {
        (0..n)
            .map(|i| {
                let a = (i % 20) as f32 / 20.0;
                let noise = ((i * 7919) % 13) as f32 / 13.0;
                FrameSample {
                    low: vec![a * 3.0 + 1.0, noise],
                    high: vec![a * 3.0 + 1.2, noise],
                    tv: a,
                    // The regret follows feature 1, and only odd frames have labels.
                    regret: (i % 2 == 1).then_some(noise - 0.5),
                    held_out: i % 5 == 4,
                }
            })
            .collect()
    }

    #[test]
    fn the_fit_finds_the_feature_that_predicts_disagreement() {
        let s = frames(400);
        let t = fit(&s, (0.75, 1.0), FitConfig::default(), card()).unwrap();
        // The top quarter of tv: a >= 0.75, i.e. 5 of 20 values.
        assert!((t.card.tv_threshold - 0.75).abs() < 1e-6);
        assert!(t.weights[0] > 0.0 && t.weights[0].abs() > 5.0 * t.weights[1].abs());
        // Positives are weighted up to balance the classes: every positive is
        // caught, at the price of some negatives near the boundary.
        assert!(t.card.held_out.recall > 0.99, "{:?}", t.card.held_out);
        assert!(t.card.held_out.accuracy >= 0.75, "{:?}", t.card.held_out);
        assert!((t.card.fit.positive_rate - 0.25).abs() < 1e-6);
        assert!(t.p_high(&[3.95, 0.5]) > 0.5 && t.p_high(&[1.0, 0.5]) < 0.5);
        let report = t.card.report();
        assert!(
            report.contains("positive: total variation >= 0.750 (top 25 %)\n"),
            "{report}"
        );
        assert!(report.contains("\nheld out  n "), "{report}");
        // Deterministic.
        assert_eq!(
            t,
            fit(&s, (0.75, 1.0), FitConfig::default(), card()).unwrap()
        );
    }

    #[test]
    fn the_regret_target_reads_the_labels_not_the_disagreement() {
        let s = frames(400);
        let cfg = FitConfig {
            target: Target::Regret,
            ..FitConfig::default()
        };
        let t = fit(&s, (0.75, 1.0), cfg, card()).unwrap();
        assert_eq!(t.card.target, Target::Regret);
        // Only the labelled (odd) frames take part: 160 of the 320 fit frames.
        assert_eq!(t.card.frames_fit, 160);
        // Feature 1 (low branch) carries the regret now, feature 0 does not.
        assert!(
            t.weights[1].abs() > 2.0 * t.weights[0].abs(),
            "{:?}",
            t.weights
        );
        assert!(t.card.tv_threshold > 0.0);
        // A frame that loses nothing is never a positive, however few lose something.
        let none: Vec<FrameSample> = frames(100)
            .into_iter()
            .map(|f| FrameSample {
                regret: Some(0.0),
                ..f
            })
            .collect();
        let t = fit(&none, (0.75, 1.0), cfg, card()).unwrap();
        assert_eq!(t.card.fit.positive_rate, 0.0);
        // Without any label there is nothing to fit, and the error says so.
        let bare: Vec<FrameSample> = frames(100)
            .into_iter()
            .map(|f| FrameSample { regret: None, ..f })
            .collect();
        let e = fit(&bare, (0.75, 1.0), cfg, card())
            .unwrap_err()
            .to_string();
        assert!(e.contains("regret") && e.contains("mrdrive label"), "{e}");
    }

    #[test]
    fn expected_value_weighs_action_values_by_probability() {
        let mut p = [0.0f32; NUM_ACTIONS];
        let mut q = [1.0f32; NUM_ACTIONS];
        p[0] = 0.25;
        p[1] = 0.75;
        q[1] = 3.0;
        assert_eq!(expected_value(&p, &q), 0.25 + 2.25);
    }

    #[test]
    fn total_variation_of_equal_and_disjoint_distributions() {
        let mut p = [0.0f32; NUM_ACTIONS];
        let mut q = [0.0f32; NUM_ACTIONS];
        p[0] = 1.0;
        q[1] = 1.0;
        assert_eq!(total_variation(&p, &p), 0.0);
        assert_eq!(total_variation(&p, &q), 1.0);
    }

    #[test]
    fn a_bad_trigger_file_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.json");
        std::fs::write(&path, "{\"format\": 3}").unwrap();
        let e = Trigger::load(&path).unwrap_err().to_string();
        assert!(
            e.contains("t.json") && e.contains("mrdrive policy trigger"),
            "{e}"
        );
        let mut t = fit(&frames(100), (0.75, 1.0), FitConfig::default(), card()).unwrap();
        t.save(&path).unwrap();
        let back = Trigger::load(&path).unwrap();
        assert_eq!(back, t);
        let e = back
            .check_fits(&path, 256, &[0.75, 1.0])
            .unwrap_err()
            .to_string();
        assert!(e.contains("field `weights`") && e.contains("256"), "{e}");
        let e = back
            .check_fits(&path, 2, &[0.5, 1.0])
            .unwrap_err()
            .to_string();
        assert!(e.contains("field `low`"), "{e}");
        assert!(back.check_fits(&path, 2, &[0.75, 1.0]).is_ok());
        t.format = "other".into();
        t.save(&path).unwrap();
        assert!(
            Trigger::load(&path)
                .unwrap_err()
                .to_string()
                .contains("format")
        );
    }
}
