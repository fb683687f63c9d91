//! Which burn device runs the network: the CPU (`flex`, always built) or a GPU
//! through burn's `wgpu` or `cuda` backend (cargo features of the same names).
//!
//! The GPU backends are optional because each adds minutes to a cold build and
//! CI has no GPU: `cargo build --release --features wgpu` (Vulkan, Metal, DX12 or
//! GL through wgpu, also lavapipe's software Vulkan) or `--features cuda`
//! (NVIDIA; the driver library is loaded at run time, no toolkit needed to build).
//! A device that this build lacks, or that the machine cannot open, is an
//! error that says which, never a panic.

use burn::tensor::Device;
use std::fmt;
use std::str::FromStr;

/// A device the user can ask for (`--device`, scenario key `driver.device`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceKind {
    /// burn's `flex` CPU backend (deterministic for a fixed thread count).
    Cpu,
    /// burn's CUDA backend, GPU 0.
    Cuda,
    /// burn's wgpu backend on the adapter wgpu prefers (a discrete GPU first).
    Wgpu,
}

impl DeviceKind {
    /// Every kind, in the order the CLI lists them.
    pub const ALL: [DeviceKind; 3] = [DeviceKind::Cpu, DeviceKind::Cuda, DeviceKind::Wgpu];

    /// The name used on the command line and in scenario files.
    pub fn name(self) -> &'static str {
        match self {
            DeviceKind::Cpu => "cpu",
            DeviceKind::Cuda => "cuda",
            DeviceKind::Wgpu => "wgpu",
        }
    }

    /// Whether this build can open this kind of device at all.
    pub fn compiled(self) -> bool {
        match self {
            DeviceKind::Cpu => true,
            DeviceKind::Cuda => cfg!(feature = "cuda"),
            DeviceKind::Wgpu => cfg!(feature = "wgpu"),
        }
    }
}

impl fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for DeviceKind {
    type Err = DeviceError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        DeviceKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| DeviceError::Unknown(s.to_string()))
    }
}

/// Why a device could not be had.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    /// Not one of `cpu`, `cuda`, `wgpu`.
    #[error("unknown device \"{0}\": use cpu, cuda or wgpu")]
    Unknown(String),
    /// This binary was built without the backend.
    #[error(
        "device \"{0}\": this build has no {0} backend; rebuild with `cargo build --release --features {0}` (or use cpu)"
    )]
    NotBuilt(DeviceKind),
    /// The backend is built but the machine has no usable device.
    #[error("device \"{kind}\": {why}")]
    Unavailable {
        /// The kind asked for.
        kind: DeviceKind,
        /// What went wrong, with the fix where one is known.
        why: String,
    },
}

/// Opens a device of `kind`. GPU devices are checked with a small tensor
/// operation so that a missing driver is reported here, not in the middle of a run.
pub fn open(kind: DeviceKind) -> Result<Device, DeviceError> {
    match kind {
        DeviceKind::Cpu => Ok(Device::flex()),
        DeviceKind::Wgpu => open_wgpu(),
        DeviceKind::Cuda => open_cuda(),
    }
}

#[cfg(feature = "wgpu")]
fn open_wgpu() -> Result<Device, DeviceError> {
    let device = Device::wgpu_options()
        .init()
        .map_err(|e| DeviceError::Unavailable {
            kind: DeviceKind::Wgpu,
            why: format!(
                "{e}; on Linux without a GPU install a software Vulkan driver (`apt-get install mesa-vulkan-drivers`)"
            ),
        })?;
    smoke_test(DeviceKind::Wgpu, device)
}

#[cfg(not(feature = "wgpu"))]
fn open_wgpu() -> Result<Device, DeviceError> {
    Err(DeviceError::NotBuilt(DeviceKind::Wgpu))
}

#[cfg(feature = "cuda")]
fn open_cuda() -> Result<Device, DeviceError> {
    smoke_test(DeviceKind::Cuda, Device::cuda(0))
}

