//! The folder layout of a sweep: its plan and one record per finished run.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

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
    /// resumed sweep must be the same sweep) and that the checkpoints its
    /// records were made by have not changed ([`Self::same_checkpoints`]).
    pub fn prepare(&self, plan: &SweepPlan) -> Result<(), SweepError> {
        if self.prepare_plan(plan)? {
            self.same_checkpoints()?;
        }
        Ok(())
    }

    /// Writes the plan, or checks that it matches the one already there;
    /// whether there was one. (A merge, which runs nothing, checks the
    /// checkpoints by [`one_digest_per_checkpoint`] instead.)
    pub fn prepare_plan(&self, plan: &SweepPlan) -> Result<bool, SweepError> {
        std::fs::create_dir_all(self.runs_dir())
            .map_err(|e| SweepError::io("create", self.runs_dir(), e))?;
        let path = self.plan_path();
        if path.exists() {
            if self.read_plan()? != *plan {
                return Err(SweepError::OtherSweep {
                    root: self.root.clone(),
                });
            }
            return Ok(true);
        }
        let text = serde_json::to_string_pretty(plan).expect("a plan serialises");
        std::fs::write(&path, text).map_err(|e| SweepError::io("write", path, e))?;
        Ok(false)
    }

    /// Checks that every policy that made a record here is still the same
    /// file: the digest its records carry is the digest of the file now
    /// (the checkpoint's, and the learned trigger's where a record names
    /// one). Records of a policy that carry no checkpoint digest (made
    /// before digests were recorded) cannot be checked and are refused too.
    pub fn same_checkpoints(&self) -> Result<(), SweepError> {
        // Each file's digest now (or why it cannot be read), read once.
        let mut now: BTreeMap<String, Result<String, String>> = BTreeMap::new();
        for rec in read_records(self)? {
            let p = &rec.result.provenance;
            if p.checkpoint.is_none() && p.driver.starts_with("policy:") {
                return Err(SweepError::CheckpointChanged {
                    root: self.root.clone(),
                    file: p.driver.clone(),
                    recorded: "none recorded".into(),
                    now: "cannot be told apart from another checkpoint".into(),
                });
            }
            for id in p.model_files() {
                let here = now.entry(id.file.clone()).or_insert_with(|| {
                    record::CheckpointId::of(Path::new(&id.file))
                        .map(|here| here.sha256)
                        .map_err(|e| e.to_string())
                });
                if here.as_deref() != Ok(id.sha256.as_str()) {
                    return Err(SweepError::CheckpointChanged {
                        root: self.root.clone(),
                        file: id.file.clone(),
                        recorded: id.sha256.clone(),
                        now: match here {
                            Ok(d) => format!("has SHA-256 {d}"),
                            Err(e) => format!("cannot be read: {e}"),
                        },
                    });
                }
            }
        }
        Ok(())
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

/// Checks that records, from one folder or several, name one digest per
/// checkpoint file: what a merge of shards run elsewhere (where the files
/// may not be) can check. Each record comes with the folder it was read from,
/// which an error names.
pub fn one_digest_per_checkpoint<'a>(
    records: impl IntoIterator<Item = (&'a Path, &'a RunRecord)>,
) -> Result<(), SweepError> {
    let mut seen: BTreeMap<&str, &str> = BTreeMap::new();
    for (from, rec) in records {
        for id in rec.result.provenance.model_files() {
            match seen.get(id.file.as_str()) {
                Some(&d) if d != id.sha256 => {
                    return Err(SweepError::CheckpointChanged {
                        root: from.to_path_buf(),
                        file: id.file.clone(),
                        recorded: d.to_string(),
                        now: format!("has SHA-256 {} in this folder's records", id.sha256),
                    });
                }
                Some(_) => {}
                None => {
                    seen.insert(&id.file, &id.sha256);
                }
            }
        }
    }
    Ok(())
}

/// Checks that records, from one folder or several, name one render fingerprint
/// (records that rendered nothing, or predate fingerprints, name none and pass).
pub fn one_render_fingerprint<'a>(
    records: impl IntoIterator<Item = (&'a Path, &'a RunRecord)>,
) -> Result<(), SweepError> {
    let mut first: Option<(&Path, &str)> = None;
    for (from, rec) in records {
        let Some(fp) = rec.result.provenance.render_fingerprint.as_deref() else {
            continue;
        };
        match first {
            Some((other, there)) if there != fp => {
                return Err(SweepError::RenderFingerprintsDiffer {
                    root: from.to_path_buf(),
                    here: fp.to_string(),
                    other: other.to_path_buf(),
                    there: there.to_string(),
                });
            }
            Some(_) => {}
            None => first = Some((from, fp)),
        }
    }
    Ok(())
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
    use super::super::fixtures::{fake_record, plan};
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
    fn a_folder_made_by_a_checkpoint_that_has_changed_since_is_refused() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = SweepDir {
            root: tmp.path().join("sweep"),
        };
        let p = plan();
        dir.prepare(&p).unwrap();
        let weights = tmp.path().join("ra.safetensors");
        std::fs::write(&weights, b"the first weights").unwrap();
        let mut rec = fake_record(&p.runs[0]);
        rec.result.provenance.driver = format!("policy:{} (cpu, fused)", weights.display());
        rec.result.provenance.checkpoint = Some(record::CheckpointId::of(&weights).unwrap());
        record::write_atomically(&dir.record_path(&p.runs[0]), &rec).unwrap();
        // The same file: the sweep resumes.
        dir.prepare(&p).unwrap();
        // Retrained under the same name: refused, naming the file and the fix.
        std::fs::write(&weights, b"other weights").unwrap();
        let e = dir.prepare(&p).unwrap_err().to_string();
        assert!(
            e.contains("ra.safetensors") && e.contains("move the folder aside"),
            "{e}"
        );
        assert!(e.contains(&record::sha256_hex(b"the first weights")), "{e}");
        // The learned trigger beside it is checked the same way.
        std::fs::write(&weights, b"the first weights").unwrap();
        let trigger = tmp.path().join("ra.trigger.json");
        std::fs::write(&trigger, b"{\"the first\": \"trigger\"}").unwrap();
        let mut with_trigger = rec.clone();
        with_trigger.result.provenance.trigger = Some(record::CheckpointId::of(&trigger).unwrap());
        record::write_atomically(&dir.record_path(&p.runs[0]), &with_trigger).unwrap();
        dir.prepare(&p).unwrap();
        std::fs::write(&trigger, b"{\"refit\": \"trigger\"}").unwrap();
        let e = dir.prepare(&p).unwrap_err().to_string();
        assert!(e.contains("ra.trigger.json"), "{e}");
        record::write_atomically(&dir.record_path(&p.runs[0]), &rec).unwrap();
        // Gone: refused too.
        std::fs::remove_file(&weights).unwrap();
        let e = dir.prepare(&p).unwrap_err().to_string();
        assert!(e.contains("cannot be read"), "{e}");
        // A policy's record without a digest cannot be checked.
        rec.result.provenance.checkpoint = None;
        record::write_atomically(&dir.record_path(&p.runs[0]), &rec).unwrap();
        let e = dir.prepare(&p).unwrap_err().to_string();
        assert!(e.contains("none recorded"), "{e}");
        // The expert's records carry none and need none.
        rec.result.provenance.driver = "expert".into();
        record::write_atomically(&dir.record_path(&p.runs[0]), &rec).unwrap();
        dir.prepare(&p).unwrap();
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
