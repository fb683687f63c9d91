//! Scenario files: what to drive, where, with what traffic, timing and driver.
//!
//! The schema is documented for users in `scenarios/README.md`; every field
//! here has a default except the map and the route. Unknown keys and bad
//! values are errors that name the file and the key.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// A whole scenario file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// A short name for result records (defaults to the file's stem).
    #[serde(default)]
    pub name: String,
    /// The town.
    pub map: MapSpec,
    /// The route to drive.
    pub route: RouteSpec,
    /// NPC vehicles and pedestrians.
    #[serde(default)]
    pub traffic: TrafficSpec,
    /// Ticks, camera rate, control period, delay and latency.
    #[serde(default)]
    pub timing: TimingSpec,
    /// Who drives.
    #[serde(default)]
    pub driver: DriverSpec,
    /// Which input scale the driver sees.
    #[serde(default)]
    pub resolution: ResolutionSpec,
    /// The camera rig.
    #[serde(default)]
    pub camera: CameraSpec,
    /// When a run ends early.
    #[serde(default)]
    pub termination: TerminationSpec,
    /// What a run writes.
    #[serde(default)]
    pub outputs: OutputSpec,
}

/// Where the town comes from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapSpec {
    /// An OpenDRIVE file, relative to the scenario file.
    pub file: PathBuf,
    /// For maps without `<signal>`s (CARLA's Town03, Town04, Town06): lights
    /// generated at each junction of three or more approach roads (`true`, and
    /// the default when left out) or no lights (`false`). Maps with lights of
    /// their own keep them either way.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generate_lights: Option<bool>,
}

impl MapSpec {
    /// Whether a map without lights of its own gets generated ones.
    pub fn generates_lights(&self) -> bool {
        self.generate_lights.unwrap_or(true)
    }
}

/// Which route of which file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RouteSpec {
    /// A CARLA leaderboard route XML or a native TOML route file, relative to
    /// the scenario file.
    pub file: PathBuf,
    /// The route's id in that file (`id = 0` and `id = "0"` are the same).
    #[serde(deserialize_with = "id_string")]
    pub id: String,
}

/// Reads a route id written as a number or a string.
fn id_string<'de, D: serde::Deserializer<'de>>(d: D) -> Result<String, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Id {
        Number(u64),
        Text(String),
    }
    Ok(match Id::deserialize(d)? {
        Id::Number(n) => n.to_string(),
        Id::Text(t) => t,
    })
}

/// The traffic to spawn.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrafficSpec {
    /// Target number of NPC vehicles (the realised count is reported).
    pub vehicles: u32,
    /// Target number of pedestrians (the realised count is reported).
    pub pedestrians: u32,
    /// Share of pedestrians that cross the road away from crosswalks, in [0, 1]
    /// (CARLA's cross factor).
    pub cross_factor: f32,
    /// Walkers sent across the road just ahead of the ego, per minute of
    /// driving, in [0, 60]: a data-collection aid like CARLA's
    /// pedestrian-crossing scenarios (`world::traffic::crossings`); 0, the
    /// default, in every evaluation scenario.
    #[serde(skip_serializing_if = "is_off")]
    pub ego_crossings_per_min: f32,
    /// The seed every random choice of the run is derived from.
    pub seed: u64,
}

fn is_off(rate: &f32) -> bool {
    *rate == 0.0
}

impl Default for TrafficSpec {
    fn default() -> Self {
        Self {
            vehicles: 0,
            pedestrians: 0,
            cross_factor: 0.1,
            ego_crossings_per_min: 0.0,
            seed: 0,
        }
    }
}

/// How execution latency is modelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum LatencyModel {
    /// A fixed number of milliseconds per input scale (`latency_ms`):
    /// reproducible.
    #[default]
    Fixed,
    /// The driver's measured compute time: realistic, not reproducible.
    Measured,
}

