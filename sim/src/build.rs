//! From a scenario to a runnable run: the driver, the resolution selector
//! and the camera a scenario asks for, and [`run_scenario`], which drives one
//! scenario file with overrides (what `mrdrive run` and each sweep run do).
//!
//! `sim` knows nothing of networks: the drivers it cannot build itself (a
//! policy from a checkpoint) come from a [`DriverFactory`] that the program
//! registers in [`Drivers`] under the [`DriverKind`] a scenario names.

use std::path::{Path, PathBuf};

use crate::camera::Camera;
use crate::driver::Driver;
use crate::expert::{Expert, ExpertParams};
use crate::observe::{Progress, RenderEveryFrame, RunObserver, RunProgress};
use crate::record::RunRecord;
use crate::recorder::{RecordError, RecordOptions, Recorder};
use crate::render::{RenderError, Renderer, RigConfig};
use crate::runner::{self, Prepared, RunError, RunInputs};
use crate::scenario::{DriverKind, RigKind, Scenario, ScenarioError, SelectorKind};
use crate::selector::{
    Fixed, LatencyBudget, LatencyTable, LatencyTableError, Learned, Lookahead, Oracle,
    ResolutionSelector,
};

/// Settings given on the command line over the scenario's.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// Injected delay (milliseconds).
    pub delay_ms: Option<f64>,
    /// Traffic seed.
    pub seed: Option<u64>,
    /// Target vehicles.
    pub vehicles: Option<u32>,
    /// Target pedestrians.
    pub pedestrians: Option<u32>,
    /// Who drives, over the scenario's `[driver]` (paths relative to the working folder).
    pub driver: Option<crate::scenario::DriverSpec>,
}

impl Overrides {
    /// The scenario with the overrides applied.
    pub fn apply(&self, scenario: &Scenario) -> Scenario {
        let mut s = scenario.clone();
        if let Some(d) = self.delay_ms {
            s.timing.delay_ms = d;
        }
        if let Some(seed) = self.seed {
            s.traffic.seed = seed;
        }
        if let Some(v) = self.vehicles {
            s.traffic.vehicles = v;
        }
        if let Some(p) = self.pedestrians {
            s.traffic.pedestrians = p;
        }
        if let Some(d) = &self.driver {
            s.driver = d.clone();
        }
        s
    }
}

/// Any error a [`DriverFactory`] reports (it comes from another crate).
pub type FactoryError = Box<dyn std::error::Error + Send + Sync>;

/// Builds the driver of one [`DriverKind`] for a scenario.
///
/// `sim` builds the expert itself ([`ExpertFactory`]); the `policy` crate
/// implements this for its checkpoint driver, and the program registers it
/// in [`Drivers`].
pub trait DriverFactory: Send + Sync {
    /// The driver `scenario`'s `[driver]` section asks for, on the prepared
    /// town and route.
    fn driver(
        &self,
        scenario: &Scenario,
        prepared: &Prepared,
    ) -> Result<Box<dyn Driver>, FactoryError>;

    /// The base size S0 of the images this driver reads, (height, width) in
    /// pixels, when the driver fixes it (a policy's checkpoint does); `None`
    /// leaves the scenario's `[camera]` rig.
    fn input_size(&self, _scenario: &Scenario) -> Result<Option<(u32, u32)>, FactoryError> {
        Ok(None)
    }
}

/// The privileged expert with its default tuning.
#[derive(Debug, Clone, Copy, Default)]
pub struct ExpertFactory;

impl DriverFactory for ExpertFactory {
    fn driver(
        &self,
        _scenario: &Scenario,
        _prepared: &Prepared,
    ) -> Result<Box<dyn Driver>, FactoryError> {
        Ok(Box::new(Expert::new(ExpertParams::default())))
    }
}

/// The driver kinds this program can build, each with its factory.
pub struct Drivers {
    factories: Vec<(DriverKind, Box<dyn DriverFactory>)>,
}

impl Default for Drivers {
    fn default() -> Self {
        Self::new()
    }
}

impl Drivers {
    /// The expert only.
    pub fn new() -> Self {
        Drivers {
            factories: vec![(DriverKind::Expert, Box::new(ExpertFactory))],
        }
    }

    /// These drivers with `factory` building `kind` (replacing any factory
    /// registered for it before).
    pub fn with(mut self, kind: DriverKind, factory: impl DriverFactory + 'static) -> Self {
        self.factories.retain(|(k, _)| *k != kind);
        self.factories.push((kind, Box::new(factory)));
        self
    }

