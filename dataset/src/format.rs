//! The on-disk dataset: a JSON index and one safetensors shard per episode.
//!
//! ```text
//! DIR/dataset.json                 the index (format, S0, views, episodes)
//! DIR/episode-00000.safetensors    one driven episode: images, classes, state
//! DIR/labels-00000.safetensors     its action values (written by the labeller)
//! ```
//!
//! Shard tensors, N frames, V camera views, S0 = W x H pixels, A actor rows:
//!
//! | name | dtype | shape | what |
//! | --- | --- | --- | --- |
//! | `images` | U8 | total bytes | frame `i`'s images, zstd-compressed: bytes `offsets[i]..offsets[i + 1]` decompress to its `rgb` (V x H x W x 3, the stitched rig image at S0, sRGB) followed by its `classes` (V x H x W, WoR class ids 0-5, `sim::render::classes::WorClass`) |
//! | `offsets` | U64 | N + 1 | where each frame's compressed images start in `images` (the last: the total) |
//! | `ego` | F32 | N x 4 | x, y (metres, OpenDRIVE frame), yaw (radians), speed (m/s) |
//! | `command` | U8 | N | the route command (`world::Command` as u8) |
//! | `route` | F32 | N x 2 | route index reached, route distance of the ego (metres) |
//! | `tick` | U32 | N | the loop tick of the frame |
//! | `actors` | F32 | N x A x 8 | kind (0 padding, 1 vehicle, 2 pedestrian), id, x, y, yaw, length, width, speed |
//! | `lights` | U8 | N x L | every light's state (0 red, 1 yellow, 2 green), by `LightIdx` |
//!
//! The images are compressed frame by frame (zstd level 3, about 27 times
//! smaller for our rendered towns): a frame is read and decompressed on its own
//! (about 0.1 ms), so a loader still reads frames at random.
//!
//! Frames are `frame_every_ticks` apart (10 ticks = 0.25 s at 40 Hz), so the
//! world state of frame `i + k` is the "on rails" future of frame `i` at
//! `k x 0.25 s`: the labeller reads it from the same shard.
//!
//! Label tensors (`labels-*.safetensors`): `q` F32 N x V x 6 x 4 x 28 (raw
//! action values per command, speed bin and action) and `valid` U8 N (0 for
//! the last frames, whose future was not driven). Its metadata names the
//! label version; a label file of another version is refused.
//!
//! Files are written under a temporary name and renamed, and the index is
//! rewritten (also by rename) only after an episode is complete, so a killed
//! collection loses at most the episode in progress. See `docs/dataset.md`
//! for reading a dataset from NumPy.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use memmap2::Mmap;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use serde::{Deserialize, Serialize};

/// The format tag in the index and in every shard's metadata.
pub const FORMAT: &str = "mrdrive-dataset/2";
/// The zstd level of a frame's images: level 3 compresses our frames about 27 times
/// at 0.2 ms a frame; higher levels gain under 10 % at 5 times the time.
const IMAGES_ZSTD_LEVEL: i32 = 3;
/// The index file's name inside a dataset directory.
pub const INDEX_FILE: &str = "dataset.json";
/// Numbers per actor row in the `actors` tensor.
pub const ACTOR_FIELDS: usize = 8;

/// A dataset could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The index is missing or malformed.
    #[error("{path}: {msg}")]
    Index {
        /// The index file.
        path: PathBuf,
        /// What is wrong and how to fix it.
        msg: String,
    },
    /// A shard or label file is malformed or does not match the index.
    #[error("{path}: {field}: {msg}")]
    Shard {
        /// The shard file.
        path: PathBuf,
        /// The tensor or metadata field.
        field: String,
        /// What is wrong and how to fix it.
        msg: String,
    },
}

impl DataError {
    fn io(path: &Path, source: std::io::Error) -> DataError {
        DataError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    fn shard(path: &Path, field: &str, msg: impl Into<String>) -> DataError {
        DataError::Shard {
            path: path.to_path_buf(),
            field: field.to_string(),
            msg: msg.into(),
        }
    }
}

/// The route an episode drove: a file and id, or explicit waypoints (random routes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RouteSpec {
    /// The route file, if the route came from one.
    pub file: Option<String>,
    /// The route's id.
    pub id: String,
    /// The waypoints as driven: x, y (metres, OpenDRIVE frame), heading (degrees).
    pub waypoints: Vec<[f32; 3]>,
}

/// One driven episode in the index.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Episode {
    /// The index of the episode in the collection plan.
    pub id: u32,
    /// The shard's file name inside the dataset directory.
    pub shard: String,
    /// Frames in the shard.
    pub frames: u32,
    /// The town's name.
    pub town: String,
    /// The map file the episode drove (as given to the collector).
    pub map: String,
    /// Whether unsignalled junctions got generated lights.
    pub generate_lights: bool,
    /// The route.
    pub route: RouteSpec,
    /// The traffic seed.
    pub seed: u64,
    /// Target NPC vehicles.
    pub vehicles: u32,
    /// Target pedestrians.
    pub pedestrians: u32,
    /// Walkers sent across the road ahead of the ego per minute
    /// (`dataset::collect::CROSSINGS_PER_MIN`; 0 in an index written before it).
    #[serde(default)]
    pub crossings_per_min: f32,
    /// Walkers that were sent.
    #[serde(default)]
    pub walkers_sent: u32,
    /// Simulated time driven (seconds).
    pub sim_time_s: f64,
    /// The label file's name, once labelled.
    pub labels: Option<String>,
}

/// The dataset index (`dataset.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Index {
    /// Always [`FORMAT`].
    pub format: String,
    /// The dataset's name (for example `original` or `retarget`).
    pub name: String,
    /// Image size S0: width, height (pixels).
    pub s0: [u32; 2],
    /// Camera view yaw offsets (degrees, counter-clockwise: positive looks
    /// left); the first is 0 (the rig as mounted).
    pub view_yaws_deg: Vec<f32>,
    /// Loop ticks between frames.
    pub frame_every_ticks: u32,
    /// The loop's tick (seconds).
    pub tick_s: f64,
    /// Finished episodes, in plan order.
    pub episodes: Vec<Episode>,
}

