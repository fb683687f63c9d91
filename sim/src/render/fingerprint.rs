//! The render fingerprint: a fixed set of frames whose bytes identify what this
//! machine's renderer draws.
//!
//! A software rasteriser compiles its shaders for the CPU it runs on, so "the
//! same build and backend" does not by itself promise the same pixels. This
//! module renders fixed moments, needing no file: the hand-made demo town and
//! the generated town `gen02`, built in memory. Each camera (the CPU rig at 1.0x
//! and 0.75x, the paper's rig, the top-down view) is rendered and the SHA-256
//! of its colour and class bytes taken. Two machines whose fingerprints agree
//! draw these frames bit for bit alike; `mrdrive render fingerprint` prints it,
//! and every run record carries its digest ([`crate::record::Provenance`]).

use std::fmt::Write as _;
use std::path::Path;
use std::sync::OnceLock;

use glam::Vec3;
use world::map::generator::{GridTownParams, generate_grid_town};
use world::{ActorKind, ActorSnapshot, EgoPose, LightState, Town};

use super::demo;
use super::image::save_png;
use super::renderer::{RenderError, Renderer};
use super::rig::RigConfig;
use crate::driver::RgbImage;
use crate::record::sha256_hex;

/// One rendered frame's identity.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameHash {
    /// What the frame shows, e.g. `demo/cpu-rig@0.75`.
    pub name: String,
    /// Width and height (pixels).
    pub size: (u32, u32),
    /// SHA-256 of the RGB bytes (row-major, 3 bytes a pixel), lower-case hex.
    pub rgb_sha256: String,
    /// SHA-256 of the class-id bytes (one a pixel), lower-case hex.
    pub class_sha256: String,
}

/// The fingerprint: every fixed frame, and one digest over all of them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fingerprint {
    /// The render backend and adapter that drew the frames.
    pub backend: String,
    /// The frames, in a fixed order.
    pub frames: Vec<FrameHash>,
}

impl Fingerprint {
    /// SHA-256 over every frame's name, size and hashes, lower-case hex: the one
    /// value to compare between machines.
    pub fn digest(&self) -> String {
        let lines: String = self
            .frames
            .iter()
            .map(|f| {
                format!(
                    "{} {}x{} {} {}\n",
                    f.name, f.size.0, f.size.1, f.rgb_sha256, f.class_sha256
                )
            })
            .collect();
        sha256_hex(lines.as_bytes())
    }

    /// The short form records carry: the digest's first 16 hex digits.
    pub fn short(&self) -> String {
        self.digest()[..16].to_string()
    }

    /// A table: one line per frame, then the digest.
    pub fn report(&self) -> String {
        let mut s = format!("backend  {}\n", self.backend);
        for f in &self.frames {
            let _ = writeln!(
                s,
                "{:<26} {:>3}x{:<3} rgb {}  class {}",
                f.name,
                f.size.0,
                f.size.1,
                &f.rgb_sha256[..16],
                &f.class_sha256[..16]
            );
        }
        let _ = writeln!(s, "digest   {}", self.digest());
        s
    }
}

/// This process's fingerprint in the short form records carry, rendered on first use
/// (about a quarter of a second with a warm shader cache) and kept; `None` where the
/// frames cannot be rendered.
pub fn this_process() -> Option<String> {
    static SHORT: OnceLock<Option<String>> = OnceLock::new();
    SHORT
        .get_or_init(|| fingerprint(None).ok().map(|f| f.short()))
        .clone()
}

/// One moment to draw: where the ego is, what is around, the lights.
struct Moment {
    name: &'static str,
    town: Town,
    seed: u64,
    ego: EgoPose,
    actors: Vec<ActorSnapshot>,
    lights: Vec<LightState>,
}

/// The demo town's moment (cars and walkers around a junction, red ahead).
fn demo_moment() -> Moment {
    let town = demo::grid_town(3, 3, 100.0, 7);
    let (ego, actors, lights) = demo::demo_state(&town);
    Moment {
        name: "demo",
        town,
        seed: 7,
        ego,
        actors,
        lights,
    }
}