    /// The factory for the kind `scenario` names.
    fn factory(&self, scenario: &Scenario) -> Result<&dyn DriverFactory, BuildError> {
        let kind = scenario.driver.kind;
        self.factories
            .iter()
            .find(|(k, _)| *k == kind)
            .map(|(_, f)| f.as_ref())
            .ok_or_else(|| BuildError::DriverUnavailable {
                scenario: scenario.name.clone(),
                kind,
            })
    }

    /// The driver `scenario` asks for.
    pub fn driver(
        &self,
        scenario: &Scenario,
        prepared: &Prepared,
    ) -> Result<Box<dyn Driver>, BuildError> {
        self.factory(scenario)?
            .driver(scenario, prepared)
            .map_err(|source| BuildError::Driver {
                scenario: scenario.name.clone(),
                source,
            })
    }

    /// The base size S0 (height, width) in pixels that `scenario`'s driver
    /// fixes, if it does.
    pub fn input_size(&self, scenario: &Scenario) -> Result<Option<(u32, u32)>, BuildError> {
        self.factory(scenario)?
            .input_size(scenario)
            .map_err(|source| BuildError::Driver {
                scenario: scenario.name.clone(),
                source,
            })
    }
}

/// A run could not be built from its scenario, or failed.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The scenario file could not be read or is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The map or route could not be loaded, or the run failed.
    #[error("scenario {path}")]
    Run {
        /// The scenario file.
        path: PathBuf,
        /// Why (boxed: a run error is large, and most results carry none).
        #[source]
        source: Box<RunError>,
    },
    /// The scenario names a driver kind this program has no factory for.
    #[error(
        "scenario {scenario}: driver.kind = \"{}\" cannot be built here; fix: register a factory for it with `Drivers::with` (the mrdrive program registers \"policy\"), or use driver.kind = \"expert\"",
        kind.name()
    )]
    DriverUnavailable {
        /// The scenario's name.
        scenario: String,
        /// The kind asked for.
        kind: DriverKind,
    },
    /// The driver's factory failed (a missing checkpoint, a device).
    #[error("scenario {scenario}: the driver")]
    Driver {
        /// The scenario's name.
        scenario: String,
        /// What the factory said.
        #[source]
        source: FactoryError,
    },
    /// The scenario's latency table is unusable for its selector.
    #[error("scenario {scenario}: timing.latency_ms")]
    LatencyTable {
        /// The scenario's name.
        scenario: String,
        /// Why.
        #[source]
        source: LatencyTableError,
    },
    /// A selector needs latencies the scenario does not give.
    #[error(
        "scenario {scenario}: resolution.selector = \"{selector}\" needs timing.latency_ms for the scales {low} and {high}; fix: e.g. latency_ms = {{ \"{low}\" = 50.0, \"{high}\" = 100.0 }}"
    )]
    MissingLatency {
        /// The scenario's name.
        scenario: String,
        /// The selector's name in the scenario.
        selector: &'static str,
        /// Its low scale.
        low: f32,
        /// Its high scale.
        high: f32,
    },
    /// A latency key is not a scale.
    #[error(
        "scenario {scenario}: timing.latency_ms key \"{key}\" is not a scale; fix: write keys as scales like \"0.75\""
    )]
    LatencyKey {
        /// The scenario's name.
        scenario: String,
        /// The key.
        key: String,
    },
    /// A fixed scale given over the scenario is out of range.
    #[error("--scale {scale}: scales are fractions of S0 in (0, 1]; fix: e.g. --scale 0.75")]
    Scale {
        /// The scale given.
        scale: f64,
    },
    /// The driver's base size cannot be cut into the three-camera rig.
    #[error(
        "scenario {scenario}: the driver's S0 {width}x{height}: the rig needs a width divisible by 3 and a height by 4; fix: use a checkpoint trained at such a size (e.g. 240x96)"
    )]
    RigSize {
        /// The scenario's name.
        scenario: String,
        /// S0 width (pixels).
        width: u32,
        /// S0 height (pixels).
        height: u32,
    },
    /// The camera could not be set up.
    #[error("scenario {scenario}: the camera")]
    Camera {
        /// The scenario's name.
        scenario: String,
        /// Why.
        #[source]
        source: RenderError,
    },
    /// The log could not be created or finished.
    #[error("recording {path}")]
    Record {
        /// The log file.
        path: PathBuf,
        /// Why.
        #[source]
        source: RecordError,
    },
}

