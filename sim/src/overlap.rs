//! The policy computing frame k's control while the loop goes on to frame k + 1.
//!
//! When the control computed at a boundary lands one tick or more later (a delay D >=
//! 25 ms, or an execution latency per scale), nothing before its landing depends on it:
//! the world steps and the next frame renders from controls already landed. So the
//! driver can act on a background thread while the loop steps and renders (on 2 cores:
//! the camera's rasteriser threads beside the policy's). Everything the driver sees and
//! returns is what the sequential loop gives it, in the same order, so a run's record is
//! the same (tested in `tests/closed_loop.rs`); only its time split differs.
//!
//! The loop uses it only where that holds without exception: a driver that needs the
//! camera and nothing else (no exact state, no class image), without a learned trigger
//! (the next boundary's selector would read its hint), a fixed execution latency (a
//! measured one depends on the compute time), and no observer that reads each
//! boundary's control at its tick (the log's recorder does; the progress display does
//! not).

use std::thread::{Scope, ScopedJoinHandle};
use std::time::Instant;

use world::Command;

use crate::delay::DelayLine;
use crate::driver::{Driver, Observation, RgbImage, VehicleControl};

/// What a driver that needs only the camera is shown at a boundary, apart from the image.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Seen {
    /// Simulation time (seconds).
    pub time_s: f64,
    /// Ego speed (metres per second).
    pub speed_mps: f32,
    /// The route command.
    pub command: Command,
    /// The scale the image was rendered at.
    pub scale: f32,
}

/// What comes back from the background thread.
struct Answer<'d> {
    driver: &'d mut dyn Driver,
    control: VehicleControl,
    compute_s: f64,
    image: RgbImage,
}

/// A control being computed and the tick it lands at.
struct InFlight<'scope, 'd> {
    handle: ScopedJoinHandle<'scope, Answer<'d>>,
    landing: u64,
}

/// The driver, either here or acting on a background thread of `scope`.
pub(crate) struct Overlap<'scope, 'env, 'd> {
    scope: &'scope Scope<'scope, 'env>,
    driver: Option<&'d mut dyn Driver>,
    in_flight: Option<InFlight<'scope, 'd>>,
    /// The image buffer the next background act gets (reused, no allocation a frame).
    spare: RgbImage,
}

impl<'scope, 'env, 'd: 'scope> Overlap<'scope, 'env, 'd> {
    /// The driver, acting nowhere yet.
    pub fn new(scope: &'scope Scope<'scope, 'env>, driver: &'d mut dyn Driver) -> Self {
        Overlap {
            scope,
            driver: Some(driver),
            in_flight: None,
            spare: RgbImage::default(),
        }
    }

    /// Waits for the control in flight, if any, and hands it to `delay`; adds the
    /// driver's compute time to `driver_s`.
    pub fn join(&mut self, delay: &mut DelayLine, driver_s: &mut f64) {
        if let Some(f) = self.in_flight.take() {
            let answer = match f.handle.join() {
                Ok(answer) => answer,
                // The driver panicked on its thread: panic here as it would have.
                Err(panic) => std::panic::resume_unwind(panic),
            };
            delay.fulfil(f.landing, answer.control);
            *driver_s += answer.compute_s;
            self.driver = Some(answer.driver);
            self.spare = answer.image;
        }
    }

    /// Joins the control in flight if it lands at or before `tick`: call before
    /// [`DelayLine::control_for_step`] of every tick.
    pub fn settle(&mut self, tick: u64, delay: &mut DelayLine, driver_s: &mut f64) {
        if self.in_flight.as_ref().is_some_and(|f| f.landing <= tick) {
            self.join(delay, driver_s);
        }
    }

    /// The driver, after the control in flight (if any) has landed in `delay`.
    pub fn driver(&mut self, delay: &mut DelayLine, driver_s: &mut f64) -> &mut dyn Driver {
        self.join(delay, driver_s);
        self.driver
            .as_deref_mut()
            .expect("the driver is back once nothing is in flight")
    }

    /// Boundary `tick`: the driver acts on `image` and `seen`. Joins the previous
    /// control first; when this one lands later than `tick` it is computed on a
    /// background thread, otherwise here.
    pub fn act(
        &mut self,
        tick: u64,
        image: &RgbImage,
        seen: Seen,
        delay: &mut DelayLine,
        driver_s: &mut f64,
    ) {
        self.join(delay, driver_s);
        let landing = delay.defer(tick);
        let mut owned = std::mem::take(&mut self.spare);
        owned.clone_from(image);
        let driver = self
            .driver
            .take()
            .expect("the driver is back once nothing is in flight");
        let work = move || {
            let obs = Observation {
                time_s: seen.time_s,
                speed_mps: seen.speed_mps,
                command: seen.command,
                scale: seen.scale,
                image: Some(&owned),
                labels: None,
                privileged: None,
            };
            let started = Instant::now();
            let control = driver.act(&obs);
            let compute_s = started.elapsed().as_secs_f64();
            Answer {
                driver,
                control,
                compute_s,
                image: owned,
            }
        };
        if landing > tick {
            self.in_flight = Some(InFlight {
                handle: self.scope.spawn(work),
                landing,
            });
        } else {
            let answer = work();
            delay.fulfil(landing, answer.control);
            *driver_s += answer.compute_s;
            self.driver = Some(answer.driver);
            self.spare = answer.image;
        }
    }
}
