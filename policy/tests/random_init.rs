//! `mrdrive policy init`'s network is fixed by its seed: two saves give the
//! same bytes, and the same network as seeding the device and initialising.
//! In its own test binary (its own process): the backend's random stream is
//! shared by every thread of a process, so a test running beside it would
//! draw from the stream between the seed and the init.

use policy::backbone::Depth;
use policy::burn::prelude::*;
use policy::checkpoint::{load, save_random_init};
use policy::model::PolicyConfig;

#[test]
fn a_random_init_is_fixed_by_its_seed() {
    let cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
        .with_input_height(64)
        .with_input_width(96);
    let dir = tempfile::tempdir().unwrap();
    let (a, b, c) = (
        dir.path().join("a.safetensors"),
        dir.path().join("b.safetensors"),
        dir.path().join("c.safetensors"),
    );
    save_random_init(&cfg, 5, &a).unwrap();
    save_random_init(&cfg, 5, &b).unwrap();
    save_random_init(&cfg, 6, &c).unwrap();
    let bytes = |p| std::fs::read(p).unwrap();
    assert!(bytes(&a) == bytes(&b), "seed 5 twice: other weights");
    assert!(bytes(&a) != bytes(&c), "seeds 5 and 6: the same weights");
    // The same network as seeding the device and initialising.
    let device = Device::flex();
    device.seed(5);
    let net = cfg.init(&device);
    let (back, _) = load(&a, &device).unwrap();
    let x = Tensor::<4>::ones([1, 3, 64, 96], &device);
    let logits = |n: &policy::model::PolicyNet| {
        n.valid()
            .forward(x.clone(), 1, false)
            .action_logits
            .into_data()
    };
    assert_eq!(logits(&net), logits(&back));
}
