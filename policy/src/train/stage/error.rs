//! Why a stage could not run: [`StageError`].

use std::path::{Path, PathBuf};

use crate::checkpoint::CheckpointError;
use crate::model::ConfigError;
use crate::train::loader::LoadError;
use crate::train::multires::StateError;
use crate::train::presets::UnknownPreset;

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
    Preset(#[from] UnknownPreset),
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

/// A file of the run folder at `path` that could not be read or written (`e`), and `fix`.
pub(super) fn io_err(path: &Path, e: impl std::fmt::Display, fix: &str) -> StageError {
    StageError::File {
        path: path.to_path_buf(),
        problem: e.to_string(),
        fix: fix.into(),
    }
}
