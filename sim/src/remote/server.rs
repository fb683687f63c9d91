//! The environment server behind `mrdrive serve`: one episode at a time for a
//! client in another process (the Python package in `python/`), over a byte
//! stream. CARLA's shape, a server and a thin client, on a pipe instead of a
//! socket. The frames are [`super::frame`]'s.
//!
//! # The protocol
//! Requests (`op`):
//! - `reset`: `{"op": "reset", "scenario": PATH, "seed": u64|null, "delay_ms":
//!   f64|null, "vehicles": u32|null, "pedestrians": u32|null, "scale": f64|null,
//!   "agent_scale": bool, "camera": bool, "classes": bool, "record": PATH|null}`: ends any episode under way and starts
//!   one; the answer is the first observation. `scale` fixes the input scale (or,
//!   with `agent_scale`, is the first one); null keeps the scenario's selector.
//!   `camera: false` renders nothing (observations without an image); `classes: true`
//!   adds the class image (WoR's ids 0-5, one byte a pixel) after the RGB bytes.
//! - `step`: `{"op": "step", "control": [steer, throttle, brake], "scale": f64|null}`:
//!   the control for the observation just sent (steer in [-1, 1], throttle and brake
//!   in [0, 1]), or `"action": J` for discrete action J ([`DiscreteActions`]: WoR's
//!   0..27, `dataset::action`, for `mrdrive serve`); `scale`, with `agent_scale`, is
//!   the scale of the next observation.
//! - `spec`: `{"op": "spec", "scenario": PATH, "scales": [f64]}`: the image size at S0
//!   and at each scale (`{"ok": true, "s0": [h, w], "sizes": [[h, w], ...]}`), for
//!   the observation space; starts nothing.
//! - `close`: ends the episode and the server.
//!
//! Answers: `{"ok": true, "obs": {...}, "reward": f64, "done": bool, "info": {...}}`
//! with the image (RGB8, `obs.height x obs.width x 3`) as the payload, or
//! `{"ok": false, "error": TEXT}` with an empty payload. `info` holds the step's
//! infractions, the route completion and the ego's pose; at the end (`done`), also
//! `record`: the same result record as `mrdrive run --json`. The reward is
//! [`super::reward`].
//!
//! A server whose input closes ends its episode (the run thread unwinds) and
//! returns: a client that dies leaves nothing behind.

use std::io::{self, Read, Write};
use std::path::PathBuf;
use std::sync::Mutex;
use std::thread::JoinHandle;

use serde_json::{Value, json};

use super::frame::{read_frame, write_frame};
use super::{Event, Link, RemoteDriver, Since, Snapshot};
use crate::build::Overrides;
use crate::build::{self, Drivers, Extras, FactoryError, RunRequest};
use crate::driver::{Driver, VehicleControl};
use crate::recorder::RecordOptions;
use crate::runner::Prepared;
use crate::scenario::{DriverKind, DriverSpec, Scenario};

/// What a request can fail with: the text the answer's `error` carries.
type Answer = Result<(Value, Vec<u8>), String>;

/// A discrete action space a `step` may name by index instead of a control.
#[derive(Debug, Clone, Copy)]
pub struct DiscreteActions {
    /// How many actions there are (indices `0..count`).
    pub count: usize,
    /// The control of action `j` (`j < count`).
    pub control: fn(usize) -> VehicleControl,
}

/// Hands the one remote driver of an episode to the run.
struct Once(Mutex<Option<RemoteDriver>>);

impl build::DriverFactory for Once {
    fn driver(
        &self,
        _scenario: &Scenario,
        _prepared: &Prepared,
    ) -> Result<Box<dyn Driver>, FactoryError> {
        let d = self.0.lock().unwrap_or_else(|e| e.into_inner()).take();
        d.map(|d| Box::new(d) as Box<dyn Driver>)
            .ok_or_else(|| "the remote driver was already taken".into())
    }
}

/// An episode under way.
struct Episode {
    link: Link,
    thread: JoinHandle<()>,
    completion_pct: f64,
    agent_scale: bool,
}

/// `key` of `v` read by `read` (`None` when absent or null); `what` names the type.
fn opt<T>(
    v: &Value,
    key: &str,
    read: fn(&Value) -> Option<T>,
    what: &str,
) -> Result<Option<T>, String> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(x) => read(x)
            .map(Some)
            .ok_or_else(|| format!("`{key}` must be {what}, got {x}")),
    }
}

