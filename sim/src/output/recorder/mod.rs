//! Run logs in MCAP that Foxglove opens.
//!
//! Messages use Foxglove's well-known JSON schemas (schema encoding
//! `jsonschema`, message encoding `json`), with simulation time as log time,
//! so Foxglove's Image, 3D, Plot and Log panels work without set-up:
//!
//! | topic | schema | what |
//! | --- | --- | --- |
//! | `/camera/image` | `foxglove.CompressedImage` | the policy's view (PNG) at the scale in force |
//! | `/camera/labels` | `foxglove.CompressedImage` | the class image, coloured (optional) |
//! | `/bev/image` | `foxglove.CompressedImage` | the bird's-eye view |
//! | `/tf` | `foxglove.FrameTransform` | world -> ego |
//! | `/scene/map` | `foxglove.SceneUpdate` | lanes, markings, stop lines (once) |
//! | `/scene/actors` | `foxglove.SceneUpdate` | vehicles, pedestrians, lights coloured by state |
//! | `/control` | `mrdrive.Control` | the control computed at a boundary and the one latched (in force) |
//! | `/ego` | `mrdrive.EgoState` | speed, route command, active scale, latency in force |
//! | `/infractions` | `foxglove.Log` | every infraction, as a log line |
//! | `/infractions/events` | `mrdrive.Infraction` | every infraction, as data |
//! | `/contacts` | `mrdrive.Touch` | every contact of the ego, kerbs included (`monitors::contacts`) |
//!
//! The final result record is written as MCAP metadata named `result`; its
//! `contacts` carry each touch's `left_tick` too, and `collisions` the counts
//! under each named rule.
//!
//! Chunks are zstd-compressed, single-threaded at a fixed level, so a
//! deterministic run gives byte-identical files. The writer streams chunks to
//! the file as they fill (1 MiB), so a long run never holds its log in memory.
//!
//! [`writer`] writes a log ([`Recorder`]); [`reader`] reads one back in a
//! streaming pass ([`read_summary`]).

pub mod reader;
pub mod writer;

pub use reader::{LogSummary, ReadError, TopicSummary, read_summary, summarize};
pub use writer::{BEV_EXTENT_M, BEV_SIZE_PX, RecordError, RecordOptions, Recorder, base64};

/// Nanoseconds in a second.
pub(crate) const NS: u64 = 1_000_000_000;

/// Simulation time of a tick in nanoseconds.
pub fn tick_ns(tick: u64, tick_s: f64) -> u64 {
    (tick as f64 * tick_s * NS as f64).round() as u64
}
