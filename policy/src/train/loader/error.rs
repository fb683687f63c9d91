//! Why a dataset cannot feed training: [`LoadError`].

use std::path::PathBuf;

use dataset::action::{NUM_COMMANDS, NUM_SPEED_BINS};
use dataset::format::DataError;

/// Why a dataset cannot feed training.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The index is missing or unreadable.
    #[error(transparent)]
    Data(#[from] DataError),
    /// The directory has nothing in it.
    #[error(
        "{0}: the dataset directory is empty; collect into it with `mrdrive collect --out {0}`, then label it with `mrdrive label {0}`"
    )]
    EmptyDir(PathBuf),
    /// No episode gave a labelled frame.
    #[error(
        "{dir}: no labelled frame to train on ({episodes} episodes in the index{skipped}); label the dataset with `mrdrive label {dir}`"
    )]
    NoSamples {
        /// The dataset directory.
        dir: PathBuf,
        /// Episodes in the index.
        episodes: usize,
        /// The skipped files, as text.
        skipped: String,
    },
    /// Fewer usable episodes than the run is pinned to (`--episodes`).
    #[error(
        "{dir}: the stage trains on the first {wanted} episodes (--episodes {wanted}) but {usable} of them are collected and labelled{first_problem}; collect and label up to {wanted} (`mrdrive data study` goes on where it stopped), or lower --episodes"
    )]
    Short {
        /// The dataset directory.
        dir: PathBuf,
        /// The episodes the run trains on.
        wanted: usize,
        /// Those of them usable.
        usable: usize,
        /// The first unusable one and why, as text.
        first_problem: String,
    },
    /// The dataset's images are not the size the policy takes.
    #[error(
        "{index}: s0 is {w} x {h} but the policy takes {pw} x {ph}; train a policy config with input_width {w} and input_height {h}, or collect at the policy's size"
    )]
    Size {
        /// The index file.
        index: PathBuf,
        /// The dataset's width.
        w: u32,
        /// The dataset's height.
        h: u32,
        /// The policy's width.
        pw: usize,
        /// The policy's height.
        ph: usize,
    },
    /// A further dataset was collected with other camera views or frame spacing.
    #[error(
        "{index}: {found}, but the stage's first dataset has {want}; train on datasets collected with one rig (mrdrive collect's defaults)"
    )]
    Mismatch {
        /// The further dataset's index file.
        index: PathBuf,
        /// What it holds, as text.
        found: String,
        /// What the first holds, as text.
        want: String,
    },
    /// The policy's head does not have WoR's commands and speed bins.
    #[error(
        "policy config num_commands {commands} and num_speed_bins {bins}: the labels have {NUM_COMMANDS} and {NUM_SPEED_BINS}; use those"
    )]
    Head {
        /// The config's commands.
        commands: usize,
        /// The config's speed bins.
        bins: usize,
    },
}
