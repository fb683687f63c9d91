//! Cross-checks our MCAP logs with readers we did not write: the official
//! Python `mcap` package reads the file, and `jsonschema` validates one
//! message of each topic against Foxglove's schemas.
//!
//! Needs a Python with `mcap` and `jsonschema` in `MRDRIVE_PYTHON` (`cargo
//! xtask test` makes one); without it the test skips through
//! `world::testdata::skip` (counted by `cargo xtask test`), unless
//! `MRDRIVE_REQUIRE_PYTHON=1`.

use std::path::{Path, PathBuf};
use std::process::Command;

use sim::driver::{RgbImage, VehicleControl};
use sim::expert::{Expert, ExpertParams};
use sim::monitors::{Infraction, InfractionKind};
use sim::recorder::{RecordOptions, Recorder, tick_ns};
use sim::render::{Renderer, RigConfig};
use sim::runner::{self, RunInputs};
use sim::scenario::Scenario;
use sim::selector::Fixed;
use world::testdata::{self, Needs};
use world::{
    ActorKind, ActorSnapshot, LaneMarking, LightState, MarkColor, MarkKind, Town, Vec2, Vec3,
};

/// The Python `cargo xtask test` made (`MRDRIVE_PYTHON`), or `None` after
/// skipping `test`.
fn python(test: &str) -> Option<PathBuf> {
    let python = std::env::var_os("MRDRIVE_PYTHON").map(PathBuf::from);
    if python.is_none() {
        testdata::skip(
            test,
            Needs::Python,
            "MRDRIVE_PYTHON not set (run `cargo xtask test` to make the Python environment)",
        );
    }
    python
}

fn town() -> Town {
    Town {
        markings: vec![LaneMarking {
            points: vec![Vec3::ZERO, Vec3::new(50.0, 0.0, 0.0)],
            kind: MarkKind::Broken,
            color: MarkColor::White,
            width_m: 0.15,
            dash_m: Some((3.0, 9.0)),
        }],
        bounds: (Vec2::ZERO, Vec2::new(50.0, 5.0)),
        ..Town::empty("strip")
    }
}

/// Runs `check_mcap.py` on a log; returns its output after checking it passed.
fn check_with_python(python: &Path, log: &Path) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new(python)
        .arg(root.join("tests/check_mcap.py"))
        .arg(log)
        .arg(root.join("schemas/foxglove"))
        .output()
        .expect("python starts");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "check_mcap.py failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

#[test]
fn python_mcap_reads_and_validates_a_log_of_the_real_loop() {
    let test = "python_mcap_reads_and_validates_a_log_of_the_real_loop";
    let Some(python) = python(test) else { return };
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut scenario = Scenario::from_file(&root.join("scenarios/default.toml")).unwrap();
    scenario.termination.timeout_s = Some(2.0);
    let prepared = runner::prepare(&scenario).unwrap();
    let mut camera = match Renderer::new(&prepared.town, RigConfig::cpu_default(), 1) {
        Ok(r) => Some(r),
        Err(e) => {
            testdata::skip(
                &format!("{test} (camera topics)"),
                Needs::Renderer,
                &format!("no renderer here: {e}"),
            );
            None
        }
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("loop.mcap");
    let options = RecordOptions {
        camera: true,
        labels: true,
        bev: true,
    };
    let mut rec = Recorder::create(&path, options, &prepared.town).unwrap();
    let mut driver = Expert::new(ExpertParams::default());
    let mut selector = Fixed { scale: 1.0 };
    let record = runner::run(
        &scenario,
        &root.join("scenarios/default.toml"),
        RunInputs {
            prepared: &prepared,
            driver: &mut driver,
            selector: &mut selector,
            camera: camera.as_mut().map(|c| c as &mut dyn sim::camera::Camera),
            observers: vec![&mut rec],
            max_ticks: None,
        },
    )
    .unwrap();
    rec.finish(&record.result).unwrap();
    assert!(record.result.ticks >= 40, "{} ticks", record.result.ticks);

    let stdout = check_with_python(&python, &path);
    let mut expected = vec![
        ("/tf", "foxglove.FrameTransform"),
        ("/scene/map", "foxglove.SceneUpdate"),
        ("/scene/actors", "foxglove.SceneUpdate"),
        ("/control", "mrdrive.Control"),
        ("/ego", "mrdrive.EgoState"),
    ];
    if camera.is_some() {
        expected.extend([
            ("/camera/image", "foxglove.CompressedImage"),
            ("/camera/labels", "foxglove.CompressedImage"),
            ("/bev/image", "foxglove.CompressedImage"),
        ]);
    }
    for (topic, schema) in expected {
        assert!(
            stdout.contains(&format!("{topic}\t{schema}\tdecoded+validated")),
            "{topic} missing in:\n{stdout}"
        );
    }
}

#[test]
fn python_mcap_reads_and_validates_every_topic() {
    let Some(python) = python("python_mcap_reads_and_validates_every_topic") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    let town = town();
    let options = RecordOptions {
        camera: true,
        labels: true,
        bev: true,
    };
    let mut rec = Recorder::create(&path, options, &town).unwrap();
    let image = RgbImage {
        width: 8,
        height: 4,
        data: vec![128; 8 * 4 * 3],
    };
    for tick in 0..20u64 {
        let t = tick_ns(tick, 0.025);
        let ego = ActorSnapshot {
            id: 0,
            kind: ActorKind::Ego,
            position: Vec3::new(tick as f32 * 0.2, -1.75, 0.0),
            heading: 0.0,
            extent: Vec3::new(4.79, 2.16, 1.45),
            speed_mps: 8.0,
            color: 0,
        };
        let npc = ActorSnapshot {
            id: 1,
            kind: ActorKind::Vehicle,
            position: Vec3::new(30.0, 1.75, 0.0),
            ..ego
        };
        rec.ego_transform(t, &ego).unwrap();
        rec.actors(t, &[ego, npc], &town, &[LightState::Red])
            .unwrap();
        rec.camera(t, &image).unwrap();
        rec.labels(t, &image).unwrap();
        rec.bev(t, &image).unwrap();
        rec.control(
            t,
            Some(VehicleControl {
                steer: 0.0,
                throttle: 0.7,
                brake: 0.0,
            }),
            VehicleControl::default(),
        )
        .unwrap();
        rec.ego_state(t, &ego, world::Command::LaneFollow, 1.0, 50.0)
            .unwrap();
    }
    let infraction = Infraction {
        tick: 10,
        time_s: 0.25,
        kind: InfractionKind::LaneCrossing,
        position: [2.0, -1.0],
        detail: "marking 0".into(),
    };
    rec.infraction(tick_ns(10, 0.025), &infraction).unwrap();
    rec.finish(&serde_json::json!({ "completion_pct": 12.5 }))
        .unwrap();

    let stdout = check_with_python(&python, &path);
    for (topic, schema) in [
        ("/camera/image", "foxglove.CompressedImage"),
        ("/camera/labels", "foxglove.CompressedImage"),
        ("/bev/image", "foxglove.CompressedImage"),
        ("/tf", "foxglove.FrameTransform"),
        ("/scene/map", "foxglove.SceneUpdate"),
        ("/scene/actors", "foxglove.SceneUpdate"),
        ("/control", "mrdrive.Control"),
        ("/ego", "mrdrive.EgoState"),
        ("/infractions", "foxglove.Log"),
        ("/infractions/events", "mrdrive.Infraction"),
    ] {
        assert!(
            stdout.contains(&format!("{topic}\t{schema}\tdecoded+validated")),
            "{topic} missing in:\n{stdout}"
        );
    }
}
