//! Training: the loader over dataset shards and its augmentations, the network
//! presets, the losses, the batch resize, the multi-resolution step, BN
//! recalibration (on batches, or on frames rendered along scenarios), and a
//! synthetic toy batch with the smoke run that trains on it; the stages of the
//! paper's pipeline, from a name and flags ([`request`]) to a settings file
//! ([`spec`]), a resumable run ([`stage`]) and its published checkpoint
//! ([`publish`]).

pub mod augment;
pub mod fit;
pub mod loader;
pub mod losses;
pub mod multires;
pub mod presets;
pub mod publish;
pub mod recalibrate;
pub mod recalibrate_scenes;
pub mod request;
pub mod resize;
pub mod spec;
pub mod stage;
pub mod synthetic;

pub use multires::{Batch, MultiResTrainer, TrainConfig};
pub use presets::Preset;
pub use request::{RecipeChanges, SpecError, StageRequest};
pub use spec::StageSpec;
pub use stage::run_stage;
