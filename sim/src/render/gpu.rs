//! A headless wgpu device: no window, no display. Picks a hardware GPU when
//! there is one, else Mesa's software Vulkan (lavapipe), else GL through
//! EGL/llvmpipe.

use thiserror::Error;

/// Why no device could be opened.
#[derive(Debug, Error)]
pub enum GpuError {
    /// No adapter on any backend.
    #[error(
        "no graphics adapter found (tried Vulkan and GL/EGL). Install Mesa's software \
         Vulkan driver: `apt-get install mesa-vulkan-drivers` (Debian/Ubuntu), or a GPU driver"
    )]
    NoAdapter,
    /// The adapter refused to open a device.
    #[error("opening a device on adapter `{adapter}` failed: {source}")]
    Device {
        /// The adapter's name and backend.
        adapter: String,
        /// wgpu's error.
        source: wgpu::RequestDeviceError,
    },
}

/// An open device with its queue, and what it runs on.
#[derive(Debug)]
pub struct Gpu {
    /// The logical device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter's description (name, backend, device type, driver).
    pub info: wgpu::AdapterInfo,
}

impl Gpu {
    /// Opens the best adapter: hardware GPU, else lavapipe Vulkan, else GL.
    pub fn new() -> Result<Gpu, GpuError> {
        // Vulkan (and the platform's native APIs) first; GL only when they
        // have no adapter, so GL/EGL is not even probed on a Vulkan machine.
        let mut chosen = None;
        for backends in [wgpu::Backends::PRIMARY, wgpu::Backends::GL] {
            let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
            desc.backends = backends;
            let instance = wgpu::Instance::new(desc);
            let mut adapters = pollster::block_on(instance.enumerate_adapters(backends));
            // Fixed order: rank, then name, so the choice is reproducible.
            adapters.sort_by_key(|a| {
                let i = a.get_info();
                (adapter_rank(&i), i.name.clone())
            });
            if let Some(a) = adapters.into_iter().next() {
                chosen = Some(a);
                break;
            }
        }
        let adapter = chosen.ok_or(GpuError::NoAdapter)?;
        let info = adapter.get_info();
        let desc = wgpu::DeviceDescriptor {
            label: Some("mrdrive render device"),
            required_features: wgpu::Features::empty(),
            required_limits: adapter.limits(),
            ..Default::default()
        };
        let (device, queue) =
            pollster::block_on(adapter.request_device(&desc)).map_err(|source| {
                GpuError::Device {
                    adapter: format!("{} ({:?})", info.name, info.backend),
                    source,
                }
            })?;
        Ok(Gpu {
            device,
            queue,
            info,
        })
    }

    /// A one-line description for result records: backend, adapter, driver.
    pub fn describe(&self) -> String {
        describe(&self.info)
    }
}

/// A one-line description of an adapter, e.g. `Vulkan llvmpipe (LLVM 15) [Cpu, Mesa 22.3.6]`.
pub fn describe(info: &wgpu::AdapterInfo) -> String {
    format!(
        "{:?} {} [{:?}, {} {}]",
        info.backend, info.name, info.device_type, info.driver, info.driver_info
    )
}

/// Lower is preferred: hardware GPUs first, then software Vulkan, then GL.
fn adapter_rank(info: &wgpu::AdapterInfo) -> u8 {
    use wgpu::{Backend, DeviceType};
    let hardware = matches!(
        info.device_type,
        DeviceType::DiscreteGpu | DeviceType::IntegratedGpu | DeviceType::VirtualGpu
    );
    match (hardware, info.backend) {
        (true, Backend::Vulkan | Backend::Metal | Backend::Dx12) => 0,
        (true, _) => 1,
        (false, Backend::Vulkan) => 2,
        (false, Backend::Gl) => 3,
        _ => 4,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(backend: wgpu::Backend, device_type: wgpu::DeviceType) -> wgpu::AdapterInfo {
        wgpu::AdapterInfo::new(device_type, backend)
    }

    #[test]
    fn hardware_beats_lavapipe_beats_gl() {
        use wgpu::{Backend, DeviceType};
        let gpu = adapter_rank(&info(Backend::Vulkan, DeviceType::DiscreteGpu));
        let lavapipe = adapter_rank(&info(Backend::Vulkan, DeviceType::Cpu));
        let llvmpipe_gl = adapter_rank(&info(Backend::Gl, DeviceType::Cpu));
        assert!(gpu < lavapipe && lavapipe < llvmpipe_gl);
    }

    #[test]
    fn opens_a_device_here() {
        let gpu = Gpu::new().expect("this machine has lavapipe or GL");
        assert!(!gpu.describe().is_empty());
    }
}
