//! A stage asked for by name ([`StageRequest`]: `mrdrive train --stage nra-0.75`)
//! with the settings that change its recipe ([`RecipeChanges`]: the other flags),
//! made into a [`StageSpec`] or refused by the flag at fault ([`SpecError`]).

use std::path::PathBuf;

use super::loader::Sampling;
use super::presets::Preset;
use super::spec::StageSpec;

/// A stage asked for by name, with the settings that replace its recipe's.
#[derive(Debug, Clone, PartialEq)]
pub struct StageRequest {
    /// The stage: `original`, `nra-<scale>` (e.g. nra-0.75) or `ra`.
    pub stage: String,
    /// The network preset.
    pub preset: Preset,
    /// The scale set R of `ra` (fractions of S0).
    pub scales: Vec<f32>,
    /// The labelled dataset; `None`: the cache's `data/original` for the
    /// Original, `data/retarget` for a retargeting stage (`dataset::cache`).
    pub data: Option<PathBuf>,
    /// The teacher of a retargeting stage; it must exist.
    pub teacher: PathBuf,
    /// The settings that replace the recipe's.
    pub changes: RecipeChanges,
}

/// Settings that replace a stage recipe's; each `None` keeps the recipe's.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RecipeChanges {
    /// Steps.
    pub steps: Option<usize>,
    /// Samples per step.
    pub batch: Option<usize>,
    /// Adam's learning rate.
    pub lr: Option<f64>,
    /// Seed of the initialisation, the sample order and the augmentations.
    pub seed: Option<u64>,
    /// Steps between unfreezing stages of a retargeting stage (0: none).
    pub unfreeze_every: Option<usize>,
    /// Batches per scale for the final BN recalibration.
    pub recalibrate_batches: Option<usize>,
    /// Steps between checkpoints of the run state.
    pub checkpoint_every: Option<usize>,
    /// The share of standing frames kept, in [0, 1].
    pub standing_keep: Option<f64>,
    /// Copies of each kept starting frame per epoch (at least 1).
    pub start_repeat: Option<usize>,
    /// Copies of each kept frame with a pedestrian ahead per epoch (at least 1).
    pub pedestrian_repeat: Option<usize>,
    /// Copies of each kept frame with a stopped vehicle ahead per epoch (at least 1).
    pub stopped_vehicle_repeat: Option<usize>,
    /// Draw commands evenly.
    pub balanced: Option<bool>,
    /// Start from this checkpoint's weights instead of a fresh initialisation.
    pub init: Option<PathBuf>,
    /// Train on the dataset's first this many episodes only.
    pub episodes: Option<usize>,
    /// Further labelled datasets trained on with it, every episode of each.
    pub also: Vec<PathBuf>,
}

/// Why a stage request does not make a stage. The messages name `mrdrive train`'s
/// flags, which set the request's fields.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpecError {
    /// `nra-R` with an R that is not a scale.
    #[error("--stage {stage}: `{scale}` is not a scale in (0, 1]; fix: e.g. --stage nra-0.75")]
    Scale {
        /// The stage asked for.
        stage: String,
        /// The text after `nra-`.
        scale: String,
    },
    /// A stage name that is none of the recipes'.
    #[error("--stage {0}: unknown stage; fix: use original, nra-<scale> (e.g. nra-0.75) or ra")]
    UnknownStage(String),
    /// A retargeting stage whose teacher is not there.
    #[error(
        "{}: the teacher of stage {stage} does not exist; fix: train the Original first (`mrdrive train --stage original`) or pass --teacher",
        teacher.display()
    )]
    NoTeacher {
        /// The teacher checkpoint.
        teacher: PathBuf,
        /// The stage asked for.
        stage: String,
    },
    /// A share of standing frames outside [0, 1].
    #[error("--standing-keep {0}: a share in [0, 1]")]
    StandingKeep(f64),
    /// A repeat count of 0.
    #[error("--{flag} 0: at least 1 (1 draws each {what} once per epoch)")]
    NoRepeat {
        /// The flag.
        flag: &'static str,
        /// The frames it repeats.
        what: &'static str,
    },
    /// No steps, or empty batches.
    #[error("--steps {steps} --batch {batch}: both must be at least 1")]
    Empty {
        /// Steps.
        steps: usize,
        /// Samples per step.
        batch: usize,
    },
    /// `--episodes 0`.
    #[error("--episodes 0: train on at least 1 episode (or leave --episodes out: every one)")]
    NoEpisodes,
}

