//! The closed loop through the command line: determinism, each resolution
//! selector switching past a light, a policy driving, and a sweep that is
//! killed mid-way and resumed.

mod common;

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{mrdrive, root, run_ok};

/// `mrdrive run --quiet ARGS --json JSON`: the record it wrote.
fn run_json(args: &[&str], json: &Path) -> serde_json::Value {
    let mut all: Vec<OsString> = vec!["run".into(), "--quiet".into()];
    all.extend(args.iter().map(OsString::from));
    all.extend(["--json".into(), json.into()]);
    run_ok(&all);
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

#[test]
fn two_runs_of_one_scenario_give_identical_records() {
    let tmp = tempfile::tempdir().unwrap();
    // The default scenario has traffic (5 vehicles, 10 pedestrians); the expert drives
    // (the policy's determinism is the regression suite's gen01_route0_ra_oracle).
    let a = run_json(
        &["scenarios/default.toml", "--expert", "--seed", "7"],
        &tmp.path().join("a.json"),
    );
    let b = run_json(
        &["scenarios/default.toml", "--expert", "--seed", "7"],
        &tmp.path().join("b.json"),
    );
    assert_eq!(
        a["result"], b["result"],
        "the deterministic part of the record differs"
    );
    assert_eq!(a["result"]["traffic"]["vehicles"], 5);
    // A different seed gives a different run (so the test can tell).
    let c = run_json(
        &["scenarios/default.toml", "--expert", "--seed", "8"],
        &tmp.path().join("c.json"),
    );
    assert_ne!(a["result"]["ticks"], c["result"]["ticks"]);
}

#[test]
fn the_expert_drives_gen03_through_lane_changes_and_the_roundabout_in_traffic() {
    // Route 4 changes lanes on the north-south arterial and goes round the
    // roundabout; 20 vehicles and 40 pedestrians, three seeds.
    let tmp = tempfile::tempdir().unwrap();
    for seed in ["1", "2", "3"] {
        let r = run_json(
            &[
                "scenarios/gen03/gen03_random4.toml",
                "--expert",
                "--vehicles",
                "20",
                "--pedestrians",
                "40",
                "--seed",
                seed,
                "--no-picture",
            ],
            &tmp.path().join(format!("{seed}.json")),
        );
        let r = &r["result"];
        assert_eq!(r["success"], true, "seed {seed}: {}", r["termination"]);
        for kind in [
            "collision_vehicle",
            "collision_pedestrian",
            "collision_static",
            "red_light",
            "on_sidewalk",
        ] {
            assert_eq!(r["counts"][kind], 0, "seed {seed}: {kind}");
        }
    }
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

/// A scenario on gen01's route 0 (its first light is ~80 m on, and the ego
/// waits there for green) with the latencies of 0.75 and 1.0, `resolution`
/// and `driver` sections, cut at `timeout_s` seconds.
fn selector_scenario(dir: &Path, name: &str, sections: &str, timeout_s: f64) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(
        &path,
        format!(
            "[map]\nfile = {:?}\n[route]\nfile = {:?}\nid = 0\n\
             [timing]\nlatency_ms = {{ \"0.75\" = 50.0, \"1.0\" = 100.0 }}\n{sections}\n\
             [termination]\ntimeout_s = {timeout_s:?}\n",
            root().join("maps/gen01.xodr"),
            root().join("routes/gen01.toml"),
        ),
    )
    .unwrap();
    path
}

/// Share of control boundaries at `scale` ("0.75", "1") in a record.
fn share(record: &serde_json::Value, scale: &str) -> f64 {
    record["result"]["scale_share"][scale]
        .as_f64()
        .unwrap_or(0.0)
}

#[test]
fn each_selector_switches_as_its_scenario_says_past_a_light() {
    let tmp = tempfile::tempdir().unwrap();
    // 60 s: the expert reaches the first light, waits for green and drives
    // through it and on (about 45 % of the route).
    let run = |name: &str, resolution: &str| {
        let scenario = selector_scenario(tmp.path(), name, resolution, 60.0);
        let record = run_json(
            &[scenario.to_str().unwrap()],
            &tmp.path().join(format!("{name}.json")),
        );
        let completion = record["result"]["completion_pct"].as_f64().unwrap();
        assert!(completion > 30.0, "{name}: only {completion} % driven");
        record
    };
    let name = |r: &serde_json::Value| r["result"]["settings"]["resolution"].clone();
    let latency = |r: &serde_json::Value| r["result"]["max_latency_ms"].as_f64().unwrap();

    let fixed = run(
        "fixed",
        "[resolution]\nselector = \"fixed\"\nscale = 0.75\n",
    );
    assert_eq!(name(&fixed), "fixed-0.75");
    assert_eq!(share(&fixed, "0.75"), 1.0);
    assert_eq!(latency(&fixed), 50.0);

    // The oracle: low on the road, high within 5 m of the light and until
    // 15 m past it, low again after.
    let oracle = run("oracle", "[resolution]\nselector = \"oracle\"\n");
    assert_eq!(name(&oracle), "oracle-0.75/1-5/15m");
    let oracle_high = share(&oracle, "1");
    assert!(
        oracle_high > 0.1 && share(&oracle, "0.75") > 0.1,
        "the oracle must switch up at the light and back down past it: {}",
        oracle["result"]["scale_share"]
    );
    assert_eq!(latency(&oracle), 100.0);

    // Its parameters reach it: switching up from 30 m keeps the high scale longer.
    let early = run(
        "oracle-early",
        "[resolution]\nselector = \"oracle\"\nnear_m = 30.0\nfar_m = 40.0\n",
    );
    assert_eq!(name(&early), "oracle-0.75/1-30/40m");
    assert!(
        share(&early, "1") > oracle_high,
        "{}",
        early["result"]["scale_share"]
    );

    // The lookahead, with the lead time its latencies need (50 + 100 ms).
    let lookahead = run("lookahead", "[resolution]\nselector = \"lookahead\"\n");
    assert_eq!(name(&lookahead), "lookahead-0.75/1-5/15m-cover0.15s");
    assert!(
        share(&lookahead, "1") > 0.1 && share(&lookahead, "0.75") > 0.1,
        "{}",
        lookahead["result"]["scale_share"]
    );

    // The budget: the highest scale within 75 ms.
    let budget = run(
        "budget",
        "[resolution]\nselector = \"budget\"\nbudget_ms = 75.0\n",
    );
    assert_eq!(name(&budget), "budget-75ms");
    assert_eq!(share(&budget, "0.75"), 1.0);
    assert_eq!(latency(&budget), 50.0);
}

/// A policy whose control lands a tick or more after its frame computes beside the loop
/// while the next frame renders (`sim::overlap`); a run with the log's recorder, which
/// reads each control at its own tick, computes it in line. Both give the same record.
#[test]
fn a_policy_computed_beside_the_loop_gives_the_record_of_the_loop_in_line() {
    let tmp = tempfile::tempdir().unwrap();
    // The shipped RA with the oracle selector: latency 50 ms at 0.75x, 100 ms at 1.0x.
    let args = [
        "scenarios/policy_oracle.toml",
        "--vehicles",
        "5",
        "--pedestrians",
        "10",
        "--seed",
        "3",
        "--no-picture",
    ];
    let beside = run_json(&args, &tmp.path().join("beside.json"));
    let log = tmp.path().join("in_line.mcap");
    let mut in_line_args = args.to_vec();
    in_line_args.extend(["--record", log.to_str().unwrap(), "--no-images"]);
    let in_line = run_json(&in_line_args, &tmp.path().join("in_line.json"));
    assert_eq!(
        beside["result"], in_line["result"],
        "computing the control beside the loop changed the run"
    );
    assert!(beside["result"]["ticks"].as_u64().unwrap() > 400);
    assert!(beside["result"]["max_latency_ms"].as_f64().unwrap() >= 50.0);
}

#[test]
fn a_policy_checkpoint_drives_a_scenario_through_its_camera() {
    let tmp = tempfile::tempdir().unwrap();
    let weights = tmp.path().join("random.safetensors");
    let weights_arg = weights.to_str().unwrap();
    run_ok(&["policy", "init", "--seed", "1", "--out", weights_arg]);
    let scenario = selector_scenario(
        tmp.path(),
        "policy",
        "[driver]\nkind = \"policy\"\ncheckpoint = \"random.safetensors\"\n\
         [resolution]\nselector = \"oracle\"\n",
        1.5,
    );
    let record = run_json(&[scenario.to_str().unwrap()], &tmp.path().join("p.json"));
    let r = &record["result"];
    assert!(
        r["provenance"]["driver"]
            .as_str()
            .unwrap()
            .contains("random.safetensors"),
        "{r}"
    );
    assert!(
        r["provenance"]["render_backend"].as_str().unwrap() != "none",
        "the policy needs the camera"
    );
    assert!(r["ticks"].as_u64().unwrap() > 0);
    assert!(
        r["max_latency_ms"].as_f64().unwrap() <= 100.0,
        "latency above L_high"
    );
}

#[test]
fn latency_jitter_spreads_the_latency_and_is_reproducible() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |name: &str, jitter: f64, seed: u64| {
        let scenario = selector_scenario(
            tmp.path(),
            name,
            &format!(
                "[resolution]\nselector = \"fixed\"\nscale = 0.75\n[traffic]\nseed = {seed}\n"
            ),
            20.0,
        );
        // The jitter goes into the [timing] section the helper writes.
        let text = std::fs::read_to_string(&scenario).unwrap().replace(
            "[timing]\n",
            &format!("[timing]\nlatency_jitter = {jitter:?}\n"),
        );
        std::fs::write(&scenario, text).unwrap();
        run_json(
            &[scenario.to_str().unwrap()],
            &tmp.path().join(format!("{name}.json")),
        )["result"]
            .clone()
    };
    // A run's result without where it came from (the scenario's file name).
    let run = |name: &str, jitter: f64, seed: u64| {
        let mut r = run(name, jitter, seed);
        r.as_object_mut().unwrap().remove("provenance");
        r
    };
    let steady = run("steady", 0.0, 1);
    assert_eq!(steady["max_latency_ms"].as_f64().unwrap(), 50.0);
    let a = run("a", 0.3, 1);
    let b = run("b", 0.3, 1);
    let other = run("other", 0.3, 2);
    let max = |r: &serde_json::Value| r["max_latency_ms"].as_f64().unwrap();
    // ~200 boundaries: the largest of as many log-normal draws (sigma 0.3) is
    // well above the median.
    assert!(max(&a) > 60.0, "{}", max(&a));
    assert_eq!(a, b, "same seed, same jitter draws, same run");
    assert_ne!(max(&a), max(&other), "another seed draws other latencies");
}

