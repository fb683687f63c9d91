//! A scenario's `[traffic]` section reaches the traffic the loop runs.

use std::path::{Path, PathBuf};

use sim::build::{self, Drivers};
use sim::observe::Moments;
use sim::runner::{self, RunInputs};
use sim::scenario::Scenario;
use world::ActorKind;

fn default_scenario() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/default.toml")
}

/// Where the pedestrians are, once a second over the first `seconds` of the
/// default scenario (expert driving, 40 pedestrians, no vehicles) with
/// `traffic.cross_factor = cross_factor`.
fn pedestrian_track(cross_factor: f32, seconds: u64) -> Vec<Vec<[f32; 2]>> {
    let path = default_scenario();
    let mut scenario = Scenario::from_file(&path).unwrap();
    scenario.traffic.vehicles = 0;
    scenario.traffic.pedestrians = 40;
    scenario.traffic.seed = 3;
    scenario.traffic.cross_factor = cross_factor;
    scenario.driver = sim::scenario::DriverSpec::default();
    let prepared = runner::prepare(&scenario).unwrap();
    let mut driver = Drivers::new().driver(&scenario, &prepared).unwrap();
    let mut selector = build::selector_for(&scenario, None).unwrap();
    let ticks_per_s = (1.0 / scenario.timing.tick_s).round() as u64;
    let mut moments = Moments::every(ticks_per_s);
    runner::run(
        &scenario,
        &path,
        RunInputs {
            prepared: &prepared,
            driver: driver.as_mut(),
            selector: selector.as_mut(),
            camera: None,
            observers: vec![&mut moments],
            max_ticks: Some(seconds * ticks_per_s),
        },
    )
    .unwrap();
    moments
        .kept
        .iter()
        .map(|m| {
            m.actors
                .iter()
                .filter(|a| a.kind == ActorKind::Pedestrian)
                .map(|a| [a.position.x, a.position.y])
                .collect()
        })
        .collect()
}

#[test]
fn the_scenario_cross_factor_changes_where_pedestrians_walk() {
    let (cautious, again) = (pedestrian_track(0.0, 60), pedestrian_track(0.0, 60));
    assert_eq!(cautious, again, "a run is deterministic");
    assert_eq!(cautious.len(), 60);
    assert!(cautious[0].len() > 30, "{} pedestrians", cautious[0].len());
    // Every walker a jaywalker: the same seed, other paths.
    let bold = pedestrian_track(1.0, 60);
    assert!(
        bold != cautious,
        "traffic.cross_factor did not change where anyone walks: it does not reach the traffic"
    );
}
