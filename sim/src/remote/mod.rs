//! Driving from outside the loop: a driver whose controls come from another
//! thread (the `mrdrive serve` process, which a Python environment talks to).
//!
//! The run itself is unchanged: [`crate::build::run_scenario_with`] drives it on
//! its own thread, and at every control boundary the [`RemoteDriver`] hands an
//! [`Observation`](crate::driver::Observation) over as an owned [`Snapshot`] and
//! waits for the control; that control then goes through the same delay line and
//! zero-order hold as any driver's. A [`RemoteWatch`] observer collects what the
//! agent is told between boundaries (infractions, route progress, the ego's pose),
//! and a [`RemoteSelector`] lets the agent choose the scale of the next observation.
//!
//! Dropping the [`Link`]'s action sender aborts the run: the driver unwinds its
//! thread with [`std::panic::resume_unwind`] (no panic message), so a client that
//! goes away never leaves a run behind.
//!
//! | file | what |
//! | --- | --- |
//! | `mod.rs` | the link between a run and its agent: [`RemoteDriver`], [`RemoteWatch`], [`RemoteSelector`], [`reward`] |
//! | [`frame`] | the wire format: length-prefixed JSON and a payload |
//! | [`server`] | the environment server (`mrdrive serve`): its requests, answers and episodes |

pub mod frame;
pub mod server;

use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::sync::{Arc, Mutex};

use crate::camera::Camera;
use crate::driver::{Driver, DriverNeeds, Observation, VehicleControl};
use crate::error::RunError;
use crate::monitors::Infraction;
use crate::observe::{RunObserver, TickView};
use crate::selector::{ResolutionSelector, SelectorInput};

/// What the agent is shown at a control boundary (owned: it crosses threads).
#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// Simulation time (seconds).
    pub time_s: f64,
    /// Ego speed (metres per second).
    pub speed_mps: f32,
    /// The route command (`world::Command` as u8: 0 LEFT ... 5 CHANGELANERIGHT).
    pub command: u8,
    /// The input scale of the image (fraction of S0).
    pub scale: f32,
    /// Image height and width (pixels).
    pub size: (u32, u32),
    /// The stitched rig image, RGB8 row-major (`height * width * 3` bytes); empty when
    /// the run has no camera.
    pub image: Vec<u8>,
    /// WoR's class id (0-5) of every pixel, row-major (`height * width` bytes); empty
    /// unless asked for.
    pub classes: Vec<u8>,
    /// What happened since the previous boundary.
    pub since: Since,
}

/// What the monitors and the route saw between two control boundaries.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Since {
    /// Infractions counted since the previous boundary.
    pub infractions: Vec<Infraction>,
    /// Route completion now (percent).
    pub completion_pct: f64,
    /// Distance along the route now (metres).
    pub route_s: f32,
    /// The ego's pose now: x, y (metres, world frame), heading (radians).
    pub ego_pose: [f32; 3],
}

/// The reward of one environment step: the route completion gained (percentage
/// points) minus, for each infraction, what it costs leaderboard-1.0's driving score
/// at full completion: `100 * (1 - penalty)` (pedestrian 50, vehicle 40, static 35,
/// red light 30; lane crossings and the run-ending infractions cost nothing more).
/// An episode that completes its route without an infraction sums to 100.
pub fn reward(completion_before_pct: f64, since: &Since) -> f64 {
    let gained = since.completion_pct - completion_before_pct;
    let cost: f64 = since
        .infractions
        .iter()
        .map(|i| 100.0 * (1.0 - crate::monitors::score::penalty(i.kind)))
        .sum();
    gained - cost
}

/// What the run's thread tells the agent's thread.
pub enum Event {
    /// A control boundary: the agent must answer with a control.
    Observe(Snapshot),
    /// The run ended (its record), or could not be built or failed.
    Done(Result<Box<crate::build::ScenarioRun>, String>),
}

/// The shared state between the [`RemoteWatch`] and the [`RemoteDriver`].
type Shared = Arc<Mutex<Since>>;

/// The two ends of a remote run, for the thread that talks to the agent.
pub struct Link {
    /// Events from the run: a snapshot per control boundary, then its end.
    pub events: Receiver<Event>,
    /// Controls to the driver, one per snapshot; dropping it aborts the run.
    pub controls: SyncSender<VehicleControl>,
    /// The scale the next observation is rendered at (read at each boundary).
    pub next_scale: Arc<Mutex<Option<f32>>>,
    /// What happened since the last snapshot (drained by [`Link::drain`] at the run's end).
    shared: Shared,
}

impl Link {
    /// What happened since the last snapshot, emptied (for the episode's last step).
    pub fn drain(&self) -> Since {
        take_since(&self.shared)
    }
}

