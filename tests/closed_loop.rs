//! The closed loop through the command line: determinism, and a sweep that is
//! killed mid-way and resumed.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn mrdrive() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_mrdrive"));
    c.current_dir(root());
    c
}

fn run_json(args: &[&str], json: &Path) -> serde_json::Value {
    let out = mrdrive()
        .args(["run", "--quiet"])
        .args(args)
        .arg("--json")
        .arg(json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "mrdrive run failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

#[test]
fn two_runs_of_one_scenario_give_identical_records() {
    let tmp = tempfile::tempdir().unwrap();
    // The default scenario has traffic (5 vehicles, 10 pedestrians).
    let a = run_json(
        &["scenarios/default.toml", "--seed", "7"],
        &tmp.path().join("a.json"),
    );
    let b = run_json(
        &["scenarios/default.toml", "--seed", "7"],
        &tmp.path().join("b.json"),
    );
    assert_eq!(
        a["result"], b["result"],
        "the deterministic part of the record differs"
    );
    assert_eq!(a["result"]["traffic"]["vehicles"], 5);
    // A different seed gives a different run (so the test can tell).
    let c = run_json(
        &["scenarios/default.toml", "--seed", "8"],
        &tmp.path().join("c.json"),
    );
    assert_ne!(a["result"]["ticks"], c["result"]["ticks"]);
}

#[test]
fn bad_scenario_gets_an_error_naming_the_file_and_key() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("bad.toml");
    std::fs::write(
        &path,
        "[map]\nfile = \"x.xodr\"\n[route]\nfile = \"r.toml\"\nid = 0\n[timing]\ndelay = 50\n",
    )
    .unwrap();
    let out = mrdrive().arg("run").arg(&path).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.toml") && err.contains("delay"), "{err}");
    assert!(
        !err.contains("stack backtrace"),
        "a user error must not print a backtrace:\n{err}"
    );
}

#[test]
fn a_killed_sweep_resumes_with_every_finished_record_intact() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sweep");
    let args = |c: &mut Command| {
        c.args([
            "sweep",
            "tests/regression/gen02_route1.toml",
            "--densities",
            "5:10",
            "--seeds",
            "1..21",
            "--jobs",
            "1",
            "--out",
        ])
        .arg(&out);
    };
    // Start it, wait for the first finished record, kill it.
    let mut first = mrdrive();
    args(&mut first);
    let mut child = first
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let runs = out.join("runs");
    let started = Instant::now();
    let finished = |dir: &Path| -> Vec<PathBuf> {
        let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
            .map(|d| {
                d.filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|x| x == "json"))
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    };
    while finished(&runs).is_empty() {
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "no run finished in 2 minutes"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let done: Vec<(PathBuf, Vec<u8>)> = finished(&runs)
        .into_iter()
        .map(|p| (p.clone(), std::fs::read(&p).unwrap()))
        .collect();
    assert!(
        !done.is_empty() && done.len() < 20,
        "killed after {} of 20 runs",
        done.len()
    );
    for (path, bytes) in &done {
        serde_json::from_slice::<serde_json::Value>(bytes)
            .unwrap_or_else(|e| panic!("{} is not whole: {e}", path.display()));
    }
    // Resume: the rest is run, the finished records are untouched.
    let mut again = mrdrive();
    args(&mut again);
    let resumed = again.output().unwrap();
    let stderr = String::from_utf8_lossy(&resumed.stderr);
    assert!(resumed.status.success(), "{stderr}");
    assert!(
        stderr.contains(&format!("{} already done", done.len())),
        "{stderr}"
    );
    assert_eq!(finished(&runs).len(), 20);
    for (path, bytes) in &done {
        assert_eq!(
            &std::fs::read(path).unwrap(),
            bytes,
            "{} changed on resume",
            path.display()
        );
    }
    assert!(out.join("summary.md").is_file() && out.join("summary.csv").is_file());
}

#[test]
fn a_policy_checkpoint_drives_a_scenario_with_each_selector() {
    let tmp = tempfile::tempdir().unwrap();
    let weights = tmp.path().join("random.safetensors");
    let init = mrdrive()
        .args(["policy", "init", "--seed", "1", "--out"])
        .arg(&weights)
        .output()
        .unwrap();
    assert!(
        init.status.success(),
        "{}",
        String::from_utf8_lossy(&init.stderr)
    );
    for selector in ["fixed", "oracle", "lookahead", "budget"] {
        let scenario = tmp.path().join(format!("{selector}.toml"));
        std::fs::write(
            &scenario,
            format!(
                "[map]\nfile = {:?}\n[route]\nfile = {:?}\nid = 0\n[driver]\nkind = \"policy\"\ncheckpoint = \"random.safetensors\"\n\
                 [timing]\nlatency_ms = {{ \"0.75\" = 50.0, \"1.0\" = 100.0 }}\n[resolution]\nselector = \"{selector}\"\nscale = 0.75\nbudget_ms = 75.0\n\
                 [termination]\ntimeout_s = 1.5\n",
                root().join("maps/gen01.xodr"),
                root().join("routes/gen01.toml"),
            ),
        )
        .unwrap();
        let json = tmp.path().join(format!("{selector}.json"));
        let record = run_json(&[scenario.to_str().unwrap()], &json);
        let r = &record["result"];
        assert!(
            r["provenance"]["driver"]
                .as_str()
                .unwrap()
                .contains("random.safetensors"),
            "{selector}: {r}"
        );
        assert!(
            r["provenance"]["render_backend"].as_str().unwrap() != "none",
            "{selector}: the policy needs the camera"
        );
        assert!(r["ticks"].as_u64().unwrap() > 0);
        assert!(
            r["max_latency_ms"].as_f64().unwrap() <= 100.0,
            "{selector}: latency above L_high"
        );
    }
}