/// The latency table of a scenario (`timing.latency_ms`), if it has one.
pub fn latency_table(scenario: &Scenario) -> Result<Option<LatencyTable>, BuildError> {
    if scenario.timing.latency_ms.is_empty() {
        return Ok(None);
    }
    let pairs: Vec<(f32, f64)> = scenario
        .timing
        .latency_ms
        .iter()
        .map(|(k, v)| {
            k.parse::<f32>()
                .map(|s| (s, *v))
                .map_err(|_| BuildError::LatencyKey {
                    scenario: scenario.name.clone(),
                    key: k.clone(),
                })
        })
        .collect::<Result<_, _>>()?;
    LatencyTable::new(&pairs)
        .map(Some)
        .map_err(|source| BuildError::LatencyTable {
            scenario: scenario.name.clone(),
            source,
        })
}

/// The selector `scenario` asks for; a `scale` given over the scenario makes
/// it [`Fixed`] at that scale.
pub fn selector_for(
    scenario: &Scenario,
    scale: Option<f64>,
) -> Result<Box<dyn ResolutionSelector>, BuildError> {
    if let Some(s) = scale {
        if !(s > 0.0 && s <= 1.0) {
            return Err(BuildError::Scale { scale: s });
        }
        return Ok(Box::new(Fixed { scale: s as f32 }));
    }
    let r = &scenario.resolution;
    let (low, high) = (r.low as f32, r.high as f32);
    let table = |selector: &'static str| -> Result<LatencyTable, BuildError> {
        let missing = || BuildError::MissingLatency {
            scenario: scenario.name.clone(),
            selector,
            low,
            high,
        };
        latency_table(scenario)?.ok_or_else(missing)
    };
    Ok(match r.selector {
        SelectorKind::Fixed => Box::new(Fixed {
            scale: r.scale as f32,
        }),
        SelectorKind::Oracle => Box::new(Oracle {
            low,
            high,
            enter_m: r.near_m as f32,
            exit_m: r.far_m as f32,
            active: false,
        }),
        SelectorKind::Lookahead | SelectorKind::Braking => {
            type Make = fn(f32, f32, &LatencyTable) -> Option<Lookahead>;
            let (name, make): (&'static str, Make) = match r.selector {
                SelectorKind::Braking => ("braking", Lookahead::braking),
                _ => ("lookahead", Lookahead::covering),
            };
            let table = table(name)?;
            let mut l = make(low, high, &table).ok_or(BuildError::MissingLatency {
                scenario: scenario.name.clone(),
                selector: name,
                low,
                high,
            })?;
            l.enter_m = r.near_m as f32;
            l.exit_m = r.far_m as f32;
            Box::new(l)
        }
        SelectorKind::Learned => Box::new(Learned {
            low,
            high,
            threshold: r.trigger_p.unwrap_or(0.5) as f32,
            hold_steps: r.hold_steps.unwrap_or(10),
            left: 0,
        }),
        SelectorKind::Budget => Box::new(LatencyBudget {
            table: table("budget")?,
            budget_ms: r.budget_ms.unwrap_or(f64::INFINITY),
        }),
    })
}

/// The rig a scenario asks for: its driver's own S0 if the driver fixes one
/// (a policy's checkpoint), else the scenario's `[camera]` rig. The crop
/// keeps WoR's proportions (the top fifth of each camera's image is cut).
pub fn rig_for(scenario: &Scenario, drivers: &Drivers) -> Result<RigConfig, BuildError> {
    let base = match scenario.camera.rig {
        RigKind::Cpu => RigConfig::cpu_default(),
        RigKind::Paper => RigConfig::paper(),
    };
    let base = match drivers.input_size(scenario)? {
        Some((h0, w0)) => {
            if w0 % 3 != 0 || h0 % 4 != 0 {
                return Err(BuildError::RigSize {
                    scenario: scenario.name.clone(),
                    width: w0,
                    height: h0,
                });
            }
            RigConfig {
                cam_width_px: w0 / 3,
                cam_height_px: h0 * 5 / 4,
                crop_top_px: h0 / 4,
                ..base
            }
        }
        None => base,
    };
    Ok(RigConfig {
        supersample: scenario.camera.supersample,
        msaa: scenario.camera.msaa,
        ..base
    })
}

