//! An episode's shard, `DIR/episode-NNNNN.safetensors`: per-frame
//! zstd-compressed images beside the state of every frame (the ego, the
//! command, the route, every actor and light). [`Shard`] holds it in memory,
//! [`MappedShard`] reads it from the file a frame at a time.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use ::safetensors::tensor::Dtype;
use memmap2::Mmap;

use super::DataError;
use super::safetensors::{
    bytes_of, check_format, expect_shape, f32s, map_file, offset_in, parse, serialize, st_metadata,
    tensor,
};

/// The zstd level of a frame's images: level 3 compresses our frames about 27 times
/// at 0.2 ms a frame; higher levels gain under 10 % at 5 times the time.
const IMAGES_ZSTD_LEVEL: i32 = 3;
/// Numbers per actor row in the `actors` tensor.
pub const ACTOR_FIELDS: usize = 8;

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

    /// The row of a run's actor (a vehicle or a pedestrian; the ego has an
    /// [`EgoRow`]), as the episode recorder writes it.
    pub fn of(a: &world::ActorSnapshot) -> ActorRow {
        ActorRow {
            kind: if a.kind == world::ActorKind::Pedestrian {
                ActorRow::PEDESTRIAN
            } else {
                ActorRow::VEHICLE
            },
            id: a.id,
            x: a.position.x,
            y: a.position.y,
            yaw: a.heading,
            length: a.extent.x,
            width: a.extent.y,
            speed: a.speed_mps,
        }
    }

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

impl EgoRow {
    /// The row of a run's ego, as the episode recorder writes it.
    pub fn of(ego: &world::ActorSnapshot) -> EgoRow {
        EgoRow {
            x: ego.position.x,
            y: ego.position.y,
            yaw: ego.heading,
            speed: ego.speed_mps,
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
