//! The interface between the loop and whatever drives the ego.

pub use world::Command;
/// What a driver emits: the vehicle model's control (steer, throttle, brake).
pub use world::agents::VehicleControl;

/// An RGB image in row-major order, 3 bytes a pixel, no row padding.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RgbImage {
    /// Width (pixels).
    pub width: u32,
    /// Height (pixels).
    pub height: u32,
    /// `width * height * 3` bytes, sRGB.
    pub data: Vec<u8>,
}

/// What a driver sees at a control boundary.
#[derive(Debug, Clone, Copy)]
pub struct Observation<'a> {
    /// Simulation time (seconds since the start of the run).
    pub time_s: f64,
    /// Ego speed (metres per second).
    pub speed_mps: f32,
    /// The route command at the ego's position.
    pub command: Command,
    /// The input scale this observation was rendered at (fraction of S0).
    pub scale: f32,
    /// The stitched camera rig image at that scale, if the driver asked for it.
    pub image: Option<&'a RgbImage>,
    /// The rig's class image at that scale in the label palette
    /// (`sim::render::labels`), if the driver asked for it.
    pub labels: Option<&'a RgbImage>,
    /// The simulator's exact state, for drivers that declare they need it.
    pub privileged: Option<&'a Privileged<'a>>,
}

/// The simulator's exact state at a control boundary: what the privileged
/// expert drives from. Learned drivers never get it.
#[derive(Debug, Clone, Copy)]
pub struct Privileged<'a> {
    /// The town.
    pub town: &'a world::Town,
    /// The dense route being driven.
    pub route: &'a world::route::DenseRoute,
    /// The route point the ego has reached.
    pub route_index: usize,
    /// The ego.
    pub ego: world::ActorSnapshot,
    /// Every light's state, by `LightIdx`.
    pub lights: &'a [world::LightState],
    /// The stop lines on the route, in route order (the rule book's).
    pub stops: &'a world::rules::RouteStops,
    /// The nearest actor ahead along the route, if any within range.
    pub ahead: Option<world::rules::Ahead>,
    /// Where the route enters a junction without lights that the ego must
    /// wait before (route arc length, metres): a vehicle holds a connecting
    /// lane that conflicts with the route's ([`world::rules::junction_yield`]).
    pub junction_yield_s: Option<f32>,
    /// Where the route's next lane change starts, while the lane it moves into
    /// has no room (route arc length, metres; [`world::rules::lane_change_clear`]).
    pub lane_change_wait_s: Option<f32>,
    /// The ego's vehicle model.
    pub vehicle: &'a world::agents::VehicleParams,
}

/// What a driver needs the loop to provide.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DriverNeeds {
    /// The camera rig must be rendered for it.
    pub camera: bool,
    /// It reads the simulator's exact state (the expert).
    pub privileged: bool,
    /// It wants the rig's class image beside the colour image (for an external agent
    /// that learns segmentation; rendered in the same pass).
    pub labels: bool,
}

/// Anything that turns observations into controls: the expert, a CNN policy,
/// a replay of recorded controls.
pub trait Driver: Send {
    /// A short name for result records and logs.
    fn name(&self) -> String;
    /// What the loop must provide.
    fn needs(&self) -> DriverNeeds;
    /// Computes the control for this observation.
    fn act(&mut self, obs: &Observation<'_>) -> VehicleControl;
    /// The probability, from the last observation, that the high input
    /// scale is needed: a policy's learned trigger, read by the
    /// [`Learned`](crate::selector::Learned) selector at the next boundary.
    /// `None` for drivers without one.
    fn scale_hint(&self) -> Option<f32> {
        None
    }
    /// The checkpoint this driver runs (file and digest), written into its
    /// run records; `None` for drivers without one (the expert).
    fn checkpoint(&self) -> Option<crate::record::CheckpointId> {
        None
    }
    /// The learned trigger this driver reads (file and digest), written into
    /// its run records; `None` for drivers without one.
    fn trigger(&self) -> Option<crate::record::CheckpointId> {
        None
    }
}
