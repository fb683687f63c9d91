//! What can go wrong in a sweep.

use std::path::PathBuf;

use crate::record::ReadRecordError;

/// A sweep's folder, plan or tables could not be used.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// `--shard` is not `INDEX/COUNT` with `0 <= INDEX < COUNT`.
    #[error(
        "--shard {text}: {problem}; fix: write it as INDEX/COUNT with 0 <= INDEX < COUNT, e.g. 0/4"
    )]
    Shard {
        /// What was given.
        text: String,
        /// What is wrong with it.
        problem: &'static str,
    },
    /// `--seeds` or `--densities` is not a list the sweep can run.
    #[error("--{flag} {text}: {problem}")]
    Axis {
        /// The flag, without its dashes.
        flag: &'static str,
        /// What was given.
        text: String,
        /// What is wrong with it and how to write it.
        problem: &'static str,
        /// The number that did not parse.
        #[source]
        source: Option<std::num::ParseIntError>,
    },
    /// A file or folder could not be read, written or created.
    #[error("cannot {action} {path}")]
    Io {
        /// "read", "write" or "create".
        action: &'static str,
        /// The file or folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// `plan.json` is not a sweep plan.
    #[error("{path} is not a sweep plan; fix: give a sweep's folder, or another --out folder")]
    NotAPlan {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        #[source]
        source: serde_json::Error,
    },
    /// A run record could not be read.
    #[error(transparent)]
    Record(#[from] ReadRecordError),
    /// The folder holds another sweep's plan.
    #[error(
        "{root} holds a different sweep; fix: resume it with the same arguments, or give another --out folder"
    )]
    OtherSweep {
        /// The sweep folder.
        root: PathBuf,
    },
    /// A shard folder of a merge belongs to another sweep.
    #[error(
        "{shard} belongs to another sweep (its plan.json differs); fix: merge only the shards of one sweep"
    )]
    ShardOfOtherSweep {
        /// The shard folder.
        shard: PathBuf,
    },
    /// The folder's records were made by a checkpoint (or learned trigger)
    /// whose file has changed since (or by a policy whose records name no
    /// digest).
    #[error(
        "{root}: its runs were made by {file} with SHA-256 {recorded}, but that file now {now}; \
         fix: move the folder aside (or give another --out folder) so that the runs of two \
         checkpoints or triggers are never mixed, or put the old file back"
    )]
    CheckpointChanged {
        /// The sweep folder.
        root: PathBuf,
        /// The checkpoint (or trigger) file as the records name it.
        file: String,
        /// The digest in the records ("none recorded" for records from before digests).
        recorded: String,
        /// What the file is now ("has SHA-256 ...", "cannot be read: ...").
        now: String,
    },
    /// Records drawn by renderers whose fixed frames differ (another Mesa, or a CPU
    /// without FMA), which would mix two cameras in one table.
    #[error(
        "{root}: its records were rendered with fingerprint {here}, but {other} with {there} \
         (`mrdrive render fingerprint` prints a machine's); fix: run every shard of a sweep on \
         machines whose fingerprints agree, or keep the sweeps apart"
    )]
    RenderFingerprintsDiffer {
        /// The folder of the first record with the other fingerprint.
        root: PathBuf,
        /// Its fingerprint.
        here: String,
        /// Where the first fingerprint was seen.
        other: PathBuf,
        /// That fingerprint.
        there: String,
    },
    /// A merge without shards.
    #[error("no shard folders to merge; fix: give at least one")]
    NoShards,
    /// A table could not be written as CSV.
    #[error("writing a CSV table")]
    Csv(#[from] csv::Error),
}

impl SweepError {
    /// An I/O error on `path`.
    pub(crate) fn io(
        action: &'static str,
        path: impl Into<PathBuf>,
        source: std::io::Error,
    ) -> Self {
        SweepError::Io {
            action,
            path: path.into(),
            source,
        }
    }
}