/// The wgpu renderer for a scenario's town on its rig (scenery seeded from
/// its traffic seed).
pub fn camera_for(
    scenario: &Scenario,
    prepared: &Prepared,
    drivers: &Drivers,
) -> Result<Renderer, BuildError> {
    Renderer::new(
        &prepared.town,
        rig_for(scenario, drivers)?,
        scenario.traffic.seed,
    )
    .map_err(|source| BuildError::Camera {
        scenario: scenario.name.clone(),
        source,
    })
}

/// What to run: a scenario file and what is given over it.
#[derive(Debug, Clone, Copy)]
pub struct RunRequest<'a> {
    /// The scenario file.
    pub scenario: &'a Path,
    /// Delay and traffic over the scenario's.
    pub overrides: &'a Overrides,
    /// A fixed input scale (fraction of S0) over the scenario's selector.
    pub scale: Option<f64>,
    /// Record an MCAP log here with these options (else the scenario's
    /// `[outputs]` decide).
    pub record: Option<(&'a Path, RecordOptions)>,
    /// Render the rig at every camera tick even if nothing needs it (what
    /// data collection costs; shows in the time split).
    pub render_every_frame: bool,
    /// Stop after this many ticks (the route, the timeout and the
    /// terminations still end it earlier).
    pub max_ticks: Option<u64>,
    /// Open the scenario's camera even if nothing in the run needs it, and
    /// hand it back in [`ScenarioRun::camera`] (to draw a moment of the run
    /// afterwards). It renders during the run only if the driver, the log or
    /// `render_every_frame` asks.
    pub keep_camera: bool,
}

impl<'a> RunRequest<'a> {
    /// The scenario file as it is, with `overrides`: no scale, no log, no tick limit.
    pub fn new(scenario: &'a Path, overrides: &'a Overrides) -> RunRequest<'a> {
        RunRequest {
            scenario,
            overrides,
            scale: None,
            record: None,
            render_every_frame: false,
            max_ticks: None,
            keep_camera: false,
        }
    }
}

/// A finished run and what the user should know about how it ran.
pub struct ScenarioRun {
    /// The result record.
    pub record: RunRecord,
    /// Things that did not go as asked but did not stop the run (a log
    /// recorded without images because no renderer could be opened).
    pub warnings: Vec<String>,
    /// The run's camera, when [`RunRequest::keep_camera`] asked for it.
    pub camera: Option<Renderer>,
}

impl std::fmt::Debug for ScenarioRun {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ScenarioRun")
            .field("record", &self.record)
            .field("warnings", &self.warnings)
            .field("camera", &self.camera.as_ref().map(|c| c.backend()))
            .finish()
    }
}

/// Runs one scenario file with overrides: loads and prepares it, builds its
/// driver, selector, camera (when anything needs images) and recorder, drives
/// it, and finishes the log. `progress` hears where the run stands every half second
/// of simulated time, and once at the end.
pub fn run_scenario(
    request: &RunRequest<'_>,
    drivers: &Drivers,
    progress: &mut dyn FnMut(&RunProgress),
) -> Result<ScenarioRun, BuildError> {
    run_scenario_with(request, drivers, progress, Extras::default())
}

/// What a caller adds to a run of [`run_scenario_with`]: an observer of its own,
/// a selector or a driver in place of the scenario's, a scenario built in memory.
#[derive(Default)]
pub struct Extras<'a> {
    /// Sees every tick after the run's own observers.
    pub observer: Option<&'a mut dyn RunObserver>,
    /// Chooses the scale instead of the scenario's selector (and `RunRequest::scale`).
    pub selector: Option<Box<dyn ResolutionSelector>>,
    /// Drives instead of the driver the scenario names (data collection's noisy expert).
    pub driver: Option<&'a mut dyn Driver>,
    /// The scenario and its prepared town and route, when the caller built
    /// them (data collection, from its cache of towns): then
    /// [`RunRequest::scenario`] only names the scenario in the record, and
    /// its overrides are not applied again.
    pub prebuilt: Option<(&'a Scenario, &'a Prepared)>,
}