impl Index {
    /// An empty index.
    pub fn new(
        name: &str,
        s0: [u32; 2],
        view_yaws_deg: Vec<f32>,
        frame_every_ticks: u32,
        tick_s: f64,
    ) -> Index {
        Index {
            format: FORMAT.to_string(),
            name: name.to_string(),
            s0,
            view_yaws_deg,
            frame_every_ticks,
            tick_s,
            episodes: Vec::new(),
        }
    }

    /// Seconds between frames.
    pub fn frame_s(&self) -> f64 {
        f64::from(self.frame_every_ticks) * self.tick_s
    }

    /// Reads `DIR/dataset.json`.
    pub fn load(dir: &Path) -> Result<Index, DataError> {
        let path = dir.join(INDEX_FILE);
        if !dir.is_dir() {
            return Err(DataError::Index {
                path,
                msg: format!(
                    "no dataset directory {}; make one with `mrdrive collect` (or `cargo xtask data`)",
                    dir.display()
                ),
            });
        }
        let text = std::fs::read_to_string(&path).map_err(|e| DataError::Index {
            path: path.clone(),
            msg: format!(
                "cannot read the index ({e}); a dataset directory needs the {INDEX_FILE} that `mrdrive collect` writes: collect again into this directory to rebuild it"
            ),
        })?;
        let index: Index = serde_json::from_str(&text).map_err(|e| DataError::Index {
            path: path.clone(),
            msg: format!("not a dataset index ({e}); collect again into a new directory"),
        })?;
        if index.format != FORMAT {
            return Err(DataError::Index {
                path,
                msg: format!(
                    "format is {:?}, this build reads {FORMAT:?}; collect the data again with this build",
                    index.format
                ),
            });
        }
        let bad_size = index.s0[0] < 3 || index.s0[1] < 1;
        if bad_size || index.view_yaws_deg.is_empty() || index.frame_every_ticks == 0 {
            return Err(DataError::Index {
                path,
                msg: "s0, view_yaws_deg or frame_every_ticks is empty or zero; collect again"
                    .into(),
            });
        }
        Ok(index)
    }

    /// Writes `DIR/dataset.json` atomically (temporary file, then rename).
    pub fn save(&self, dir: &Path) -> Result<(), DataError> {
        let path = dir.join(INDEX_FILE);
        let text = serde_json::to_string_pretty(self).expect("the index serialises");
        write_atomic(&path, text.as_bytes())
    }

    /// Total frames over every episode.
    pub fn frames(&self) -> u64 {
        self.episodes.iter().map(|e| u64::from(e.frames)).sum()
    }
}

/// Writes `bytes` to `path` through a temporary file in the same directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), DataError> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes).map_err(|e| DataError::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| DataError::io(path, e))
}

/// A light state as a shard stores it: 0 red, 1 yellow, 2 green.
pub fn light_code(s: world::LightState) -> u8 {
    match s {
        world::LightState::Red => 0,
        world::LightState::Yellow => 1,
        world::LightState::Green => 2,
    }
}

/// The light state of a shard's code (anything but 0 and 1 reads as green).
pub fn light_of_code(code: u8) -> world::LightState {
    match code {
        0 => world::LightState::Red,
        1 => world::LightState::Yellow,
        _ => world::LightState::Green,
    }
}

/// One actor in a frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ActorRow {
    /// 1 vehicle, 2 pedestrian (0 is padding in the file, never returned).
    pub kind: u8,
    /// The actor's id in its run.
    pub id: u32,
    /// Centre (metres, OpenDRIVE frame).
    pub x: f32,
    /// Centre (metres, OpenDRIVE frame).
    pub y: f32,
    /// Heading (radians, counter-clockwise from +x).
    pub yaw: f32,
    /// Length (metres).
    pub length: f32,
    /// Width (metres).
    pub width: f32,
    /// Speed (metres per second).
    pub speed: f32,
}

impl ActorRow {
    /// A vehicle.
    pub const VEHICLE: u8 = 1;
    /// A pedestrian.
    pub const PEDESTRIAN: u8 = 2;

    /// The actor as the rule book's "what is ahead" sees it.
    pub fn view(&self) -> world::rules::ActorView {
        world::rules::ActorView {
            id: self.id,
            kind: if self.kind == ActorRow::PEDESTRIAN {
                world::ActorKind::Pedestrian
            } else {
                world::ActorKind::Vehicle
            },
            position: world::Vec2::new(self.x, self.y),
            yaw: self.yaw,
            speed_mps: self.speed,
            half_length_m: self.length * 0.5,
            half_width_m: self.width * 0.5,
        }
    }
}

/// How far straight ahead of the ego [`pedestrian_ahead`] looks (metres):
/// about 2.5 s at the 8 m/s the expert drives, the time a pedestrian on a
/// crosswalk past a turn is in view before the car must brake.
pub const PEDESTRIAN_AHEAD_M: f32 = 20.0;

/// The distance to the nearest pedestrian straight ahead of `ego` within
/// [`PEDESTRIAN_AHEAD_M`] (metres), by the rule book's "ahead"
/// (`world::rules::nearest_ahead`) in the expert's corridor
/// (`sim::runner::AHEAD_CORRIDOR_M`), on a straight path along the ego's
/// heading: a frame property the training loader can weigh without the map.
pub fn pedestrian_ahead(ego: &EgoRow, actors: &[ActorRow]) -> Option<f32> {
    nearest_straight_ahead(ego, actors, |a| a.kind == ActorRow::PEDESTRIAN)
}

/// Below this speed a vehicle counts as stopped (metres per second).
pub const STOPPED_MPS: f32 = 0.5;

