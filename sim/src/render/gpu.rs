//! A headless wgpu device: no window, no display. Picks a hardware GPU when
//! there is one, else Mesa's software Vulkan (lavapipe), else GL through
//! EGL/llvmpipe; `MRDRIVE_RENDER_BACKEND=vulkan|gl` picks one.
//!
//! Two things concern the whole process, so the `mrdrive` binary calls
//! [`init_process`] first:
//! - it sets `NODEVICE_SELECT=1`, which turns off Mesa's implicit Vulkan layer
//!   `VK_LAYER_MESA_device_select`. That layer probes Wayland and X11 to rank
//!   the GPUs of a desktop and, in a headless process, makes libwayland print
//!   `error: XDG_RUNTIME_DIR is invalid or not set` on every device opened.
//!   mrdrive ranks the adapters itself ([`Gpu::new`]), so nothing is lost.
//! - once a device is open, a crash (a segfault in the driver, for one) prints
//!   which backend was open and how to pick another instead of dying silently.
//!
//! The binary sets no `LP_*`, `GALLIUM_*` or `GALLIVM_*` variable: llvmpipe's
//! defaults give the same frames on every x86-64 CPU with AVX2 and FMA
//! (`tests/cross_cpu.rs`; README, "Determinism").

use std::sync::OnceLock;

use thiserror::Error;

/// The environment variable that picks the render backend: `vulkan` or `gl`.
pub const BACKEND_VAR: &str = "MRDRIVE_RENDER_BACKEND";

/// Says once per process, on stderr, that the camera fell back to GL: its frames
/// differ from lavapipe's in a few pixels, so no record matches the goldens, and
/// the fix is one package.
fn warn_gl_fallback(backend: &str) {
    static WARNED: OnceLock<()> = OnceLock::new();
    WARNED.get_or_init(|| {
        eprintln!(
            "mrdrive: warning: the camera renders on {backend}, not on Mesa's Vulkan \
             (lavapipe): its frames differ from lavapipe's in a few pixels, so records and \
             fingerprints will not match the repository's. Install it with \
             `apt-get install mesa-vulkan-drivers` (or `cargo xtask setup`), or set \
             {BACKEND_VAR}=gl to choose GL and silence this."
        );
    });
}

