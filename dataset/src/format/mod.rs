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
//!
//! | file | what |
//! | --- | --- |
//! | `index.rs` | the index (`dataset.json`): [`Index`], [`Episode`], [`RouteSpec`] |
//! | `shard.rs` | an episode's shard: [`Shard`] in memory, [`MappedShard`] from the file, its rows ([`EgoRow`], [`ActorRow`]) and light codes |
//! | `labels.rs` | an episode's label file: [`Labels`], [`MappedLabels`] |
//! | `safetensors.rs` | the safetensors writer with its canonical header, and the checked parse both file kinds share; [`file_metadata`] |
//! | `ahead.rs` | what stands straight ahead of the ego in a frame: [`pedestrian_ahead`], [`stopped_vehicle_ahead`] |

use std::path::{Path, PathBuf};

mod ahead;
mod index;
mod labels;
mod safetensors;
mod shard;

pub use self::safetensors::file_metadata;
pub use ahead::{PEDESTRIAN_AHEAD_M, STOPPED_MPS, pedestrian_ahead, stopped_vehicle_ahead};
pub use index::{Episode, INDEX_FILE, Index, RouteSpec};
pub use labels::{Labels, MappedLabels, Q_PER_VIEW};
pub use shard::{ACTOR_FIELDS, ActorRow, EgoRow, MappedShard, Shard, light_code, light_of_code};

/// The format tag in the index and in every shard's metadata.
pub const FORMAT: &str = "mrdrive-dataset/2";

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

/// Writes `bytes` to `path` through a temporary file in the same directory.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), DataError> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes).map_err(|e| DataError::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| DataError::io(path, e))
}
