//! Joining the folders of a sharded sweep.

use std::path::{Path, PathBuf};

use super::{RunSpec, SweepDir, SweepError, SweepPlan};
use crate::record;

/// Joins shard folders into `out`: copies every record, then checks against
/// the plan that no run is missing. Returns the missing keys (empty: whole).
pub fn merge(shards: &[PathBuf], out: &Path) -> Result<Vec<String>, SweepError> {
    let out_dir = SweepDir {
        root: out.to_path_buf(),
    };
    let mut plan: Option<SweepPlan> = None;
    for shard in shards {
        let dir = SweepDir {
            root: shard.clone(),
        };
        let p = dir.read_plan()?;
        match &plan {
            None => plan = Some(p),
            Some(first) if *first != p => {
                return Err(SweepError::ShardOfOtherSweep {
                    shard: shard.clone(),
                });
            }
            Some(_) => {}
        }
    }
    let plan = plan.ok_or(SweepError::NoShards)?;
    out_dir.prepare(&plan)?;
    for shard in shards {
        let dir = SweepDir {
            root: shard.clone(),
        };
        for spec in &plan.runs {
            let from = dir.record_path(spec);
            let to = out_dir.record_path(spec);
            if from.exists() && !to.exists() {
                let rec = record::read(&from)?;
                record::write_atomically(&to, &rec).map_err(|e| SweepError::io("write", to, e))?;
            }
        }
    }
    Ok(plan
        .runs
        .iter()
        .filter(|s| !out_dir.is_done(s))
        .map(RunSpec::key)
        .collect())
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{fake_record, plan};
    use super::super::{execute, read_records};
    use super::*;

    #[test]
    fn merge_joins_shards_and_reports_missing_runs() {
        let tmp = tempfile::tempdir().unwrap();
        let p = plan();
        let shards: Vec<PathBuf> = (0..2)
            .map(|i| tmp.path().join(format!("shard{i}")))
            .collect();
        for (i, root) in shards.iter().enumerate() {
            let dir = SweepDir { root: root.clone() };
            dir.prepare(&p).unwrap();
            let mine = p.shard(i, 2);
            // Shard 1 loses its last run.
            let mine = if i == 1 {
                &mine[..mine.len() - 1]
            } else {
                &mine[..]
            };
            execute(&dir, mine, 1, |s| Ok::<_, String>(fake_record(s)), |_| {});
        }
        let out = tmp.path().join("merged");
        let missing = merge(&shards, &out).unwrap();
        assert_eq!(missing, vec![p.shard(1, 2).last().unwrap().key()]);
        assert_eq!(
            read_records(&SweepDir { root: out }).unwrap().len(),
            p.runs.len() - 1
        );
    }

    #[test]
    fn shards_of_two_sweeps_are_not_merged() {
        let tmp = tempfile::tempdir().unwrap();
        let a = tmp.path().join("a");
        let b = tmp.path().join("b");
        SweepDir { root: a.clone() }.prepare(&plan()).unwrap();
        let other = SweepPlan::cross(&["c.toml".into()], &[None], &[None], &[None], &[1]);
        SweepDir { root: b.clone() }.prepare(&other).unwrap();
        let e = merge(&[a, b.clone()], &tmp.path().join("out")).unwrap_err();
        assert!(matches!(e, SweepError::ShardOfOtherSweep { shard } if shard == b));
        assert!(matches!(
            merge(&[], &tmp.path().join("out")),
            Err(SweepError::NoShards)
        ));
    }
}
