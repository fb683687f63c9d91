//! Writing a run's MCAP log: the channels and schemas, one call per topic,
//! the result as metadata at the end.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::{Path, PathBuf};

use serde_json::{Value, json};
use world::{ActorKind, ActorSnapshot, LightState, MarkColor, Town, Vec3};

use super::NS;
use crate::camera::Camera;
use crate::driver::{RgbImage, VehicleControl};
use crate::error::RunError;
use crate::monitors::Infraction;
use crate::observe::{RunObserver, TickView};

/// Foxglove schemas, embedded (see `sim/schemas/foxglove/README.md`).
const COMPRESSED_IMAGE: &str = include_str!("../../../schemas/foxglove/CompressedImage.json");
const FRAME_TRANSFORM: &str = include_str!("../../../schemas/foxglove/FrameTransform.json");
const LOG: &str = include_str!("../../../schemas/foxglove/Log.json");
const SCENE_UPDATE: &str = include_str!("../../../schemas/foxglove/SceneUpdate.json");

/// Our own small schemas for the plain data topics.
const CONTROL_SCHEMA: &str = r#"{"title":"mrdrive.Control","type":"object","properties":{
"computed":{"type":["object","null"],"description":"control computed at this tick's boundary (null between boundaries)","properties":{"steer":{"type":"number"},"throttle":{"type":"number"},"brake":{"type":"number"}}},
"applied":{"type":"object","description":"control latched and in force during the next step","properties":{"steer":{"type":"number"},"throttle":{"type":"number"},"brake":{"type":"number"}}}}}"#;
const EGO_SCHEMA: &str = r#"{"title":"mrdrive.EgoState","type":"object","properties":{
"speed_mps":{"type":"number"},"command":{"type":"string"},"command_id":{"type":"integer"},"scale":{"type":"number"},"latency_ms":{"type":"number"},
"x":{"type":"number"},"y":{"type":"number"},"heading_rad":{"type":"number"}}}"#;
const INFRACTION_SCHEMA: &str = r#"{"title":"mrdrive.Infraction","type":"object","properties":{
"tick":{"type":"integer"},"time_s":{"type":"number"},"kind":{"type":"string"},"position":{"type":"array","items":{"type":"number"}},"detail":{"type":"string"}}}"#;

const TOUCH_SCHEMA: &str = r#"{"title":"mrdrive.Touch","type":"object","properties":{
"tick":{"type":"integer"},"time_s":{"type":"number"},"with":{"type":"string","enum":["vehicle","pedestrian","map","kerb"]},"actor":{"type":["integer","null"]},"what":{"type":"string"},"position":{"type":"array","items":{"type":"number"}},"speed_mps":{"type":"number"},"repeat":{"type":"boolean"},"kerb":{"type":"object","properties":{"front_axle":{"type":"boolean"},"height_m":{"type":"number"},"angle_deg":{"type":"number"},"speed_mps":{"type":"array","items":{"type":"number"}}}},"left_tick":{"type":["integer","null"]}}}"#;

/// Side of the square bird's-eye view image (pixels).
pub const BEV_SIZE_PX: u32 = 192;
/// Width of ground the bird's-eye view covers, centred on the ego (metres).
pub const BEV_EXTENT_M: f32 = 48.0;

/// What to record besides the always-recorded state topics.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordOptions {
    /// The policy's camera view.
    pub camera: bool,
    /// The class image.
    pub labels: bool,
    /// The bird's-eye view.
    pub bev: bool,
}

impl Default for RecordOptions {
    fn default() -> Self {
        Self {
            camera: true,
            labels: false,
            bev: true,
        }
    }
}

