//! `mrdrive policy ...` through the command line: BN recalibration on rendered frames.

mod common;

use common::{run, run_ok};
use policy::burn::tensor::Device;
use std::path::Path;

/// Running mean and variance of the stem's BN bank, branch `branch`.
fn stem_stats(weights: &Path, branch: usize) -> (Vec<f32>, Vec<f32>) {
    let (net, _) = policy::checkpoint::load(weights, &Device::flex()).unwrap();
    let bn = &net.backbone.bn1.branches[branch];
    let v = |t: policy::burn::tensor::Tensor<1>| t.into_data().try_to_vec::<f32>().unwrap();
    (
        v(bn.running_mean.value_sync()),
        v(bn.running_var.value_sync()),
    )
}

#[test]
fn recalibration_sets_each_branch_from_frames_at_its_scale() {
    let tmp = tempfile::tempdir().unwrap();
    let before = tmp.path().join("tiny.safetensors");
    let after = tmp.path().join("tiny-recal.safetensors");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    run_ok(&["policy", "init", "--preset", "tiny", "--out", &s(&before)]);
    let out = run_ok(&[
        "policy",
        "recalibrate",
        &s(&before),
        "--scenario",
        "scenarios/default.toml",
        "--batches",
        "3",
        "--batch",
        "2",
        "--every-s",
        "1.0",
        "--vehicles",
        "2",
        "--pedestrians",
        "2",
        "--out",
        &s(&after),
    ]);
    assert!(out.contains("on 3 batches of 2"), "{out}");
    // A fresh BN has mean 0 and variance 1; recalibrated, each branch has its own statistics.
    let (m0, v0) = stem_stats(&before, 0);
    assert!(m0.iter().all(|&x| x == 0.0) && v0.iter().all(|&x| x == 1.0));
    let (a_m, a_v) = stem_stats(&after, 0);
    let (b_m, b_v) = stem_stats(&after, 1);
    assert!(a_m.iter().any(|&x| x != 0.0) && a_v.iter().all(|&x| x > 0.0 && x != 1.0));
    assert_ne!(
        a_m, b_m,
        "0.75x and 1.0x frames differ, so must their statistics"
    );
    assert_ne!(a_v, b_v);
    // The card keeps the weights' status and says what was done.
    let info = run_ok(&["policy", "info", &s(&after)]);
    assert!(
        info.contains("recalibrated on 6 frames per scale") && info.contains("\"trained\": false"),
        "{info}"
    );
    // The convolutions are untouched.
    let conv = |p: &Path| {
        let (net, _) = policy::checkpoint::load(p, &Device::flex()).unwrap();
        net.backbone
            .conv1
            .weight
            .val()
            .into_data()
            .try_to_vec::<f32>()
            .unwrap()
    };
    assert_eq!(conv(&before), conv(&after));
}

#[test]
fn recalibration_errors_name_the_problem() {
    let out = run(&[
        "policy",
        "recalibrate",
        "no-such.safetensors",
        "--scenario",
        "scenarios/default.toml",
        "--out",
        "/tmp/never.safetensors",
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no-such"), "{err}");
    let out = run(&[
        "policy",
        "recalibrate",
        "x.safetensors",
        "--scenario",
        "scenarios/default.toml",
        "--batches",
        "0",
        "--out",
        "/tmp/never.safetensors",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("--batches 0"),
        "{err}"
    );
}
