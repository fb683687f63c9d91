//! The camera: offscreen wgpu rendering of the policy's view with per-pixel
//! semantic labels, and a top-down view for logs.
//!
//! - [`gpu`]: a headless device (hardware GPU, else lavapipe, else GL/EGL).
//! - [`classes`]: the one table of semantic classes and the WoR mapping.
//! - [`scene`]: static town geometry (built once) and per-frame instances.
//! - [`rig`]: WoR's three-camera rig, sizes per scale, the top-down camera.
//! - [`renderer`]: the scene pass, supersampling resolve and readback.
//! - [`srgb`]: sRGB's transfer function as exact tables for the shaders.
//! - [`image`]: the class image and PNG output; [`resize`]: resizing for training.
//! - [`demo`]: a hand-made town for demos, tests and benchmarks.
//! - [`measure`]: lamp pixel sizes and the frame-rate benchmark.
//! - [`fingerprint`]: fixed frames whose hashes identify what this machine draws.

pub mod classes;
pub mod demo;
pub mod fingerprint;
pub mod gpu;
pub mod image;
pub mod measure;
pub mod renderer;
pub mod resize;
pub mod rig;
pub mod scene;
pub mod srgb;

pub use classes::{ClassId, WorClass};
pub use image::ClassImage;
pub use renderer::{RenderError, Renderer};
pub use rig::{RigConfig, View};
pub use world::EgoPose;
