//! The scale-out guide's Slurm recipe (`docs/scale-out.md`) on a real Slurm:
//! `scripts/slurm/local-cluster.sh` starts `munged`, `slurmctld` and `slurmd`
//! on localhost in a temporary folder, and the test submits the guide's own
//! scripts, `scripts/slurm/sweep-array.sbatch` and `scripts/slurm/merge.sbatch`,
//! on a small sweep (the expert, no camera, 4 runs) in 2 shards:
//!
//! - the array, then the merge with `--dependency=afterok`, give the records
//!   of an unsharded run (every record's `result`, which holds no wall time);
//! - a task killed with `scancel` after the first run of its shard leaves a
//!   sweep that the merge reports incomplete; resubmitting that index alone
//!   (`sbatch --array=0`) finishes it without redoing a finished run, and the
//!   merge is then whole.
//!
//! The cluster is stopped at the end, also when the test fails. It needs
//! Debian's `slurm-wlm` and `munge` (`cargo xtask setup` installs them) and
//! root; without them the test skips visibly, and CI
//! (`MRDRIVE_REQUIRE_SLURM=1`) fails instead. About 20-30 s on 2 cores.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant, SystemTime};

use common::root;
use world::testdata::{Needs, skip};

/// The sweep: 2 delays x 2 densities x 1 seed = 4 runs, driven by the expert
/// (which draws nothing: no camera).
const SWEEP: &[&str] = &[
    "scenarios/default.toml",
    "--expert",
    "--delays",
    "0,100",
    "--densities",
    "0:0,5:10",
    "--seeds",
    "1",
];

/// How long one job may take before the test gives up on it.
const JOB_TIMEOUT: Duration = Duration::from_secs(120);

/// The tools the test runs: Slurm's daemons and clients, and munge's daemon.
const TOOLS: &[&str] = &[
    "munged",
    "slurmctld",
    "slurmd",
    "sbatch",
    "scancel",
    "scontrol",
    "sinfo",
];

fn on_path(tool: &str) -> bool {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path).any(|d| d.join(tool).is_file())
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "0")
}

fn script(name: &str) -> PathBuf {
    root().join("scripts/slurm").join(name)
}

/// A free TCP port on localhost (for the daemons: a machine may run another
/// Slurm on the default ports).
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port()
}

