//! Loading an OpenDRIVE file (through the `xodr` crate) into a [`Town`].
//!
//! What the importer gives is validated (finite, bounded coordinates; positive
//! lengths) before it is used: the crate accepts NaN or 1e308 coordinates and
//! negative geometry lengths without complaint.
//!
//! | file | what it builds |
//! | --- | --- |
//! | `load.rs` | the entry points ([`load_xodr_file`], [`load_xodr_str`]) and the order of the parts |
//! | `validate.rs` | nothing: it rejects bad numbers and dropped geometry, naming the road, lane or signal |
//! | `junctions.rs` | the junctions and their outlines |
//! | `lanes.rs` | the driving lanes: centrelines, widths, speed limits, links, neighbours |
//! | `markings.rs` | the lane markings |
//! | `sidewalks.rs` | the sidewalks |
//! | `objects.rs` | buildings and the map's crosswalks |
//! | `lights.rs` | traffic lights and their stop lines (read, or generated at unsignalled junctions) |
//! | `crosswalks.rs` | crosswalks at junction approaches, for maps that have none |
//! | `surface.rs` | the road surface mesh and the town's bounds |

mod crosswalks;
mod junctions;
mod lanes;
mod lights;
mod load;
mod markings;
mod objects;
mod sidewalks;
mod surface;
mod validate;

pub use crosswalks::{CROSSWALK_DEPTH_M, CROSSWALK_SETBACK_M};
pub use lanes::{CENTERLINE_SPACING_M, DEFAULT_SPEED_LIMIT_MPS};
pub use lights::{BOX_LINK_M, DEFAULT_LIGHT_HEAD_HEIGHT_M, MAX_POLE_SETBACK_M};
pub use load::{LoadOptions, LoadReport, UnsignalledJunctions, load_xodr_file, load_xodr_str};
pub use sidewalks::DEFAULT_SIDEWALK_HEIGHT_M;
pub use validate::MAX_COORD_M;

use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;

use glam::{Vec2, Vec3};
use xodr::{LaneId, RoadNetwork};

use crate::map::{JunctionIdx, LaneIdx, Town};
use crate::road::geometry::arc_lengths;

struct Ctx<'a> {
    net: &'a RoadNetwork,
    file: &'a PathBuf,
}

struct Builder<'a> {
    ctx: Ctx<'a>,
    prov: &'a xodr::Provenance,
    town: Town,
    /// xodr lane id -> our lane index (drivable lanes only).
    lane_of: HashMap<LaneId, LaneIdx>,
    /// OpenDRIVE junction id -> our index.
    junction_of: BTreeMap<String, JunctionIdx>,
}

fn p3(p: xodr::Point) -> Vec3 {
    Vec3::new(p.x, p.y, p.z)
}

/// A lane's centreline in its stored (reference) direction, resampled.
fn edge_points(lane: &xodr::Lane, side: f32) -> Vec<Vec3> {
    // side: +1 left edge, -1 right edge (looking along the stored direction).
    let pts = lane.center.points();
    let tans = lane.center.tangents();
    let cum = arc_lengths(&pts.iter().map(|p| p3(*p)).collect::<Vec<_>>());
    let total = cum.last().copied().unwrap_or(0.0).max(1e-6);
    let xl = lane.center.length();
    pts.iter()
        .zip(tans)
        .zip(&cum)
        .map(|((p, t), c)| {
            let n = Vec2::new(-t.y, t.x).normalize_or_zero();
            let w = lane.width_at(c / total * xl);
            let q = p3(*p);
            q + (n * side * w * 0.5).extend(0.0)
        })
        .collect()
}

#[cfg(test)]
mod tests;
