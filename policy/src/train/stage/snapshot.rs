//! The end of a job of a training chain: the state of the stage in progress,
//! small enough to commit (one path, replaced each time), and a line in the
//! chain's log.
//!
//! A run's full state (f32 network and Adam's moments) lives in the cache
//! (`dataset::cache`), which the next job usually finds again. When it does not
//! (a fresh machine), the committed snapshot is what is left: the network of the
//! newest run folder at its last checkpoint, in half precision
//! ([`checkpoint::save_f16`]), with its card (stage, steps) beside it.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::error::{StageError, io_err};
use super::run_folder::{
    LATEST_FILE, LOSSES_FILE, PROGRESS_FILE, Progress, STATE_DIR, read_progress,
};
use crate::checkpoint;

/// Where a snapshot's run stood, written beside it ([`resume_path`]): what a
/// stage needs to go on from the snapshot alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResumeState {
    /// The run folder, relative to the runs folder it was taken from (`wor/original`).
    pub run: PathBuf,
    /// Steps done.
    pub step: usize,
    /// Training wall time so far (seconds).
    pub wall_s: f64,
}

/// The resume record of a snapshot `out`: the same name ending in `.resume.json`.
pub fn resume_path(out: &Path) -> PathBuf {
    out.with_extension("resume.json")
}

/// Reads the resume record of snapshot `out`.
pub fn read_resume(out: &Path) -> Result<ResumeState, StageError> {
    let path = resume_path(out);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        io_err(
            &path,
            e,
            "give --resume-state a snapshot written by `mrdrive train --all --snapshot`",
        )
    })?;
    serde_json::from_str(&text).map_err(|e| {
        io_err(
            &path,
            format!("malformed: {e}"),
            "write the snapshot again, or leave --resume-state out",
        )
    })
}

/// What a snapshot holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// The run folder it was taken from.
    pub run: PathBuf,
    /// Where that run stood.
    pub progress: Progress,
    /// The last row of its loss log (`losses.csv`), as written.
    pub last_losses: Option<String>,
}

/// The run folders under `runs` (down to three levels, as the pipeline nests them:
/// `ra`, `curve/slice-05/original`) with a checkpointed state, newest first.
pub fn run_folders(runs: &Path) -> Vec<(PathBuf, Progress)> {
    let mut found = Vec::new();
    let children = |dir: &Path| -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .map(|it| {
                it.flatten()
                    .map(|e| e.path())
                    .filter(|p| p.is_dir())
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    };
    let mut runs_below = Vec::new();
    let mut level = vec![runs.to_path_buf()];
    for _ in 0..3 {
        level = level.iter().flat_map(|d| children(d)).collect();
        runs_below.extend(level.iter().cloned());
    }
    for run in runs_below {
        let state = run.join(STATE_DIR);
        let (Ok(Some(p)), Ok(meta)) = (
            read_progress(&state),
            std::fs::metadata(state.join(PROGRESS_FILE)),
        ) else {
            continue;
        };
        let when = meta.modified().unwrap_or(std::time::UNIX_EPOCH);
        found.push((when, run, p));
    }
    found.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| a.1.cmp(&b.1)));
    found.into_iter().map(|(_, run, p)| (run, p)).collect()
}

/// Writes the network of the newest run folder under `runs` at its last
/// checkpoint to `out` in half precision, with its card beside it
/// (`out` with extension `.json`); `None` when no run folder has a state yet.
pub fn snapshot(runs: &Path, out: &Path) -> Result<Option<Snapshot>, StageError> {
    let Some((run, progress)) = run_folders(runs).into_iter().next() else {
        return Ok(None);
    };
    let latest = run.join(LATEST_FILE);
    let device = burn::prelude::Device::flex();
    let (net, card) = checkpoint::load(&latest, &device)?;
    if let Some(parent) = out.parent() {
        std::fs::create_dir_all(parent)
            .map_err(|e| io_err(parent, e, "check the folder can be made"))?;
    }
    checkpoint::save_f16(&net, &card, out)?;
    let resume = ResumeState {
        run: run.strip_prefix(runs).unwrap_or(&run).to_path_buf(),
        step: progress.step,
        wall_s: progress.wall_s,
    };
    let path = resume_path(out);
    let json = serde_json::to_string_pretty(&resume).expect("a resume record serialises");
    std::fs::write(&path, json).map_err(|e| io_err(&path, e, "check the folder is writable"))?;
    let last_losses = std::fs::read_to_string(run.join(LOSSES_FILE))
        .ok()
        .and_then(|t| t.lines().last().map(String::from))
        .filter(|l| !l.starts_with("step,"));
    Ok(Some(Snapshot {
        run,
        progress,
        last_losses,
    }))
}