impl StageRequest {
    /// The stage's recipe, with [`StageRequest::changes`] applied.
    pub fn spec(&self) -> Result<StageSpec, SpecError> {
        let mut spec = self.recipe()?;
        if spec.teacher.is_some() && !self.teacher.exists() {
            return Err(SpecError::NoTeacher {
                teacher: self.teacher.clone(),
                stage: self.stage.clone(),
            });
        }
        self.changes.apply(&mut spec)?;
        Ok(spec)
    }

    /// The recipe of the stage named [`StageRequest::stage`].
    fn recipe(&self) -> Result<StageSpec, SpecError> {
        let stage = self.stage.as_str();
        let data_or = |d: &str| {
            self.data
                .clone()
                .unwrap_or_else(|| dataset::cache::dataset(d))
        };
        let retarget = |scales: &[f32]| {
            StageSpec::retarget(
                stage,
                scales,
                &data_or("retarget"),
                &self.teacher,
                self.preset,
            )
        };
        if stage == "original" {
            Ok(StageSpec::original(&data_or("original"), self.preset))
        } else if stage == "ra" {
            Ok(retarget(&self.scales))
        } else if let Some(r) = stage.strip_prefix("nra-") {
            let scale = r
                .parse()
                .ok()
                .filter(|r: &f32| *r > 0.0 && *r <= 1.0)
                .ok_or_else(|| SpecError::Scale {
                    stage: stage.into(),
                    scale: r.into(),
                })?;
            Ok(retarget(&[scale]))
        } else {
            Err(SpecError::UnknownStage(stage.into()))
        }
    }
}

impl RecipeChanges {
    /// Replaces `spec`'s settings by those given; refuses a share or a count out of range.
    pub fn apply(&self, spec: &mut StageSpec) -> Result<(), SpecError> {
        if let Some(v) = self.steps {
            spec.steps = v;
        }
        if let Some(v) = self.batch {
            spec.batch = v;
        }
        if let Some(v) = self.lr {
            spec.train.lr = v;
        }
        if let Some(v) = self.seed {
            spec.seed = v;
        }
        if let Some(v) = self.unfreeze_every {
            spec.train.unfreeze_every = (v > 0).then_some(v);
        }
        if let Some(v) = self.recalibrate_batches {
            spec.recalibrate_batches = v;
        }
        if let Some(v) = self.checkpoint_every {
            spec.checkpoint_every = v;
        }
        self.apply_sampling(&mut spec.sampling)?;
        if let Some(v) = &self.init {
            spec.init = Some(v.clone());
        }
        if let Some(v) = self.episodes {
            spec.episodes = Some(v);
        }
        spec.also.extend(self.also.iter().cloned());
        if spec.episodes == Some(0) {
            return Err(SpecError::NoEpisodes);
        }
        if spec.steps == 0 || spec.batch == 0 {
            return Err(SpecError::Empty {
                steps: spec.steps,
                batch: spec.batch,
            });
        }
        Ok(())
    }