/// The generated town `gen02`, the ego 12 m before its first light's stop
/// line, a car stopped 8 m ahead of it, a walker beside the road, the lights
/// cycling through red, yellow and green by index.
fn gen02_moment() -> Moment {
    let xml = generate_grid_town(&GridTownParams::gen02()).expect("gen02's parameters are valid");
    let town = Town::from_xodr_str(&xml, "gen02").expect("the generator writes a loadable map");
    let stop = town
        .lights
        .iter()
        .flat_map(|l| &l.stop_lines)
        .next()
        .expect("gen02 has signalled stop lines");
    let lane = &town.lanes[stop.lane.0 as usize];
    let at = |ahead_m: f32| {
        let (p, heading, _) = lane.pose_at((stop.s - ahead_m).max(0.0));
        (p.extend(0.0), heading)
    };
    let (position, heading) = at(12.0);
    let (car_at, car_heading) = at(4.0);
    let side = Vec3::new(-heading.sin(), heading.cos(), 0.0);
    let actors = vec![
        ActorSnapshot {
            id: 1,
            kind: ActorKind::Vehicle,
            position: car_at,
            heading: car_heading,
            extent: Vec3::new(4.6, 2.0, 1.5),
            speed_mps: 0.0,
            color: 2,
        },
        ActorSnapshot {
            id: 2,
            kind: ActorKind::Pedestrian,
            position: position + Vec3::new(heading.cos(), heading.sin(), 0.0) * 6.0 - side * 4.5,
            heading: heading + 1.0,
            extent: Vec3::new(0.5, 0.5, 1.8),
            speed_mps: 1.4,
            color: 1,
        },
    ];
    let states = [LightState::Red, LightState::Yellow, LightState::Green];
    let lights = (0..town.lights.len()).map(|i| states[i % 3]).collect();
    Moment {
        name: "gen02",
        town,
        seed: 1,
        ego: EgoPose { position, heading },
        actors,
        lights,
    }
}

/// Renders every fixed frame; with `png_dir`, also writes each as a PNG there
/// (`<moment>_<camera>.png`).
pub fn fingerprint(png_dir: Option<&Path>) -> Result<Fingerprint, RenderError> {
    let mut frames = Vec::new();
    let mut backend = String::new();
    let cameras: [(&str, RigConfig, Option<f32>); 5] = [
        ("cpu-rig@1.0", RigConfig::cpu_default(), Some(1.0)),
        ("cpu-rig@0.75", RigConfig::cpu_default(), Some(0.75)),
        ("paper-rig@1.0", RigConfig::paper(), Some(1.0)),
        ("paper-rig@0.75", RigConfig::paper(), Some(0.75)),
        ("top-down", RigConfig::cpu_default(), None),
    ];
    for m in [demo_moment(), gen02_moment()] {
        let mut renderers: Vec<(RigConfig, Renderer)> = Vec::new();
        for (camera, rig, scale) in &cameras {
            let i = match renderers.iter().position(|(r, _)| r == rig) {
                Some(i) => i,
                None => {
                    renderers.push((*rig, Renderer::new(&m.town, *rig, m.seed)?));
                    renderers.len() - 1
                }
            };
            let r = &mut renderers[i].1;
            backend = r.backend();
            let (rgb, class) = match scale {
                Some(s) => r.render_rig(&m.ego, &m.actors, &m.lights, *s)?,
                None => r.render_top_down(&m.ego, &m.actors, &m.lights, 160, 160, 60.0)?,
            };
            let name = format!("{}/{camera}", m.name);
            if let Some(dir) = png_dir {
                let file = dir.join(format!("{}_{camera}.png", m.name));
                save_png(rgb, &file).map_err(|e| {
                    RenderError::Readback(format!("writing {}: {e}", file.display()))
                })?;
            }
            frames.push(frame_hash(name, rgb, &class.data));
        }
    }
    Ok(Fingerprint { backend, frames })
}

fn frame_hash(name: String, rgb: &RgbImage, class: &[u8]) -> FrameHash {
    FrameHash {
        name,
        size: (rgb.width, rgb.height),
        rgb_sha256: sha256_hex(&rgb.data),
        class_sha256: sha256_hex(class),
    }
}
