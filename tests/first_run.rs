//! What a new user sees from `cargo xtask run`: `mrdrive run` on the default
//! scenario succeeds without a line that reads as an error, shows its progress
//! (plain lines when its output is not a terminal), and writes its record, its
//! picture and its log where it says.

mod common;

use common::run;

#[test]
fn the_default_run_speaks_plainly_and_says_where_its_picture_and_log_are() {
    let tmp = tempfile::tempdir().unwrap();
    // A folder that does not exist yet: the run makes it.
    let dir = tmp.path().join("out");
    let (json, mcap) = (dir.join("run.json"), dir.join("run.mcap"));
    let args = [
        "run".into(),
        "scenarios/default.toml".into(),
        "--json".into(),
        json.clone().into_os_string(),
        "--record".into(),
        mcap.clone().into_os_string(),
        "--no-images".into(),
    ];
    let out = run(&args);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(
        stdout.contains("SUCCESS"),
        "the default scenario succeeds:\n{stdout}"
    );
    for line in stdout.lines().chain(stderr.lines()) {
        assert!(
            !line.trim_start().to_lowercase().starts_with("error"),
            "a successful run printed an error line: {line:?}\n--- stderr\n{stderr}"
        );
    }
    assert!(
        stderr
            .lines()
            .any(|l| l.starts_with("progress: ") && l.contains("real time")),
        "no progress line on a non-terminal:\n{stderr}"
    );
    let png = dir.join("run.png");
    for (what, file) in [("record", &json), ("picture", &png), ("log", &mcap)] {
        assert!(file.is_file(), "no {what} at {}", file.display());
        assert!(
            stdout.contains(&format!("{what}: {}", file.display())),
            "the {what}'s path is not printed:\n{stdout}"
        );
    }
    assert!(stdout.contains("Foxglove"), "{stdout}");
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(
        record["result"]["trace"]
            .as_array()
            .is_some_and(|t| t.len() > 100),
        "the record carries the path driven"
    );
}
