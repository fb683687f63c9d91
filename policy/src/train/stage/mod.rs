//! A training stage on a dataset: the paper's four recipes, run in a folder that
//! survives a kill.
//!
//! A stage is one of (docs/protocol.md §4-§6, WOR.md §4-§5):
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
//!
//! | file | concern |
//! | --- | --- |
//! | `start.rs` | resume and init: where a run folder stands, the network, the dataset and the trainer |
//! | `train_loop.rs` | the steps: batches, the loss log, the checkpoints of the run state |
//! | `finish.rs` | the BN recalibration and the trained checkpoint |
//! | `cards.rs` | the cards written on `latest.safetensors` and `final.safetensors` |
//! | `run_folder.rs` | the files of a run folder, written so that a kill leaves them whole |
//! | `snapshot.rs` | a job's end: the newest run's network in half precision, to commit |
//! | `error.rs` | [`StageError`]: why a stage could not run, and the fix |
//!
//! The stage's settings are [`StageSpec`] (`crate::train::spec`); a finished run is
//! copied beside the other models by [`crate::train::publish`].

mod cards;
mod error;
mod finish;
mod run_folder;
mod snapshot;
mod start;
mod train_loop;

use std::path::{Path, PathBuf};
use std::time::SystemTime;

use burn::prelude::*;

pub use crate::train::spec::StageSpec;
pub use cards::machine;
pub use error::StageError;
pub use finish::StageOutcome;
pub use run_folder::{FINAL_FILE, LATEST_FILE, LOSSES_FILE, Progress, losses_header};
pub use snapshot::{ResumeState, Snapshot, read_resume, resume_path, run_folders, snapshot};
pub use train_loop::StepUpdate;

use start::{ResumePoint, Session, resume_point};

/// Runs (or resumes, or skips when done) the stage `spec` in `run_dir` on `device` (an
/// autodiff device); `on_step` sees every step. Returns the trained checkpoint.
pub fn run_stage(
    spec: &StageSpec,
    run_dir: &Path,
    device: &Device,
    on_step: impl FnMut(&StepUpdate<'_>),
) -> Result<StageOutcome, StageError> {
    run_stage_until(spec, run_dir, device, &Job::default(), on_step)
}

/// What a job of a chain asks of a stage besides its spec.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Job {
    /// The time limit: once it has passed, the stage checkpoints its state after the
    /// step in progress and returns with [`StageOutcome::stopped_at`] set; running it
    /// again goes on from there, bit for bit as if it had not stopped.
    pub stop_at: Option<SystemTime>,
    /// A committed snapshot ([`snapshot`]) to go on from when the run folder has no
    /// state of its own (the cache was lost): the snapshot's weights at its step,
    /// Adam's moments started afresh. Used only when the snapshot is of this run.
    pub resume_state: Option<PathBuf>,
}

/// [`run_stage`] as a job of a chain (a Slurm time limit, a preemptible machine):
/// see [`Job`].
pub fn run_stage_until(
    spec: &StageSpec,
    run_dir: &Path,
    device: &Device,
    job: &Job,
    mut on_step: impl FnMut(&StepUpdate<'_>),
) -> Result<StageOutcome, StageError> {
    // A snapshot of this run: used below only when the run folder has no state. One
    // at step 0 holds nothing trained (it says where a chain goes on): the stage
    // starts from its init as without it.
    let snapshot_here = match &job.resume_state {
        Some(file) => {
            let r = read_resume(file)?;
            (run_dir.ends_with(&r.run) && r.step > 0).then_some((file.as_path(), r))
        }
        None => None,
    };
    let progress = match resume_point(spec, run_dir, snapshot_here.is_some())? {
        ResumePoint::Done(p) => {
            cards::complete_final_card(spec, run_dir)?;
            return Ok(StageOutcome {
                checkpoint: run_dir.join(FINAL_FILE),
                steps_now: 0,
                wall_s: p.wall_s,
                stopped_at: None,
            });
        }
        ResumePoint::From(progress) => progress,
    };
    let from_snapshot = if progress.is_none() {
        snapshot_here
    } else {
        None
    };
    let mut session = Session::start(spec, run_dir, device, progress, from_snapshot)?;
    let done_before = session.done;
    let (wall_s, stopped_at) = session.train(device, job.stop_at, &mut on_step)?;
    if let Some(step) = stopped_at {
        return Ok(StageOutcome {
            checkpoint: run_dir.join(LATEST_FILE),
            steps_now: step - done_before,
            wall_s,
            stopped_at,
        });
    }
    session.finish(device, wall_s)
}

// The tests are in `policy/tests/stage.rs`: they seed burn's device RNG, which is global,
// so they run in their own process, one at a time.
