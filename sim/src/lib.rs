//! The closed loop: camera, timing and delay, drivers, monitors, recorder,
//! scenarios and sweeps. It knows nothing of neural networks: a policy is a
//! [`Driver`], built from a scenario by a [`build::DriverFactory`] that the
//! program registers.
//!
//! From a scenario file to a result: [`scenario`] reads it, [`build`] makes
//! its driver, selector and camera, [`runner`] drives the loop, [`record`]
//! holds the result, [`picture`] draws it, [`sweep`] runs many and tabulates them;
//! [`moment`] drives a run to a moment and draws its camera's picture there.

pub mod build;
pub mod camera;
pub mod delay;
pub mod driver;
pub mod error;
pub mod expert;
pub mod moment;
pub mod monitors;
pub mod observe;
mod overlap;
pub mod picture;
pub mod record;
pub mod recorder;
pub mod remote;
pub mod render;
pub mod runner;
pub mod scenario;
pub mod selector;
pub mod sweep;

pub use driver::*;
