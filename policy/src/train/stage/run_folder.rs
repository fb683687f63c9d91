//! The files of a run folder: the spec and the inputs a run started from (checked
//! on resume), the trainer state with its [`Progress`] (swapped in whole), and the
//! loss log.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::error::{StageError, io_err};
use crate::train::multires::MultiResTrainer;
use crate::train::spec::StageSpec;

/// Where a stage stands, saved with each checkpoint.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// Steps done.
    pub step: usize,
    /// Training wall time so far (seconds, over every session).
    pub wall_s: f64,
}

pub(super) const SPEC_FILE: &str = "spec.json";
/// The SHA-256 of the checkpoints a run started from, by field (`teacher`, `init`).
const INPUTS_FILE: &str = "inputs.json";
pub(super) const STATE_DIR: &str = "state";
pub(super) const PROGRESS_FILE: &str = "progress.json";
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

pub(super) fn check_or_write_spec(
    spec: &StageSpec,
    path: &Path,
    run_dir: &Path,
) -> Result<(), StageError> {
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
/// before it existed) takes today's checkpoints as its own. With `init_gone`, the
/// `--init` checkpoint is left out (it is not needed: the run goes on from a
/// committed snapshot).
pub(super) fn check_or_write_inputs(
    spec: &StageSpec,
    run_dir: &Path,
    init_gone: bool,
) -> Result<(), StageError> {
    let path = run_dir.join(INPUTS_FILE);
    let saved: std::collections::BTreeMap<String, String> =
        read_json(&path, &start_again(run_dir))?.unwrap_or_default();
    let mut now = std::collections::BTreeMap::new();
    let init = if init_gone { &None } else { &spec.init };
    for (field, file) in [("teacher", &spec.teacher), ("init", init)] {
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

pub(super) fn read_progress(state_dir: &Path) -> Result<Option<Progress>, StageError> {
    read_json(
        &state_dir.join(PROGRESS_FILE),
        "delete the state folder to start the stage again",
    )
}

/// Writes the state into `state.tmp/`, then swaps it in: a kill at any moment leaves
/// either the old or the new checkpoint whole.
pub(super) fn save_state(
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
pub(super) fn open_losses(
    path: &Path,
    scales: &[f32],
    done: usize,
) -> Result<std::fs::File, StageError> {
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
