//! Resume and init: where a run folder stands (done, or the step to resume from),
//! and the [`Session`] a stage trains in: the network (fresh, from `init`, or from
//! the teacher), the dataset, the trainer (new or resumed) and the loss log.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use burn::prelude::*;

use super::error::{StageError, io_err};
use super::run_folder::{
    FINAL_FILE, LOSSES_FILE, Progress, SPEC_FILE, STATE_DIR, check_or_write_inputs,
    check_or_write_spec, open_losses, read_progress,
};
use super::snapshot::ResumeState;
use crate::checkpoint;
use crate::model::{PolicyConfig, PolicyNet};
use crate::train::loader::TrainSet;
use crate::train::multires::MultiResTrainer;
use crate::train::presets::Preset;
use crate::train::spec::StageSpec;

/// Where a run folder stands before training.
pub(super) enum ResumePoint {
    /// The final checkpoint is that of the saved state's last step: nothing to do.
    Done(Progress),
    /// Train from the saved state (`None`: from the start).
    From(Option<Progress>),
}

/// A stage opened for training.
pub(super) struct Session<'a> {
    /// The stage's settings.
    pub(super) spec: &'a StageSpec,
    /// The run folder.
    pub(super) run_dir: &'a Path,
    /// The network the stage trains.
    pub(super) config: PolicyConfig,
    /// The dataset.
    pub(super) set: Arc<TrainSet>,
    /// The trainer: the student, the teacher and Adam's moments.
    pub(super) trainer: MultiResTrainer,
    /// Steps done before this process started (by earlier runs of the stage it resumes).
    pub(super) done: usize,
    /// Training wall time before this process started (seconds, summed over every earlier run of the stage).
    pub(super) wall_before_s: f64,
    /// The trainer state's folder.
    pub(super) state_dir: PathBuf,
    /// The loss log, open for appending.
    pub(super) losses: std::fs::File,
    /// Its path.
    pub(super) losses_path: PathBuf,
}

/// Makes the run folder, refuses one made with other settings or inputs, and says
/// where the stage resumes. Done when the final checkpoint is that of the saved
/// state's step (an extended run's earlier final is not).
///
/// `snapshot` says a committed snapshot of this run is at hand: then an `--init`
/// checkpoint that is gone (it lived in a lost cache: the round of the learning
/// curve before this one) is not needed, as the weights come from the snapshot.
pub(super) fn resume_point(
    spec: &StageSpec,
    run_dir: &Path,
    snapshot: bool,
) -> Result<ResumePoint, StageError> {
    std::fs::create_dir_all(run_dir)
        .map_err(|e| io_err(run_dir, e, "check the parent folder exists and is writable"))?;
    check_or_write_spec(spec, &run_dir.join(SPEC_FILE), run_dir)?;
    let init_gone = snapshot && init_gone(spec);
    check_or_write_inputs(spec, run_dir, init_gone)?;
    let progress = read_progress(&run_dir.join(STATE_DIR))?;
    let final_step = checkpoint::read_manifest(&run_dir.join(FINAL_FILE))
        .ok()
        .and_then(|(_, card)| card.training.map(|t| t.steps));
    Ok(
        match progress.filter(|p| p.step >= spec.steps && final_step == Some(p.step)) {
            Some(p) => ResumePoint::Done(p),
            None => ResumePoint::From(progress),
        },
    )
}

impl<'a> Session<'a> {
    /// Builds the network (the device seeded with the spec's seed first), opens the
    /// dataset, and makes or resumes the trainer at `progress`; the loss log keeps
    /// the rows of the steps done.
    pub(super) fn start(
        spec: &'a StageSpec,
        run_dir: &'a Path,
        device: &Device,
        progress: Option<Progress>,
        from_snapshot: Option<(&Path, ResumeState)>,
    ) -> Result<Session<'a>, StageError> {
        let preset: Preset = spec.preset.parse()?;
        let config = preset.config(&spec.scales);
        config.validate()?;
        device.seed(spec.seed);
        let (student, teacher) = match &spec.teacher {
            // Weights from a snapshot replace the student's: its init need not exist.
            None if from_snapshot.is_some() && init_gone(spec) => (config.init(device), None),
            None => (initial_net(spec, &config, device)?, None),
            Some(path) => {
                let (teacher, _) = checkpoint::load(path, device)?;
                check_teacher(&teacher, &config, path)?;
                (teacher.to_multires(spec.scales.clone())?, Some(teacher))
            }
        };
        let set = Arc::new(
            TrainSet::open_first(&spec.data, &config, spec.episodes)?
                .with_also(&spec.also, &config)?,
        );
        let state_dir = run_dir.join(STATE_DIR);
        let (trainer, wall_before_s) = match (progress, from_snapshot) {
            (Some(p), _) => (
                MultiResTrainer::resume(
                    student,
                    teacher,
                    spec.train.clone(),
                    device,
                    &state_dir,
                    p.step,
                )?,
                p.wall_s,
            ),
            (None, Some((file, r))) => {
                let (net, _) = checkpoint::load(file, device)?;
                check_same_network(&net.config, &config, file)?;
                let t = MultiResTrainer::continue_from(
                    net,
                    teacher,
                    spec.train.clone(),
                    device,
                    r.step,
                );
                (t, r.wall_s)
            }
            (None, None) => (
                MultiResTrainer::new(student, teacher, spec.train.clone(), device),
                0.0,
            ),
        };
        let done = trainer.steps_done();
        let losses_path = run_dir.join(LOSSES_FILE);
        let losses = open_losses(&losses_path, &spec.scales, done)?;
        Ok(Session {
            spec,
            run_dir,
            config,
            set,
            trainer,
            done,
            wall_before_s,
            state_dir,
            losses,
            losses_path,
        })
    }
}

/// The network a stage without a teacher starts from: a fresh initialisation, or the
/// weights of `spec.init` when they are of the same network.
fn initial_net(
    spec: &StageSpec,
    config: &PolicyConfig,
    device: &Device,
) -> Result<PolicyNet, StageError> {
    let Some(path) = &spec.init else {
        return Ok(config.init(device));
    };
    let (net, _) = checkpoint::load(path, device)?;
    check_same_network(&net.config, config, path)?;
    Ok(net)
}

/// Whether the stage's `--init` checkpoint is named but gone (it lived in a lost cache).
fn init_gone(spec: &StageSpec) -> bool {
    spec.init.as_ref().is_some_and(|p| !p.exists())
}

/// Refuses weights (`--init`, a snapshot) of another network than the stage trains.
fn check_same_network(
    c: &PolicyConfig,
    config: &PolicyConfig,
    path: &Path,
) -> Result<(), StageError> {
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
            path: path.to_path_buf(),
            problem: "the weights are of another network than the stage trains".into(),
            fix: "give a checkpoint of the same preset and scales".into(),
        });
    }
    Ok(())
}

/// Refuses a teacher that is not a single-resolution 1.0x network of the stage's
/// depth, widths and input size.
fn check_teacher(
    teacher: &PolicyNet,
    config: &PolicyConfig,
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