/// What happened since the last call: the state now, and the infractions, which it empties.
fn take_since(shared: &Shared) -> Since {
    let mut s = shared.lock().unwrap_or_else(|e| e.into_inner());
    let out = s.clone();
    s.infractions.clear();
    out
}

/// The run's ends: the driver, the observer, the selector (each goes into the run),
/// and the sender for the run's [`Event::Done`].
pub struct RunEnds {
    /// Sends the run's end (the thread that runs it does, after the run).
    pub done: SyncSender<Event>,
    /// The driver.
    pub driver: RemoteDriver,
    /// The observer.
    pub watch: RemoteWatch,
    /// The selector; `default` is the scale used until the agent picks one.
    pub selector: RemoteSelector,
}

/// A new remote run: the agent's [`Link`] and the run's ends. The run's first scale
/// is `scale` until the agent asks for another; without `camera`, nothing is rendered
/// and the snapshots carry no image; with `classes`, they carry the class image too.
pub fn remote(scale: f32, camera: bool, classes: bool) -> (Link, RunEnds) {
    let (obs_tx, obs_rx) = sync_channel(2);
    let (ctl_tx, ctl_rx) = sync_channel(1);
    let shared: Shared = Arc::default();
    let next_scale = Arc::new(Mutex::new(None));
    (
        Link {
            events: obs_rx,
            controls: ctl_tx,
            next_scale: next_scale.clone(),
            shared: shared.clone(),
        },
        RunEnds {
            done: obs_tx.clone(),
            driver: RemoteDriver {
                camera,
                classes: camera && classes,
                to_agent: obs_tx,
                from_agent: ctl_rx,
                shared: shared.clone(),
            },
            watch: RemoteWatch { shared },
            selector: RemoteSelector {
                wanted: next_scale,
                current: scale,
            },
        },
    )
}

/// The payload of the unwinding that aborts a run whose agent went away.
#[derive(Debug)]
pub struct Aborted;

/// A driver whose controls come from the agent.
pub struct RemoteDriver {
    camera: bool,
    classes: bool,
    to_agent: SyncSender<Event>,
    from_agent: Receiver<VehicleControl>,
    shared: Shared,
}

impl RemoteDriver {
    fn abort() -> ! {
        std::panic::resume_unwind(Box::new(Aborted))
    }
}

impl Driver for RemoteDriver {
    fn name(&self) -> String {
        "external".into()
    }

    fn needs(&self) -> DriverNeeds {
        DriverNeeds {
            camera: self.camera,
            privileged: false,
            labels: self.classes,
        }
    }

    fn act(&mut self, obs: &Observation<'_>) -> VehicleControl {
        let since = take_since(&self.shared);
        let (size, image) = match obs.image {
            Some(img) => ((img.height, img.width), img.data.clone()),
            None => ((0, 0), Vec::new()),
        };
        let snapshot = Snapshot {
            time_s: obs.time_s,
            speed_mps: obs.speed_mps,
            command: obs.command as u8,
            scale: obs.scale,
            size,
            image,
            classes: obs
                .labels
                .map(|l| crate::render::classes::wor_of_label_rgb(&l.data))
                .unwrap_or_default(),
            since,
        };
        if self.to_agent.send(Event::Observe(snapshot)).is_err() {
            Self::abort();
        }
        match self.from_agent.recv() {
            Ok(c) => c,
            Err(_) => Self::abort(),
        }
    }
}

/// Collects what the agent is told between boundaries.
pub struct RemoteWatch {
    shared: Shared,
}

impl RunObserver for RemoteWatch {
    fn on_tick(
        &mut self,
        view: &TickView<'_>,
        _camera: Option<&mut dyn Camera>,
    ) -> Result<(), RunError> {
        let mut s = self.shared.lock().unwrap_or_else(|e| e.into_inner());
        s.infractions.extend(view.infractions.iter().cloned());
        s.completion_pct = view.completion_pct;
        s.route_s = view.route_s;
        let ego = view.ego();
        s.ego_pose = [ego.position.x, ego.position.y, ego.heading];
        Ok(())
    }
}

/// The scale the agent asked for, else the last one.
pub struct RemoteSelector {
    wanted: Arc<Mutex<Option<f32>>>,
    current: f32,
}

impl ResolutionSelector for RemoteSelector {
    fn name(&self) -> String {
        "external".into()
    }

    fn select(&mut self, _input: &SelectorInput) -> f32 {
        if let Some(s) = self.wanted.lock().unwrap_or_else(|e| e.into_inner()).take() {
            self.current = s;
        }
        self.current
    }
}
