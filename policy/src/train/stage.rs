//! A training stage on a dataset: the paper's four recipes, run in a folder that
//! survives a kill.
//!
//! A stage is one of (PROTOCOL §4-§6, WOR.md §4-§5):
//! - **original**: a single-resolution network (1.0x) from scratch, WoR's loss
//!   (action KL with the command grouping + 0.05 segmentation), Adam 3e-4;
//! - **nra-R**: the Original retargeted to the one scale R without BN banks: teacher
//!   = the frozen Original at 1.0x, act + 0.05 seg + KD + features, progressive
//!   unfreezing layer4 -> layer1 with a new Adam per stage, the action head frozen,
//!   then BN recalibration;
//! - **ra**: the same with a BN branch per scale and the multi-resolution step.
//!
//! The run folder holds:
//! - `spec.json`: the stage's settings; a resume with other settings is refused by
//!   the field's name;
//! - `state/`: the network, Adam's moments and `progress.json`, written every
//!   [`StageSpec::checkpoint_every`] steps (to `state.tmp/`, then renamed);
//! - `losses.csv`: one row per step (a resume drops rows past the checkpoint: they
//!   are recomputed, bit for bit);
//! - `latest.safetensors` + `latest.json`: the network at the last checkpoint;
//! - `final.safetensors` + `final.json`: the trained checkpoint and its card.

use super::loader::{LoadError, Loader, LoaderConfig, Sampling, TrainSet};
use super::multires::{MultiResTrainer, StateError, StepReport, TrainConfig};
use super::presets::Preset;
use super::recalibrate::recalibrate_with;
use super::resize::resize_to_scale;
use crate::checkpoint::{self, CheckpointError, ModelCard, TrainingRecord};
use crate::model::{ConfigError, PolicyNet};
use burn::prelude::*;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

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

/// Where a stage stands, saved with each checkpoint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// Steps done.
    pub step: usize,
    /// Training wall time so far (seconds, over every session).
    pub wall_s: f64,
}

/// What a stage reports while it runs.
#[derive(Debug, Clone)]
pub struct StepUpdate<'a> {
    /// The step's losses.
    pub report: &'a StepReport,
    /// Steps in the stage.
    pub steps: usize,
    /// Samples per second since this process started or resumed the stage.
    pub samples_per_s: f64,
    /// Whether the state was just checkpointed.
    pub checkpointed: bool,
    /// The dataset's episodes left out because their files are unreadable
    /// (the same list at every step: say it once).
    pub skipped: &'a [crate::train::loader::Skipped],
}

/// How a stage ended.
#[derive(Debug, Clone, PartialEq)]
pub struct StageOutcome {
    /// The trained checkpoint (`final.safetensors` in the run folder).
    pub checkpoint: PathBuf,
    /// Steps taken in this call (0 when the stage was already done).
    pub steps_now: usize,
    /// Training wall time over every session (seconds).
    pub wall_s: f64,
}