    /// Replaces the sampling settings given.
    fn apply_sampling(&self, sampling: &mut Sampling) -> Result<(), SpecError> {
        if let Some(v) = self.standing_keep {
            if !(0.0..=1.0).contains(&v) {
                return Err(SpecError::StandingKeep(v));
            }
            sampling.standing_keep = v;
        }
        let repeats = [
            (
                self.start_repeat,
                &mut sampling.start_repeat,
                "start-repeat",
                "starting frame",
            ),
            (
                self.pedestrian_repeat,
                &mut sampling.pedestrian_repeat,
                "pedestrian-repeat",
                "frame with a pedestrian ahead",
            ),
            (
                self.stopped_vehicle_repeat,
                &mut sampling.stopped_vehicle_repeat,
                "stopped-vehicle-repeat",
                "frame with a stopped vehicle ahead",
            ),
        ];
        for (given, field, flag, what) in repeats {
            if let Some(v) = given {
                if v == 0 {
                    return Err(SpecError::NoRepeat { flag, what });
                }
                *field = v;
            }
        }
        if let Some(v) = self.balanced {
            sampling.balanced = v;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    /// A request for `stage` whose teacher is `teacher`.
    fn request(stage: &str, teacher: &Path) -> StageRequest {
        StageRequest {
            stage: stage.into(),
            preset: Preset::Tiny,
            scales: vec![0.5, 1.0],
            data: None,
            teacher: teacher.to_path_buf(),
            changes: RecipeChanges::default(),
        }
    }

    #[test]
    fn a_name_picks_its_recipe_and_default_data() {
        let dir = tempfile::tempdir().unwrap();
        let teacher = dir.path().join("original.safetensors");
        std::fs::write(&teacher, b"x").unwrap();
        let original = request("original", &teacher).spec().unwrap();
        assert_eq!(
            original,
            StageSpec::original(&dataset::cache::dataset("original"), Preset::Tiny)
        );
        let nra = request("nra-0.75", &teacher).spec().unwrap();
        assert_eq!(
            nra,
            StageSpec::retarget(
                "nra-0.75",
                &[0.75],
                &dataset::cache::dataset("retarget"),
                &teacher,
                Preset::Tiny
            )
        );
        let ra = StageRequest {
            data: Some("elsewhere".into()),
            ..request("ra", &teacher)
        };
        let ra = ra.spec().unwrap();
        assert_eq!(
            (ra.scales.as_slice(), ra.data.as_path()),
            (&[0.5, 1.0][..], Path::new("elsewhere"))
        );
    }

    #[test]
    fn changes_replace_the_recipe_s_settings() {
        let changes = RecipeChanges {
            steps: Some(7),
            batch: Some(3),
            lr: Some(0.5),
            seed: Some(9),
            unfreeze_every: Some(0),
            recalibrate_batches: Some(2),
            checkpoint_every: Some(4),
            standing_keep: Some(0.25),
            start_repeat: Some(2),
            pedestrian_repeat: Some(3),
            stopped_vehicle_repeat: Some(4),
            balanced: Some(true),
            init: Some("init.safetensors".into()),
            episodes: Some(40),
            also: vec!["dagger-1".into()],
        };
        let spec = StageRequest {
            changes,
            ..request("original", Path::new("absent"))
        }
        .spec()
        .unwrap();
        assert_eq!(
            (spec.steps, spec.batch, spec.train.lr, spec.seed),
            (7, 3, 0.5, 9)
        );
        assert_eq!(spec.train.unfreeze_every, None);
        assert_eq!((spec.recalibrate_batches, spec.checkpoint_every), (2, 4));
        assert_eq!(spec.episodes, Some(40));
        assert_eq!(spec.also, [PathBuf::from("dagger-1")]);
        assert_eq!(
            spec.sampling,
            Sampling {
                balanced: true,
                standing_keep: 0.25,
                start_repeat: 2,
                pedestrian_repeat: 3,
                stopped_vehicle_repeat: 4,
            }
        );
        assert_eq!(spec.init, Some(PathBuf::from("init.safetensors")));
    }

    #[test]
    fn a_bad_request_says_which_flag_and_what_would_fix_it() {
        let absent = Path::new("absent/original.safetensors");
        let err = |r: StageRequest| r.spec().unwrap_err().to_string();
        assert_eq!(
            err(request("nra-2", absent)),
            "--stage nra-2: `2` is not a scale in (0, 1]; fix: e.g. --stage nra-0.75"
        );
        assert_eq!(
            err(request("big", absent)),
            "--stage big: unknown stage; fix: use original, nra-<scale> (e.g. nra-0.75) or ra"
        );
        assert_eq!(
            err(request("ra", absent)),
            "absent/original.safetensors: the teacher of stage ra does not exist; fix: train the Original first (`mrdrive train --stage original`) or pass --teacher"
        );
        let changed = |changes| StageRequest {
            changes,
            ..request("original", absent)
        };
        assert_eq!(
            err(changed(RecipeChanges {
                standing_keep: Some(1.5),
                ..RecipeChanges::default()
            })),
            "--standing-keep 1.5: a share in [0, 1]"
        );
        for (changes, message) in [
            (
                RecipeChanges {
                    start_repeat: Some(0),
                    ..RecipeChanges::default()
                },
                "--start-repeat 0: at least 1 (1 draws each starting frame once per epoch)",
            ),
            (
                RecipeChanges {
                    pedestrian_repeat: Some(0),
                    ..RecipeChanges::default()
                },
                "--pedestrian-repeat 0: at least 1 (1 draws each frame with a pedestrian ahead once per epoch)",
            ),
            (
                RecipeChanges {
                    stopped_vehicle_repeat: Some(0),
                    ..RecipeChanges::default()
                },
                "--stopped-vehicle-repeat 0: at least 1 (1 draws each frame with a stopped vehicle ahead once per epoch)",
            ),
            (
                RecipeChanges {
                    batch: Some(0),
                    ..RecipeChanges::default()
                },
                "--steps 4000 --batch 0: both must be at least 1",
            ),
            (
                RecipeChanges {
                    episodes: Some(0),
                    ..RecipeChanges::default()
                },
                "--episodes 0: train on at least 1 episode (or leave --episodes out: every one)",
            ),
        ] {
            assert_eq!(err(changed(changes)), message);
        }
    }
}
