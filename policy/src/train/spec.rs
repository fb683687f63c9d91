//! What a training stage is: [`StageSpec`], the settings of one stage, with the
//! paper's recipes ([`StageSpec::original`], [`StageSpec::retarget`]) and the
//! comparison that refuses to resume a run with other settings.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::loader::Sampling;
use super::multires::TrainConfig;
use super::presets::Preset;

/// The settings of one training stage. Everything here but
/// [`StageSpec::checkpoint_every`] and [`StageSpec::steps`] must match to resume a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageSpec {
    /// The stage's name (`original`, `nra-0.75`, `nra-1.0`, `ra`): its folder and file names.
    pub name: String,
    /// The network preset (`cpu`, `paper`, `resnet18`, `tiny`).
    pub preset: String,
    /// The scales R the trained network has (one BN branch each).
    pub scales: Vec<f32>,
    /// The labelled dataset folder.
    pub data: PathBuf,
    /// Train on the first this many episodes of the dataset's index only (its first
    /// slices, while later ones are still being collected: a learning curve's point);
    /// `None`: every labelled episode. Pinning it keeps a run's samples the same when
    /// the dataset grows between its resumes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episodes: Option<usize>,
    /// Further labelled dataset folders trained on with `data`, every episode of each
    /// (a DAgger round's frames, driven by the policy and labelled by the expert);
    /// their samples join `data`'s in each epoch.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub also: Vec<PathBuf>,
    /// The teacher checkpoint (the Original) for a retargeting stage; `None` trains from
    /// scratch.
    pub teacher: Option<PathBuf>,
    /// Samples per step.
    pub batch: usize,
    /// Steps.
    pub steps: usize,
    /// Seed of the initialisation, the sample order and the augmentations.
    pub seed: u64,
    /// The step's settings (losses, learning rate, freezing).
    pub train: TrainConfig,
    /// Apply WoR's augmentations.
    pub augment: bool,
    /// Which samples an epoch draws and how often (WoR: each once; TimeParam's
    /// retargeting: commands drawn evenly).
    #[serde(flatten)]
    pub sampling: Sampling,
    /// Start from this checkpoint's weights instead of a fresh initialisation (same
    /// network; e.g. to go on from a shipped model when a run's state is lost).
    #[serde(default)]
    pub init: Option<PathBuf>,
    /// Batches per scale for the final BN recalibration (0: none).
    pub recalibrate_batches: usize,
    /// Steps between checkpoints of the run state.
    #[serde(skip)]
    pub checkpoint_every: usize,
}

impl StageSpec {
    /// The Original: single resolution, from scratch, WoR's recipe (Adam 3e-4, every
    /// sample once per epoch) at batch 32 (WoR: 128 for 20 epochs; sized for 2 CPU cores).
    pub fn original(data: &Path, preset: Preset) -> StageSpec {
        StageSpec {
            name: "original".into(),
            preset: preset.name().into(),
            scales: vec![1.0],
            data: data.to_path_buf(),
            episodes: None,
            also: Vec::new(),
            teacher: None,
            batch: 32,
            steps: 4000,
            seed: 0,
            train: TrainConfig::new()
                .with_lr(3e-4)
                .with_freeze_action_head(false),
            augment: true,
            sampling: Sampling::default(),
            init: None,
            recalibrate_batches: 0,
            checkpoint_every: 100,
        }
    }

    /// A retargeting stage from the Original `teacher`: NRA at one scale (`scales` of
    /// length 1) or RA (several), TimeParam's recipe sized for 2 CPU cores: 600 steps of
    /// 32 (TimeParam: 780 of 128), a new layer unfrozen every 75 steps (TimeParam: 200),
    /// 50 recalibration batches per scale (TimeParam: 200); each starting frame drawn 8
    /// times (at 300 steps without it, the 0.75x student stood at green lights).
    pub fn retarget(
        name: &str,
        scales: &[f32],
        data: &Path,
        teacher: &Path,
        preset: Preset,
    ) -> StageSpec {
        StageSpec {
            name: name.into(),
            preset: preset.name().into(),
            scales: scales.to_vec(),
            data: data.to_path_buf(),
            episodes: None,
            also: Vec::new(),
            teacher: Some(teacher.to_path_buf()),
            batch: 32,
            steps: 600,
            seed: 1,
            train: TrainConfig::new()
                .with_lr(1.5e-4)
                .with_unfreeze_every(Some(75)),
            augment: true,
            sampling: Sampling {
                balanced: true,
                start_repeat: 8,
                ..Sampling::default()
            },
            init: None,
            recalibrate_batches: 50,
            checkpoint_every: 50,
        }
    }

    /// The names of the paper's four stages, in pipeline order.
    pub const PAPER: [&'static str; 4] = ["original", "nra-0.75", "nra-1.0", "ra"];

    /// The fields in which `self` differs from `other`, ignoring `checkpoint_every` and
    /// `steps` (a run may be extended: it continues as if it had been asked for more steps).
    pub fn differences(&self, other: &StageSpec) -> Vec<String> {
        let a = serde_json::to_value(self).expect("a spec serialises");
        let b = serde_json::to_value(other).expect("a spec serialises");
        let (serde_json::Value::Object(a), serde_json::Value::Object(b)) = (a, b) else {
            return vec![];
        };
        let mut out = Vec::new();
        for (k, va) in &a {
            if k == "steps" {
                continue;
            }
            match b.get(k) {
                Some(vb) if vb == va => {}
                vb => out.push(format!(
                    "`{k}` is {} in the run, {} now",
                    vb.map(|v| v.to_string()).unwrap_or("missing".into()),
                    va
                )),
            }
        }
        out
    }
}