#[test]
fn render_replays_a_moment_with_the_driver_delay_and_scale_a_sweep_passes() {
    let tmp = tempfile::tempdir().unwrap();
    let png = tmp.path().join("frame.png");
    let png_s = png.to_str().unwrap();
    let render = |extra: &[&str]| -> String {
        let mut args = vec![
            "render",
            "scenarios/default.toml",
            "--at",
            "1",
            "--out",
            png_s,
        ];
        args.extend(extra);
        run_ok(&args)
    };
    // The scenario's own driver: the RA with the oracle selector.
    let own = render(&[]);
    assert!(
        own.contains("driver        policy:scenarios/../models/ra.safetensors")
            && own.contains("resolution oracle-0.75/1"),
        "{own}"
    );
    // A flag away: the expert.
    let expert = render(&["--expert"]);
    assert!(expert.contains("driver        expert"), "{expert}");
    // A sweep's flags: the shipped RA at a fixed 0.75x with a delay.
    let policy = render(&[
        "--checkpoint",
        "models/ra.safetensors",
        "--drive-scale",
        "0.75",
        "--delay-ms",
        "50",
    ]);
    assert!(
        policy.contains("driver        policy:models/ra.safetensors")
            && policy.contains("resolution fixed-0.75"),
        "{policy}"
    );
    assert!(png.exists());
    // A driving scale out of range is refused by its own flag's name.
    let bad = common::run(&[
        "render",
        "scenarios/default.toml",
        "--at",
        "1",
        "--drive-scale",
        "1.5",
        "--out",
        png_s,
    ]);
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("--drive-scale 1.5"),
        "{err}"
    );
    // The two drivers are somewhere else after a second.
    let at = |out: &str| {
        out.lines()
            .next()
            .unwrap()
            .split(": ego at")
            .nth(1)
            .unwrap()
            .to_string()
    };
    assert_ne!(at(&expert), at(&policy));
}
