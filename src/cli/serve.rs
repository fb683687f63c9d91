//! `mrdrive serve`: one environment for a client in another process (the Python
//! package in `python/`), over this process's stdin and stdout. CARLA's shape, a
//! server and a thin client, on a pipe instead of a socket.
//!
//! # The protocol
//! Every message, either way, is a frame: a little-endian `u32` length, that many
//! bytes of UTF-8 JSON, a little-endian `u64` length, that many payload bytes.
//!
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
//!   in [0, 1]), or `"action": J` for WoR's discrete action J (0..27,
//!   `dataset::action`); `scale`, with `agent_scale`, is the scale of the next
//!   observation.
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
//! [`sim::remote::reward`].
//!
//! A server whose stdin closes ends its episode (the run thread unwinds) and exits:
//! a client that dies leaves nothing behind.

use anyhow::{Context, Result, anyhow, bail};
use dataset::action::{self, NUM_ACTIONS};
use serde_json::{Value, json};
use sim::build::{self, Drivers, Extras, FactoryError, RunRequest};
use sim::driver::{Driver, VehicleControl};
use sim::recorder::RecordOptions;
use sim::remote::{self, Event, Link, RemoteDriver, Since, Snapshot};
use sim::runner::{Overrides, Prepared};
use sim::scenario::{DriverKind, DriverSpec, Scenario};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::Mutex;
use std::thread::JoinHandle;

/// Reads one frame; `None` at a clean end of input.
pub fn read_frame(r: &mut impl Read) -> Result<Option<(Value, Vec<u8>)>> {
    let mut len = [0u8; 4];
    match r.read_exact(&mut len) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(None),
        Err(e) => return Err(e.into()),
    }
    let mut text = vec![0u8; u32::from_le_bytes(len) as usize];
    r.read_exact(&mut text)?;
    let mut plen = [0u8; 8];
    r.read_exact(&mut plen)?;
    let n = u64::from_le_bytes(plen);
    if n > 1 << 30 {
        bail!("a payload of {n} bytes: the frame is corrupt");
    }
    let mut payload = vec![0u8; n as usize];
    r.read_exact(&mut payload)?;
    let value = serde_json::from_slice(&text).context("the request is not JSON")?;
    Ok(Some((value, payload)))
}

/// Writes one frame.
pub fn write_frame(w: &mut impl Write, value: &Value, payload: &[u8]) -> std::io::Result<()> {
    let text = serde_json::to_vec(value).expect("a JSON value serialises");
    w.write_all(&(text.len() as u32).to_le_bytes())?;
    w.write_all(&text)?;
    w.write_all(&(payload.len() as u64).to_le_bytes())?;
    w.write_all(payload)?;
    w.flush()
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

impl Episode {
    /// Ends the run (it unwinds at its next boundary) and waits for its thread.
    fn end(self) {
        let Episode { link, thread, .. } = self;
        drop(link);
        let _ = thread.join();
    }
}

/// `key` of `v` read by `read` (`None` when absent or null); `what` names the type.
fn opt<T>(v: &Value, key: &str, read: fn(&Value) -> Option<T>, what: &str) -> Result<Option<T>> {
    match v.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(x) => read(x)
            .map(Some)
            .ok_or_else(|| anyhow!("`{key}` must be {what}, got {x}")),
    }
}

fn opt_f64(v: &Value, key: &str) -> Result<Option<f64>> {
    opt(v, key, Value::as_f64, "a number")
}

fn opt_u64(v: &Value, key: &str) -> Result<Option<u64>> {
    opt(v, key, Value::as_u64, "a whole number >= 0")
}

fn u32_of(v: Option<u64>, key: &str) -> Result<Option<u32>> {
    v.map(|n| u32::try_from(n).map_err(|_| anyhow!("`{key}` = {n} is too large")))
        .transpose()
}

fn scale_ok(s: f64) -> Result<f64> {
    if s > 0.0 && s <= 1.0 {
        Ok(s)
    } else {
        bail!("scale {s} is not in (0, 1]")
    }
}

