//! Errors for bad maps: each names the file, what is wrong, where, and how
//! to fix it.

use std::path::PathBuf;

/// A map (OpenDRIVE) that could not be turned into a [`crate::Town`].
#[derive(Debug, thiserror::Error)]
pub enum MapError {
    /// The file could not be read from disk.
    #[error("cannot read map {file}: {source}. Fix: check the path and that the file is readable")]
    Read {
        /// The map file.
        file: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The OpenDRIVE importer rejected the document.
    #[error("map {file} is not a usable OpenDRIVE file: {detail}. Fix: {fix}")]
    Import {
        /// The map file (or `<string>`).
        file: PathBuf,
        /// What the importer said (XML errors include line and column).
        detail: String,
        /// How to fix it.
        fix: String,
    },
    /// The document loaded but holds a value the simulator cannot use.
    #[error("map {file}: {what} at {location}. Fix: {fix}")]
    Invalid {
        /// The map file (or `<string>`).
        file: PathBuf,
        /// What is wrong.
        what: String,
        /// Where (road, lane, signal id).
        location: String,
        /// How to fix it.
        fix: String,
    },
}
