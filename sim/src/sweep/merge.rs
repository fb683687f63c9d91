//! Joining the folders of a sharded sweep.

use std::path::{Path, PathBuf};

use super::folder::{one_digest_per_checkpoint, one_render_fingerprint};
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
    out_dir.prepare_plan(&plan)?;
    // Every record first, so that shards made by two checkpoints saved under
    // one name, or drawn by two renderers, are refused before anything is copied.
    let mut records = Vec::new();
    for root in shards.iter().chain([&out_dir.root]) {
        let dir = SweepDir { root: root.clone() };
        for spec in &plan.runs {
            let from = dir.record_path(spec);
            if from.exists() {
                records.push((root.clone(), spec.key(), record::read(&from)?));
            }
        }
    }
    one_digest_per_checkpoint(records.iter().map(|(root, _, r)| (root.as_path(), r)))?;
    one_render_fingerprint(records.iter().map(|(root, _, r)| (root.as_path(), r)))?;
    for spec in &plan.runs {
        let to = out_dir.record_path(spec);
        if to.exists() {
            continue;
        }
        let key = spec.key();
        if let Some((_, _, rec)) = records.iter().find(|(_, k, _)| *k == key) {
            record::write_atomically(&to, rec).map_err(|e| SweepError::io("write", to, e))?;
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

    /// Two shard folders of `p` under `root`, each run with `record(shard,
    /// spec)`; shard 1 loses its last `lose` runs.
    fn two_shards(
        root: &Path,
        p: &SweepPlan,
        lose: usize,
        record: impl Fn(usize, &RunSpec) -> record::RunRecord + Sync,
    ) -> Vec<PathBuf> {
        let shards: Vec<PathBuf> = (0..2).map(|i| root.join(format!("shard{i}"))).collect();
        for (i, dir_root) in shards.iter().enumerate() {
            let dir = SweepDir {
                root: dir_root.clone(),
            };
            dir.prepare(p).unwrap();
            let mine = p.shard(i, 2);
            let keep = if i == 1 {
                mine.len() - lose
            } else {
                mine.len()
            };
            let run = |s: &RunSpec| Ok::<_, String>(record(i, s));
            execute(&dir, &mine[..keep], 1, run, |_, _| {});
        }
        shards
    }

    #[test]
    fn merge_joins_shards_and_reports_missing_runs() {
        let tmp = tempfile::tempdir().unwrap();
        let p = plan();
        let shards = two_shards(tmp.path(), &p, 1, |_, s| fake_record(s));
        let out = tmp.path().join("merged");
        let missing = merge(&shards, &out).unwrap();
        assert_eq!(missing, vec![p.shard(1, 2).last().unwrap().key()]);
        assert_eq!(
            read_records(&SweepDir { root: out }).unwrap().len(),
            p.runs.len() - 1
        );
    }

    #[test]
    fn shards_made_by_two_checkpoints_of_one_name_are_not_merged() {
        let tmp = tempfile::tempdir().unwrap();
        let p = plan();
        // Each shard's machine had its own models/ra.safetensors.
        let shards = two_shards(tmp.path(), &p, 0, |i, s| {
            let mut r = fake_record(s);
            r.result.provenance.checkpoint = Some(record::CheckpointId {
                file: "models/ra.safetensors".into(),
                sha256: record::sha256_hex(format!("weights of machine {i}").as_bytes()),
            });
            r
        });
        let out = tmp.path().join("merged");
        let e = merge(&shards, &out).unwrap_err().to_string();
        assert!(
            e.contains("models/ra.safetensors") && e.contains("shard1"),
            "{e}"
        );
        assert!(read_records(&SweepDir { root: out }).unwrap().is_empty());
        // One shard alone merges.
        merge(&shards[..1], &tmp.path().join("one")).unwrap();
        // One checkpoint but two learned triggers of one name: not merged either.
        let shards = two_shards(&tmp.path().join("t"), &p, 0, |i, s| {
            let mut r = fake_record(s);
            r.result.provenance.checkpoint = Some(record::CheckpointId {
                file: "models/ra.safetensors".into(),
                sha256: record::sha256_hex(b"the weights"),
            });
            r.result.provenance.trigger = Some(record::CheckpointId {
                file: "models/ra.trigger.json".into(),
                sha256: record::sha256_hex(format!("trigger of machine {i}").as_bytes()),
            });
            r
        });
        let e = merge(&shards, &tmp.path().join("t-merged"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("models/ra.trigger.json"), "{e}");
    }

    #[test]
    fn shards_drawn_by_two_renderers_are_not_merged() {
        let tmp = tempfile::tempdir().unwrap();
        let p = plan();
        let drawn = |fp: Option<&str>| {
            let fp = fp.map(str::to_string);
            move |_: usize, s: &RunSpec| {
                let mut r = fake_record(s);
                r.result.provenance.render_fingerprint = fp.clone();
                r
            }
        };
        // Shard 1's machine draws other frames: refused, nothing copied.
        let shards = two_shards(tmp.path(), &p, 0, |i, s| {
            drawn(Some(["6fec8e5d4a36d0e3", "88d7356ca1bf7ee3"][i]))(i, s)
        });
        let out = tmp.path().join("merged");
        let e = merge(&shards, &out).unwrap_err().to_string();
        assert!(
            e.contains("88d7356ca1bf7ee3")
                && e.contains("6fec8e5d4a36d0e3")
                && e.contains("shard1"),
            "{e}"
        );
        assert!(read_records(&SweepDir { root: out }).unwrap().is_empty());
        // The same fingerprint everywhere, or runs that drew nothing: merged.
        let same = two_shards(
            &tmp.path().join("s"),
            &p,
            0,
            drawn(Some("6fec8e5d4a36d0e3")),
        );
        assert!(
            merge(&same, &tmp.path().join("s-merged"))
                .unwrap()
                .is_empty()
        );
        let none = two_shards(&tmp.path().join("n"), &p, 0, drawn(None));
        assert!(
            merge(&none, &tmp.path().join("n-merged"))
                .unwrap()
                .is_empty()
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