/// The distance to the nearest stopped vehicle (below [`STOPPED_MPS`]) straight ahead
/// of `ego` within [`PEDESTRIAN_AHEAD_M`] (metres), by the same rule as
/// [`pedestrian_ahead`]: a queue at a light, a car waiting to turn.
pub fn stopped_vehicle_ahead(ego: &EgoRow, actors: &[ActorRow]) -> Option<f32> {
    nearest_straight_ahead(ego, actors, |a| {
        a.kind == ActorRow::VEHICLE && a.speed.abs() < STOPPED_MPS
    })
}

/// The nearest of the `actors` that `keep` accepts in the ego's corridor on a straight
/// path along its heading, within [`PEDESTRIAN_AHEAD_M`] (the rule book's
/// `nearest_ahead`).
fn nearest_straight_ahead(
    ego: &EgoRow,
    actors: &[ActorRow],
    keep: impl Fn(&ActorRow) -> bool,
) -> Option<f32> {
    let candidates: Vec<world::rules::ActorView> = actors
        .iter()
        .filter(|a| keep(a))
        .map(ActorRow::view)
        .collect();
    if candidates.is_empty() {
        return None;
    }
    let start = world::Vec2::new(ego.x, ego.y);
    let dir = world::Vec2::from_angle(ego.yaw);
    let path: Vec<world::Vec2> = (0..=PEDESTRIAN_AHEAD_M as usize)
        .map(|k| start + dir * k as f32)
        .collect();
    world::rules::nearest_ahead(
        &path,
        &candidates,
        None,
        sim::runner::AHEAD_CORRIDOR_M,
        PEDESTRIAN_AHEAD_M,
        world::rules::walker_horizon_s(ego.speed),
    )
    .map(|a| a.distance_m)
}

/// The ego's state in a frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EgoRow {
    /// Centre x (metres).
    pub x: f32,
    /// Centre y (metres).
    pub y: f32,
    /// Heading (radians, counter-clockwise from +x).
    pub yaw: f32,
    /// Speed (metres per second).
    pub speed: f32,
}

/// One episode in memory: what a shard holds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Shard {
    /// S0 width and height (pixels).
    pub size: (u32, u32),
    /// Camera views per frame.
    pub views: usize,
    /// `N x V x H x W x 3` bytes.
    pub rgb: Vec<u8>,
    /// `N x V x H x W` WoR class ids.
    pub classes: Vec<u8>,
    /// The ego per frame.
    pub ego: Vec<EgoRow>,
    /// The route command per frame.
    pub command: Vec<u8>,
    /// Route index reached and route distance (metres) per frame.
    pub route: Vec<[f32; 2]>,
    /// The loop tick per frame.
    pub tick: Vec<u32>,
    /// Every other actor per frame.
    pub actors: Vec<Vec<ActorRow>>,
    /// Every light's state per frame (0 red, 1 yellow, 2 green).
    pub lights: Vec<Vec<u8>>,
}

impl Shard {
    /// An empty shard for images of `size` with `views` views.
    pub fn new(size: (u32, u32), views: usize) -> Shard {
        Shard {
            size,
            views,
            ..Shard::default()
        }
    }

    /// Frames held.
    pub fn len(&self) -> usize {
        self.ego.len()
    }

    /// Whether it holds no frame.
    pub fn is_empty(&self) -> bool {
        self.ego.is_empty()
    }

    /// Bytes of one RGB view.
    pub fn rgb_len(&self) -> usize {
        self.size.0 as usize * self.size.1 as usize * 3
    }

    /// Bytes of one class view.
    pub fn class_len(&self) -> usize {
        self.size.0 as usize * self.size.1 as usize
    }

    /// The RGB image of `frame` seen from `view` (`H x W x 3`).
    pub fn rgb(&self, frame: usize, view: usize) -> &[u8] {
        let n = self.rgb_len();
        let at = (frame * self.views + view) * n;
        &self.rgb[at..at + n]
    }

    /// The class image of `frame` seen from `view` (`H x W`).
    pub fn classes(&self, frame: usize, view: usize) -> &[u8] {
        let n = self.class_len();
        let at = (frame * self.views + view) * n;
        &self.classes[at..at + n]
    }

    /// The safetensors bytes of this shard.
    pub fn to_bytes(&self, metadata: &HashMap<String, String>) -> Vec<u8> {
        let n = self.len();
        let (w, h) = (self.size.0 as usize, self.size.1 as usize);
        let a = self.actors.iter().map(Vec::len).max().unwrap_or(0);
        let l = self.lights.first().map_or(0, Vec::len);
        let mut actors = vec![0f32; n * a * ACTOR_FIELDS];
        for (f, rows) in self.actors.iter().enumerate() {
            for (i, r) in rows.iter().enumerate() {
                let at = (f * a + i) * ACTOR_FIELDS;
                actors[at..at + ACTOR_FIELDS].copy_from_slice(&[
                    f32::from(r.kind),
                    r.id as f32,
                    r.x,
                    r.y,
                    r.yaw,
                    r.length,
                    r.width,
                    r.speed,
                ]);
            }
        }
        let ego: Vec<f32> = self
            .ego
            .iter()
            .flat_map(|e| [e.x, e.y, e.yaw, e.speed])
            .collect();
        let route: Vec<f32> = self.route.iter().flatten().copied().collect();
        let lights: Vec<u8> = self.lights.iter().flatten().copied().collect();
        let (frame_rgb, frame_classes) =
            (self.views * self.rgb_len(), self.views * self.class_len());
        let mut images = Vec::new();
        let mut offsets = vec![0u64];
        let mut raw = Vec::with_capacity(frame_rgb + frame_classes);
        // Each frame carries its size and a checksum, so a damaged frame is found.
        let mut zstd =
            zstd::bulk::Compressor::new(IMAGES_ZSTD_LEVEL).expect("a zstd context in memory");
        zstd.set_parameter(zstd::zstd_safe::CParameter::ChecksumFlag(true))
            .expect("zstd takes the checksum flag");
        for f in 0..n {
            raw.clear();
            raw.extend_from_slice(&self.rgb[f * frame_rgb..][..frame_rgb]);
            raw.extend_from_slice(&self.classes[f * frame_classes..][..frame_classes]);
            let packed = zstd
                .compress(&raw)
                .expect("compressing bytes in memory cannot fail");
            images.extend_from_slice(&packed);
            offsets.push(images.len() as u64);
        }
        let _ = (w, h);
        let tensors: Vec<(&str, Dtype, Vec<usize>, &[u8])> = vec![
            ("images", Dtype::U8, vec![images.len()], &images),
            ("offsets", Dtype::U64, vec![n + 1], bytes_of(&offsets)),
            ("ego", Dtype::F32, vec![n, 4], bytes_of(&ego)),
            ("command", Dtype::U8, vec![n], &self.command),
            ("route", Dtype::F32, vec![n, 2], bytes_of(&route)),
            ("tick", Dtype::U32, vec![n], bytes_of(&self.tick)),
            (
                "actors",
                Dtype::F32,
                vec![n, a, ACTOR_FIELDS],
                bytes_of(&actors),
            ),
            ("lights", Dtype::U8, vec![n, l], &lights),
        ];
        serialize(tensors, metadata)
    }

