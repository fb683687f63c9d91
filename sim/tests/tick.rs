//! The loop steps the world by the scenario's `timing.tick_s`: a run at
//! 20 Hz drives the ego as far in the same simulated time as one at 40 Hz.

use std::path::Path;

use sim::expert::{Expert, ExpertParams};
use sim::observe::Moments;
use sim::runner::{self, RunInputs};
use sim::scenario::Scenario;
use sim::selector::Fixed;
use world::Vec2;

/// Where the ego is after `seconds` of the default scenario (no traffic),
/// stepping `tick_s`; and the simulated time the run reports.
fn ego_after(tick_s: f64, seconds: f64) -> (Vec2, f64) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let file = root.join("scenarios/default.toml");
    let mut scenario = Scenario::from_file(&file).unwrap();
    scenario.timing.tick_s = tick_s;
    scenario.traffic.vehicles = 0;
    scenario.traffic.pedestrians = 0;
    // The expert with no latency: only the tick differs between two runs.
    scenario.timing.latency_ms.clear();
    let prepared = runner::prepare(&scenario).unwrap();
    let mut driver = Expert::new(ExpertParams::default());
    let mut selector = Fixed { scale: 1.0 };
    let mut last = Moments::last();
    let record = runner::run(
        &scenario,
        &file,
        RunInputs {
            prepared: &prepared,
            driver: &mut driver,
            selector: &mut selector,
            camera: None,
            observers: vec![&mut last],
            max_ticks: Some((seconds / tick_s).round() as u64),
        },
    )
    .unwrap();
    let last = last.kept[0].actors[0].position.truncate();
    let start = prepared.route.points[0].position.truncate();
    (last - start, record.result.sim_time_s)
}

#[test]
fn a_run_at_20_hz_drives_as_far_as_one_at_40_hz() {
    let (d40, t40) = ego_after(0.025, 6.0);
    let (d20, t20) = ego_after(0.05, 6.0);
    assert!(
        (t40 - 6.0).abs() < 1e-9 && (t20 - 6.0).abs() < 1e-9,
        "{t40} {t20}"
    );
    assert!(d40.length() > 20.0, "the expert drove {d40}");
    assert!(
        (d20 - d40).length() < 0.05 * d40.length(),
        "after 6 s: {d20} at 20 Hz vs {d40} at 40 Hz"
    );
}
