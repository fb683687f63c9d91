//! The town as data and where it comes from: the [`Town`] model, OpenDRIVE
//! loading ([`opendrive`]), our town [`generator`], the hand-built grid town
//! for tests ([`testtown`]), a top-down [`picture`] of a town, and the trees and
//! street lamps beside its roads ([`props`]).

pub mod error;
pub mod generator;
pub mod opendrive;
pub mod picture;
pub mod props;
pub mod testtown;
pub mod town;

pub use error::MapError;
pub use opendrive::{LoadOptions, LoadReport, UnsignalledJunctions, load_xodr_file, load_xodr_str};
pub use town::*;