    /// Reads and checks a shard written by [`Shard::to_bytes`], images
    /// included; `s0` and `views` are what the index says.
    pub fn read(path: &Path, s0: [u32; 2], views: usize) -> Result<Shard, DataError> {
        MappedShard::open(path, s0, views)?.into_shard()
    }
}

/// A shard opened by memory map: its state (everything but the images) is
/// read and checked at once; the images stay in the file, and only the
/// pages of the frames asked for are read.
///
/// Dataset files are written under a temporary name and renamed, never
/// changed in place, so the mapped bytes do not change under the map.
#[derive(Debug)]
pub struct MappedShard {
    path: PathBuf,
    map: Mmap,
    /// Where the compressed images start in the file.
    images_at: usize,
    /// Each frame's compressed images within them (N + 1 ends).
    offsets: Vec<u64>,
    /// The state of every frame; its `rgb` and `classes` are empty.
    pub state: Shard,
}

impl MappedShard {
    /// Maps and checks a shard written by [`Shard::to_bytes`]; `s0` and
    /// `views` are what the index says.
    pub fn open(path: &Path, s0: [u32; 2], views: usize) -> Result<MappedShard, DataError> {
        let map = map_file(path)?;
        let st = parse(path, &map)?;
        check_format(path, &st_metadata(path, &map)?)?;
        let n = tensor(path, &st, "ego", Dtype::F32)?.shape()[0];
        let images = tensor(path, &st, "images", Dtype::U8)?;
        let offsets_t = tensor(path, &st, "offsets", Dtype::U64)?;
        expect_shape(path, "offsets", offsets_t.shape(), &[n + 1], "frames")?;
        let offsets: Vec<u64> = offsets_t
            .data()
            .chunks_exact(8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        let ascending = offsets.windows(2).all(|w| w[0] <= w[1]);
        if offsets[0] != 0 || !ascending || offsets[n] != images.data().len() as u64 {
            return Err(DataError::shard(
                path,
                "offsets",
                "not ascending from 0 to the images' length; collect this episode again",
            ));
        }
        // Each compressed frame names its size in its header: check it against the
        // index's S0 and views without decompressing.
        let want = (views * s0[0] as usize * s0[1] as usize * 4) as u64;
        for (f, w) in offsets.windows(2).enumerate() {
            let packed = &images.data()[w[0] as usize..w[1] as usize];
            let holds = match zstd::zstd_safe::get_frame_content_size(packed) {
                Ok(Some(size)) if size == want => continue,
                Ok(Some(size)) => format!("{size} bytes"),
                Ok(None) => "no stated size".into(),
                Err(_) => "no zstd frame".into(),
            };
            return Err(DataError::shard(
                path,
                "images",
                format!(
                    "frame {f} holds {holds}, the index's S0 and views make {want} bytes: this shard is damaged or belongs to another dataset or S0; collect it again"
                ),
            ));
        }
        let ego = tensor(path, &st, "ego", Dtype::F32)?;
        expect_shape(path, "ego", ego.shape(), &[n, 4], "frames")?;
        let command = tensor(path, &st, "command", Dtype::U8)?;
        expect_shape(path, "command", command.shape(), &[n], "frames")?;
        if let Some(c) = command.data().iter().find(|&&c| c > 5) {
            return Err(DataError::shard(
                path,
                "command",
                format!("command {c} is not 0-5; collect again"),
            ));
        }
        let route = tensor(path, &st, "route", Dtype::F32)?;
        expect_shape(path, "route", route.shape(), &[n, 2], "frames")?;
        let tick = tensor(path, &st, "tick", Dtype::U32)?;
        expect_shape(path, "tick", tick.shape(), &[n], "frames")?;
        let actors = tensor(path, &st, "actors", Dtype::F32)?;
        let a = actors.shape().get(1).copied().unwrap_or(0);
        expect_shape(
            path,
            "actors",
            actors.shape(),
            &[n, a, ACTOR_FIELDS],
            "frames",
        )?;
        let lights = tensor(path, &st, "lights", Dtype::U8)?;
        let l = lights.shape().get(1).copied().unwrap_or(0);
        expect_shape(path, "lights", lights.shape(), &[n, l], "frames")?;

        let ego_f = f32s(ego.data());
        let route_f = f32s(route.data());
        let actor_f = f32s(actors.data());
        let mut shard = Shard::new((s0[0], s0[1]), views);
        shard.command = command.data().to_vec();
        shard.tick = tick
            .data()
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        shard.ego = ego_f
            .chunks_exact(4)
            .map(|e| EgoRow {
                x: e[0],
                y: e[1],
                yaw: e[2],
                speed: e[3],
            })
            .collect();
        if shard.ego.iter().any(|e| {
            !(e.x.is_finite() && e.y.is_finite() && e.yaw.is_finite() && e.speed.is_finite())
        }) {
            return Err(DataError::shard(
                path,
                "ego",
                "non-finite values; collect this episode again",
            ));
        }
        shard.route = route_f.chunks_exact(2).map(|r| [r[0], r[1]]).collect();
        shard.actors = actor_f
            .chunks_exact(a.max(1) * ACTOR_FIELDS)
            .take(n)
            .map(|rows| {
                rows.chunks_exact(ACTOR_FIELDS)
                    .filter(|r| r[0] != 0.0)
                    .map(|r| ActorRow {
                        kind: r[0] as u8,
                        id: r[1] as u32,
                        x: r[2],
                        y: r[3],
                        yaw: r[4],
                        length: r[5],
                        width: r[6],
                        speed: r[7],
                    })
                    .collect()
            })
            .collect();
        if a == 0 {
            shard.actors = vec![Vec::new(); n];
        }
        shard.lights = if l == 0 {
            vec![Vec::new(); n]
        } else {
            lights.data().chunks_exact(l).map(<[u8]>::to_vec).collect()
        };
        let images_at = offset_in(&map, images.data());
        Ok(MappedShard {
            path: path.to_path_buf(),
            map,
            images_at,
            offsets,
            state: shard,
        })
    }

    /// The shard's file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Frames held.
    pub fn len(&self) -> usize {
        self.state.len()
    }

    /// Whether it holds no frame.
    pub fn is_empty(&self) -> bool {
        self.state.is_empty()
    }

    /// Every view's images of `frame`, decompressed from the file: the RGB images
    /// (`V x H x W x 3`) followed by the class images (`V x H x W`).
    pub fn frame_images(&self, frame: usize) -> Result<Vec<u8>, DataError> {
        let (a, b) = (
            self.offsets[frame] as usize,
            self.offsets[frame + 1] as usize,
        );
        let packed = &self.map[self.images_at + a..self.images_at + b];
        let views = self.state.views;
        let want = views * (self.state.rgb_len() + self.state.class_len());
        let raw = zstd::bulk::decompress(packed, want).map_err(|e| {
            DataError::shard(
                &self.path,
                "images",
                format!("frame {frame} does not decompress ({e}); collect this episode again"),
            )
        })?;
        if raw.len() != want {
            return Err(DataError::shard(
                &self.path,
                "images",
                format!(
                    "frame {frame} holds {} bytes, the index's S0 and views make {want}; collect this episode again",
                    raw.len()
                ),
            ));
        }
        Ok(raw)
    }

    /// The RGB image (`H x W x 3`) and class image (`H x W`) of `frame` seen from `view`.
    pub fn view_images(&self, frame: usize, view: usize) -> Result<(Vec<u8>, Vec<u8>), DataError> {
        let raw = self.frame_images(frame)?;
        let (rgb, classes) = (self.state.rgb_len(), self.state.class_len());
        let at = self.state.views * rgb;
        Ok((
            raw[view * rgb..][..rgb].to_vec(),
            raw[at + view * classes..][..classes].to_vec(),
        ))
    }

    /// The whole shard in memory, every frame's images decompressed.
    pub fn into_shard(self) -> Result<Shard, DataError> {
        let frame_rgb = self.state.views * self.state.rgb_len();
        let mut rgb = Vec::with_capacity(self.len() * frame_rgb);
        let mut classes = Vec::new();
        for f in 0..self.len() {
            let raw = self.frame_images(f)?;
            rgb.extend_from_slice(&raw[..frame_rgb]);
            classes.extend_from_slice(&raw[frame_rgb..]);
        }
        let mut shard = self.state;
        shard.rgb = rgb;
        shard.classes = classes;
        Ok(shard)
    }
}

/// Action values of one episode: what a label file holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Labels {
    /// Views per frame.
    pub views: usize,
    /// `N x V x 6 x 4 x 28` raw action values.
    pub q: Vec<f32>,
    /// Whether each frame has a label (its whole future was driven).
    pub valid: Vec<bool>,
}