/// The loop's clock and the controller's timing (docs/protocol.md §1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TimingSpec {
    /// Physics tick (seconds): the world (vehicle model, physics, walkers)
    /// advances this much a tick. Rules that docs/protocol.md gives per tick (an NPC
    /// stopped 40 ticks is respawned, a walker picks a new goal with
    /// p = 0.02 a tick) stay per tick.
    pub tick_s: f64,
    /// Camera rate (frames per second); must divide the tick rate.
    pub camera_hz: f64,
    /// Control period Tc (milliseconds).
    pub control_period_ms: f64,
    /// Injected delay D (milliseconds), a zero-order hold.
    pub delay_ms: f64,
    /// Fixed or measured execution latency.
    pub latency: LatencyModel,
    /// Execution latency Lexec per input scale (milliseconds), keyed by the
    /// scale written as in the resolution section (`"0.75"`, `"1.0"`).
    /// Scales not listed have none.
    pub latency_ms: BTreeMap<String, f64>,
    /// Spread of the fixed execution latency (the sigma of a log-normal
    /// factor with mean 1; 0 = none): at each control boundary the latency
    /// in force is `max(D, Lexec(scale) x factor)`, the factor drawn from a
    /// generator seeded by the traffic seed, so runs stay reproducible.
    /// 0.25 puts 95 % of the draws within about 0.6x-1.6x of `Lexec`.
    pub latency_jitter: f64,
}

impl Default for TimingSpec {
    fn default() -> Self {
        Self {
            tick_s: 0.025,
            camera_hz: 20.0,
            control_period_ms: 50.0,
            delay_ms: 0.0,
            latency: LatencyModel::Fixed,
            latency_ms: BTreeMap::new(),
            latency_jitter: 0.0,
        }
    }
}

/// Who drives the ego.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DriverSpec {
    /// `expert` (the privileged autopilot) or `policy` (a checkpoint).
    pub kind: DriverKind,
    /// For `policy`: the checkpoint file (`.safetensors` with its config
    /// beside it), relative to the scenario file.
    pub checkpoint: Option<PathBuf>,
    /// For `policy`: `cpu` (default), `cuda` or `wgpu`.
    pub device: Option<String>,
    /// For `policy`: a learned trigger for the `learned` selector (the JSON
    /// file of `mrdrive policy trigger`), relative to the scenario file.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trigger: Option<PathBuf>,
}

impl Default for DriverSpec {
    fn default() -> Self {
        Self {
            kind: DriverKind::Expert,
            checkpoint: None,
            device: None,
            trigger: None,
        }
    }
}

impl DriverSpec {
    /// The policy of `checkpoint` on the default device, without a trigger.
    pub fn policy(checkpoint: PathBuf) -> Self {
        Self {
            kind: DriverKind::Policy,
            checkpoint: Some(checkpoint),
            ..Self::default()
        }
    }
}

/// The kinds of driver a scenario can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DriverKind {
    /// The privileged autopilot.
    Expert,
    /// A trained (or randomly initialised) network from a checkpoint.
    Policy,
    /// Controls from outside the process (`mrdrive serve`, the Python environment).
    External,
}

impl DriverKind {
    /// The name a scenario file uses (`driver.kind = "expert"`).
    pub fn name(self) -> &'static str {
        match self {
            DriverKind::Expert => "expert",
            DriverKind::Policy => "policy",
            DriverKind::External => "external",
        }
    }
}

/// The camera rig: WoR's three cameras at a base size S0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraSpec {
    /// `cpu` (S0 = 240 x 96, the default for CPU training) or `paper`
    /// (S0 = 480 x 192). A policy checkpoint's own S0 takes precedence.
    pub rig: RigKind,
    /// Supersampling factor per axis for anti-aliasing (1 turns it off).
    pub supersample: u32,
    /// Multisamples per drawn pixel for anti-aliasing: 1 (off) or 4.
    pub msaa: u32,
}

impl Default for CameraSpec {
    fn default() -> Self {
        Self {
            rig: RigKind::Cpu,
            supersample: crate::render::rig::DEFAULT_SUPERSAMPLE,
            msaa: crate::render::rig::DEFAULT_MSAA,
        }
    }
}

