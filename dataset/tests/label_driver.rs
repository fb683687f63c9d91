//! The labels drive: a driver that decodes the action values of the moment
//! (no network) follows the default scenario's route through its junctions
//! and lights.

use std::path::Path;

use dataset::label_driver::LabelDriver;
use sim::runner::{self, RunInputs};
use sim::scenario::Scenario;
use sim::selector::Fixed;
use world::agents::VehicleParams;

#[test]
fn the_label_driver_completes_the_default_route_without_running_a_red_light() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/default.toml");
    let mut scenario = Scenario::from_file(&path).unwrap();
    // Labels every 100 ms instead of 50 ms: half the labelling, same answer.
    scenario.timing.control_period_ms = 100.0;
    let prepared = runner::prepare(&scenario).unwrap();
    let mut driver = LabelDriver::new(&prepared.town, &VehicleParams::default());
    let mut selector = Fixed { scale: 1.0 };
    let started = std::time::Instant::now();
    let record = runner::run(
        &scenario,
        &path,
        RunInputs {
            prepared: &prepared,
            driver: &mut driver,
            selector: &mut selector,
            camera: None,
            observers: Vec::new(),
            max_ticks: None,
        },
    )
    .unwrap();
    let r = &record.result;
    println!(
        "label driver: success {} completion {:.1} % in {:.1} s simulated ({:.1} s wall); counts {:?}; outside lanes {:.1} %",
        r.success,
        r.completion_pct,
        r.sim_time_s,
        started.elapsed().as_secs_f64(),
        r.counts,
        r.outside_lane_pct
    );
    assert!(r.success, "{:?}", r.infractions);
    use sim::monitors::InfractionKind::*;
    for kind in [
        RedLight,
        CollisionVehicle,
        CollisionPedestrian,
        CollisionStatic,
    ] {
        assert_eq!(r.counts[&kind], 0, "{:?}", r.infractions);
    }
}