/// Commands, speed bins and actions of one label: 6 x 4 x 28.
pub const Q_PER_VIEW: usize = 6 * 4 * 28;

impl Labels {
    /// The label of `frame` seen from `view`: `[6][4][28]` flattened.
    pub fn q(&self, frame: usize, view: usize) -> &[f32] {
        let at = (frame * self.views + view) * Q_PER_VIEW;
        &self.q[at..at + Q_PER_VIEW]
    }

    /// The safetensors bytes, with the label version in the metadata.
    pub fn to_bytes(&self, label_version: u32, shard: &str) -> Vec<u8> {
        let n = self.valid.len();
        let valid: Vec<u8> = self.valid.iter().map(|&v| u8::from(v)).collect();
        let metadata = HashMap::from([
            ("format".to_string(), FORMAT.to_string()),
            ("label_version".to_string(), label_version.to_string()),
            ("shard".to_string(), shard.to_string()),
        ]);
        serialize(
            vec![
                (
                    "q",
                    Dtype::F32,
                    vec![n, self.views, 6, 4, 28],
                    bytes_of(&self.q),
                ),
                ("valid", Dtype::U8, vec![n], &valid),
            ],
            &metadata,
        )
    }

    /// Reads a label file, refusing another label version or frame count.
    pub fn read(
        path: &Path,
        label_version: u32,
        frames: usize,
        views: usize,
    ) -> Result<Labels, DataError> {
        MappedLabels::open(path, label_version, frames, views).map(|m| m.to_labels())
    }
}

/// A label file opened by memory map: checked once when opened (version,
/// shapes, finite values), then read one label at a time.
#[derive(Debug)]
pub struct MappedLabels {
    map: Mmap,
    q_at: usize,
    views: usize,
    /// Whether each frame has a label (its whole future was driven).
    pub valid: Vec<bool>,
}

