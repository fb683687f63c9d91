//! The closed loop: camera, timing and delay, drivers, monitors, recorder,
//! scenarios and sweeps. It knows nothing of neural networks: a policy is a
//! [`Driver`], built from a scenario by a [`build::DriverFactory`] that the
//! program registers.
//!
//! From a scenario file to a result: [`scenario`] reads it, [`build`] makes
//! its driver, selector and camera (with the command line's [`build::Overrides`]),
//! [`runner`] drives the loop, [`output`] holds what a run gives (the record, the
//! log, the picture, a moment's picture), [`sweep`] runs many and tabulates them.
//! [`record`], [`recorder`], [`picture`] and [`moment`] are [`output`]'s, re-exported
//! here under their short names.

pub mod build;
pub mod camera;
pub mod delay;
pub mod driver;
pub mod error;
pub mod expert;
pub mod monitors;
pub mod observe;
pub mod output;
mod overlap;
pub mod remote;
pub mod render;
pub mod runner;
pub mod scenario;
pub mod selector;
pub mod sweep;

pub use driver::*;
pub use output::{moment, picture, record, recorder};