/// [`run_scenario`] with [`Extras`] (the remote environment's observer and
/// selector, data collection's driver and towns).
pub fn run_scenario_with(
    request: &RunRequest<'_>,
    drivers: &Drivers,
    progress: &mut dyn FnMut(&RunProgress),
    extras: Extras<'_>,
) -> Result<ScenarioRun, BuildError> {
    let path = request.scenario;
    let loaded;
    let (scenario, prepared) = match extras.prebuilt {
        Some(built) => built,
        None => {
            let scenario = request.overrides.apply(&Scenario::from_file(path)?);
            let prepared = runner::prepare(&scenario).map_err(|source| BuildError::Run {
                path: path.to_path_buf(),
                source: Box::new(source),
            })?;
            loaded = (scenario, prepared);
            (&loaded.0, &loaded.1)
        }
    };
    let mut built_driver;
    let driver: &mut dyn Driver = match extras.driver {
        Some(d) => d,
        None => {
            built_driver = drivers.driver(scenario, prepared)?;
            built_driver.as_mut()
        }
    };
    let mut selector = match extras.selector {
        Some(s) => s,
        None => selector_for(scenario, request.scale)?,
    };
    let record_path = request
        .record
        .map(|(p, o)| (p.to_path_buf(), o))
        .or_else(|| {
            scenario.outputs.record.clone().map(|p| {
                (
                    p,
                    RecordOptions {
                        labels: scenario.outputs.record_labels,
                        ..Default::default()
                    },
                )
            })
        });
    let mut warnings = Vec::new();
    let mut record_opts = record_path.as_ref().map(|(_, o)| *o);
    let wants_images = record_opts.is_some_and(|o| o.camera || o.labels || o.bev);
    let needs_camera = driver.needs().camera;
    let renders = needs_camera || wants_images || request.render_every_frame;
    let mut camera = if renders || request.keep_camera {
        match camera_for(scenario, prepared, drivers) {
            Ok(r) => Some(r),
            Err(e) if !needs_camera && !request.keep_camera => {
                warnings.push(format!(
                    "recording without camera images: {}",
                    error_chain(&e)
                ));
                record_opts = record_opts.map(|_| RecordOptions {
                    camera: false,
                    labels: false,
                    bev: false,
                });
                None
            }
            Err(e) => return Err(e),
        }
    } else {
        None
    };
    let mut recorder = match (&record_path, record_opts) {
        (Some((p, _)), Some(o)) => Some(Recorder::create(p, o, &prepared.town).map_err(
            |source| BuildError::Record {
                path: p.clone(),
                source,
            },
        )?),
        _ => None,
    };
    let mut watch_progress = Progress::new(&mut *progress);
    let mut render_every_frame = RenderEveryFrame;
    let mut observers: Vec<&mut dyn RunObserver> = vec![&mut watch_progress];
    if let Some(rec) = recorder.as_mut() {
        observers.push(rec);
    } else if request.render_every_frame {
        observers.push(&mut render_every_frame);
    }
    if let Some(o) = extras.observer {
        observers.push(o);
    }
    let record = runner::run(
        scenario,
        path,
        RunInputs {
            prepared,
            driver,
            selector: selector.as_mut(),
            camera: camera
                .as_mut()
                .filter(|_| renders)
                .map(|c| c as &mut dyn Camera),
            observers,
            max_ticks: request.max_ticks,
        },
    )
    .map_err(|source| BuildError::Run {
        path: path.to_path_buf(),
        source: Box::new(source),
    })?;
    progress(&RunProgress {
        sim_time_s: record.result.sim_time_s,
        completion_pct: record.result.completion_pct,
        scale: record.result.trace.last().map_or(1.0, |p| p[3]),
    });
    if let (Some(rec), Some((p, _))) = (recorder, &record_path) {
        // The log holds what the run was, not which machine made it: without the CPU's
        // name its bytes are the same on every machine (README, "Determinism").
        let mut result = record.result.clone();
        result.provenance.cpu = None;
        rec.finish(&result).map_err(|source| BuildError::Record {
            path: p.clone(),
            source,
        })?;
    }
    Ok(ScenarioRun {
        record,
        warnings,
        camera: camera.filter(|_| request.keep_camera),
    })
}