impl MappedLabels {
    /// Maps a label file, refusing another label version, frame or view count.
    pub fn open(
        path: &Path,
        label_version: u32,
        frames: usize,
        views: usize,
    ) -> Result<MappedLabels, DataError> {
        let map = map_file(path)?;
        let st = parse(path, &map)?;
        let meta = st_metadata(path, &map)?;
        check_format(path, &meta)?;
        let version = meta
            .get("label_version")
            .map(String::as_str)
            .unwrap_or("none");
        if version != label_version.to_string() {
            return Err(DataError::shard(
                path,
                "label_version",
                format!(
                    "labels are version {version}, this build makes version {label_version}; run `mrdrive label` on the dataset again"
                ),
            ));
        }
        let q = tensor(path, &st, "q", Dtype::F32)?;
        expect_shape(
            path,
            "q",
            q.shape(),
            &[frames, views, 6, 4, 28],
            "frames and views (label again)",
        )?;
        let valid = tensor(path, &st, "valid", Dtype::U8)?;
        expect_shape(
            path,
            "valid",
            valid.shape(),
            &[frames],
            "frames (label again)",
        )?;
        if q.data()
            .chunks_exact(4)
            .any(|b| !f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite())
        {
            return Err(DataError::shard(
                path,
                "q",
                "non-finite action values; run `mrdrive label` again",
            ));
        }
        let valid = valid.data().iter().map(|&v| v != 0).collect();
        let q_at = offset_in(&map, q.data());
        Ok(MappedLabels {
            map,
            q_at,
            views,
            valid,
        })
    }

    /// Writes the label of `frame` seen from `view` (`[6][4][28]` flattened) into `out`.
    pub fn q_into(&self, frame: usize, view: usize, out: &mut [f32]) {
        let at = self.q_at + (frame * self.views + view) * Q_PER_VIEW * 4;
        let bytes = &self.map[at..at + Q_PER_VIEW * 4];
        for (o, b) in out[..Q_PER_VIEW].iter_mut().zip(bytes.chunks_exact(4)) {
            *o = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
    }

    /// The whole label file in memory.
    pub fn to_labels(&self) -> Labels {
        let n = self.valid.len() * self.views * Q_PER_VIEW * 4;
        Labels {
            views: self.views,
            q: f32s(&self.map[self.q_at..self.q_at + n]),
            valid: self.valid.clone(),
        }
    }
}

/// The metadata in a dataset file's header (the format tag, the label
/// version of a label file), read without reading its tensors.
pub fn file_metadata(path: &Path) -> Result<HashMap<String, String>, DataError> {
    let map = map_file(path)?;
    st_metadata(path, &map)
}

/// Maps a whole file read-only.
fn map_file(path: &Path) -> Result<Mmap, DataError> {
    let file = std::fs::File::open(path).map_err(|e| DataError::io(path, e))?;
    // SAFETY: dataset files are replaced by rename, never written in place
    // (`write_atomic`), so the mapped bytes stay as they are while mapped.
    unsafe { Mmap::map(&file) }.map_err(|e| DataError::io(path, e))
}

/// Where `part` (a slice of `whole`) starts in `whole` (bytes).
fn offset_in(whole: &[u8], part: &[u8]) -> usize {
    part.as_ptr() as usize - whole.as_ptr() as usize
}

fn serialize(
    tensors: Vec<(&str, Dtype, Vec<usize>, &[u8])>,
    metadata: &HashMap<String, String>,
) -> Vec<u8> {
    let views: Vec<(String, TensorView<'_>)> = tensors
        .into_iter()
        .map(|(name, dtype, shape, data)| {
            (
                name.to_string(),
                TensorView::new(dtype, shape, data).expect("shapes match the data by construction"),
            )
        })
        .collect();
    let mut meta = metadata.clone();
    meta.entry("format".into())
        .or_insert_with(|| FORMAT.to_string());
    let bytes =
        safetensors::serialize(views, Some(meta)).expect("in-memory serialisation cannot fail");
    canonical_header(bytes)
}

/// The same file with its JSON header's keys in sorted order: safetensors
/// writes the metadata map in hash order, which differs from map to map, and
/// a dataset must be the same bytes for the same plan. The sorted header has
/// the same length, so the data offsets stay as they are.
fn canonical_header(mut bytes: Vec<u8>) -> Vec<u8> {
    fn sorted(v: serde_json::Value) -> serde_json::Value {
        match v {
            serde_json::Value::Object(m) => {
                let tree: std::collections::BTreeMap<String, serde_json::Value> =
                    m.into_iter().map(|(k, v)| (k, sorted(v))).collect();
                serde_json::to_value(tree).expect("a map of JSON values")
            }
            other => other,
        }
    }
    let n = u64::from_le_bytes(bytes[..8].try_into().expect("8 bytes")) as usize;
    let header: serde_json::Value =
        serde_json::from_slice(&bytes[8..8 + n]).expect("safetensors wrote JSON");
    let mut text = serde_json::to_vec(&sorted(header)).expect("JSON serialises");
    assert!(
        text.len() <= n,
        "a sorted header is no longer than the original"
    );
    text.resize(n, b' ');
    bytes[8..8 + n].copy_from_slice(&text);
    bytes
}

fn parse<'a>(path: &Path, bytes: &'a [u8]) -> Result<SafeTensors<'a>, DataError> {
    SafeTensors::deserialize(bytes).map_err(|e| {
        DataError::shard(
            path,
            "header",
            format!("not a readable safetensors file ({e}); it may be truncated: delete it and collect (or label) again"),
        )
    })
}

fn st_metadata(path: &Path, bytes: &[u8]) -> Result<HashMap<String, String>, DataError> {
    let (_, meta) = SafeTensors::read_metadata(bytes).map_err(|e| {
        DataError::shard(
            path,
            "header",
            format!("unreadable header ({e}); it may be truncated: delete it and collect (or label) again"),
        )
    })?;
    Ok(meta.metadata().clone().unwrap_or_default())
}

