//! A tiny network and synthetic datasets for the loader's tests.

use crate::backbone::Depth;
use crate::model::PolicyConfig;
use dataset::synthetic::{self, SyntheticSpec};

/// A network that takes the synthetic dataset's 24 x 8 images.
pub fn config() -> PolicyConfig {
    PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
        .with_input_height(8)
        .with_input_width(24)
}

/// A synthetic dataset of `episodes` episodes of `frames` frames.
pub fn write(episodes: u32, frames: u32) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    synthetic::write(dir.path(), &SyntheticSpec::tiny(episodes, frames)).unwrap();
    dir
}
