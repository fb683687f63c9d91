//! What a run gives: the result record ([`record`], with where it came from,
//! [`provenance`]), its Foxglove log ([`recorder`]), its picture ([`picture`]),
//! and the camera's picture at a chosen moment of a run ([`moment`]).

pub mod moment;
pub mod picture;
pub mod provenance;
pub mod record;
pub mod recorder;
