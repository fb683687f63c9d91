//! The Python environment (`python/`) against this build: its own tests (Gymnasium's
//! checker, seeds, bad input, ten environments), then the same simulator proof: the
//! scripted controls the Python test sends, given to the loop by a Rust driver, give
//! the identical result record.

mod common;

use sim::build::Overrides;
use sim::build::{self, Drivers, Extras, FactoryError, RunRequest};
use sim::driver::{Driver, DriverNeeds, Observation, VehicleControl};
use sim::record::RunRecord;
use sim::runner::Prepared;
use sim::scenario::{DriverKind, DriverSpec, Scenario};
use world::testdata::{self, Needs};

/// Step k's control of the scripted driver (`scripted` in python/tests/test_env.py).
fn scripted(k: usize) -> VehicleControl {
    let steer = ((k % 7) as f64 - 3.0) / 32.0;
    let throttle = if (k / 20) % 3 != 2 { 0.5 } else { 0.0 };
    let brake = if throttle > 0.0 { 0.0 } else { 0.25 };
    VehicleControl {
        steer: steer as f32,
        throttle: throttle as f32,
        brake: brake as f32,
    }
}

/// The scripted controls as a driver named like the remote one, with a camera as it has.
struct Scripted(usize);

impl Driver for Scripted {
    fn name(&self) -> String {
        "external".into()
    }
    fn needs(&self) -> DriverNeeds {
        DriverNeeds {
            camera: true,
            privileged: false,
            labels: false,
        }
    }
    fn act(&mut self, _obs: &Observation<'_>) -> VehicleControl {
        self.0 += 1;
        scripted(self.0 - 1)
    }
}

struct ScriptedFactory;

impl build::DriverFactory for ScriptedFactory {
    fn driver(&self, _: &Scenario, _: &Prepared) -> Result<Box<dyn Driver>, FactoryError> {
        Ok(Box::new(Scripted(0)))
    }
}

#[test]
fn the_python_environment_passes_its_tests_and_drives_like_rust() {
    let test = "the_python_environment_passes_its_tests_and_drives_like_rust";
    let Some(python) = testdata::python_with("gymnasium, numpy") else {
        testdata::skip(
            test,
            Needs::Python,
            "no Python with gymnasium and numpy (cargo xtask setup makes .venv)",
        );
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let record_path = tmp.path().join("scripted.json");
    let out = std::process::Command::new(&python)
        .args(["-m", "unittest", "discover", "-s", "python/tests", "-v"])
        .current_dir(common::root())
        .env("MRDRIVE_BIN", env!("CARGO_BIN_EXE_mrdrive"))
        .env("MRDRIVE_SCRIPTED_RECORD", &record_path)
        .output()
        .expect("python starts");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the Python tests failed:\n{stderr}");

    let text = std::fs::read_to_string(&record_path).expect("the scripted test wrote its record");
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let python: RunRecord = serde_json::from_value(v["record"].clone()).unwrap();
    // Canonical, as Python resolves it: the record names the file.
    let scenario = std::fs::canonicalize(common::root().join("scenarios/default.toml")).unwrap();
    let overrides = Overrides {
        seed: Some(2),
        driver: Some(DriverSpec {
            kind: DriverKind::External,
            checkpoint: None,
            device: None,
            trigger: None,
        }),
        ..Default::default()
    };
    let request = RunRequest {
        scale: Some(0.75),
        record: None,
        ..RunRequest::new(&scenario, &overrides)
    };
    let drivers = Drivers::new().with(DriverKind::External, ScriptedFactory);
    let rust = build::run_scenario_with(&request, &drivers, &mut |_| {}, Extras::default())
        .unwrap()
        .record;
    assert!(python.result.ticks > 100, "{:?}", python.result.ticks);
    assert_eq!(python.result, rust.result);
}