/// The rig sizes a scenario can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RigKind {
    /// S0 = 240 x 96.
    Cpu,
    /// S0 = 480 x 192, the paper's.
    Paper,
}

/// How the input scale is chosen at each control boundary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ResolutionSpec {
    /// `fixed`, `oracle` (the paper's), `lookahead` (map-based), `braking`
    /// (map-based, up before the braking point), `budget` or `learned` (the
    /// policy's own trigger, `driver.trigger`).
    pub selector: SelectorKind,
    /// For `fixed`: the scale (fraction of S0).
    pub scale: f64,
    /// For `oracle`/`lookahead`/`braking`: the default (low) and near-light (high) scales.
    pub low: f64,
    /// The scale near a traffic light.
    pub high: f64,
    /// For `oracle`: switch up within this distance of the light (metres).
    pub near_m: f64,
    /// For `oracle`: switch back down beyond this distance (metres).
    pub far_m: f64,
    /// For `budget`: the latency budget (milliseconds).
    pub budget_ms: Option<f64>,
    /// For `learned`: the trigger fires at this probability or above (default 0.5).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trigger_p: Option<f64>,
    /// For `learned`: control boundaries the high scale is held after the
    /// trigger last fired (default 10).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hold_steps: Option<u32>,
}

impl Default for ResolutionSpec {
    fn default() -> Self {
        Self {
            selector: SelectorKind::Fixed,
            scale: 1.0,
            low: 0.75,
            high: 1.0,
            near_m: 5.0,
            far_m: 15.0,
            budget_ms: None,
            trigger_p: None,
            hold_steps: None,
        }
    }
}

/// The resolution selectors a scenario can name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SelectorKind {
    /// One scale throughout.
    Fixed,
    /// The paper's oracle: high within `near_m` of a light, low beyond `far_m`.
    Oracle,
    /// Map-based: switch up early enough, from the distance along the route.
    Lookahead,
    /// Map-based like `lookahead`, and up before the braking point for the
    /// light, so the high scale decides the stop (`Lookahead::braking`).
    Braking,
    /// The highest scale whose latency fits `budget_ms`.
    Budget,
    /// The policy's learned trigger (`driver.trigger`): high while it fires,
    /// held `hold_steps` boundaries; no map.
    Learned,
}

/// When a run ends before the route does (docs/protocol.md §3).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TerminationSpec {
    /// Stuck: this long below 0.2 m/s while throttle > 0.3 or after a
    /// collision (seconds).
    pub stuck_s: f64,
    /// Low-speed timeout: this long below 0.2 m/s (seconds).
    pub low_speed_s: f64,
    /// Route deviation: farther than this from the next route point (metres).
    pub deviation_m: f64,
    /// Route timeout (seconds); by default from the route's length.
    pub timeout_s: Option<f64>,
}

impl Default for TerminationSpec {
    fn default() -> Self {
        Self {
            stuck_s: 8.0,
            low_speed_s: 40.0,
            deviation_m: 10.0,
            timeout_s: None,
        }
    }
}

/// What a run writes besides its result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSpec {
    /// Record an MCAP log to this file.
    pub record: Option<PathBuf>,
    /// Include the class image in the log.
    pub record_labels: bool,
}

/// A scenario file could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The file could not be read.
    #[error("cannot read scenario {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not valid TOML for the schema (unknown key, wrong type).
    #[error("scenario {path}: {message}\n  (the schema is in scenarios/README.md)")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What the parser said, with the line and the key.
        message: String,
    },
    /// A value is out of its range.
    #[error("scenario {path}: `{key}` = {value}: {fix}")]
    Value {
        /// The file.
        path: PathBuf,
        /// The key, dotted (`timing.delay_ms`).
        key: String,
        /// The offending value.
        value: String,
        /// What would be accepted.
        fix: String,
    },
}