fn opt_f64(v: &Value, key: &str) -> Result<Option<f64>, String> {
    opt(v, key, Value::as_f64, "a number")
}

fn opt_u64(v: &Value, key: &str) -> Result<Option<u64>, String> {
    opt(v, key, Value::as_u64, "a whole number >= 0")
}

fn u32_of(v: Option<u64>, key: &str) -> Result<Option<u32>, String> {
    v.map(|n| u32::try_from(n).map_err(|_| format!("`{key}` = {n} is too large")))
        .transpose()
}

fn scale_ok(s: f64) -> Result<f64, String> {
    if s > 0.0 && s <= 1.0 {
        Ok(s)
    } else {
        Err(format!("scale {s} is not in (0, 1]"))
    }
}

/// The scenario file a request names.
fn scenario_path(req: &Value) -> Result<PathBuf, String> {
    req.get("scenario")
        .and_then(Value::as_str)
        .map(PathBuf::from)
        .ok_or_else(|| "`scenario` (a scenario file path) is missing".into())
}

/// The image sizes a `spec` asks for.
fn spec(req: &Value) -> Answer {
    let path = scenario_path(req)?;
    let mut scenario = Scenario::from_file(&path).map_err(|e| build::error_chain(&e))?;
    scenario.driver = DriverSpec::default();
    let rig = build::rig_for(&scenario, &Drivers::new()).map_err(|e| build::error_chain(&e))?;
    let (w0, h0) = rig.base_size();
    let mut sizes = Vec::new();
    for s in req
        .get("scales")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
    {
        let r = s
            .as_f64()
            .ok_or_else(|| format!("`scales` holds {s}, not a number"))?;
        let (w, h) = rig
            .size_at(scale_ok(r)? as f32)
            .ok_or_else(|| format!("scale {r} gives an empty image"))?;
        sizes.push([h, w]);
    }
    Ok((
        json!({"ok": true, "s0": [h0, w0], "sizes": sizes}),
        Vec::new(),
    ))
}

fn since_json(s: &Since) -> Value {
    json!({
        "infractions": s.infractions,
        "completion_pct": s.completion_pct,
        "route_s": s.route_s,
        "ego_pose": s.ego_pose,
    })
}

fn obs_json(s: &Snapshot) -> Value {
    json!({
        "time_s": s.time_s,
        "speed_mps": s.speed_mps,
        "command": s.command,
        "scale": s.scale,
        "height": s.size.0,
        "width": s.size.1,
        "classes": !s.classes.is_empty(),
    })
}

/// The control a `step` asks for: `action` (an index into `actions`) or `control`.
fn control_of(req: &Value, actions: &DiscreteActions) -> Result<VehicleControl, String> {
    if let Some(j) = req.get("action") {
        let j = j
            .as_u64()
            .filter(|&j| (j as usize) < actions.count)
            .ok_or_else(|| {
                format!(
                    "`action` = {j}: a discrete action is 0..{}",
                    actions.count - 1
                )
            })?;
        return Ok((actions.control)(j as usize));
    }
    let c = req
        .get("control")
        .and_then(Value::as_array)
        .ok_or_else(|| {
            format!(
                "`control` must be [steer, throttle, brake] (or `action`: 0..{})",
                actions.count - 1
            )
        })?;
    if c.len() != 3 {
        return Err(format!(
            "`control` must have 3 numbers [steer, throttle, brake], got {}",
            c.len()
        ));
    }
    let v: Vec<f64> = c
        .iter()
        .map(|x| {
            x.as_f64()
                .ok_or_else(|| format!("`control` holds {x}, not a number"))
        })
        .collect::<Result<_, _>>()?;
    let (steer, throttle, brake) = (v[0], v[1], v[2]);
    if !(-1.0..=1.0).contains(&steer)
        || !(0.0..=1.0).contains(&throttle)
        || !(0.0..=1.0).contains(&brake)
    {
        return Err(format!(
            "control {v:?} out of range: steer in [-1, 1], throttle and brake in [0, 1]"
        ));
    }
    Ok(VehicleControl {
        steer: steer as f32,
        throttle: throttle as f32,
        brake: brake as f32,
    })
}

