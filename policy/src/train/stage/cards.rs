//! The cards a stage writes on its checkpoints: the network so far
//! (`latest.safetensors`, at every checkpoint of the run state) and the trained
//! network with its [`TrainingRecord`] (`final.safetensors`).

use std::path::Path;

use crate::checkpoint::{ModelCard, TrainingRecord};
use crate::train::spec::StageSpec;

/// The card of the network at step `step` of a stage still in training (without the
/// final recalibration), in `run_dir`.
pub(super) fn latest_card(spec: &StageSpec, run_dir: &Path, step: usize) -> ModelCard {
    ModelCard {
        trained: true,
        description: format!("{} (in training: step {step})", describe(spec)),
        source: format!("{} after {step} of {} steps", run_dir.display(), spec.steps),
        training: None,
    }
}

/// The card of the trained network: `steps` steps in all, on `samples_in_data`
/// samples, in `wall_s` seconds of training over every session.
pub(super) fn final_card(
    spec: &StageSpec,
    samples_in_data: usize,
    steps: usize,
    wall_s: f64,
) -> ModelCard {
    ModelCard {
        trained: true,
        description: describe(spec),
        source: format!(
            "mrdrive train --stage {} ({} steps of {} samples, seed {}, data {})",
            spec.name,
            steps,
            spec.batch,
            spec.seed,
            spec.data.display()
        ),
        training: Some(TrainingRecord {
            stage: spec.name.clone(),
            data: spec.data.display().to_string(),
            samples_in_data,
            steps,
            batch: spec.batch,
            seed: spec.seed,
            lr: spec.train.lr,
            losses: "see losses.csv beside the run".into(),
            wall_s,
            machine: machine(),
            init: spec.init.as_ref().map(|p| p.display().to_string()),
            sampling: spec.sampling.clone(),
        }),
    }
}

/// A sentence on what the stage's network is.
fn describe(spec: &StageSpec) -> String {
    let sampling = spec.sampling.describe();
    match (&spec.teacher, spec.scales.as_slice()) {
        (None, _) => match &spec.init {
            None => format!(
                "Original: single-resolution {} policy trained from scratch on world-on-rails action values (WoR's loss{sampling})",
                spec.preset
            ),
            Some(init) => format!(
                "Original: single-resolution {} policy, continued from {} on world-on-rails action values (WoR's loss{sampling})",
                spec.preset,
                init.display()
            ),
        },
        (Some(_), [r]) => format!(
            "NRA {r}: the Original retargeted to {r}x without BN banks (TimeParam's recipe{sampling})"
        ),
        (Some(_), rs) => format!(
            "RA {rs:?}: the Original retargeted to every scale at once with one BN branch per scale (multi-resolution step{sampling})"
        ),
    }
}

/// The CPU model and core count, for model cards.
pub fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    format!("{cpu}, {cores} cores")
}