impl Scenario {
    /// Reads and checks a scenario file; relative paths in it are resolved
    /// against the file's folder.
    pub fn from_file(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let mut scenario = Self::from_toml_str(&text, path)?;
        let base = path.parent().unwrap_or(Path::new("."));
        scenario.map.file = base.join(&scenario.map.file);
        scenario.route.file = base.join(&scenario.route.file);
        if let Some(c) = &scenario.driver.checkpoint {
            scenario.driver.checkpoint = Some(base.join(c));
        }
        if let Some(t) = &scenario.driver.trigger {
            scenario.driver.trigger = Some(base.join(t));
        }
        if scenario.name.is_empty() {
            scenario.name = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
        }
        Ok(scenario)
    }

    /// Parses and checks scenario text; `path` is only used in messages.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self, ScenarioError> {
        let scenario: Scenario = toml::from_str(text).map_err(|e| ScenarioError::Parse {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        scenario.check(path)?;
        Ok(scenario)
    }

    /// Checks the values' ranges.
    pub fn check(&self, path: &Path) -> Result<(), ScenarioError> {
        let bad = |key: &str, value: String, fix: &str| {
            Err(ScenarioError::Value {
                path: path.to_path_buf(),
                key: key.into(),
                value,
                fix: fix.into(),
            })
        };
        let t = &self.timing;
        if !(t.tick_s > 0.0 && t.tick_s <= 0.1) {
            return bad(
                "timing.tick_s",
                t.tick_s.to_string(),
                "use a tick in (0, 0.1] seconds, e.g. 0.025 (40 Hz)",
            );
        }
        let ticks_per_frame = 1.0 / (t.camera_hz * t.tick_s);
        if !(t.camera_hz > 0.0
            && (ticks_per_frame - ticks_per_frame.round()).abs() < 1e-6
            && ticks_per_frame.round() >= 1.0)
        {
            return bad(
                "timing.camera_hz",
                t.camera_hz.to_string(),
                "the camera rate must divide the tick rate (e.g. 20 Hz on a 40 Hz tick)",
            );
        }
        if !(t.delay_ms >= 0.0 && t.delay_ms <= 10_000.0) {
            return bad(
                "timing.delay_ms",
                t.delay_ms.to_string(),
                "use a delay in [0, 10000] milliseconds",
            );
        }
        if !(t.control_period_ms >= t.tick_s * 1000.0 - 1e-9 && t.control_period_ms <= 10_000.0) {
            return bad(
                "timing.control_period_ms",
                t.control_period_ms.to_string(),
                "use a period of at least one tick and at most 10000 ms",
            );
        }
        for (scale, ms) in &t.latency_ms {
            if scale
                .parse::<f64>()
                .map(|s| !(s > 0.0 && s <= 1.0))
                .unwrap_or(true)
            {
                return bad(
                    &format!("timing.latency_ms.\"{scale}\""),
                    scale.clone(),
                    "keys are scales in (0, 1], written like \"0.75\"",
                );
            }
            if !(*ms >= 0.0 && *ms <= 10_000.0) {
                return bad(
                    &format!("timing.latency_ms.\"{scale}\""),
                    ms.to_string(),
                    "use a latency in [0, 10000] milliseconds",
                );
            }
        }
        if !(0.0..=2.0).contains(&t.latency_jitter) {
            return bad(
                "timing.latency_jitter",
                t.latency_jitter.to_string(),
                "use a log-normal sigma in [0, 2] (0.25 is a moderate spread)",
            );
        }
        if !(0.0..=1.0).contains(&self.traffic.cross_factor) {
            return bad(
                "traffic.cross_factor",
                self.traffic.cross_factor.to_string(),
                "use a share in [0, 1]",
            );
        }
        if !(0.0..=60.0).contains(&self.traffic.ego_crossings_per_min) {
            return bad(
                "traffic.ego_crossings_per_min",
                self.traffic.ego_crossings_per_min.to_string(),
                "use a rate in [0, 60] per minute (0: no walkers sent; collection uses 4)",
            );
        }
        let r = &self.resolution;
        for (key, v) in [
            ("resolution.scale", r.scale),
            ("resolution.low", r.low),
            ("resolution.high", r.high),
        ] {
            if !(v > 0.0 && v <= 1.0) {
                return bad(key, v.to_string(), "scales are fractions of S0 in (0, 1]");
            }
        }
        if !(r.near_m >= 0.0 && r.far_m >= r.near_m) {
            return bad(
                "resolution.far_m",
                r.far_m.to_string(),
                "use 0 <= near_m <= far_m (metres)",
            );
        }
        if r.selector == SelectorKind::Budget && r.budget_ms.is_none() {
            return bad(
                "resolution.budget_ms",
                "missing".into(),
                "the budget selector needs `budget_ms` (milliseconds)",
            );
        }
        if let Some(p) = r.trigger_p
            && !(p > 0.0 && p < 1.0)
        {
            return bad(
                "resolution.trigger_p",
                p.to_string(),
                "a probability strictly between 0 and 1, e.g. 0.5",
            );
        }
        if r.selector == SelectorKind::Learned
            && (self.driver.kind != DriverKind::Policy || self.driver.trigger.is_none())
        {
            return bad(
                "driver.trigger",
                "missing".into(),
                "the learned selector needs a policy driver with `trigger = \"path/to/model.trigger.json\"` (made by `mrdrive policy trigger`)",
            );
        }
        if self.driver.kind == DriverKind::Policy && self.driver.checkpoint.is_none() {
            return bad(
                "driver.checkpoint",
                "missing".into(),
                "a policy driver needs `checkpoint = \"path/to/model.safetensors\"`",
            );
        }
        if !(1..=4).contains(&self.camera.supersample) {
            return bad(
                "camera.supersample",
                self.camera.supersample.to_string(),
                "use 1 (off) to 4",
            );
        }
        if ![1, 4].contains(&self.camera.msaa) {
            return bad(
                "camera.msaa",
                self.camera.msaa.to_string(),
                "use 1 (off) or 4 (the sample counts lavapipe offers)",
            );
        }
        let term = &self.termination;
        for (key, v) in [
            ("termination.stuck_s", term.stuck_s),
            ("termination.low_speed_s", term.low_speed_s),
            ("termination.deviation_m", term.deviation_m),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return bad(key, v.to_string(), "use a positive number");
            }
        }
        Ok(())
    }

