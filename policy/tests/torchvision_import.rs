//! Loading a torchvision ResNet state dict written by Python's `safetensors` + `numpy`.
//!
//! Needs a Python with those packages: `MRDRIVE_PYTHON` names it, else
//! `<workspace>/.venv/bin/python`, else `python3`. Without one the test skips
//! through `world::testdata::skip` (counted by `cargo xtask test`), unless
//! `MRDRIVE_REQUIRE_PYTHON=1`.

use policy::backbone::Depth;
use policy::burn::prelude::*;
use policy::checkpoint::load_torchvision_backbone;
use policy::model::PolicyConfig;
use std::path::Path;
use std::process::Command;

fn write_files(test: &str) -> Option<tempfile::TempDir> {
    let Some(py) = world::testdata::python_with("safetensors.numpy, numpy") else {
        world::testdata::skip(
            test,
            world::testdata::Needs::Python,
            "no Python with `safetensors` and `numpy` (set MRDRIVE_PYTHON or create .venv)",
        );
        return None;
    };
    let dir = tempfile::tempdir().unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/write_torchvision_tiny.py");
    let out = Command::new(&py)
        .arg(&script)
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    Some(dir)
}

fn expected(name: &str, n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| {
            let v = ((i * 7 + name.len()) % 13) as f32 / 13.0 - 0.5;
            if name.ends_with("running_var") {
                v + 1.0
            } else {
                v
            }
        })
        .collect()
}

fn vals<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data().try_to_vec::<f32>().unwrap()
}

fn close(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
}

fn config() -> PolicyConfig {
    PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
        .with_input_height(64)
        .with_input_width(96)
}

#[test]
fn torchvision_state_dict_loads_into_every_branch() {
    let Some(dir) = write_files("torchvision_state_dict_loads_into_every_branch") else {
        return;
    };
    let device = Device::flex();
    for (file, prefix) in [
        ("tiny_resnet18.safetensors", ""),
        ("tiny_prefixed.safetensors", "backbone_wide."),
    ] {
        let net = load_torchvision_backbone(&dir.path().join(file), prefix, &config(), &device)
            .unwrap_or_else(|e| panic!("{file}: {e}"));
        // Values depend on the unprefixed torchvision name (the script copies them).
        let n = |s: &str| s.to_string();
        let b = &net.backbone;
        assert!(close(
            &vals(b.conv1.weight.val()),
            &expected(&n("conv1.weight"), 4 * 3 * 49)
        ));
        assert!(close(
            &vals(b.layer4[1].conv2.weight.val()),
            &expected(&n("layer4.1.conv2.weight"), 16 * 16 * 9)
        ));
        assert!(close(
            &vals(b.layer2[0].downsample.as_ref().unwrap().conv.weight.val()),
            &expected(&n("layer2.0.downsample.0.weight"), 8 * 4)
        ));
        for branch in 0..2 {
            let bn = &b.bn1.branches[branch];
            assert!(close(&vals(bn.gamma.val()), &expected(&n("bn1.weight"), 4)));
            assert!(close(&vals(bn.beta.val()), &expected(&n("bn1.bias"), 4)));
            let ds = &b.layer3[0].downsample.as_ref().unwrap().bn.branches[branch];
            assert!(close(
                &vals(ds.running_var.value_sync()),
                &expected(&n("layer3.0.downsample.1.running_var"), 8)
            ));
            assert!(close(
                &vals(ds.running_mean.value_sync()),
                &expected(&n("layer3.0.downsample.1.running_mean"), 8)
            ));
            let bn2 = &b.layer1[1].bn2.branches[branch];
            assert!(close(
                &vals(bn2.gamma.val()),
                &expected(&n("layer1.1.bn2.weight"), 4)
            ));
        }
        // The loaded backbone runs at both scales.
        let out = net
            .valid()
            .forward(Tensor::ones([1, 3, 48, 72], &device), 0, false);
        assert_eq!(out.action_logits.dims(), [1, 6, 4, 28]);
    }
}

#[test]
fn broken_torchvision_files_name_the_tensor() {
    let Some(dir) = write_files("broken_torchvision_files_name_the_tensor") else {
        return;
    };
    let device = Device::flex();
    let e = load_torchvision_backbone(
        &dir.path().join("tiny_missing.safetensors"),
        "",
        &config(),
        &device,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("tiny_missing.safetensors")
            && e.contains("`layer4.1.conv2.weight` is missing")
            && e.contains("fix"),
        "{e}"
    );
    let e = load_torchvision_backbone(
        &dir.path().join("tiny_badshape.safetensors"),
        "",
        &config(),
        &device,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains(
            "`layer3.0.conv1.weight` has shape [8, 4, 3, 3], the network expects [8, 8, 3, 3]"
        ),
        "{e}"
    );
    // Wrong depth: a ResNet-34 config wants blocks the file does not have.
    let e = load_torchvision_backbone(
        &dir.path().join("tiny_resnet18.safetensors"),
        "",
        &PolicyConfig {
            depth: Depth::Resnet34,
            ..config()
        },
        &device,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("layer1.2."), "{e}");
}
