//! The policy the way the closed loop will use it: a checkpoint on disk, a selector
//! choosing the scale at each control boundary, the image rendered at that scale,
//! the driver's control, and the latency in force for that scale.

use policy::PolicyDriver;
use policy::backbone::Depth;
use policy::burn::prelude::*;
use policy::checkpoint::{self, ModelCard};
use policy::model::PolicyConfig;
use sim::driver::{Command, Driver, Observation, RgbImage};
use sim::render::image::test_pattern;
use sim::selector::{
    Fixed, LatencyBudget, LatencyTable, Lookahead, Oracle, ResolutionSelector, SelectorInput,
};

/// A stand-in for the renderer: a deterministic image of the size the scale gives.
fn render(cfg: &PolicyConfig, scale: f32, t: usize) -> RgbImage {
    let [h, w] = cfg.input_size(scale);
    test_pattern(w as u32, h as u32, t as u64)
}

#[test]
fn a_checkpoint_drives_a_scripted_approach_with_each_selector() {
    let device = Device::flex();
    device.seed(3);
    let cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
        .with_input_height(64)
        .with_input_width(96);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("random.safetensors");
    checkpoint::save(&cfg.init(&device), &ModelCard::random_init(3), &path).unwrap();

    let table = LatencyTable::new(&[(0.75, 50.0), (1.0, 100.0)]).unwrap();
    let selectors: Vec<Box<dyn ResolutionSelector>> = vec![
        Box::new(Fixed { scale: 0.75 }),
        Box::new(Fixed { scale: 1.0 }),
        Box::new(Oracle::default()),
        Box::new(Lookahead::covering(0.75, 1.0, &table).unwrap()),
        Box::new(LatencyBudget {
            table: table.clone(),
            budget_ms: 60.0,
        }),
    ];
    for mut selector in selectors {
        let mut driver = PolicyDriver::from_checkpoint(&path, device.clone()).unwrap();
        assert!(!driver.card().trained, "a random checkpoint's card says so");
        assert!(driver.name().contains("random.safetensors"));
        let mut d = 30.0f32;
        let mut used = vec![];
        for t in 0..40 {
            let input = SelectorInput {
                light_ahead_m: (d >= 0.0).then_some(d),
                light_behind_m: (d < 0.0).then_some(-d),
                speed_mps: 10.0,
                driver_hint: driver.scale_hint(),
            };
            let scale = selector.select(&input);
            let latency_ms = table.latency_ms(scale).expect("every scale has a latency");
            let image = render(&cfg, scale, t);
            let obs = Observation {
                time_s: t as f64 * 0.05,
                speed_mps: 5.0,
                command: Command::LaneFollow,
                scale,
                image: Some(&image),
                labels: None,
                privileged: None,
            };
            let c = driver.act(&obs);
            assert!(
                (-1.0..=1.0).contains(&c.steer)
                    && (0.0..=1.0).contains(&c.throttle)
                    && (0.0..=1.0).contains(&c.brake)
            );
            used.push((scale, latency_ms));
            d -= 1.5;
        }
        let highs = used.iter().filter(|(s, _)| *s == 1.0).count();
        match selector.name().as_str() {
            "fixed-0.75" | "budget-60ms" => assert_eq!(highs, 0),
            "fixed-1" => assert_eq!(highs, 40),
            // 30 m -> -28.5 m in 1.5 m steps: up at d = 4.5 m (oracle) / 6.0 m (lookahead: trigger at
            // 5 + 10 m/s x 0.15 s = 6.5 m),
            // down past 15 m behind.
            "oracle-0.75/1-5/15m" => assert_eq!(highs, 14, "{used:?}"),
            "lookahead-0.75/1-5/15m-cover0.15s" => assert_eq!(highs, 15, "{used:?}"),
            other => panic!("unexpected selector {other}"),
        }
        assert!(used.iter().all(|(s, l)| (*s == 1.0) == (*l == 100.0)));
    }
}
