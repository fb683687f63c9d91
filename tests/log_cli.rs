//! `mrdrive run --record` and `mrdrive log summary` end to end: two
//! recordings of one deterministic run are byte-identical, and the summary
//! reads them back.

mod common;

use std::path::{Path, PathBuf};

use common::{run, run_ok};

/// The default scenario, cut to `timeout_s` of sim time, with absolute paths.
fn short_scenario(dir: &Path, timeout_s: f64) -> PathBuf {
    let root = common::root();
    let text = format!(
        "name = \"short\"\n\
         [map]\nfile = \"{}\"\n\
         [route]\nfile = \"{}\"\nid = 0\n\
         [traffic]\nvehicles = 5\npedestrians = 10\nseed = 1\n\
         [termination]\ntimeout_s = {timeout_s:?}\n",
        root.join("maps/gen01.xodr").display(),
        root.join("routes/gen01.toml").display(),
    );
    let path = dir.join("short.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// The message count of `topic` in a summary's topic table.
fn count(summary: &str, topic: &str) -> u64 {
    let line = summary
        .lines()
        .find(|l| l.split_whitespace().next() == Some(topic))
        .unwrap_or_else(|| panic!("no {topic} in:\n{summary}"));
    line.split_whitespace().last().unwrap().parse().unwrap()
}

#[test]
fn two_recordings_are_byte_identical_and_summarised() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = short_scenario(dir.path(), 2.0);
    let scenario = scenario.to_str().unwrap();
    let a = dir.path().join("a.mcap");
    let b = dir.path().join("b.mcap");
    for log in [&a, &b] {
        run_ok(&[
            "run",
            scenario,
            "--quiet",
            "--record",
            log.to_str().unwrap(),
        ]);
    }
    let (bytes_a, bytes_b) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    assert!(bytes_a.len() > 1000, "{} bytes", bytes_a.len());
    assert!(bytes_a == bytes_b, "the two recordings differ");

    let summary = run_ok(&["log", "summary", a.to_str().unwrap()]);
    for (topic, schema) in [
        ("/tf", "foxglove.FrameTransform"),
        ("/scene/map", "foxglove.SceneUpdate"),
        ("/scene/actors", "foxglove.SceneUpdate"),
        ("/control", "mrdrive.Control"),
        ("/ego", "mrdrive.EgoState"),
        ("/camera/image", "foxglove.CompressedImage"),
        ("/bev/image", "foxglove.CompressedImage"),
        ("/infractions/events", "mrdrive.Infraction"),
    ] {
        assert!(
            summary
                .lines()
                .any(|l| l.split_whitespace().take(2).eq([topic, schema])),
            "no {topic} {schema} in:\n{summary}"
        );
    }
    // One control a tick, state every second tick (20 Hz camera), the map once.
    let control = count(&summary, "/control");
    assert!(control >= 80, "{summary}");
    assert_eq!(count(&summary, "/tf"), control / 2, "{summary}");
    assert_eq!(count(&summary, "/scene/map"), 1, "{summary}");
    // The run ends by its 2 s route timeout: the summary shows the infraction
    // and the result record.
    assert_eq!(count(&summary, "/infractions/events"), 1, "{summary}");
    assert!(summary.contains("route_timeout"), "{summary}");
    assert!(summary.contains("result        FAILURE"), "{summary}");
    assert!(
        summary.contains("counts        route_timeout 1"),
        "{summary}"
    );
}

#[test]
fn summary_of_a_missing_or_broken_file_names_it() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.mcap");
    let o = run(&["log", "summary", missing.to_str().unwrap()]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("nope.mcap") && err.contains("--record"),
        "{err}"
    );

    let broken = dir.path().join("broken.mcap");
    std::fs::write(&broken, b"\x89MCAP0\r\nnot a log").unwrap();
    let o = run(&["log", "summary", broken.to_str().unwrap()]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("broken.mcap") && err.contains("record it again"),
        "{err}"
    );
}
