//! The cards a stage writes on its checkpoints: the network so far
//! (`latest.safetensors`, at every checkpoint of the run state) and the trained
//! network with its [`TrainingRecord`] (`final.safetensors`).

use std::collections::BTreeMap;
use std::path::Path;

use dataset::format::{Episode, Index};

use super::error::StageError;
use super::run_folder::FINAL_FILE;
use crate::checkpoint::{self, ModelCard, TrainingRecord};
use crate::train::loader::TrainSet;
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

/// The card of the trained network: `steps` steps in all, on `set` (the
/// episodes it trained on), in `wall_s` seconds of training over every session.
pub(super) fn final_card(spec: &StageSpec, set: &TrainSet, steps: usize, wall_s: f64) -> ModelCard {
    let used = first_episodes(&set.index.episodes, spec.episodes);
    let (towns, routes) = by_town_and_route(
        used.iter()
            .chain(set.also.iter().flat_map(|(_, i)| &i.episodes)),
    );
    // A shard that cannot be read was skipped by the loader too: its hash is left out.
    let data_sha256 = used
        .iter()
        .map(|e| (set.dir.as_path(), e))
        .chain(
            set.also
                .iter()
                .flat_map(|(dir, index)| index.episodes.iter().map(move |e| (dir.as_path(), e))),
        )
        .filter_map(|(dir, e)| dataset::hashes::of_episodes(dir, std::slice::from_ref(e)).ok())
        .flatten()
        .collect();
    let data = std::iter::once(&spec.data)
        .chain(&spec.also)
        .map(|d| d.display().to_string())
        .collect::<Vec<_>>()
        .join(" + ");
    let own = (steps * spec.batch) as u64;
    let start = spec.init.as_ref().or(spec.teacher.as_ref());
    let start_sha256 = start
        .and_then(|p| std::fs::read(p).ok())
        .map(|bytes| sim::record::sha256_hex(&bytes));
    let before = match start {
        None => Some(0),
        Some(start) => checkpoint::read_manifest(start)
            .ok()
            .and_then(|(_, card)| card.training?.frames_seen),
    };
    ModelCard {
        trained: true,
        description: describe(spec),
        source: format!(
            "mrdrive train --stage {} ({} steps of {} samples, seed {}, data {})",
            spec.name, steps, spec.batch, spec.seed, data
        ),
        training: Some(TrainingRecord {
            stage: spec.name.clone(),
            data,
            samples_in_data: set.samples.len(),
            steps,
            batch: spec.batch,
            seed: spec.seed,
            lr: spec.train.lr,
            losses: "see losses.csv beside the run".into(),
            wall_s,
            machine: machine(),
            init: spec.init.as_ref().map(|p| p.display().to_string()),
            sampling: spec.sampling.clone(),
            build: sim::output::provenance::build_id(),
            episodes: spec.episodes,
            towns,
            routes,
            frames_seen: before.map(|b| b + own),
            start_sha256,
            data_sha256,
            checkpoint_sha256: None,
            learning_curve: None,
        }),
    }
}

/// The episodes a stage trains on of its first dataset: the first `limit` (all
/// without one).
fn first_episodes(episodes: &[Episode], limit: Option<usize>) -> &[Episode] {
    &episodes[..limit.unwrap_or(usize::MAX).min(episodes.len())]
}

/// Episodes by town and by route (`RouteSpec::key`).
type Tally = BTreeMap<String, usize>;

/// Counts `episodes` by town and by route.
fn by_town_and_route<'a>(episodes: impl Iterator<Item = &'a Episode>) -> (Tally, Tally) {
    let (mut towns, mut routes) = (Tally::new(), Tally::new());
    for e in episodes {
        *towns.entry(e.town.clone()).or_insert(0) += 1;
        *routes.entry(e.route.key()).or_insert(0) += 1;
    }
    (towns, routes)
}

/// Adds to a finished run's card (`final.json` in `run_dir`) its episodes by route,
/// where the build that trained it did not write them (before 2026-12-07): counted
/// as [`final_card`] counts them, from the indexes of the data `spec` names (the
/// first `spec.episodes` of its `data`, every episode of its `also`). The weights
/// are not touched. A card that has them, or data whose index cannot be read (a lost
/// cache), is left as it is.
pub(super) fn complete_final_card(spec: &StageSpec, run_dir: &Path) -> Result<(), StageError> {
    let weights = run_dir.join(FINAL_FILE);
    let (config, mut card) = checkpoint::read_manifest(&weights)?;
    let Some(record) = card.training.as_mut().filter(|t| t.routes.is_empty()) else {
        return Ok(());
    };
    let Ok(first) = Index::load(&spec.data) else {
        return Ok(());
    };
    let mut also = Vec::new();
    for dir in &spec.also {
        let Ok(index) = Index::load(dir) else {
            return Ok(());
        };
        also.push(index);
    }
    let used = first_episodes(&first.episodes, spec.episodes);
    let (_, routes) = by_town_and_route(used.iter().chain(also.iter().flat_map(|i| &i.episodes)));
    record.routes = routes;
    checkpoint::write_manifest(&weights, &config, &card)?;
    Ok(())
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