impl Episode {
    /// Starts the episode a `reset` asks for and waits for its first event.
    fn start(req: &Value) -> Result<(Episode, Value, Vec<u8>), String> {
        let scenario = scenario_path(req)?;
        Scenario::from_file(&scenario).map_err(|e| build::error_chain(&e))?;
        let overrides = Overrides {
            delay_ms: opt_f64(req, "delay_ms")?,
            seed: opt_u64(req, "seed")?,
            vehicles: u32_of(opt_u64(req, "vehicles")?, "vehicles")?,
            pedestrians: u32_of(opt_u64(req, "pedestrians")?, "pedestrians")?,
            driver: Some(DriverSpec {
                kind: DriverKind::External,
                checkpoint: None,
                device: None,
                trigger: None,
            }),
        };
        let scale = opt_f64(req, "scale")?.map(scale_ok).transpose()?;
        let agent_scale = req
            .get("agent_scale")
            .and_then(Value::as_bool)
            .unwrap_or(false);
        let record = req.get("record").and_then(Value::as_str).map(PathBuf::from);
        let camera = req.get("camera").and_then(Value::as_bool).unwrap_or(true);
        let classes = req.get("classes").and_then(Value::as_bool).unwrap_or(false);
        let (link, ends) = super::remote(scale.unwrap_or(1.0) as f32, camera, classes);
        let thread = std::thread::Builder::new()
            .name("mrdrive-serve-run".into())
            .spawn(move || {
                let super::RunEnds {
                    done,
                    driver,
                    mut watch,
                    selector,
                } = ends;
                let drivers =
                    Drivers::new().with(DriverKind::External, Once(Mutex::new(Some(driver))));
                let request = RunRequest {
                    scale: if agent_scale { None } else { scale },
                    record: record.as_deref().map(|p| (p, RecordOptions::default())),
                    ..RunRequest::new(&scenario, &overrides)
                };
                let extras = Extras {
                    observer: Some(&mut watch),
                    selector: agent_scale.then(|| Box::new(selector) as _),
                    ..Extras::default()
                };
                let outcome = build::run_scenario_with(&request, &drivers, &mut |_| {}, extras)
                    .map(Box::new)
                    .map_err(|e| build::error_chain(&e));
                let _ = done.send(Event::Done(outcome));
            })
            .map_err(|e| format!("cannot start the run thread: {e}"))?;
        let mut episode = Episode {
            link,
            thread,
            completion_pct: 0.0,
            agent_scale,
        };
        let (answer, payload) = episode.next()?;
        Ok((episode, answer, payload))
    }

    /// Ends the run (it unwinds at its next boundary) and waits for its thread.
    fn end(self) {
        let Episode { link, thread, .. } = self;
        drop(link);
        let _ = thread.join();
    }

    /// Waits for the run's next event and turns it into an answer.
    fn next(&mut self) -> Answer {
        match self.link.events.recv() {
            Ok(Event::Observe(snap)) => {
                let reward = super::reward(self.completion_pct, &snap.since);
                self.completion_pct = snap.since.completion_pct;
                let answer = json!({
                    "ok": true,
                    "obs": obs_json(&snap),
                    "reward": reward,
                    "done": false,
                    "info": since_json(&snap.since),
                });
                let mut payload = snap.image;
                payload.extend_from_slice(&snap.classes);
                Ok((answer, payload))
            }
            Ok(Event::Done(Ok(run))) => {
                let mut since = self.link.drain();
                since.completion_pct = run.record.result.completion_pct;
                let reward = super::reward(self.completion_pct, &since);
                self.completion_pct = since.completion_pct;
                let mut info = since_json(&since);
                info["record"] = serde_json::to_value(&run.record).map_err(|e| e.to_string())?;
                info["warnings"] = json!(run.warnings);
                let answer = json!({
                    "ok": true,
                    "obs": null,
                    "reward": reward,
                    "done": true,
                    "info": info,
                });
                Ok((answer, Vec::new()))
            }
            Ok(Event::Done(Err(e))) => Err(e),
            Err(_) => Err("the run ended without a result (it failed inside; see stderr)".into()),
        }
    }

    /// Sets the next scale (if asked), sends the step's control, waits for the next event.
    fn step(&mut self, req: &Value, actions: &DiscreteActions) -> Answer {
        let control = control_of(req, actions)?;
        if let Some(s) = opt_f64(req, "scale")? {
            if !self.agent_scale {
                return Err("`scale` in a step needs an environment made with agent_scale".into());
            }
            *self
                .link
                .next_scale
                .lock()
                .unwrap_or_else(|e| e.into_inner()) = Some(scale_ok(s)? as f32);
        }
        self.link
            .controls
            .send(control)
            .map_err(|_| "the episode has ended; call reset".to_string())?;
        self.next()
    }
}