/// The image sizes a `spec` asks for.
fn spec(req: &Value) -> Result<(Value, Vec<u8>)> {
    let path = PathBuf::from(
        req.get("scenario")
            .and_then(Value::as_str)
            .ok_or_else(|| anyhow!("`scenario` (a scenario file path) is missing"))?,
    );
    let mut scenario =
        Scenario::from_file(&path).map_err(|e| anyhow!("{}", build::error_chain(&e)))?;
    scenario.driver = DriverSpec::default();
    let rig = build::rig_for(&scenario, &Drivers::new())
        .map_err(|e| anyhow!("{}", build::error_chain(&e)))?;
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
            .ok_or_else(|| anyhow!("`scales` holds {s}, not a number"))?;
        let (w, h) = rig
            .size_at(scale_ok(r)? as f32)
            .ok_or_else(|| anyhow!("scale {r} gives an empty image"))?;
        sizes.push([h, w]);
    }
    Ok((
        json!({"ok": true, "s0": [h0, w0], "sizes": sizes}),
        Vec::new(),
    ))
}

/// Starts the episode a `reset` asks for and waits for its first event.
fn start(req: &Value) -> Result<(Episode, Value, Vec<u8>)> {
    let scenario = PathBuf::from(
        req.get("scenario")
            .and_then(Value::as_str)
            .ok_or_else(|| anyhow!("`scenario` (a scenario file path) is missing"))?,
    );
    Scenario::from_file(&scenario).map_err(|e| anyhow!("{}", build::error_chain(&e)))?;
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
    let (link, ends) = remote::remote(scale.unwrap_or(1.0) as f32, camera, classes);
    let thread = std::thread::Builder::new()
        .name("mrdrive-serve-run".into())
        .spawn(move || {
            let remote::RunEnds {
                done,
                driver,
                mut watch,
                selector,
            } = ends;
            let drivers = Drivers::new().with(DriverKind::External, Once(Mutex::new(Some(driver))));
            let request = RunRequest {
                scenario: &scenario,
                overrides: &overrides,
                scale: if agent_scale { None } else { scale },
                record: record.as_deref().map(|p| (p, RecordOptions::default())),
                render_every_frame: false,
            };
            let extras = Extras {
                observer: Some(&mut watch),
                selector: agent_scale.then(|| Box::new(selector) as _),
            };
            let outcome = build::run_scenario_with(&request, &drivers, &mut |_| {}, extras)
                .map(Box::new)
                .map_err(|e| build::error_chain(&e));
            let _ = done.send(Event::Done(outcome));
        })
        .context("cannot start the run thread")?;
    let mut episode = Episode {
        link,
        thread,
        completion_pct: 0.0,
        agent_scale,
    };
    let (answer, payload) = episode.next()?;
    Ok((episode, answer, payload))
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

impl Episode {
    /// Waits for the run's next event and turns it into an answer.
    fn next(&mut self) -> Result<(Value, Vec<u8>)> {
        match self.link.events.recv() {
            Ok(Event::Observe(snap)) => {
                let reward = remote::reward(self.completion_pct, &snap.since);
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
                let reward = remote::reward(self.completion_pct, &since);
                self.completion_pct = since.completion_pct;
                let mut info = since_json(&since);
                info["record"] = serde_json::to_value(&run.record)?;
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
            Ok(Event::Done(Err(e))) => bail!("{e}"),
            Err(_) => bail!("the run ended without a result (it failed inside; see stderr)"),
        }
    }

    /// Sends a control (and the next scale) and waits for the next event.
    fn step(&mut self, req: &Value) -> Result<(Value, Vec<u8>)> {
        if let Some(j) = req.get("action") {
            let j = j
                .as_u64()
                .filter(|&j| (j as usize) < NUM_ACTIONS)
                .ok_or_else(|| {
                    anyhow!(
                        "`action` = {j}: a discrete action is 0..{}",
                        NUM_ACTIONS - 1
                    )
                })?;
            let control = match action::action(j as usize) {
                action::Action::Brake => VehicleControl::BRAKE,
                action::Action::Drive { steer, throttle } => VehicleControl {
                    steer,
                    throttle,
                    brake: 0.0,
                },
            };
            return self.send(req, control);
        }
        let c = req
            .get("control")
            .and_then(Value::as_array)
            .ok_or_else(|| {
                anyhow!("`control` must be [steer, throttle, brake] (or `action`: 0..27)")
            })?;
        if c.len() != 3 {
            bail!(
                "`control` must have 3 numbers [steer, throttle, brake], got {}",
                c.len()
            );
        }
        let v: Vec<f64> = c
            .iter()
            .map(|x| {
                x.as_f64()
                    .ok_or_else(|| anyhow!("`control` holds {x}, not a number"))
            })
            .collect::<Result<_>>()?;
        let (steer, throttle, brake) = (v[0], v[1], v[2]);
        if !(-1.0..=1.0).contains(&steer)
            || !(0.0..=1.0).contains(&throttle)
            || !(0.0..=1.0).contains(&brake)
        {
            bail!("control {v:?} out of range: steer in [-1, 1], throttle and brake in [0, 1]");
        }
        let control = VehicleControl {
            steer: steer as f32,
            throttle: throttle as f32,
            brake: brake as f32,
        };
        self.send(req, control)
    }

    /// Sets the next scale (if asked), sends `control`, waits for the next event.
    fn send(&mut self, req: &Value, control: VehicleControl) -> Result<(Value, Vec<u8>)> {
        if let Some(s) = opt_f64(req, "scale")? {
            if !self.agent_scale {
                bail!("`scale` in a step needs an environment made with agent_scale");
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
            .map_err(|_| anyhow!("the episode has ended; call reset"))?;
        self.next()
    }
}

/// Runs the server on stdin/stdout until `close` or the end of input.
pub fn serve() -> Result<()> {
    let stdin = std::io::stdin();
    let stdout = std::io::stdout();
    let (mut input, mut output) = (stdin.lock(), stdout.lock());
    let mut episode: Option<Episode> = None;
    let mut finished = false;
    while let Some((req, _)) = read_frame(&mut input)? {
        let op = req.get("op").and_then(Value::as_str).unwrap_or("");
        let answer = match op {
            "reset" => {
                if let Some(e) = episode.take() {
                    e.end();
                }
                start(&req).map(|(e, a, p)| {
                    finished = false;
                    episode = Some(e);
                    (a, p)
                })
            }
            "step" => match episode.as_mut() {
                Some(_) if finished => Err(anyhow!("the episode has ended; call reset")),
                Some(e) => e.step(&req),
                None => Err(anyhow!("no episode: call reset first")),
            },
            "spec" => spec(&req),
            "close" => {
                if let Some(e) = episode.take() {
                    e.end();
                }
                write_frame(&mut output, &json!({"ok": true}), &[])?;
                return Ok(());
            }
            other => Err(anyhow!("unknown op `{other}`: use reset, step or close")),
        };
        match answer {
            Ok((a, payload)) => {
                if a["done"] == json!(true) {
                    finished = true;
                }
                write_frame(&mut output, &a, &payload)?;
            }
            Err(e) => write_frame(
                &mut output,
                &json!({"ok": false, "error": format!("{e:#}")}),
                &[],
            )?,
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

    #[test]
    fn frames_round_trip_and_a_truncated_frame_is_an_error() {
        let mut buf = Vec::new();
        write_frame(
            &mut buf,
            &json!({"op": "step", "control": [0.0, 0.5, 0.0]}),
            &[1, 2, 3],
        )
        .unwrap();
        let (v, p) = read_frame(&mut buf.as_slice()).unwrap().unwrap();
        assert_eq!(v["op"], "step");
        assert_eq!(p, vec![1, 2, 3]);
        assert!(read_frame(&mut [].as_slice()).unwrap().is_none());
        let truncated: &[u8] = &buf[..buf.len() - 1];
        assert!(read_frame(&mut &*truncated).is_err());
    }
}
