//! Watching a run: the one way anything looks at a run's ticks without
//! driving it. The MCAP recorder, the progress bar, moment capture (for
//! `mrdrive render --at` and BN recalibration) and the dataset's episode
//! recorder all implement [`RunObserver`] and are handed to
//! [`crate::runner::run`] in a list; each sees every tick as a [`TickView`].

use world::agents::VehicleControl;
use world::route::DenseRoute;
use world::{ActorSnapshot, Command, LightState, Town};

use crate::camera::{Camera, CameraFrame};
use crate::driver::RgbImage;
use crate::error::RunError;
use crate::monitors::Infraction;

/// What one tick of a run looks like after its physics step and monitors.
#[derive(Debug, Clone, Copy)]
pub struct TickView<'a> {
    /// The tick just completed (the first step ends at tick 1).
    pub tick: u64,
    /// Simulation time at its end (seconds).
    pub time_s: f64,
    /// Whether the camera renders at this tick (every `ticks_per_frame`).
    pub camera_frame: bool,
    /// The town.
    pub town: &'a Town,
    /// The route being driven.
    pub route: &'a DenseRoute,
    /// The route point the ego has reached.
    pub route_index: usize,
    /// The ego's distance along the route (metres).
    pub route_s: f32,
    /// The route command at the ego.
    pub command: Command,
    /// Route completion (percent).
    pub completion_pct: f64,
    /// Every actor after the step, ego first.
    pub actors: &'a [ActorSnapshot],
    /// Every light's state during the step, by `LightIdx`.
    pub lights: &'a [LightState],
    /// The input scale in force (fraction of S0).
    pub scale: f64,
    /// The latency in force (milliseconds).
    pub latency_ms: f64,
    /// The control in force during the step.
    pub control: VehicleControl,
    /// The control the driver computed at this tick's boundary, if it was one.
    pub computed: Option<VehicleControl>,
    /// Infractions the monitors counted this tick.
    pub infractions: &'a [Infraction],
    /// The ego's touches of this tick (`monitors::contacts`): each contact's start
    /// and repeats, each kerb. Their `left_tick` is not known yet (`None`).
    pub touches: &'a [crate::monitors::contacts::Touch],
}

impl<'a> TickView<'a> {
    /// The ego after the step.
    pub fn ego(&self) -> &'a ActorSnapshot {
        &self.actors[0]
    }

    /// What the camera would draw now.
    pub fn camera_frame(&self) -> CameraFrame<'a> {
        CameraFrame {
            ego: self.ego(),
            actors: self.actors,
            lights: self.lights,
        }
    }
}

/// Something that looks at every tick of a run.
pub trait RunObserver {
    /// Looks at one tick. `camera` is the run's camera, if it has one (its
    /// renders count as the run's render time).
    fn on_tick(
        &mut self,
        view: &TickView<'_>,
        camera: Option<&mut dyn Camera>,
    ) -> Result<(), RunError>;

    /// Whether it reads [`TickView::computed`]. Only then must the loop have each
    /// boundary's control at the boundary's own tick; otherwise a driver that needs
    /// only the camera may compute it beside the loop (`crate::overlap`). Say `false`
    /// only for an observer that never looks at `computed`.
    fn reads_computed(&self) -> bool {
        true
    }
}

/// The world at one tick: every actor (ego first) and every light's state.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Moment {
    /// The tick.
    pub tick: u64,
    /// Every actor, ego first.
    pub actors: Vec<ActorSnapshot>,
    /// Every light's state.
    pub lights: Vec<LightState>,
}

/// Keeps moments of a run: every `every_ticks`-th tick, or only the last.
#[derive(Debug, Clone, Default)]
pub struct Moments {
    every_ticks: Option<u64>,
    /// The moments kept, in tick order.
    pub kept: Vec<Moment>,
}

impl Moments {
    /// Keeps a moment every `ticks` ticks (at least 1).
    pub fn every(ticks: u64) -> Moments {
        Moments {
            every_ticks: Some(ticks.max(1)),
            kept: Vec::new(),
        }
    }

    /// Keeps only the last tick's moment.
    pub fn last() -> Moments {
        Moments::default()
    }
}