/// A recording failed.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The file could not be created or written.
    #[error("cannot write the log {path}: {message}")]
    Io {
        /// The log file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

/// Channel ids of the topics.
#[derive(Debug, Clone, Copy)]
struct Channels {
    camera: u16,
    labels: u16,
    bev: u16,
    tf: u16,
    map: u16,
    actors: u16,
    control: u16,
    ego: u16,
    log: u16,
    events: u16,
    touches: u16,
}

/// Writes one run's MCAP log.
pub struct Recorder<W: Write + Seek = BufWriter<File>> {
    writer: mcap::Writer<W>,
    channels: Channels,
    options: RecordOptions,
    path: PathBuf,
    sequence: u32,
    /// Reused PNG buffer.
    png: Vec<u8>,
    /// Reused class-image buffer.
    label_image: RgbImage,
}

fn io_error(path: &Path, e: impl std::fmt::Display) -> RecordError {
    RecordError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// A Foxglove `Time` from nanoseconds.
fn time(t_ns: u64) -> Value {
    json!({ "sec": t_ns / NS, "nsec": t_ns % NS })
}

fn vec3(v: Vec3) -> Value {
    json!({ "x": v.x, "y": v.y, "z": v.z })
}

/// A quaternion for a rotation of `yaw` (radians) about +z.
fn yaw_quaternion(yaw: f32) -> Value {
    json!({ "x": 0.0, "y": 0.0, "z": (yaw / 2.0).sin(), "w": (yaw / 2.0).cos() })
}

fn color(r: f32, g: f32, b: f32, a: f32) -> Value {
    json!({ "r": r, "g": g, "b": b, "a": a })
}

fn light_color(state: LightState) -> Value {
    match state {
        LightState::Red => color(0.9, 0.1, 0.1, 1.0),
        LightState::Yellow => color(0.95, 0.8, 0.1, 1.0),
        LightState::Green => color(0.1, 0.85, 0.2, 1.0),
    }
}

/// A scene entity with every required field, the primitives given.
fn entity(t_ns: u64, id: &str, primitives: Value) -> Value {
    let mut e = json!({
        "timestamp": time(t_ns), "frame_id": "world", "id": id,
        "lifetime": { "sec": 0, "nsec": 0 }, "frame_locked": false, "metadata": [],
        "arrows": [], "cubes": [], "spheres": [], "cylinders": [], "lines": [],
        "triangles": [], "texts": [], "models": []
    });
    if let (Some(e), Some(p)) = (e.as_object_mut(), primitives.as_object()) {
        for (k, v) in p {
            e.insert(k.clone(), v.clone());
        }
    }
    e
}

fn line_strip(points: &[Vec3], thickness: f32, c: Value) -> Value {
    json!({
        "type": 0, "pose": { "position": vec3(Vec3::ZERO), "orientation": yaw_quaternion(0.0) },
        "thickness": thickness, "scale_invariant": false,
        "points": points.iter().map(|p| vec3(*p)).collect::<Vec<_>>(),
        "color": c, "colors": [], "indices": []
    })
}

fn cube(center: Vec3, yaw: f32, size: Vec3, c: Value) -> Value {
    json!({ "pose": { "position": vec3(center), "orientation": yaw_quaternion(yaw) }, "size": vec3(size), "color": c })
}

impl Recorder<BufWriter<File>> {
    /// Creates the log file and writes the static map into it.
    pub fn create(path: &Path, options: RecordOptions, town: &Town) -> Result<Self, RecordError> {
        let file = File::create(path).map_err(|e| io_error(path, e))?;
        Self::new(BufWriter::new(file), path, options, town)
    }
}

impl<W: Write + Seek> Recorder<W> {
    /// Starts a log on `sink` (`path` is only used in messages).
    pub fn new(
        sink: W,
        path: &Path,
        options: RecordOptions,
        town: &Town,
    ) -> Result<Self, RecordError> {
        let opts = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(3)
            .compression_threads(0)
            .profile("")
            .library(format!("mrdrive {}", env!("CARGO_PKG_VERSION")));
        let mut writer = opts.create(sink).map_err(|e| io_error(path, e))?;
        let mut channel = |topic: &str, schema: &str, data: &str| -> Result<u16, RecordError> {
            let schema_id = writer
                .add_schema(schema, "jsonschema", data.as_bytes())
                .map_err(|e| io_error(path, e))?;
            writer
                .add_channel(schema_id, topic, "json", &BTreeMap::new())
                .map_err(|e| io_error(path, e))
        };
        let channels = Channels {
            camera: channel(
                "/camera/image",
                "foxglove.CompressedImage",
                COMPRESSED_IMAGE,
            )?,
            labels: channel(
                "/camera/labels",
                "foxglove.CompressedImage",
                COMPRESSED_IMAGE,
            )?,
            bev: channel("/bev/image", "foxglove.CompressedImage", COMPRESSED_IMAGE)?,
            tf: channel("/tf", "foxglove.FrameTransform", FRAME_TRANSFORM)?,
            map: channel("/scene/map", "foxglove.SceneUpdate", SCENE_UPDATE)?,
            actors: channel("/scene/actors", "foxglove.SceneUpdate", SCENE_UPDATE)?,
            control: channel("/control", "mrdrive.Control", CONTROL_SCHEMA)?,
            ego: channel("/ego", "mrdrive.EgoState", EGO_SCHEMA)?,
            log: channel("/infractions", "foxglove.Log", LOG)?,
            events: channel(
                "/infractions/events",
                "mrdrive.Infraction",
                INFRACTION_SCHEMA,
            )?,
            touches: channel("/contacts", "mrdrive.Touch", TOUCH_SCHEMA)?,
        };
        let mut recorder = Self {
            writer,
            channels,
            options,
            path: path.to_path_buf(),
            sequence: 0,
            png: Vec::new(),
            label_image: RgbImage::default(),
        };
        recorder.map(town)?;
        Ok(recorder)
    }

    fn write(&mut self, channel: u16, t_ns: u64, value: &Value) -> Result<(), RecordError> {
        let data = serde_json::to_vec(value).map_err(|e| io_error(&self.path, e))?;
        self.write_bytes(channel, t_ns, &data)
    }

    fn write_bytes(&mut self, channel: u16, t_ns: u64, data: &[u8]) -> Result<(), RecordError> {
        self.sequence += 1;
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: t_ns,
            publish_time: t_ns,
        };
        self.writer
            .write_to_known_channel(&header, data)
            .map_err(|e| io_error(&self.path, e))
    }

    /// The static map: lanes (grey centrelines), markings, stop lines, junctions.
    fn map(&mut self, town: &Town) -> Result<(), RecordError> {
        let mut lines = Vec::new();
        for lane in &town.lanes {
            lines.push(line_strip(
                &lane.centerline,
                0.05,
                color(0.5, 0.5, 0.55, 0.6),
            ));
        }
        for m in &town.markings {
            let c = match m.color {
                MarkColor::White => color(0.95, 0.95, 0.95, 1.0),
                MarkColor::Yellow => color(0.95, 0.8, 0.1, 1.0),
            };
            lines.push(line_strip(&m.points, m.width_m.max(0.1), c));
        }
        for light in &town.lights {
            for stop in &light.stop_lines {
                lines.push(line_strip(&stop.ends, 0.3, color(0.9, 0.9, 0.9, 1.0)));
            }
        }
        for j in &town.junctions {
            let mut outline: Vec<Vec3> = j.outline.iter().map(|p| p.extend(0.0)).collect();
            if let Some(first) = outline.first().copied() {
                outline.push(first);
            }
            lines.push(line_strip(&outline, 0.1, color(0.3, 0.5, 0.9, 0.8)));
        }
        let update =
            json!({ "deletions": [], "entities": [entity(0, "map", json!({ "lines": lines }))] });
        let channel = self.channels.map;
        self.write(channel, 0, &update)
    }

    /// The ego's pose as the transform world -> ego.
    pub fn ego_transform(&mut self, t_ns: u64, ego: &ActorSnapshot) -> Result<(), RecordError> {
        let msg = json!({
            "timestamp": time(t_ns), "parent_frame_id": "world", "child_frame_id": "ego",
            "translation": vec3(ego.position), "rotation": yaw_quaternion(ego.heading)
        });
        let channel = self.channels.tf;
        self.write(channel, t_ns, &msg)
    }

    /// Vehicles and pedestrians as boxes, and the lights coloured by state.
    pub fn actors(
        &mut self,
        t_ns: u64,
        actors: &[ActorSnapshot],
        town: &Town,
        lights: &[LightState],
    ) -> Result<(), RecordError> {
        let cubes: Vec<Value> = actors
            .iter()
            .map(|a| {
                let c = match a.kind {
                    ActorKind::Ego => color(0.1, 0.6, 1.0, 1.0),
                    ActorKind::Vehicle => color(0.8, 0.4, 0.2, 1.0),
                    ActorKind::Pedestrian => color(0.9, 0.2, 0.8, 1.0),
                };
                cube(
                    a.position + Vec3::new(0.0, 0.0, a.extent.z / 2.0),
                    a.heading,
                    a.extent,
                    c,
                )
            })
            .chain(town.lights.iter().zip(lights).map(|(l, s)| {
                cube(
                    l.position + Vec3::new(0.0, 0.0, l.head_height_m),
                    l.heading,
                    Vec3::new(0.4, 0.4, 1.0),
                    light_color(*s),
                )
            }))
            .collect();
        let update = json!({ "deletions": [], "entities": [entity(t_ns, "actors", json!({ "cubes": cubes }))] });
        let channel = self.channels.actors;
        self.write(channel, t_ns, &update)
    }

    fn image(
        &mut self,
        channel: u16,
        t_ns: u64,
        frame: &str,
        image: &RgbImage,
    ) -> Result<(), RecordError> {
        use image::ImageEncoder;
        self.png.clear();
        let encoder = image::codecs::png::PngEncoder::new_with_quality(
            &mut self.png,
            image::codecs::png::CompressionType::Fast,
            image::codecs::png::FilterType::Sub,
        );
        encoder
            .write_image(
                &image.data,
                image.width,
                image.height,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(|e| io_error(&self.path, e))?;
        let msg = json!({ "timestamp": time(t_ns), "frame_id": frame, "format": "png", "data": base64(&self.png) });
        self.write(channel, t_ns, &msg)
    }

    /// What this log records besides the state topics.
    pub fn options(&self) -> RecordOptions {
        self.options
    }

    /// The policy's view at the scale in force (if camera recording is on).
    pub fn camera(&mut self, t_ns: u64, image: &RgbImage) -> Result<(), RecordError> {
        if !self.options.camera {
            return Ok(());
        }
        let channel = self.channels.camera;
        self.image(channel, t_ns, "camera", image)
    }

    /// The class image, coloured (if label recording is on).
    pub fn labels(&mut self, t_ns: u64, image: &RgbImage) -> Result<(), RecordError> {
        if !self.options.labels {
            return Ok(());
        }
        let channel = self.channels.labels;
        self.image(channel, t_ns, "camera", image)
    }

    /// The bird's-eye view (if on).
    pub fn bev(&mut self, t_ns: u64, image: &RgbImage) -> Result<(), RecordError> {
        if !self.options.bev {
            return Ok(());
        }
        let channel = self.channels.bev;
        self.image(channel, t_ns, "ego", image)
    }

    /// The control computed at a boundary (if this tick is one) and the one in force.
    pub fn control(
        &mut self,
        t_ns: u64,
        computed: Option<VehicleControl>,
        applied: VehicleControl,
    ) -> Result<(), RecordError> {
        let c = |c: VehicleControl| json!({ "steer": c.steer, "throttle": c.throttle, "brake": c.brake });
        let msg = json!({ "computed": computed.map(c), "applied": c(applied) });
        let channel = self.channels.control;
        self.write(channel, t_ns, &msg)
    }

    /// Speed, route command, active scale and latency in force.
    pub fn ego_state(
        &mut self,
        t_ns: u64,
        ego: &ActorSnapshot,
        command: world::Command,
        scale: f64,
        latency_ms: f64,
    ) -> Result<(), RecordError> {
        let msg = json!({
            "speed_mps": ego.speed_mps, "command": format!("{command:?}"), "command_id": command as u8,
            "scale": scale, "latency_ms": latency_ms,
            "x": ego.position.x, "y": ego.position.y, "heading_rad": ego.heading
        });
        let channel = self.channels.ego;
        self.write(channel, t_ns, &msg)
    }

    /// An infraction, as a log line and as data.
    pub fn infraction(&mut self, t_ns: u64, infraction: &Infraction) -> Result<(), RecordError> {
        let level = if infraction.kind.terminates() { 4 } else { 3 };
        let log = json!({
            "timestamp": time(t_ns), "level": level,
            "message": format!("{} at ({:.1}, {:.1}): {}", infraction.kind.name(), infraction.position[0], infraction.position[1], infraction.detail),
            "name": "monitors", "file": infraction.kind.name(), "line": 0
        });
        let channel = self.channels.log;
        self.write(channel, t_ns, &log)?;
        let data = serde_json::to_value(infraction).map_err(|e| io_error(&self.path, e))?;
        let channel = self.channels.events;
        self.write(channel, t_ns, &data)
    }

    /// Logs one touch of the ego (`/contacts`).
    pub fn touch(
        &mut self,
        t_ns: u64,
        touch: &crate::monitors::contacts::Touch,
    ) -> Result<(), RecordError> {
        let data = serde_json::to_value(touch).map_err(|e| io_error(&self.path, e))?;
        let channel = self.channels.touches;
        self.write(channel, t_ns, &data)
    }

    /// Writes the result record as metadata `result` and closes the file.
    pub fn finish(mut self, result: &impl serde::Serialize) -> Result<W, RecordError> {
        let text = serde_json::to_string(result).map_err(|e| io_error(&self.path, e))?;
        let metadata = mcap::records::Metadata {
            name: "result".into(),
            metadata: BTreeMap::from([("json".to_string(), text)]),
        };
        self.writer
            .write_metadata(&metadata)
            .map_err(|e| io_error(&self.path, e))?;
        self.writer.finish().map_err(|e| io_error(&self.path, e))?;
        let mut sink = self.writer.into_inner();
        sink.flush().map_err(|e| io_error(&self.path, e))?;
        Ok(sink)
    }
}

/// Standard base64 with padding (what Foxglove expects for `bytes` fields).
pub fn base64(data: &[u8]) -> String {
    const TABLE: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let b = [
            chunk[0],
            *chunk.get(1).unwrap_or(&0),
            *chunk.get(2).unwrap_or(&0),
        ];
        let n = (u32::from(b[0]) << 16) | (u32::from(b[1]) << 8) | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(TABLE[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

impl<W: Write + Seek> RunObserver for Recorder<W> {
    /// Logs the tick's infractions and controls; at camera ticks also the
    /// ego, the actors and lights, and the images the options ask for
    /// (rendered by the run's camera at the scale in force).
    fn on_tick(
        &mut self,
        v: &TickView<'_>,
        camera: Option<&mut dyn Camera>,
    ) -> Result<(), RunError> {
        let t_ns = (v.time_s * NS as f64).round() as u64;
        for i in v.infractions {
            self.infraction(t_ns, i)?;
        }
        for t in v.touches {
            self.touch(t_ns, t)?;
        }
        self.control(t_ns, v.computed, v.control)?;
        if !v.camera_frame {
            return Ok(());
        }
        let ego = v.ego();
        self.ego_transform(t_ns, ego)?;
        self.actors(t_ns, v.actors, v.town, v.lights)?;
        self.ego_state(t_ns, ego, v.command, v.scale, v.latency_ms)?;
        let Some(cam) = camera else {
            return Ok(());
        };
        let frame = v.camera_frame();
        let opts = self.options();
        let mut labels = std::mem::take(&mut self.label_image);
        let labelled = if opts.labels {
            cam.render_labelled(&frame, v.scale, &mut labels)
        } else {
            None
        };
        if let Some(image) = labelled {
            let image = image.map_err(RunError::Camera)?;
            self.camera(t_ns, image)?;
            self.labels(t_ns, &labels)?;
        } else if opts.camera {
            let image = cam.render(&frame, v.scale).map_err(RunError::Camera)?;
            self.camera(t_ns, image)?;
        }
        self.label_image = labels;
        if opts.bev
            && let Some(image) = cam.render_bev(&frame, BEV_SIZE_PX, BEV_SIZE_PX, BEV_EXTENT_M)
        {
            let image = image.map_err(RunError::Camera)?;
            self.bev(t_ns, image)?;
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::monitors::InfractionKind;
    use crate::recorder::tick_ns;
    use std::io::Cursor;
    use world::Vec2;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        assert_eq!(base64(b""), "");
        assert_eq!(base64(b"f"), "Zg==");
        assert_eq!(base64(b"fo"), "Zm8=");
        assert_eq!(base64(b"foo"), "Zm9v");
        assert_eq!(base64(b"foobar"), "Zm9vYmFy");
    }

    #[test]
    fn embedded_schemas_match_the_shared_copies() {
        let Some(shared) = world::testdata::shared_subdir(
            "embedded_schemas_match_the_shared_copies",
            "foxglove-schemas",
            "CompressedImage.json",
        ) else {
            return;
        };
        for (name, ours) in [
            ("CompressedImage.json", COMPRESSED_IMAGE),
            ("FrameTransform.json", FRAME_TRANSFORM),
            ("Log.json", LOG),
            ("SceneUpdate.json", SCENE_UPDATE),
        ] {
            let theirs = std::fs::read_to_string(shared.join(name)).unwrap();
            assert_eq!(ours, theirs, "{name} differs from the shared copy");
        }
    }

    pub(crate) fn tiny_town() -> Town {
        Town {
            bounds: (Vec2::ZERO, Vec2::ONE),
            ..Town::empty("tiny")
        }
    }

    /// Records a few ticks of a scripted run into memory.
    pub(crate) fn scripted_log() -> Vec<u8> {
        let town = tiny_town();
        let mut rec = Recorder::new(
            Cursor::new(Vec::new()),
            Path::new("mem.mcap"),
            RecordOptions::default(),
            &town,
        )
        .unwrap();
        let image = crate::render::image::test_pattern(4, 2, 0);
        for tick in 0..40u64 {
            let t = tick_ns(tick, 0.025);
            let ego = ActorSnapshot {
                id: 0,
                kind: ActorKind::Ego,
                position: Vec3::new(tick as f32 * 0.1, 0.0, 0.0),
                heading: 0.0,
                extent: Vec3::new(4.79, 2.16, 1.5),
                speed_mps: 4.0,
                color: 0,
            };
            rec.ego_transform(t, &ego).unwrap();
            rec.control(
                t,
                (tick % 2 == 0).then_some(VehicleControl {
                    steer: 0.1,
                    throttle: 0.5,
                    brake: 0.0,
                }),
                VehicleControl::default(),
            )
            .unwrap();
            if tick == 7 {
                let i = Infraction {
                    tick,
                    time_s: t as f64 / NS as f64,
                    kind: InfractionKind::RedLight,
                    position: [0.7, 0.0],
                    detail: "light 3".into(),
                };
                rec.infraction(t, &i).unwrap();
            }
            if tick == 9 {
                let touch = crate::monitors::contacts::Touch {
                    tick,
                    time_s: t as f64 / NS as f64,
                    with: crate::monitors::contacts::TouchWith::Kerb,
                    actor: None,
                    what: "kerb up".into(),
                    position: [0.9, 0.0],
                    speed_mps: 4.0,
                    repeat: false,
                    kerb: None,
                    left_tick: None,
                };
                rec.touch(t, &touch).unwrap();
            }
            if tick % 2 == 0 {
                rec.camera(t, &image).unwrap();
                rec.actors(t, &[ego], &town, &[]).unwrap();
            }
        }
        rec.finish(&json!({ "completion_pct": 100.0 }))
            .unwrap()
            .into_inner()
    }

    #[test]
    fn two_recordings_of_one_run_are_byte_identical() {
        assert_eq!(scripted_log(), scripted_log());
    }

    #[test]
    fn log_reads_back_with_the_mcap_reader() {
        let bytes = scripted_log();
        let mut topics: BTreeMap<String, usize> = BTreeMap::new();
        for message in mcap::MessageStream::new(&bytes).unwrap() {
            let message = message.unwrap();
            let value: Value = serde_json::from_slice(&message.data).unwrap();
            assert!(value.is_object());
            *topics.entry(message.channel.topic.clone()).or_default() += 1;
        }
        assert_eq!(topics.get("/tf"), Some(&40));
        assert_eq!(topics.get("/camera/image"), Some(&20));
        assert_eq!(topics.get("/scene/map"), Some(&1));
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        assert_eq!(summary.metadata_indexes.len(), 1);
    }
}