    /// Ticks between two camera frames.
    pub fn ticks_per_frame(&self) -> u32 {
        (1.0 / (self.timing.camera_hz * self.timing.tick_s)).round() as u32
    }

    /// The execution latency at `scale` (milliseconds; 0 where none is set).
    pub fn latency_ms_at(&self, scale: f64) -> f64 {
        self.timing
            .latency_ms
            .iter()
            .find(|(key, _)| key.parse::<f64>().is_ok_and(|s| (s - scale).abs() < 1e-6))
            .map_or(0.0, |(_, ms)| *ms)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = "[map]\nfile = \"town.xodr\"\n[route]\nfile = \"routes.toml\"\nid = 3\n";

    fn parse(text: &str) -> Result<Scenario, ScenarioError> {
        Scenario::from_toml_str(text, Path::new("scenarios/x.toml"))
    }

    #[test]
    fn minimal_scenario_takes_the_protocol_defaults() {
        let s = parse(MINIMAL).unwrap();
        assert_eq!(s.route.id, "3");
        assert_eq!(s.timing.tick_s, 0.025);
        assert_eq!(s.ticks_per_frame(), 2);
        assert_eq!(s.timing.control_period_ms, 50.0);
        assert_eq!(s.driver.kind, DriverKind::Expert);
        assert_eq!(s.termination.stuck_s, 8.0);
        // A map without lights of its own gets generated ones unless told not to.
        assert!(s.map.generates_lights());
        let off = parse(&MINIMAL.replace("[route]", "generate_lights = false\n[route]")).unwrap();
        assert!(!off.map.generates_lights());
    }

    #[test]
    fn unknown_key_is_named_with_the_file() {
        let err = parse(&format!("{MINIMAL}[timing]\ndelay_msec = 50\n"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("scenarios/x.toml"), "{err}");
        assert!(err.contains("delay_msec"), "{err}");
    }

    #[test]
    fn bad_value_names_the_key_and_the_fix() {
        let err = parse(&format!("{MINIMAL}[timing]\ncamera_hz = 15\n"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("timing.camera_hz") && err.contains("divide"),
            "{err}"
        );
        let err = parse(&format!("{MINIMAL}[driver]\nkind = \"policy\"\n"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("driver.checkpoint"), "{err}");
        let err = parse(&format!("{MINIMAL}[camera]\nmsaa = 2\n"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("camera.msaa") && err.contains("1 (off) or 4"),
            "{err}"
        );
        let s = parse(&format!("{MINIMAL}[camera]\nmsaa = 4\nsupersample = 1\n")).unwrap();
        assert_eq!((s.camera.msaa, s.camera.supersample), (4, 1));
        let err = parse(&format!("{MINIMAL}[resolution]\nscale = 1.5\n"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("resolution.scale"), "{err}");
        let err = parse(&format!("{MINIMAL}[timing]\nlatency_jitter = -0.1\n"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("timing.latency_jitter") && err.contains("sigma"),
            "{err}"
        );
        let err = parse(&format!("{MINIMAL}[traffic]\nego_crossings_per_min = 90\n"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("traffic.ego_crossings_per_min") && err.contains("[0, 60]"),
            "{err}"
        );
        let s = parse(&format!("{MINIMAL}[traffic]\nego_crossings_per_min = 4\n")).unwrap();
        assert_eq!(s.traffic.ego_crossings_per_min, 4.0);
        let learned = format!("{MINIMAL}[resolution]\nselector = \"learned\"\n");
        let err = parse(&learned).unwrap_err().to_string();
        assert!(
            err.contains("driver.trigger") && err.contains("mrdrive policy trigger"),
            "{err}"
        );
        let with_trigger = format!(
            "{learned}trigger_p = 0.6\n[driver]\nkind = \"policy\"\ncheckpoint = \"m.safetensors\"\ntrigger = \"t.json\"\n"
        );
        let s = parse(&with_trigger).unwrap();
        assert_eq!(s.resolution.trigger_p, Some(0.6));
        let err = parse(&with_trigger.replace("0.6", "1.0"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("resolution.trigger_p"), "{err}");
    }

    #[test]
    fn driver_kinds_are_named_as_the_file_writes_them() {
        for kind in [DriverKind::Expert, DriverKind::Policy] {
            let text = format!(
                "{MINIMAL}[driver]\nkind = \"{}\"\ncheckpoint = \"m.safetensors\"\n",
                kind.name()
            );
            assert_eq!(parse(&text).unwrap().driver.kind, kind);
        }
    }

    #[test]
    fn missing_route_is_an_error() {
        let err = parse("[map]\nfile = \"town.xodr\"\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("route"), "{err}");
    }

    #[test]
    fn latency_per_scale_is_looked_up_by_value() {
        let s = parse(&format!(
            "{MINIMAL}[timing]\nlatency_ms = {{ \"0.75\" = 50.0, \"1.0\" = 100.0 }}\n"
        ))
        .unwrap();
        assert_eq!(s.latency_ms_at(0.75), 50.0);
        assert_eq!(s.latency_ms_at(1.0), 100.0);
        assert_eq!(s.latency_ms_at(0.5), 0.0);
    }

    #[test]
    fn relative_paths_resolve_against_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.toml");
        std::fs::write(&path, MINIMAL).unwrap();
        let s = Scenario::from_file(&path).unwrap();
        assert_eq!(s.map.file, dir.path().join("town.xodr"));
        assert_eq!(s.name, "s");
    }
}
