//! How a paper run is asked for ([`RunOptions`]) and the wall-time log it keeps
//! beside its records ([`WallLog`]): what the runner and the page both read.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::PaperError;
use crate::experiment::Experiment;

/// How to run a paper.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// The folder of everything (`docs/paper`): the sweeps (`sweeps/ID/`, one
    /// record per run, committed so every number can be checked), derived
    /// scenarios (`scenarios/`), the wall-time log, tables, figures and page.
    pub out: PathBuf,
    /// Runs at a time.
    pub jobs: usize,
    /// The experiments to run and write.
    pub experiments: Vec<Experiment>,
    /// Only write the tables and figures from the runs already finished.
    pub report_only: bool,
    /// "quick" or "full", written on the page.
    pub label: String,
    /// Add runs to a folder whose runs another build made (the page then
    /// warns that it mixes builds); `false` refuses ([`crate::PaperError::Build`]).
    pub mixed_builds: bool,
    /// Run only the configuration's first this many seeds this time (the
    /// sweep plans still hold every seed; a later call goes on); `None`: all.
    pub seeds: Option<usize>,
    /// The folder whose registration (`registration.md`, `registered.toml`)
    /// binds these runs: `out` itself for the paper's routes, the paper's
    /// folder for the held-out routes (one registration, one study).
    pub registered_in: PathBuf,
}

/// The wall time spent running sweeps into one output folder, over every
/// invocation (a resumed run adds to it).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct WallLog {
    /// Seconds spent in sweeps.
    pub sweep_s: f64,
    /// Invocations that ran at least one run.
    pub invocations: u32,
    /// Runs finished over all invocations.
    pub runs: usize,
    /// Jobs of the last invocation.
    pub jobs: usize,
}

impl WallLog {
    fn path(out: &Path) -> PathBuf {
        out.join("wall.json")
    }

    /// Reads `OUT/wall.json` (zero if there is none yet).
    pub fn read(out: &Path) -> Self {
        std::fs::read_to_string(Self::path(out))
            .ok()
            .and_then(|t| serde_json::from_str(&t).ok())
            .unwrap_or_default()
    }

    /// Writes `OUT/wall.json` whole or not at all (a temporary file, then a
    /// rename), so a kill never leaves a torn log that reads as zero.
    pub(crate) fn write(&self, out: &Path) -> Result<(), PaperError> {
        let p = Self::path(out);
        let tmp = out.join("wall.json.tmp");
        let text = serde_json::to_string_pretty(self).expect("a wall log serialises");
        std::fs::write(&tmp, text).map_err(|e| PaperError::io("write", &tmp, e))?;
        std::fs::rename(&tmp, &p).map_err(|e| PaperError::io("write", &p, e))
    }
}
