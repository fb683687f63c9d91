//! The folder layout of a sweep: its plan and one record per finished run.

use std::path::PathBuf;

use super::{RunSpec, SweepError, SweepPlan};
use crate::record::{self, RunRecord};

/// The folder layout of a sweep.
#[derive(Debug, Clone)]
pub struct SweepDir {
    /// The sweep's folder.
    pub root: PathBuf,
}

impl SweepDir {
    /// The plan file.
    pub fn plan_path(&self) -> PathBuf {
        self.root.join("plan.json")
    }

    /// The folder of records.
    pub fn runs_dir(&self) -> PathBuf {
        self.root.join("runs")
    }

    /// The record file of a run.
    pub fn record_path(&self, spec: &RunSpec) -> PathBuf {
        self.runs_dir().join(format!("{}.json", spec.key()))
    }

    /// Writes the plan, or checks that it matches the one already there (a
    /// resumed sweep must be the same sweep).
    pub fn prepare(&self, plan: &SweepPlan) -> Result<(), SweepError> {
        std::fs::create_dir_all(self.runs_dir())
            .map_err(|e| SweepError::io("create", self.runs_dir(), e))?;
        let path = self.plan_path();
        if path.exists() {
            if self.read_plan()? != *plan {
                return Err(SweepError::OtherSweep {
                    root: self.root.clone(),
                });
            }
            return Ok(());
        }
        let text = serde_json::to_string_pretty(plan).expect("a plan serialises");
        std::fs::write(&path, text).map_err(|e| SweepError::io("write", path, e))
    }

    /// Reads the plan.
    pub fn read_plan(&self) -> Result<SweepPlan, SweepError> {
        let path = self.plan_path();
        let text =
            std::fs::read_to_string(&path).map_err(|e| SweepError::io("read", path.clone(), e))?;
        serde_json::from_str(&text).map_err(|source| SweepError::NotAPlan { path, source })
    }

    /// Whether a run's record is there and readable.
    pub fn is_done(&self, spec: &RunSpec) -> bool {
        record::read(&self.record_path(spec)).is_ok()
    }
}

/// Reads every record of a sweep folder that its plan names.
pub fn read_records(dir: &SweepDir) -> Result<Vec<RunRecord>, SweepError> {
    let plan = dir.read_plan()?;
    plan.runs
        .iter()
        .filter(|s| dir.record_path(s).exists())
        .map(|s| record::read(&dir.record_path(s)).map_err(SweepError::from))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::plan;
    use super::*;

    #[test]
    fn a_folder_of_another_sweep_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = SweepDir {
            root: tmp.path().to_path_buf(),
        };
        dir.prepare(&plan()).unwrap();
        dir.prepare(&plan()).unwrap();
        let other = SweepPlan::cross(&["a.toml".into()], &[Some(0.0)], &[None], &[None], &[1]);
        let e = dir.prepare(&other).unwrap_err().to_string();
        assert!(e.contains("different sweep") && e.contains("--out"), "{e}");
    }

    #[test]
    fn a_broken_plan_is_named() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = SweepDir {
            root: tmp.path().to_path_buf(),
        };
        std::fs::write(dir.plan_path(), "{").unwrap();
        let e = dir.read_plan().unwrap_err().to_string();
        assert!(
            e.contains("plan.json") && e.contains("not a sweep plan"),
            "{e}"
        );
    }
}