/// Panics with `what`, the command's status and output unless it succeeded;
/// returns its standard output.
fn ok(what: &str, out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The local cluster: started by `new`, stopped when dropped (also when the
/// test panics).
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        // The guard first: a start that fails half-way leaves daemons to stop.
        let cluster = Cluster {
            dir: dir.to_path_buf(),
            conf: dir.join("slurm.conf"),
        };
        let (ctld, d) = (free_port(), free_port());
        let out = Command::new(script("local-cluster.sh"))
            .arg("start")
            .arg(dir)
            .env("SLURMCTLD_PORT", ctld.to_string())
            .env("SLURMD_PORT", d.to_string())
            .output()
            .expect("local-cluster.sh starts");
        eprint!("{}", String::from_utf8_lossy(&out.stdout));
        ok("local-cluster.sh start", &out);
        cluster
    }

    /// A Slurm client command talking to this cluster, run from the
    /// workspace root (the jobs' `SLURM_SUBMIT_DIR`), without any `SLURM_*`
    /// or `SBATCH_*` variable of a Slurm job this test may itself run in.
    fn command(&self, tool: &str) -> Command {
        let mut c = Command::new(tool);
        c.current_dir(root());
        for (k, _) in std::env::vars_os() {
            let k = k.to_string_lossy();
            if k.starts_with("SLURM_") || k.starts_with("SBATCH_") {
                c.env_remove(&*k);
            }
        }
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// Submits `script` with `options` and `args`; returns the job id.
    fn sbatch(&self, options: &[String], script: &str, args: &[String]) -> String {
        let out = self
            .command("sbatch")
            .arg("--parsable")
            .args(options)
            .arg(root().join("scripts/slurm").join(script))
            .args(args)
            .output()
            .expect("sbatch starts");
        let id = ok(&format!("sbatch {options:?} {script} {args:?}"), &out);
        id.trim().split(';').next().unwrap().to_string()
    }

    /// Each task of `job` (an array's tasks, or the job) and its state, as
    /// `scontrol` shows them (`JobState`; `NEVER` for a job pending on a
    /// dependency that can no longer be satisfied).
    fn states(&self, job: &str) -> Vec<(String, String)> {
        let out = self
            .command("scontrol")
            .args(["-o", "show", "job", job])
            .output()
            .expect("scontrol starts");
        let text = ok("scontrol show job", &out);
        text.lines()
            .filter(|l| !l.trim().is_empty())
            .map(|line| {
                let field = |name: &str| {
                    line.split_whitespace()
                        .find_map(|f| f.strip_prefix(name).map(str::to_string))
                };
                let task = field("ArrayTaskId=").unwrap_or_else(|| "-".into());
                let mut state = field("JobState=").unwrap_or_else(|| "?".into());
                if field("Reason=").as_deref() == Some("DependencyNeverSatisfied") {
                    state = "NEVER".into();
                }
                (task, state)
            })
            .collect()
    }

    /// Waits until every task of `job` has ended; returns their states.
    fn wait(&self, job: &str) -> Vec<(String, String)> {
        const ENDED: &[&str] = &[
            "COMPLETED",
            "FAILED",
            "CANCELLED",
            "TIMEOUT",
            "NODE_FAIL",
            "OUT_OF_MEMORY",
            "PREEMPTED",
            "BOOT_FAIL",
            "DEADLINE",
            "NEVER",
        ];
        let start = Instant::now();
        loop {
            let states = self.states(job);
            if !states.is_empty() && states.iter().all(|(_, s)| ENDED.contains(&s.as_str())) {
                return states;
            }
            assert!(
                start.elapsed() < JOB_TIMEOUT,
                "job {job} has not ended after {JOB_TIMEOUT:?}: {states:?}\n{}",
                self.log_tail()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// Waits for `job` and asserts that every task completed (exit code 0).
    fn wait_completed(&self, job: &str, logs: &Path) {
        let states = self.wait(job);
        assert!(
            states.iter().all(|(_, s)| s == "COMPLETED"),
            "job {job}: {states:?}\n{}",
            job_logs(logs)
        );
    }

    fn log_tail(&self) -> String {
        let mut text = String::new();
        for log in ["log/slurmctld.log", "log/slurmd.log"] {
            let body = std::fs::read_to_string(self.dir.join(log)).unwrap_or_default();
            let lines: Vec<&str> = body.lines().collect();
            text += &format!(
                "--- {log}\n{}\n",
                lines[lines.len().saturating_sub(15)..].join("\n")
            );
        }
        text
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        match Command::new(script("local-cluster.sh"))
            .arg("stop")
            .arg(&self.dir)
            .output()
        {
            Ok(o) if o.status.success() => eprintln!("slurm: local cluster stopped"),
            Ok(o) => eprintln!(
                "slurm: stopping the local cluster failed: {}",
                String::from_utf8_lossy(&o.stderr)
            ),
            Err(e) => eprintln!("slurm: stopping the local cluster failed: {e}"),
        }
    }
}

/// Every job log in `logs`, for failure messages.
fn job_logs(logs: &Path) -> String {
    let mut text = String::new();
    let mut files: Vec<_> = std::fs::read_dir(logs)
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.sort();
    for f in files {
        let body = std::fs::read_to_string(&f).unwrap_or_default();
        text += &format!("--- {}\n{body}\n", f.display());
    }
    text
}

/// The `result` of every record of the sweep folder `dir` (by run key); a
/// record's `perf` (wall-clock timings) is left out.
fn results(dir: &Path) -> BTreeMap<String, serde_json::Value> {
    let runs = dir.join("runs");
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(&runs).unwrap_or_else(|e| panic!("{}: {e}", runs.display())) {
        let path = e.unwrap().path();
        if path.extension().is_some_and(|x| x == "json") {
            let v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
            let result = v.get("result").cloned().expect("a record has a result");
            out.insert(
                path.file_stem().unwrap().to_string_lossy().into_owned(),
                result,
            );
        }
    }
    out
}

/// The modification time and inode of every record of a sweep folder: a run
/// that is redone rewrites its record (a new file renamed over the old one).
fn stamps(dir: &Path) -> BTreeMap<String, (SystemTime, u64)> {
    use std::os::unix::fs::MetadataExt;
    std::fs::read_dir(dir.join("runs"))
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            let m = e.metadata().unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                (m.modified().unwrap(), m.ino()),
            )
        })
        .collect()
}

fn assert_same_results(merged: &Path, unsharded: &BTreeMap<String, serde_json::Value>) {
    let merged_results = results(merged);
    assert_eq!(
        merged_results.keys().collect::<Vec<_>>(),
        unsharded.keys().collect::<Vec<_>>(),
        "{}: other runs than the unsharded sweep's",
        merged.display()
    );
    for (key, result) in unsharded {
        assert_eq!(
            &merged_results[key],
            result,
            "{}: run {key} differs from the unsharded sweep's",
            merged.display()
        );
    }
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

#[test]
fn the_guides_slurm_array_job_shards_merges_and_recovers_a_killed_task() {
    let test = "the_guides_slurm_array_job_shards_merges_and_recovers_a_killed_task";
    let missing: Vec<&str> = TOOLS.iter().copied().filter(|t| !on_path(t)).collect();
    if !missing.is_empty() {
        skip(
            test,
            Needs::Slurm,
            &format!(
                "{} not found (Debian: apt-get install slurm-wlm munge)",
                missing.join(", ")
            ),
        );
        return;
    }
    if !is_root() {
        skip(
            test,
            Needs::Slurm,
            "the local Slurm (scripts/slurm/local-cluster.sh) runs as root",
        );
        return;
    }
    let t0 = Instant::now();
    let lap = |what: &str| eprintln!("slurm: {:>5.1} s  {what}", t0.elapsed().as_secs_f64());
    let tmp = tempfile::tempdir().unwrap();
    // munged wants every folder above its socket searchable by all.
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let mrdrive = env!("CARGO_BIN_EXE_mrdrive");

    // The reference: the sweep in one process, unsharded.
    let unsharded_dir = tmp.path().join("unsharded");
    let mut args = vec!["sweep".to_string()];
    args.extend(strings(SWEEP));
    args.extend(strings(&["--jobs", "2", "--out"]));
    args.push(unsharded_dir.display().to_string());
    common::run_ok(&args);
    let unsharded = results(&unsharded_dir);
    assert_eq!(unsharded.len(), 4, "{:?}", unsharded.keys());
    lap("unsharded sweep done (4 runs)");

    let cluster = Cluster::start(&tmp.path().join("cluster"));
    lap("local Slurm up");
    let logs = tmp.path().join("logs");
    std::fs::create_dir_all(&logs).unwrap();
    // The header asks for 8 tasks of 2 CPUs and 4 GB; here 2 tasks of 1 CPU
    // each run side by side on 2 cores.
    let array_options = |array: &str, mrdrive: &str| {
        vec![
            format!("--array={array}"),
            "--cpus-per-task=1".into(),
            "--mem=256M".into(),
            format!("--output={}/%x-%A_%a.out", logs.display()),
            format!("--export=ALL,SHARDS=2,MRDRIVE={mrdrive}"),
        ]
    };
    let merge_options = |job: &str| {
        vec![
            format!("--dependency=afterok:{job}"),
            "--mem=256M".into(),
            format!("--output={}/%x-%j.out", logs.display()),
            format!("--export=ALL,MRDRIVE={mrdrive}"),
        ]
    };
    let sweep_args = |out: &Path| {
        let mut v = vec![out.display().to_string()];
        v.extend(strings(SWEEP));
        v
    };

    // 1. The array in 2 shards, then the merge once both tasks succeeded.
    let a = tmp.path().join("a");
    let job = cluster.sbatch(
        &array_options("0-1", mrdrive),
        "sweep-array.sbatch",
        &sweep_args(&a),
    );
    let merge = cluster.sbatch(
        &merge_options(&job),
        "merge.sbatch",
        &[a.display().to_string()],
    );
    cluster.wait_completed(&job, &logs);
    cluster.wait_completed(&merge, &logs);
    for shard in ["shard-0", "shard-1"] {
        assert_eq!(
            results(&a.join(shard)).len(),
            2,
            "{shard} holds its half of the runs"
        );
    }
    assert_same_results(&a.join("all"), &unsharded);
    lap("array job (2 shards) + merge: the unsharded records");

    // 2. Task 0 does the first run of its shard (what shard 0/4 holds), then
    // hangs until it is cancelled: a node lost mid-shard.
    let b = tmp.path().join("b");
    let started = tmp.path().join("task0-started");
    let killable = tmp.path().join("killable-mrdrive");
    std::fs::write(
        &killable,
        format!(
            r#"#!/bin/bash
if [ "$SLURM_ARRAY_TASK_ID" = 0 ]; then
    args=()
    for a in "$@"; do [ "$a" = 0/2 ] && a=0/4; args+=("$a"); done
    "{mrdrive}" "${{args[@]}}"
    touch "{started}"
    exec sleep 600
fi
exec "{mrdrive}" "$@"
"#,
            started = started.display()
        ),
    )
    .unwrap();
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&killable, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let job = cluster.sbatch(
        &array_options("0-1", &killable.display().to_string()),
        "sweep-array.sbatch",
        &sweep_args(&b),
    );
    let waited = Instant::now();
    while !started.exists() {
        assert!(
            waited.elapsed() < JOB_TIMEOUT,
            "task 0 did not start: {:?}\n{}",
            cluster.states(&job),
            job_logs(&logs)
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    ok(
        "scancel",
        &cluster
            .command("scancel")
            .arg(format!("{job}_0"))
            .output()
            .unwrap(),
    );
    let states = cluster.wait(&job);
    let state = |task: &str| {
        states
            .iter()
            .find(|(t, _)| t == task)
            .map(|(_, s)| s.as_str())
    };
    assert_eq!(state("0"), Some("CANCELLED"), "{states:?}");
    assert_eq!(state("1"), Some("COMPLETED"), "{states:?}");
    let killed = results(&b.join("shard-0"));
    assert_eq!(
        killed.len(),
        1,
        "task 0 finished one run before it was killed"
    );
    // The sweep is incomplete: the merge lists the missing run.
    let partial = common::run(&[
        "sweep".into(),
        "merge".into(),
        b.join("shard-0").display().to_string(),
        b.join("shard-1").display().to_string(),
        "--out".into(),
        tmp.path().join("partial").display().to_string(),
    ]);
    let stderr = String::from_utf8_lossy(&partial.stderr);
    assert!(
        !partial.status.success() && stderr.contains("1 run(s) missing"),
        "the merge of a killed sweep must fail and list the missing run ({}):\n{stderr}",
        partial.status
    );
    lap("task 0 cancelled after 1 of its 2 runs: the merge reports 1 run missing");

    // 3. Index 0 alone resubmitted (still shard 0/2): it does the missing run
    // only, and the merge is whole.
    let before: Vec<_> = [stamps(&b.join("shard-0")), stamps(&b.join("shard-1"))].into();
    let job = cluster.sbatch(
        &array_options("0", mrdrive),
        "sweep-array.sbatch",
        &sweep_args(&b),
    );
    let merge = cluster.sbatch(
        &merge_options(&job),
        "merge.sbatch",
        &[b.display().to_string()],
    );
    cluster.wait_completed(&job, &logs);
    cluster.wait_completed(&merge, &logs);
    let task_log = std::fs::read_to_string(logs.join(format!("mrdrive-sweep-{job}_0.out")))
        .expect("the resubmitted task's log");
    assert!(
        task_log.contains("2 in this shard (0/2), 1 already done"),
        "the resubmitted task runs shard 0/2 and skips its finished run:\n{task_log}"
    );
    let after = [stamps(&b.join("shard-0")), stamps(&b.join("shard-1"))];
    for (shard, (old, new)) in before.iter().zip(&after).enumerate() {
        for (file, stamp) in old {
            assert_eq!(
                new.get(file),
                Some(stamp),
                "shard-{shard}/runs/{file} was rewritten: a finished run was redone"
            );
        }
    }
    assert_eq!(after[0].len(), 2, "shard 0 is finished");
    assert_same_results(&b.join("all"), &unsharded);
    lap("index 0 resubmitted: 1 run done, 3 kept; the merge is whole and equal");
    drop(cluster);
}
