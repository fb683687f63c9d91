//! The closed loop: camera, timing and delay, drivers, monitors, recorder,
//! scenarios and sweeps. It knows nothing of neural networks: a policy is a
//! [`Driver`].

pub mod driver;
pub mod render;

pub use driver::*;
