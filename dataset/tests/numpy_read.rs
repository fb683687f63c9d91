//! A dataset written by Rust, read by Python's `safetensors.numpy` and NumPy
//! the way `docs/dataset.md` shows (`read_dataset.py`): every tensor's shape,
//! dtype and a sample of its values must be what the writer put there.
//!
//! Needs a Python with `safetensors`, `numpy` and `zstandard`: `MRDRIVE_PYTHON` names it,
//! else `<workspace>/.venv/bin/python`, else `python3`. Without one the test
//! skips through `world::testdata::skip` (counted by `cargo xtask test`),
//! unless `MRDRIVE_REQUIRE_PYTHON=1`.

use std::path::Path;
use std::process::Command;

use dataset::action::NUM_ACTIONS;
use dataset::format::{ACTOR_FIELDS, FORMAT};
use dataset::synthetic::{self, SyntheticSpec};
use serde_json::Value;

fn f32s(v: &Value) -> Vec<f32> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() as f32)
        .collect()
}

#[test]
fn numpy_reads_a_shard_and_its_labels_as_written() {
    let Some(py) = world::testdata::python_with("safetensors.numpy, numpy, zstandard") else {
        world::testdata::skip(
            "numpy_reads_a_shard_and_its_labels_as_written",
            world::testdata::Needs::Python,
            "no Python with `safetensors`, `numpy` and `zstandard` (set MRDRIVE_PYTHON or create .venv)",
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let spec = SyntheticSpec::tiny(2, 9);
    synthetic::write(dir.path(), &spec).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/read_dataset.py");
    let out = Command::new(&py)
        .arg(&script)
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "read_dataset.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got: Value = serde_json::from_slice(&out.stdout).unwrap();

    let [w, h] = spec.s0.map(|v| v as u64);
    let (n, views) = (9u64, 3u64);
    assert_eq!(got["name"], "synthetic");
    assert_eq!(got["episodes"], 2);
    assert_eq!(got["s0"], serde_json::json!([w, h]));
    let shapes = &got["shapes"];
    assert_eq!(shapes["rgb"], serde_json::json!([n, views, h, w, 3]));
    assert_eq!(shapes["classes"], serde_json::json!([n, views, h, w]));
    assert_eq!(shapes["ego"], serde_json::json!([n, 4]));
    assert_eq!(shapes["actors"], serde_json::json!([n, 2, ACTOR_FIELDS]));
    assert_eq!(
        shapes["q"],
        serde_json::json!([n, views, 6, 4, NUM_ACTIONS])
    );
    let dtypes = &got["dtypes"];
    assert_eq!(shapes["offsets"], serde_json::json!([n + 1]));
    for (name, dtype) in [
        ("images", "uint8"),
        ("offsets", "uint64"),
        ("rgb", "uint8"),
        ("classes", "uint8"),
        ("ego", "float32"),
        ("command", "uint8"),
        ("route", "float32"),
        ("tick", "uint32"),
        ("actors", "float32"),
        ("lights", "uint8"),
        ("q", "float32"),
        ("valid", "uint8"),
    ] {
        assert_eq!(dtypes[name], dtype, "{name}");
    }

    // Values of episode 1.
    let rgb: Vec<u8> = (0..3)
        .map(|c| synthetic::rgb_byte(5, 3, c, 2, 1, 1))
        .collect();
    assert_eq!(got["rgb_2_1_3_5"], serde_json::json!(rgb));
    assert_eq!(
        got["classes_2_1_0_5"],
        synthetic::class_id(5, w as usize, 2, 1)
    );
    let ego = synthetic::ego(3);
    assert_eq!(f32s(&got["ego_3"]), [ego.x, ego.y, ego.yaw, ego.speed]);
    let commands: Vec<u8> = (0..n as usize).map(synthetic::command).collect();
    assert_eq!(got["command"], serde_json::json!(commands));
    let ticks: Vec<u32> = (0..n as u32).map(|i| 10 * i).collect();
    assert_eq!(got["tick"], serde_json::json!(ticks));
    let vehicle = f32s(&got["actors_3"][0]);
    assert_eq!(&vehicle[..4], [1.0, 1.0, ego.x + 15.0, ego.y]);
    let lights = got["lights_2"].as_array().unwrap();
    assert!(lights.iter().all(|l| l == synthetic::light(2)));
    let q: Vec<f32> = (0..NUM_ACTIONS)
        .map(|a| synthetic::q_value(2, 1, 3, 2, a))
        .collect();
    assert_eq!(f32s(&got["q_2_1_3_2"]), q);
    let valid: Vec<bool> = (0..n as usize)
        .map(|i| i + synthetic::UNLABELLED_TAIL < n as usize)
        .collect();
    assert_eq!(got["valid"], serde_json::json!(valid));

    // The docs' example: frame 0, LANEFOLLOW, 0.5 m/s -> bin 0, view 0.
    let ex = &got["example"];
    assert_eq!(
        (
            ex["frame"].as_u64(),
            ex["command"].as_u64(),
            ex["bin"].as_u64()
        ),
        (Some(0), Some(3), Some(0))
    );
    assert_eq!(
        ex["best"].as_u64(),
        Some(27),
        "standing at a red light: the brake"
    );
    assert!(ex["p_best"].as_f64().unwrap() > 0.999);

    assert_eq!(
        got["label_meta"]["label_version"],
        synthetic::LABEL_VERSION.to_string()
    );
    assert_eq!(got["label_meta"]["format"], FORMAT);
    assert_eq!(got["shard_format"], FORMAT);
}