/// Serves requests from `input` until `close` or the end of input, answering on
/// `output`; `actions` is the discrete action space `step`'s `action` indexes.
/// Only reading or writing a frame fails it: a bad request gets an error answer.
pub fn serve(
    input: &mut impl Read,
    output: &mut impl Write,
    actions: &DiscreteActions,
) -> io::Result<()> {
    let mut episode: Option<Episode> = None;
    let mut finished = false;
    while let Some((req, _)) = read_frame(input)? {
        let op = req.get("op").and_then(Value::as_str).unwrap_or("");
        let answer = match op {
            "reset" => {
                if let Some(e) = episode.take() {
                    e.end();
                }
                Episode::start(&req).map(|(e, a, p)| {
                    finished = false;
                    episode = Some(e);
                    (a, p)
                })
            }
            "step" => match episode.as_mut() {
                Some(_) if finished => Err("the episode has ended; call reset".into()),
                Some(e) => e.step(&req, actions),
                None => Err("no episode: call reset first".into()),
            },
            "spec" => spec(&req),
            "close" => {
                if let Some(e) = episode.take() {
                    e.end();
                }
                write_frame(output, &json!({"ok": true}), &[])?;
                return Ok(());
            }
            other => Err(format!("unknown op `{other}`: use reset, step or close")),
        };
        match answer {
            Ok((a, payload)) => {
                if a["done"] == json!(true) {
                    finished = true;
                }
                write_frame(output, &a, &payload)?;
            }
            Err(e) => write_frame(output, &json!({"ok": false, "error": e}), &[])?,
        }
    }
    if let Some(e) = episode.take() {
        e.end();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_actions() -> DiscreteActions {
        DiscreteActions {
            count: 2,
            control: |j| {
                if j == 0 {
                    VehicleControl::BRAKE
                } else {
                    VehicleControl {
                        steer: 0.0,
                        throttle: 1.0,
                        brake: 0.0,
                    }
                }
            },
        }
    }

    /// Sends `requests` to a server and returns its answers.
    fn exchange(requests: &[Value]) -> Vec<Value> {
        let mut input = Vec::new();
        for r in requests {
            write_frame(&mut input, r, &[]).unwrap();
        }
        let mut output = Vec::new();
        serve(&mut input.as_slice(), &mut output, &two_actions()).unwrap();
        let mut answers = Vec::new();
        let mut rest = output.as_slice();
        while let Some((v, _)) = read_frame(&mut rest).unwrap() {
            answers.push(v);
        }
        answers
    }

    #[test]
    fn bad_requests_get_error_answers_that_say_what_to_send() {
        let answers = exchange(&[
            json!({"op": "step", "control": [0.0, 0.5, 0.0]}),
            json!({"op": "fly"}),
            json!({"op": "reset"}),
            json!({"op": "spec", "scenario": "/no/such/scenario.toml"}),
            json!({"op": "close"}),
        ]);
        assert_eq!(answers.len(), 5);
        assert_eq!(answers[0]["error"], "no episode: call reset first");
        assert!(
            answers[1]["error"]
                .as_str()
                .unwrap()
                .contains("unknown op `fly`")
        );
        assert!(answers[2]["error"].as_str().unwrap().contains("`scenario`"));
        assert!(
            answers[3]["error"]
                .as_str()
                .unwrap()
                .contains("/no/such/scenario.toml")
        );
        assert_eq!(answers[4], json!({"ok": true}));
    }

    #[test]
    fn a_step_is_a_control_in_range_or_an_action_index() {
        let a = two_actions();
        assert_eq!(
            control_of(&json!({"action": 0}), &a).unwrap(),
            VehicleControl::BRAKE
        );
        let e = control_of(&json!({"action": 2}), &a).unwrap_err();
        assert!(e.contains("0..1"), "{e}");
        let c = control_of(&json!({"control": [-0.5, 0.25, 0.0]}), &a).unwrap();
        assert_eq!((c.steer, c.throttle, c.brake), (-0.5, 0.25, 0.0));
        let e = control_of(&json!({"control": [2.0, 0.0, 0.0]}), &a).unwrap_err();
        assert!(e.contains("out of range"), "{e}");
        let e = control_of(&json!({"control": [0.0, 0.0]}), &a).unwrap_err();
        assert!(e.contains("3 numbers"), "{e}");
    }
}