#[cfg(not(feature = "cuda"))]
fn open_cuda() -> Result<Device, DeviceError> {
    Err(DeviceError::NotBuilt(DeviceKind::Cuda))
}

/// Runs `1 + 1` on `device`; a backend that panics for want of a driver becomes an error.
#[cfg(any(feature = "wgpu", feature = "cuda"))]
fn smoke_test(kind: DeviceKind, device: Device) -> Result<Device, DeviceError> {
    use burn::tensor::Tensor;
    let probe = device.clone();
    let result = std::panic::catch_unwind(move || {
        let x = Tensor::<1>::ones([4], &probe);
        (x.clone() + x).into_data().try_to_vec::<f32>()
    });
    match result {
        Ok(Ok(v)) if v == [2.0; 4] => Ok(device),
        Ok(Ok(v)) => Err(DeviceError::Unavailable {
            kind,
            why: format!("a test addition gave {v:?} instead of [2, 2, 2, 2]"),
        }),
        Ok(Err(e)) => Err(DeviceError::Unavailable {
            kind,
            why: format!("reading a test tensor back failed: {e:?}"),
        }),
        Err(panic) => {
            let msg = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "the backend panicked".into());
            Err(DeviceError::Unavailable {
                kind,
                why: format!(
                    "{msg} (is the {} driver installed and a device present?)",
                    match kind {
                        DeviceKind::Cuda => "NVIDIA",
                        _ => "GPU",
                    }
                ),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_errors() {
        for k in DeviceKind::ALL {
            assert_eq!(k.name().parse::<DeviceKind>().unwrap(), k);
        }
        let e = "tpu".parse::<DeviceKind>().unwrap_err().to_string();
        assert!(e.contains("tpu") && e.contains("cpu, cuda or wgpu"), "{e}");
    }

    #[test]
    fn cpu_always_opens_and_a_missing_backend_says_how_to_build_it() {
        assert!(open(DeviceKind::Cpu).is_ok());
        for k in [DeviceKind::Cuda, DeviceKind::Wgpu] {
            if !k.compiled() {
                let e = open(k).unwrap_err().to_string();
                assert!(e.contains(&format!("--features {k}")), "{e}");
            }
        }
    }

    /// With the `wgpu` feature the network runs on wgpu and agrees with the CPU.
    /// (`cargo test --release -p policy --features wgpu`; lavapipe is enough.)
    #[cfg(feature = "wgpu")]
    #[test]
    fn wgpu_forward_matches_the_cpu() {
        use crate::backbone::Depth;
        use crate::model::PolicyConfig;
        use burn::module::Module;
        use burn::tensor::{Distribution, Tensor};
        let gpu = open(DeviceKind::Wgpu).expect("a wgpu adapter (install mesa-vulkan-drivers)");
        let cpu = Device::flex();
        cpu.seed(5);
        let cfg = PolicyConfig::new(Depth::Resnet18, [8, 16, 16, 32])
            .with_input_height(48)
            .with_input_width(96);
        let net = cfg.init(&cpu).valid();
        let x = Tensor::<4>::random([1, 3, 48, 96], Distribution::Normal(0.0, 1.0), &cpu);
        let on_gpu = net.clone().fork(&gpu);
        for branch in 0..cfg.scales.len() {
            let x = crate::train::resize::resize_to_scale(x.clone(), cfg.scales[branch]);
            let a = net.forward(x.clone(), branch, false).action_logits;
            let b = on_gpu
                .forward(x.to_device(&gpu), branch, false)
                .action_logits;
            let a = a.into_data().try_to_vec::<f32>().unwrap();
            let b = b.into_data().try_to_vec::<f32>().unwrap();
            let worst = a
                .iter()
                .zip(&b)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0f32, f32::max);
            assert!(worst < 1e-3, "branch {branch}: max |cpu - wgpu| = {worst}");
        }
    }
}