/// Why no device could be opened.
#[derive(Debug, Error)]
pub enum GpuError {
    /// `MRDRIVE_RENDER_BACKEND` names no backend.
    #[error(
        "{BACKEND_VAR}={value}: no such render backend; use `vulkan` (lavapipe or a GPU's \
         driver) or `gl` (EGL, llvmpipe), or unset it to pick the best one"
    )]
    BadBackendChoice {
        /// The value given.
        value: String,
    },
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
    /// Opens the best adapter: hardware GPU, else lavapipe Vulkan, else GL; only
    /// the backend `MRDRIVE_RENDER_BACKEND` names, if set.
    pub fn new() -> Result<Gpu, GpuError> {
        // Vulkan (and the platform's native APIs) first; GL only when they
        // have no adapter, so GL/EGL is not even probed on a Vulkan machine.
        let order: &[wgpu::Backends] = match std::env::var(BACKEND_VAR).ok().as_deref() {
            None | Some("") => &[wgpu::Backends::PRIMARY, wgpu::Backends::GL],
            Some("vulkan") => &[wgpu::Backends::VULKAN],
            Some("gl") => &[wgpu::Backends::GL],
            Some(other) => {
                return Err(GpuError::BadBackendChoice {
                    value: other.to_string(),
                });
            }
        };
        let mut chosen = None;
        for &backends in order {
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
        if info.backend == wgpu::Backend::Gl && order.len() > 1 {
            warn_gl_fallback(&describe(&info));
        }
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
        crash_report::arm(&describe(&info));
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

/// Prepares the process for rendering; call it first thing in `main`.
///
/// Sets `NODEVICE_SELECT=1` (unless set) so Mesa's device-select layer does not
/// probe for a display and print spurious `XDG_RUNTIME_DIR` errors (module docs).
///
/// # Safety
/// It changes the environment: call it before any other thread exists.
pub unsafe fn init_process() {
    if std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: the caller promises no other thread exists yet.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
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

/// A readable last word when the process crashes with a renderer open: which
/// backend was open, which llvmpipe settings were in the environment, and how to
/// pick another backend. Installed when the first device opens; the process
/// still dies by the same signal (its exit status is unchanged).
mod crash_report {
    use super::{BACKEND_VAR, OnceLock};

    /// The message, written once the first device is open.
    static MESSAGE: OnceLock<Vec<u8>> = OnceLock::new();
    /// The handlers in place before ours, by signal, to pass the signal on to.
    static PREVIOUS: OnceLock<Vec<(libc::c_int, libc::sigaction)>> = OnceLock::new();

    const SIGNALS: [(libc::c_int, &str); 5] = [
        (libc::SIGSEGV, "SIGSEGV"),
        (libc::SIGBUS, "SIGBUS"),
        (libc::SIGILL, "SIGILL"),
        (libc::SIGFPE, "SIGFPE"),
        (libc::SIGABRT, "SIGABRT"),
    ];

    /// The text printed on a crash with `backend` open.
    pub(super) fn message(backend: &str, settings: &[(String, String)]) -> String {
        let mut m = format!(
            " (crashed) with the renderer open on `{backend}`. A crash there is most often \
             inside the graphics driver, not in mrdrive.\n"
        );
        if settings.is_empty() {
            m += "  No LP_*, GALLIUM_* or GALLIVM_* setting is in the environment.\n";
        } else {
            m += "  llvmpipe settings in the environment (unset them to use its defaults):\n";
            for (k, v) in settings {
                m += &format!("    {k}={v}\n");
            }
        }
        m += &format!(
            "  To try another backend: {BACKEND_VAR}=gl (GL through EGL) or {BACKEND_VAR}=vulkan.\n  \
             Runs driven by the expert draw nothing and need no renderer.\n"
        );
        m
    }

    /// Installs the report for `backend` (once per process; later calls do nothing).
    pub(super) fn arm(backend: &str) {
        let settings: Vec<(String, String)> = std::env::vars()
            .filter(|(k, _)| {
                ["LP_", "GALLIUM_", "GALLIVM_"]
                    .iter()
                    .any(|p| k.starts_with(p))
            })
            .collect();
        if MESSAGE
            .set(message(backend, &settings).into_bytes())
            .is_err()
        {
            return;
        }
        let mut previous = Vec::new();
        for (sig, _) in SIGNALS {
            // SAFETY: a zeroed `sigaction` is a valid "no handler" value; `on_crash` only
            // calls async-signal-safe functions (write, sigaction, raise) and reads
            // statics that were written before it was installed.
            unsafe {
                let mut action: libc::sigaction = std::mem::zeroed();
                action.sa_sigaction = on_crash as *const () as usize;
                action.sa_flags = libc::SA_SIGINFO | libc::SA_ONSTACK;
                libc::sigemptyset(&mut action.sa_mask);
                let mut old: libc::sigaction = std::mem::zeroed();
                if libc::sigaction(sig, &action, &mut old) == 0 {
                    previous.push((sig, old));
                }
            }
        }
        let _ = PREVIOUS.set(previous);
    }

    extern "C" fn on_crash(sig: libc::c_int, info: *mut libc::siginfo_t, ctx: *mut libc::c_void) {
        let name = SIGNALS
            .iter()
            .find(|(s, _)| *s == sig)
            .map_or("a signal", |(_, n)| n);
        // SAFETY: write(2), sigaction(2) and raise(3) are async-signal-safe; the statics
        // were set before this handler was installed and are never written again.
        unsafe {
            let head = b"\nmrdrive: ";
            libc::write(2, head.as_ptr().cast(), head.len());
            libc::write(2, name.as_ptr().cast(), name.len());
            if let Some(m) = MESSAGE.get() {
                libc::write(2, m.as_ptr().cast(), m.len());
            }
            // Pass the signal on: to the handler before ours (Rust's stack-overflow
            // report, for one), else die of it as the default action would.
            let old = PREVIOUS
                .get()
                .and_then(|p| p.iter().find(|(s, _)| *s == sig))
                .map(|(_, a)| *a);
            match old {
                Some(a)
                    if a.sa_sigaction != libc::SIG_DFL
                        && a.sa_sigaction != libc::SIG_IGN
                        && a.sa_flags & libc::SA_SIGINFO != 0 =>
                {
                    let f: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
                        std::mem::transmute(a.sa_sigaction);
                    f(sig, info, ctx);
                }
                _ => {
                    let mut dfl: libc::sigaction = std::mem::zeroed();
                    dfl.sa_sigaction = libc::SIG_DFL;
                    libc::sigaction(sig, &dfl, std::ptr::null_mut());
                    libc::raise(sig);
                }
            }
        }
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
    fn the_crash_report_names_the_backend_the_settings_and_the_way_out() {
        let m = crash_report::message(
            "Vulkan llvmpipe (LLVM 15.0.6, 256 bits)",
            &[("LP_NATIVE_VECTOR_WIDTH".into(), "128".into())],
        );
        assert!(
            m.contains("`Vulkan llvmpipe (LLVM 15.0.6, 256 bits)`"),
            "{m}"
        );
        assert!(m.contains("LP_NATIVE_VECTOR_WIDTH=128"), "{m}");
        assert!(m.contains("MRDRIVE_RENDER_BACKEND=gl"), "{m}");
        let none = crash_report::message("GL", &[]);
        assert!(none.contains("No LP_*"), "{none}");
    }

    #[test]
    fn opens_a_device_here() {
        let gpu = Gpu::new().expect("this machine has lavapipe or GL");
        assert!(!gpu.describe().is_empty());
    }
}
