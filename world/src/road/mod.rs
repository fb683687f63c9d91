//! The road network's geometry: plane [`geometry`] (projection onto
//! polylines, boxes crossing lines), queries on the [`lane_graph`] and
//! positions along chains of lanes ([`lane_path`]).

pub mod geometry;
pub mod lane_graph;
pub mod lane_path;

pub use lane_path::LanePath;