/// An error and its causes on one line ("a: b: c").
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut source = e.source();
    while let Some(s) = source {
        text += &format!(": {s}");
        source = s.source();
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = "[map]\nfile = \"town.xodr\"\n[route]\nfile = \"routes.toml\"\nid = 0\n";

    fn scenario(extra: &str) -> Scenario {
        Scenario::from_toml_str(&format!("{MINIMAL}{extra}"), Path::new("s.toml")).unwrap()
    }

    #[test]
    fn each_selector_kind_is_built_with_the_scenario_parameters() {
        let s = scenario(
            "[timing]\nlatency_ms = { \"0.5\" = 30.0, \"1.0\" = 100.0 }\n\
             [resolution]\nselector = \"oracle\"\nlow = 0.5\nhigh = 1.0\nnear_m = 7.0\nfar_m = 20.0\n",
        );
        assert_eq!(
            selector_for(&s, None).unwrap().name(),
            Oracle {
                low: 0.5,
                high: 1.0,
                enter_m: 7.0,
                exit_m: 20.0,
                active: false
            }
            .name()
        );
        let mut la = s.clone();
        la.resolution.selector = SelectorKind::Lookahead;
        let table = LatencyTable::new(&[(0.5, 30.0), (1.0, 100.0)]).unwrap();
        let want = Lookahead {
            enter_m: 7.0,
            exit_m: 20.0,
            ..Lookahead::covering(0.5, 1.0, &table).unwrap()
        };
        assert_eq!(selector_for(&la, None).unwrap().name(), want.name());
        let mut braking = la.clone();
        braking.resolution.selector = SelectorKind::Braking;
        let want = Lookahead {
            enter_m: 7.0,
            exit_m: 20.0,
            ..Lookahead::braking(0.5, 1.0, &table).unwrap()
        };
        assert_eq!(selector_for(&braking, None).unwrap().name(), want.name());
        assert!(want.name().ends_with("-brake3"), "{}", want.name());
        let mut budget = s.clone();
        budget.resolution.selector = SelectorKind::Budget;
        budget.resolution.budget_ms = Some(50.0);
        let mut b = selector_for(&budget, None).unwrap();
        assert_eq!(b.select(&Default::default()), 0.5);
        // A scale given over the scenario fixes it.
        let mut fixed = selector_for(&s, Some(0.75)).unwrap();
        assert_eq!(fixed.name(), Fixed { scale: 0.75 }.name());
        assert_eq!(fixed.select(&Default::default()), 0.75);
    }

    #[test]
    fn selectors_without_latencies_and_bad_scales_are_refused_by_name() {
        let mut s = scenario("[resolution]\nselector = \"lookahead\"\n");
        let e = error_chain(&selector_for(&s, None).err().unwrap());
        assert!(
            e.contains("resolution.selector = \"lookahead\"") && e.contains("timing.latency_ms"),
            "{e}"
        );
        s.resolution.selector = SelectorKind::Braking;
        let e = error_chain(&selector_for(&s, None).err().unwrap());
        assert!(
            e.contains("resolution.selector = \"braking\"") && e.contains("timing.latency_ms"),
            "{e}"
        );
        s.resolution.selector = SelectorKind::Fixed;
        let e = selector_for(&s, Some(1.5)).err().unwrap().to_string();
        assert!(e.contains("--scale 1.5"), "{e}");
    }

    /// A factory that fixes S0 without building anything.
    struct FixedS0(u32, u32);

    impl DriverFactory for FixedS0 {
        fn driver(&self, _: &Scenario, _: &Prepared) -> Result<Box<dyn Driver>, FactoryError> {
            Err("not built in this test".into())
        }
        fn input_size(&self, _: &Scenario) -> Result<Option<(u32, u32)>, FactoryError> {
            Ok(Some((self.0, self.1)))
        }
    }

    #[test]
    fn a_registered_driver_sets_the_rig_and_an_unregistered_one_is_named() {
        let mut s = scenario("");
        assert_eq!(rig_for(&s, &Drivers::new()).unwrap().base_size(), (240, 96));
        s.driver.kind = DriverKind::Policy;
        s.driver.checkpoint = Some("m.safetensors".into());
        let e = rig_for(&s, &Drivers::new()).err().unwrap().to_string();
        assert!(e.contains("driver.kind = \"policy\""), "{e}");
        let drivers = Drivers::new().with(DriverKind::Policy, FixedS0(192, 480));
        let rig = rig_for(&s, &drivers).unwrap();
        assert_eq!(rig.base_size(), (480, 192));
        assert_eq!(rig.crop_top_px, 48);
        let odd = Drivers::new().with(DriverKind::Policy, FixedS0(97, 240));
        let e = rig_for(&s, &odd).err().unwrap().to_string();
        assert!(e.contains("240x97"), "{e}");
    }
}