/// Why a stage could not run.
#[derive(Debug, thiserror::Error)]
pub enum StageError {
    /// A file of the run folder could not be read or written.
    #[error("{path}: {problem}; fix: {fix}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        problem: String,
        /// What would fix it.
        fix: String,
    },
    /// The run folder was made with other settings.
    #[error(
        "{path}: the run was started with other settings: {fields}; fix: pass the same settings, or delete {dir} to start the stage again"
    )]
    Mismatch {
        /// The run's spec file.
        path: PathBuf,
        /// The fields that differ.
        fields: String,
        /// The run folder.
        dir: PathBuf,
    },
    /// The preset name is unknown.
    #[error(transparent)]
    Preset(#[from] super::presets::UnknownPreset),
    /// The network config is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The dataset cannot feed training.
    #[error(transparent)]
    Data(#[from] LoadError),
    /// The teacher checkpoint is unusable.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// The saved trainer state is unusable.
    #[error(transparent)]
    State(#[from] StateError),
    /// A teacher or initial checkpoint does not fit the stage.
    #[error("{path}: {problem}; fix: {fix}")]
    Misfit {
        /// The teacher or initial checkpoint.
        path: PathBuf,
        /// What is wrong.
        problem: String,
        /// What would fix it.
        fix: String,
    },
}

fn io_err(path: &Path, e: impl std::fmt::Display, fix: &str) -> StageError {
    StageError::File {
        path: path.to_path_buf(),
        problem: e.to_string(),
        fix: fix.into(),
    }
}

const SPEC_FILE: &str = "spec.json";
/// The SHA-256 of the checkpoints a run started from, by field (`teacher`, `init`).
const INPUTS_FILE: &str = "inputs.json";
const STATE_DIR: &str = "state";
const PROGRESS_FILE: &str = "progress.json";
/// The loss log of a run folder.
pub const LOSSES_FILE: &str = "losses.csv";
/// The trained checkpoint of a run folder.
pub const FINAL_FILE: &str = "final.safetensors";
/// The network at the last checkpoint of a run folder (for a look during training).
pub const LATEST_FILE: &str = "latest.safetensors";

/// The header of `losses.csv` for a stage with `scales`.
pub fn losses_header(scales: &[f32]) -> String {
    let per: Vec<String> = scales.iter().map(|s| format!("loss_{s}x")).collect();
    format!(
        "step,epoch,loss,act,seg,kd,feat,{},unfrozen_stages,samples_per_s,wall_s",
        per.join(",")
    )
}

/// Runs (or resumes, or skips when done) the stage `spec` in `run_dir` on `device` (an
/// autodiff device); `on_step` sees every step. Returns the trained checkpoint.
pub fn run_stage(
    spec: &StageSpec,
    run_dir: &Path,
    device: &Device,
    mut on_step: impl FnMut(&StepUpdate<'_>),
) -> Result<StageOutcome, StageError> {
    let final_path = run_dir.join(FINAL_FILE);
    std::fs::create_dir_all(run_dir)
        .map_err(|e| io_err(run_dir, e, "check the parent folder exists and is writable"))?;
    let spec_path = run_dir.join(SPEC_FILE);
    check_or_write_spec(spec, &spec_path, run_dir)?;
    check_or_write_inputs(spec, run_dir)?;
    let state_dir = run_dir.join(STATE_DIR);
    let progress = read_progress(&state_dir)?;
    // Done when the final checkpoint is that of the saved state's step (an extended run's
    // earlier final is not).
    let final_step = checkpoint::read_manifest(&final_path)
        .ok()
        .and_then(|(_, card)| card.training.map(|t| t.steps));
    if let Some(p) = progress.filter(|p| p.step >= spec.steps && final_step == Some(p.step)) {
        return Ok(StageOutcome {
            checkpoint: final_path,
            steps_now: 0,
            wall_s: p.wall_s,
        });
    }

    let preset: Preset = spec.preset.parse()?;
    let config = preset.config(&spec.scales);
    config.validate()?;
    device.seed(spec.seed);
    let fresh = || -> Result<PolicyNet, StageError> {
        match &spec.init {
            None => Ok(config.init(device)),
            Some(path) => {
                let (net, _) = checkpoint::load(path, device)?;
                let c = &net.config;
                if (c.depth, c.widths, c.input_width, c.input_height, &c.scales)
                    != (
                        config.depth,
                        config.widths,
                        config.input_width,
                        config.input_height,
                        &config.scales,
                    )
                {
                    return Err(StageError::Misfit {
                        path: path.clone(),
                        problem: "the initial weights are of another network than the stage trains"
                            .into(),
                        fix: "pass --init a checkpoint of the same preset and scales".into(),
                    });
                }
                Ok(net)
            }
        }
    };
    let (student, teacher) = match &spec.teacher {
        None => (fresh()?, None),
        Some(path) => {
            let (teacher, _) = checkpoint::load(path, device)?;
            check_teacher(&teacher, &config, path)?;
            (teacher.to_multires(spec.scales.clone())?, Some(teacher))
        }
    };
    let set = Arc::new(TrainSet::open(&spec.data, &config)?);
    let mut trainer = match progress {
        Some(p) => MultiResTrainer::resume(
            student,
            teacher,
            spec.train.clone(),
            device,
            &state_dir,
            p.step,
        )?,
        None => MultiResTrainer::new(student, teacher, spec.train.clone(), device),
    };
    let done = trainer.steps_done();
    let mut wall_before = progress.map_or(0.0, |p| p.wall_s);
    let losses_path = run_dir.join(LOSSES_FILE);
    let mut losses = open_losses(&losses_path, &spec.scales, done)?;

    let loader_cfg = LoaderConfig {
        batch: spec.batch,
        seed: spec.seed,
        augment: spec.augment.then(Default::default),
        sampling: spec.sampling.clone(),
        ..LoaderConfig::new(spec.batch, spec.seed)
    };
    let per_epoch = (set.epoch_len(&loader_cfg) / spec.batch.max(1)).max(1);
    let mut loader = Loader::start(
        set.clone(),
        &config,
        LoaderConfig {
            first_epoch: (done / per_epoch) as u64,
            first_batch: done % per_epoch,
            ..loader_cfg.clone()
        },
    );
    let started = Instant::now();
    for step in done..spec.steps {
        let Some(batch) = loader.next_batch(device) else {
            if let Some(e) = loader.failure() {
                return Err(LoadError::from(e).into());
            }
            break;
        };
        let report = trainer.step(&batch);
        let elapsed = started.elapsed().as_secs_f64();
        let samples_per_s = ((step + 1 - done) * spec.batch) as f64 / elapsed.max(1e-9);
        let per: Vec<String> = report.per_scale.iter().map(|l| format!("{l}")).collect();
        writeln!(
            losses,
            "{},{},{},{},{},{},{},{},{},{:.2},{:.1}",
            step,
            step / per_epoch,
            report.loss,
            report.parts.act,
            report.parts.seg,
            report.parts.kd,
            report.parts.feat,
            per.join(","),
            report.unfrozen_stages,
            samples_per_s,
            wall_before + elapsed
        )
        .map_err(|e| io_err(&losses_path, e, "check the disk has room"))?;
        let last = step + 1 == spec.steps;
        let due = spec.checkpoint_every > 0 && (step + 1) % spec.checkpoint_every == 0;
        if last || due {
            losses
                .flush()
                .map_err(|e| io_err(&losses_path, e, "check the disk has room"))?;
            save_state(
                &trainer,
                &state_dir,
                Progress {
                    step: step + 1,
                    wall_s: wall_before + elapsed,
                },
            )?;
            // The network so far, loadable by every tool (e.g. `mrdrive run --checkpoint`),
            // to look at a run before it ends. Without the final recalibration.
            let card = ModelCard {
                trained: true,
                description: format!("{} (in training: step {})", describe(spec), step + 1),
                source: format!(
                    "{} after {} of {} steps",
                    run_dir.display(),
                    step + 1,
                    spec.steps
                ),
                training: None,
            };
            checkpoint::save(&trainer.net.valid(), &card, &run_dir.join(LATEST_FILE))?;
        }
        on_step(&StepUpdate {
            report: &report,
            steps: spec.steps,
            samples_per_s,
            checkpointed: last || due,
            skipped: &set.skipped,
        });
    }
    drop(loader);
    wall_before += started.elapsed().as_secs_f64();
    let trainer_steps = trainer.steps_done();
    let steps_now = trainer_steps - done;

    let mut net = trainer.net.valid();
    if spec.recalibrate_batches > 0 {
        net = recalibrate_on(net, &set, &config, spec, device);
    }
    let card = ModelCard {
        trained: true,
        description: describe(spec),
        source: format!(
            "mrdrive train --stage {} ({} steps of {} samples, seed {}, data {})",
            spec.name,
            trainer_steps,
            spec.batch,
            spec.seed,
            spec.data.display()
        ),
        training: Some(TrainingRecord {
            stage: spec.name.clone(),
            data: spec.data.display().to_string(),
            samples_in_data: set.samples.len(),
            steps: trainer_steps,
            batch: spec.batch,
            seed: spec.seed,
            lr: spec.train.lr,
            losses: "see losses.csv beside the run".into(),
            wall_s: wall_before,
            machine: machine(),
            init: spec.init.as_ref().map(|p| p.display().to_string()),
            sampling: spec.sampling.clone(),
        }),
    };
    checkpoint::save(&net, &card, &final_path)?;
    Ok(StageOutcome {
        checkpoint: final_path,
        steps_now,
        wall_s: wall_before,
    })
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

fn check_teacher(
    teacher: &PolicyNet,
    config: &crate::model::PolicyConfig,
    path: &Path,
) -> Result<(), StageError> {
    let t = &teacher.config;
    let fail = |problem: String| StageError::Misfit {
        path: path.to_path_buf(),
        problem,
        fix: "train the Original first (`mrdrive train --stage original`) with the same preset"
            .into(),
    };
    if t.scales != [1.0] {
        return Err(fail(format!(
            "the teacher has scales {:?}; a teacher is a single-resolution 1.0x network",
            t.scales
        )));
    }
    if (t.depth, t.widths, t.input_width, t.input_height)
        != (
            config.depth,
            config.widths,
            config.input_width,
            config.input_height,
        )
    {
        return Err(fail(format!(
            "the teacher is a {} {:?} at {}x{}, the stage trains a {} {:?} at {}x{}",
            t.depth.name(),
            t.widths,
            t.input_width,
            t.input_height,
            config.depth.name(),
            config.widths,
            config.input_width,
            config.input_height
        )));
    }
    Ok(())
}

/// The JSON file `path` of a run folder, or `None` when there is none; a malformed file
/// is an error whose fix is `fix`.
fn read_json<T: serde::de::DeserializeOwned>(
    path: &Path,
    fix: &str,
) -> Result<Option<T>, StageError> {
    match std::fs::read_to_string(path) {
        Ok(text) => serde_json::from_str(&text)
            .map(Some)
            .map_err(|e| io_err(path, format!("malformed: {e}"), fix)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(io_err(path, e, "check the file is readable")),
    }
}

/// Writes `value` as pretty JSON to `path` of a run folder; `fix` is the error's.
fn write_json(path: &Path, value: &impl Serialize, fix: &str) -> Result<(), StageError> {
    let json = serde_json::to_string_pretty(value).expect("run-folder records serialise");
    std::fs::write(path, json).map_err(|e| io_err(path, e, fix))
}

/// The fix for a record of a run folder that cannot be written.
const WRITABLE: &str = "check the folder is writable";

/// The fix for a malformed record of a run folder.
fn start_again(run_dir: &Path) -> String {
    format!("delete {} to start the stage again", run_dir.display())
}

fn check_or_write_spec(spec: &StageSpec, path: &Path, run_dir: &Path) -> Result<(), StageError> {
    let Some(saved) = read_json::<StageSpec>(path, &start_again(run_dir))? else {
        return write_json(path, spec, WRITABLE);
    };
    let diff = spec.differences(&saved);
    if diff.is_empty() {
        Ok(())
    } else {
        Err(StageError::Mismatch {
            path: path.to_path_buf(),
            fields: diff.join(", "),
            dir: run_dir.to_path_buf(),
        })
    }
}

/// Refuses a run folder whose teacher or initial checkpoint has changed since the run
/// started (the spec names them by path only), so a retrained Original is not silently
/// the teacher of a half-done or finished stage. A folder without the record (made
/// before it existed) takes today's checkpoints as its own.
fn check_or_write_inputs(spec: &StageSpec, run_dir: &Path) -> Result<(), StageError> {
    let path = run_dir.join(INPUTS_FILE);
    let saved: std::collections::BTreeMap<String, String> =
        read_json(&path, &start_again(run_dir))?.unwrap_or_default();
    let mut now = std::collections::BTreeMap::new();
    for (field, file) in [("teacher", &spec.teacher), ("init", &spec.init)] {
        let Some(file) = file else { continue };
        let bytes = std::fs::read(file)
            .map_err(|e| io_err(file, e, &format!("check the {field} checkpoint exists")))?;
        let sha = sim::record::sha256_hex(&bytes);
        if let Some(then) = saved.get(field).filter(|then| **then != sha) {
            return Err(StageError::File {
                path,
                problem: format!(
                    "the run started from another {field} than {} is now (SHA-256 {then}, now {sha})",
                    file.display()
                ),
                fix: format!(
                    "delete {} to train the stage again from the new {field}, or put the old checkpoint back",
                    run_dir.display()
                ),
            });
        }
        now.insert(field.to_string(), sha);
    }
    if now.keys().all(|field| saved.contains_key(field)) {
        return Ok(());
    }
    write_json(&path, &now, WRITABLE)
}

fn read_progress(state_dir: &Path) -> Result<Option<Progress>, StageError> {
    read_json(
        &state_dir.join(PROGRESS_FILE),
        "delete the state folder to start the stage again",
    )
}

/// Writes the state into `state.tmp/`, then swaps it in: a kill at any moment leaves
/// either the old or the new checkpoint whole.
fn save_state(
    trainer: &MultiResTrainer,
    state_dir: &Path,
    progress: Progress,
) -> Result<(), StageError> {
    let tmp = state_dir.with_extension("tmp");
    let old = state_dir.with_extension("old");
    let fix = "check the disk has room and the folder is writable";
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).map_err(|e| io_err(&tmp, e, fix))?;
    trainer.save_state(&tmp)?;
    write_json(&tmp.join(PROGRESS_FILE), &progress, fix)?;
    let _ = std::fs::remove_dir_all(&old);
    if state_dir.exists() {
        std::fs::rename(state_dir, &old).map_err(|e| io_err(state_dir, e, fix))?;
    }
    std::fs::rename(&tmp, state_dir).map_err(|e| io_err(state_dir, e, fix))?;
    let _ = std::fs::remove_dir_all(&old);
    Ok(())
}

/// Opens the loss log for appending after `done` steps: rows of later steps (written
/// after the last checkpoint) are dropped, a new log gets the header.
fn open_losses(path: &Path, scales: &[f32], done: usize) -> Result<std::fs::File, StageError> {
    let fix = "check the folder is writable";
    let header = losses_header(scales);
    let kept = match std::fs::read_to_string(path) {
        Ok(text) => {
            let mut lines = text.lines();
            match lines.next() {
                Some(h) if h == header => {}
                _ => {
                    return Err(io_err(
                        path,
                        "the header is not this stage's",
                        "delete the run folder to start the stage again",
                    ));
                }
            }
            lines
                .filter(|l| {
                    l.split(',')
                        .next()
                        .and_then(|s| s.parse::<usize>().ok())
                        .is_some_and(|s| s < done)
                })
                .map(String::from)
                .collect::<Vec<String>>()
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => vec![],
        Err(e) => return Err(io_err(path, e, fix)),
    };
    let mut text = header + "\n";
    for r in &kept {
        text.push_str(r);
        text.push('\n');
    }
    std::fs::write(path, text).map_err(|e| io_err(path, e, fix))?;
    std::fs::OpenOptions::new()
        .append(true)
        .open(path)
        .map_err(|e| io_err(path, e, fix))
}

/// BN recalibration on `spec.recalibrate_batches` unaugmented batches per scale.
fn recalibrate_on(
    net: PolicyNet,
    set: &Arc<TrainSet>,
    config: &crate::model::PolicyConfig,
    spec: &StageSpec,
    device: &Device,
) -> PolicyNet {
    let cfg = LoaderConfig {
        augment: None,
        sampling: spec.sampling.clone(),
        epochs: None,
        ..LoaderConfig::new(spec.batch, spec.seed ^ 0x5ca1e)
    };
    let mut loader = Loader::start(set.clone(), config, cfg);
    let batches: Vec<Tensor<4>> = (0..spec.recalibrate_batches)
        .filter_map(|_| loader.next_batch(device).map(|b| b.images))
        .collect();
    drop(loader);
    let n = batches.len();
    let scales = config.scales.clone();
    recalibrate_with(net, n, device, |branch, k| {
        resize_to_scale(batches[k].clone(), scales[branch])
    })
    .valid()
}

// The tests are in `policy/tests/stage.rs`: they seed burn's device RNG, which is global,
// so they run in their own process, one at a time.
