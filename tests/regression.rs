//! The regression suite: short scenarios driven by the expert at D = 0, 100
//! and 200 ms and each traffic density, and by the shipped RA (oracle selector)
//! and Original policies on a few runs, whose exact infraction counts and
//! route completion are golden files in `tests/golden/`. Each scenario's
//! traffic seed is its own (`[traffic] seed`), chosen so that traffic
//! changes what the ego meets: a golden file whose lines are the same at
//! every density could not catch an NPC regression.
//!
//! Runs are deterministic, so counts are exact: any change shows as a
//! readable line diff (collisions under both counting rules: `counts` holds
//! the paper's, `lb1.0` leaderboard 1.0's). After a deliberate change, `cargo xtask bless`
//! rewrites the golden files (it sets `MRDRIVE_BLESS=1`). The golden lines
//! record the render backend of each run ("none" for the expert, which draws
//! nothing). One golden file holds on every x86-64 CPU with AVX2 and FMA:
//! the frames and the policy's arithmetic do not depend on the CPU
//! (`tests/cross_cpu.rs`; README, "Determinism").
//!
//! Scenarios on CARLA's maps need `../shared/carla/` (or
//! `$MRDRIVE_SHARED_DIR/carla/`); without it they skip through
//! `world::testdata` (counted by `cargo xtask test`), unless
//! `MRDRIVE_REQUIRE_SHARED=1`.

mod common;

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use common::root;

const DELAYS: &str = "0,100,200";
const DENSITIES: &str = "0:0,5:10,20:40";

/// One line per run: its settings and every count that must not drift.
fn golden_line(record: &serde_json::Value) -> String {
    let r = &record["result"];
    let s = &r["settings"];
    let counts = r["counts"].as_object().expect("counts");
    let counts: Vec<String> = counts.iter().map(|(k, v)| format!("{k}={v}")).collect();
    // Collisions under leaderboard 1.0's rule beside the paper's (in `counts`).
    let lb1 = &r["collisions"]["leaderboard-1.0"];
    format!(
        "D={:>3} v={:>2} p={:>2} | realised {}/{} | success={} completion={:.2} score={:.2} outside_lane={:.2}% ticks={} end={} | {} | lb1.0 p={} v={} s={} | backend={}",
        s["delay_ms"],
        s["vehicles"],
        s["pedestrians"],
        r["traffic"]["vehicles"],
        r["traffic"]["pedestrians"],
        r["success"],
        r["completion_pct"].as_f64().unwrap_or(f64::NAN),
        r["driving_score"].as_f64().unwrap_or(f64::NAN),
        r["outside_lane_pct"].as_f64().unwrap_or(f64::NAN),
        r["ticks"],
        r["termination"].as_str().unwrap_or("-"),
        counts.join(" "),
        lb1["pedestrian"],
        lb1["vehicle"],
        lb1["static"],
        r["provenance"]["render_backend"].as_str().unwrap_or("?"),
    )
}

/// Runs one regression scenario through `mrdrive sweep` (at its own traffic
/// seed) and returns its lines.
fn run_scenario(scenario: &Path, out: &Path, delays: &str, densities: &str) -> Vec<String> {
    let seed = sim::scenario::Scenario::from_file(scenario)
        .unwrap()
        .traffic
        .seed
        .to_string();
    let mut args: Vec<OsString> = vec!["sweep".into(), scenario.into()];
    for a in [
        "--delays",
        delays,
        "--densities",
        densities,
        "--seeds",
        seed.as_str(),
        "--jobs",
        "2",
        "--out",
    ] {
        args.push(a.into());
    }
    args.push(out.into());
    common::run_ok(&args);
    let plan: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    let mut lines = Vec::new();
    for run in plan["runs"].as_array().unwrap() {
        let spec: sim::sweep::RunSpec = serde_json::from_value(run.clone()).unwrap();
        let text =
            std::fs::read_to_string(out.join("runs").join(format!("{}.json", spec.key()))).unwrap();
        lines.push(golden_line(&serde_json::from_str(&text).unwrap()));
    }
    lines
}

/// Compares against (or, when blessing, writes) the golden file `tests/golden/<name>.txt`.
fn check(name: &str, lines: &[String]) -> Result<(), String> {
    let path = root().join("tests/golden").join(format!("{name}.txt"));
    let got = lines.join("\n") + "\n";
    if std::env::var("MRDRIVE_BLESS").as_deref() == Ok("1") {
        std::fs::write(&path, &got).unwrap();
        eprintln!("blessed {}", path.display());
        return Ok(());
    }
    let want = std::fs::read_to_string(&path).map_err(|e| {
        format!(
            "{}: {e} (run `cargo xtask bless` to create it)",
            path.display()
        )
    })?;
    if want == got {
        return Ok(());
    }
    let mut diff = format!("{name}: counts changed (golden file {}):\n", path.display());
    let (w, g): (Vec<&str>, Vec<&str>) = (want.lines().collect(), got.lines().collect());
    for i in 0..w.len().max(g.len()) {
        match (w.get(i), g.get(i)) {
            (Some(a), Some(b)) if a == b => {}
            (a, b) => {
                diff += &format!(
                    "  - {}\n  + {}\n",
                    a.unwrap_or(&"(none)"),
                    b.unwrap_or(&"(none)")
                );
            }
        }
    }
    diff += "If the change is deliberate, run `cargo xtask bless` and commit the golden files.\n";
    Err(diff)
}

/// The scenario file of `name`. One on CARLA's maps refers to them as
/// `../../../shared/carla/...`; it is rewritten into `tmp` to point at the
/// CARLA folder the tests use, or is `None` (skipped) without one.
fn scenario_file(name: &str, needs_carla: bool, tmp: &Path) -> Option<PathBuf> {
    let file = root().join("tests/regression").join(format!("{name}.toml"));
    if !needs_carla {
        return Some(file);
    }
    common::with_tests_carla(name, &file, tmp)
}

/// An expert scenario (no camera) at every delay and density.
fn regression(name: &str, needs_carla: bool) {
    regression_at(name, needs_carla, DELAYS, DENSITIES, 9);
}

fn regression_at(name: &str, needs_carla: bool, delays: &str, densities: &str, runs: usize) {
    let tmp = tempfile::tempdir().unwrap();
    let Some(scenario) = scenario_file(name, needs_carla, tmp.path()) else {
        return;
    };
    let lines = run_scenario(&scenario, &tmp.path().join("sweep"), delays, densities);
    assert_eq!(lines.len(), runs, "delays {delays} x densities {densities}");
    if let Err(diff) = check(name, &lines) {
        panic!("{diff}");
    }
}

#[test]
fn gen01_route0() {
    regression("gen01_route0", false);
}

#[test]
fn gen01_route1() {
    regression("gen01_route1", false);
}

#[test]
fn gen02_route1() {
    regression("gen02_route1", false);
}

#[test]
fn town01_route0_segment() {
    regression("town01_route0_segment", true);
}

#[test]
fn town02_route1_segment() {
    regression("town02_route1_segment", true);
}

// The shipped policies (the camera at every control boundary: a few runs only).

#[test]
fn gen01_route0_ra_oracle() {
    regression_at("gen01_route0_ra_oracle", false, "0,100", "0:0,5:10", 4);
}

#[test]
fn gen01_route0_default() {
    regression_at("gen01_route0_default", false, "0", "0:0,5:10", 2);
}

#[test]
fn gen01_route0_original() {
    regression_at("gen01_route0_original", false, "0", "0:0,5:10", 2);
}
