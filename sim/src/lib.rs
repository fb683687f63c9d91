//! The closed loop: camera, timing and delay, drivers, monitors, recorder,
//! scenarios and sweeps. It knows nothing of neural networks: a policy is a
//! [`Driver`].

pub mod camera;
pub mod delay;
pub mod driver;
pub mod expert;
pub mod monitors;
pub mod record;
pub mod recorder;
pub mod render;
pub mod runner;
pub mod scenario;
pub mod selector;
pub mod sweep;

pub use driver::*;