impl RunObserver for Moments {
    fn on_tick(
        &mut self,
        view: &TickView<'_>,
        _camera: Option<&mut dyn Camera>,
    ) -> Result<(), RunError> {
        match self.every_ticks {
            Some(n) if !view.tick.is_multiple_of(n) => return Ok(()),
            Some(_) => self.kept.push(Moment::default()),
            None if self.kept.is_empty() => self.kept.push(Moment::default()),
            None => {}
        }
        let m = self.kept.last_mut().expect("pushed above");
        m.tick = view.tick;
        m.actors.clear();
        m.actors.extend_from_slice(view.actors);
        m.lights.clear();
        m.lights.extend_from_slice(view.lights);
        Ok(())
    }
}

/// Where a run stands, for a progress display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunProgress {
    /// Simulated time (seconds).
    pub sim_time_s: f64,
    /// Route completion (percent).
    pub completion_pct: f64,
    /// The input scale in force (fraction of S0).
    pub scale: f64,
}

/// Simulated seconds between two progress reports.
pub const PROGRESS_EVERY_S: f64 = 0.5;

/// Reports where the run stands every [`PROGRESS_EVERY_S`] of simulated time.
pub struct Progress<F: FnMut(&RunProgress)> {
    report: F,
    next_s: f64,
}

impl<F: FnMut(&RunProgress)> Progress<F> {
    /// Calls `report` with where the run stands.
    pub fn new(report: F) -> Self {
        Progress {
            report,
            next_s: 0.0,
        }
    }
}

impl<F: FnMut(&RunProgress)> RunObserver for Progress<F> {
    fn on_tick(
        &mut self,
        view: &TickView<'_>,
        _camera: Option<&mut dyn Camera>,
    ) -> Result<(), RunError> {
        if view.time_s >= self.next_s {
            (self.report)(&RunProgress {
                sim_time_s: view.time_s,
                completion_pct: view.completion_pct,
                scale: view.scale,
            });
            self.next_s = view.time_s + PROGRESS_EVERY_S;
        }
        Ok(())
    }
    fn reads_computed(&self) -> bool {
        false
    }
}

/// Renders the rig at every camera tick even when nothing consumes the
/// image: what data collection costs, for timing a run.
#[derive(Debug, Clone, Copy, Default)]
pub struct RenderEveryFrame;

impl RunObserver for RenderEveryFrame {
    fn on_tick(
        &mut self,
        view: &TickView<'_>,
        camera: Option<&mut dyn Camera>,
    ) -> Result<(), RunError> {
        if let (true, Some(cam)) = (view.camera_frame, camera) {
            cam.render(&view.camera_frame(), view.scale)
                .map_err(RunError::Camera)?;
        }
        Ok(())
    }
    fn reads_computed(&self) -> bool {
        false
    }
}

/// A camera whose renders are timed: the run's render time.
pub struct TimedCamera<'a> {
    inner: &'a mut dyn Camera,
    /// Seconds spent rendering so far.
    pub spent_s: f64,
}

impl<'a> TimedCamera<'a> {
    /// Times `inner`.
    pub fn new(inner: &'a mut dyn Camera) -> Self {
        TimedCamera {
            inner,
            spent_s: 0.0,
        }
    }
}

impl Camera for TimedCamera<'_> {
    fn render(&mut self, frame: &CameraFrame<'_>, scale: f64) -> Result<&RgbImage, String> {
        let started = std::time::Instant::now();
        let out = self.inner.render(frame, scale);
        self.spent_s += started.elapsed().as_secs_f64();
        out
    }

    fn backend(&self) -> String {
        self.inner.backend()
    }

    fn render_labelled(
        &mut self,
        frame: &CameraFrame<'_>,
        scale: f64,
        labels: &mut RgbImage,
    ) -> Option<Result<&RgbImage, String>> {
        let started = std::time::Instant::now();
        let out = self.inner.render_labelled(frame, scale, labels);
        self.spent_s += started.elapsed().as_secs_f64();
        out
    }

    fn render_bev(
        &mut self,
        frame: &CameraFrame<'_>,
        width: u32,
        height: u32,
        extent_m: f32,
    ) -> Option<Result<&RgbImage, String>> {
        let started = std::time::Instant::now();
        let out = self.inner.render_bev(frame, width, height, extent_m);
        self.spent_s += started.elapsed().as_secs_f64();
        out
    }
}