fn check_format(path: &Path, meta: &HashMap<String, String>) -> Result<(), DataError> {
    match meta.get("format") {
        Some(f) if f == FORMAT => Ok(()),
        other => Err(DataError::shard(
            path,
            "format",
            format!(
                "format is {other:?}, this build reads {FORMAT:?}; collect again with this build"
            ),
        )),
    }
}

fn tensor<'a>(
    path: &Path,
    st: &'a SafeTensors<'a>,
    name: &str,
    dtype: Dtype,
) -> Result<TensorView<'a>, DataError> {
    let t = st.tensor(name).map_err(|_| {
        DataError::shard(
            path,
            name,
            "missing; this is not a complete mrdrive shard: collect this episode again",
        )
    })?;
    if t.dtype() != dtype {
        return Err(DataError::shard(
            path,
            name,
            format!("dtype {:?}, expected {dtype:?}", t.dtype()),
        ));
    }
    Ok(t)
}

fn expect_shape(
    path: &Path,
    name: &str,
    got: &[usize],
    want: &[usize],
    what: &str,
) -> Result<(), DataError> {
    if got == want {
        Ok(())
    } else {
        Err(DataError::shard(
            path,
            name,
            format!(
                "shape {got:?}, expected {want:?} from the index's {what}: this shard belongs to another dataset or S0; collect it again"
            ),
        ))
    }
}

fn bytes_of<T: Copy>(v: &[T]) -> &[u8] {
    // f32 and u32 have no padding and any bit pattern is a valid u8.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<u8>(), std::mem::size_of_val(v)) }
}

fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stopped_vehicle_ahead_is_one_standing_in_the_corridor_in_front() {
        let ego = EgoRow {
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
            speed: 5.0,
        };
        let car = |x: f32, y: f32, speed: f32| ActorRow {
            kind: ActorRow::VEHICLE,
            id: 7,
            x,
            y,
            yaw: 0.0,
            length: 4.5,
            width: 1.9,
            speed,
        };
        let d = stopped_vehicle_ahead(&ego, &[car(12.0, 0.3, 0.0)]).expect("a queue ahead");
        assert!((8.0..12.0).contains(&d), "{d} m to its rear");
        assert_eq!(
            stopped_vehicle_ahead(&ego, &[car(12.0, 0.0, 3.0)]),
            None,
            "moving"
        );
        assert_eq!(
            stopped_vehicle_ahead(&ego, &[car(12.0, 6.0, 0.0)]),
            None,
            "next lane"
        );
        assert_eq!(
            stopped_vehicle_ahead(&ego, &[car(-8.0, 0.0, 0.0)]),
            None,
            "behind"
        );
        assert_eq!(
            stopped_vehicle_ahead(&ego, &[car(30.0, 0.0, 0.0)]),
            None,
            "too far"
        );
        let walker = ActorRow {
            kind: ActorRow::PEDESTRIAN,
            ..car(10.0, 0.0, 0.0)
        };
        assert_eq!(stopped_vehicle_ahead(&ego, &[walker]), None, "a walker");
    }

    #[test]
    fn a_pedestrian_ahead_is_one_in_the_corridor_in_front_within_range() {
        let ego = EgoRow {
            x: 0.0,
            y: 0.0,
            yaw: 0.0,
            speed: 5.0,
        };
        let walker = |x: f32, y: f32| ActorRow {
            kind: ActorRow::PEDESTRIAN,
            id: 7,
            x,
            y,
            yaw: 1.5,
            length: 0.5,
            width: 0.5,
            speed: 1.2,
        };
        // To the near edge of its footprint: 8 m less 0.27 m (a 0.5 m walker turned 1.5 rad).
        let d = pedestrian_ahead(&ego, &[walker(8.0, 0.5)]).unwrap();
        assert!((d - 7.733).abs() < 1e-3, "{d}");
        assert_eq!(
            pedestrian_ahead(&ego, &[walker(8.0, -5.0)]),
            None,
            "on the sidewalk"
        );
        assert_eq!(pedestrian_ahead(&ego, &[walker(-3.0, 0.0)]), None, "behind");
        assert_eq!(
            pedestrian_ahead(&ego, &[walker(25.0, 0.0)]),
            None,
            "too far"
        );
        // A vehicle nearer does not hide the walker; the nearest walker counts.
        let car = ActorRow {
            kind: ActorRow::VEHICLE,
            length: 4.5,
            width: 1.9,
            ..walker(5.0, 0.0)
        };
        let d = pedestrian_ahead(&ego, &[car, walker(15.0, 0.0), walker(10.0, 1.0)]).unwrap();
        assert!((d - 9.733).abs() < 1e-3, "{d}");
        // Heading matters: facing west, the walker at x = 8 is behind.
        let west = EgoRow {
            yaw: std::f32::consts::PI,
            ..ego
        };
        assert_eq!(pedestrian_ahead(&west, &[walker(8.0, 0.0)]), None);
    }

    fn sample() -> Shard {
        let mut s = Shard::new((6, 2), 2);
        for f in 0..3u32 {
            s.rgb
                .extend((0..2 * 6 * 2 * 3).map(|i| (i as u32 + f) as u8));
            s.classes
                .extend((0..2 * 6 * 2).map(|i| ((i as u32 + f) % 6) as u8));
            s.ego.push(EgoRow {
                x: f as f32,
                y: 2.0,
                yaw: 0.5,
                speed: 3.0,
            });
            s.command.push(3);
            s.route.push([f as f32, 1.5 * f as f32]);
            s.tick.push(f * 10);
            s.actors.push(
                (0..f)
                    .map(|i| ActorRow {
                        kind: 1 + (i % 2) as u8,
                        id: i + 1,
                        x: 1.0,
                        y: 2.0,
                        yaw: 0.1,
                        length: 4.0,
                        width: 2.0,
                        speed: 1.0,
                    })
                    .collect(),
            );
            s.lights.push(vec![0, 1, 2]);
        }
        s
    }

    #[test]
    fn a_shard_reads_back_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("episode-00000.safetensors");
        let s = sample();
        std::fs::write(&path, s.to_bytes(&HashMap::new())).unwrap();
        let back = Shard::read(&path, [6, 2], 2).unwrap();
        assert_eq!(back, s);
        assert_eq!(back.rgb(2, 1), s.rgb(2, 1));
    }

    #[test]
    fn a_mapped_shard_reads_the_state_and_each_image_from_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("episode-00000.safetensors");
        let s = sample();
        std::fs::write(&path, s.to_bytes(&HashMap::new())).unwrap();
        let mapped = MappedShard::open(&path, [6, 2], 2).unwrap();
        assert!(mapped.state.rgb.is_empty() && mapped.state.classes.is_empty());
        assert_eq!(mapped.state.ego, s.ego);
        assert_eq!(mapped.state.actors, s.actors);
        for f in 0..3 {
            for v in 0..2 {
                let (rgb, classes) = mapped.view_images(f, v).unwrap();
                assert_eq!(rgb, s.rgb(f, v), "rgb {f} {v}");
                assert_eq!(classes, s.classes(f, v), "classes {f} {v}");
            }
        }
    }

    #[test]
    fn images_are_stored_compressed_and_a_damaged_frame_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("episode-00000.safetensors");
        // A flat picture, as a rendered town mostly is: far smaller than its raw bytes.
        let mut s = sample();
        s.rgb.fill(90);
        s.classes.fill(1);
        let bytes = s.to_bytes(&HashMap::new());
        std::fs::write(&path, &bytes).unwrap();
        let raw = s.rgb.len() + s.classes.len();
        let mapped = MappedShard::open(&path, [6, 2], 2).unwrap();
        let packed = mapped.offsets[mapped.len()] as usize;
        assert!(packed * 2 < raw, "{packed} compressed bytes for {raw} raw");
        assert_eq!(Shard::read(&path, [6, 2], 2).unwrap(), s);
        // Frame 1's header overwritten: the shard is refused at opening, naming the frame.
        let (a, b) = (mapped.offsets[1] as usize, mapped.offsets[2] as usize);
        let at = mapped.images_at + a;
        let mut damaged = bytes.clone();
        damaged[at..at + 4].copy_from_slice(&[0xde, 0xad, 0xbe, 0xef]);
        std::fs::write(&path, &damaged).unwrap();
        let err = MappedShard::open(&path, [6, 2], 2).unwrap_err().to_string();
        assert!(
            err.contains("episode-00000") && err.contains("frame 1") && err.contains("collect"),
            "{err}"
        );
        // Its last byte (the checksum's) changed: found when the frame is read.
        let mut damaged = bytes.clone();
        damaged[mapped.images_at + b - 1] ^= 0xff;
        std::fs::write(&path, &damaged).unwrap();
        let mapped = MappedShard::open(&path, [6, 2], 2).unwrap();
        assert!(mapped.view_images(0, 0).is_ok());
        let err = mapped.view_images(1, 0).unwrap_err().to_string();
        assert!(err.contains("frame 1") && err.contains("collect"), "{err}");
    }

    #[test]
    fn mapped_labels_give_each_label_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("labels-00000.safetensors");
        let labels = Labels {
            views: 2,
            q: (0..3 * 2 * Q_PER_VIEW).map(|i| i as f32 * 0.5).collect(),
            valid: vec![true, true, false],
        };
        std::fs::write(&path, labels.to_bytes(4, "episode-00000.safetensors")).unwrap();
        let mapped = MappedLabels::open(&path, 4, 3, 2).unwrap();
        let mut out = vec![0.0; Q_PER_VIEW];
        mapped.q_into(2, 1, &mut out);
        assert_eq!(out, labels.q(2, 1));
        assert_eq!(mapped.valid, labels.valid);
        assert_eq!(file_metadata(&path).unwrap()["label_version"], "4");
    }

    #[test]
    fn a_truncated_or_foreign_shard_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("episode-00000.safetensors");
        let bytes = sample().to_bytes(&HashMap::new());
        std::fs::write(&path, &bytes[..bytes.len() - 10]).unwrap();
        let err = Shard::read(&path, [6, 2], 2).unwrap_err().to_string();
        assert!(
            err.contains("episode-00000") && err.contains("truncated"),
            "{err}"
        );
        std::fs::write(&path, &bytes).unwrap();
        let err = Shard::read(&path, [12, 4], 2).unwrap_err().to_string();
        assert!(err.contains("images") && err.contains("S0"), "{err}");
    }

    #[test]
    fn labels_of_another_version_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("labels-00000.safetensors");
        let labels = Labels {
            views: 1,
            q: vec![0.5; 2 * Q_PER_VIEW],
            valid: vec![true, false],
        };
        std::fs::write(&path, labels.to_bytes(1, "episode-00000.safetensors")).unwrap();
        assert_eq!(Labels::read(&path, 1, 2, 1).unwrap(), labels);
        let err = Labels::read(&path, 2, 2, 1).unwrap_err().to_string();
        assert!(
            err.contains("label_version") && err.contains("mrdrive label"),
            "{err}"
        );
    }

    #[test]
    fn a_missing_index_says_how_to_make_one() {
        let dir = tempfile::tempdir().unwrap();
        let err = Index::load(dir.path()).unwrap_err().to_string();
        assert!(
            err.contains(INDEX_FILE) && err.contains("mrdrive collect"),
            "{err}"
        );
        let idx = Index::new("t", [6, 2], vec![0.0], 10, 0.025);
        idx.save(dir.path()).unwrap();
        assert_eq!(Index::load(dir.path()).unwrap(), idx);
    }
}
