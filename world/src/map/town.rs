//! The town model: the data every other part of the simulator reads.
//!
//! These are plain data types with public fields. They are produced by the map
//! loader (`Town::from_xodr*`) and the town generator, and read by the route
//! planner, traffic, the camera, the monitors and the expert. One definition
//! each: a lane marking here is what the renderer draws *and* what the
//! lane-crossing monitor counts.

use glam::{Vec2, Vec3};

/// Index of a driving lane in [`Town::lanes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LaneIdx(pub u32);

/// Index of a junction in [`Town::junctions`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct JunctionIdx(pub u32);

/// Index of a traffic light in [`Town::lights`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LightIdx(pub u32);

/// A drivable lane, stored in its direction of travel.
#[derive(Debug, Clone)]
pub struct DriveLane {
    /// OpenDRIVE road id this lane belongs to.
    pub road_id: String,
    /// OpenDRIVE lane id (negative: right of the reference line).
    pub od_lane: i32,
    /// Centreline points in driving order, about 1 m apart (metres, world frame).
    pub centerline: Vec<Vec3>,
    /// Arc length at each centreline point (metres, starting at 0).
    pub s: Vec<f32>,
    /// Lane width at each centreline point (metres).
    pub width: Vec<f32>,
    /// Speed limit (metres per second).
    pub speed_limit_mps: f32,
    /// The junction this lane runs through, if it is a connecting lane.
    pub junction: Option<JunctionIdx>,
    /// Lanes a vehicle may continue into at the end of this one.
    pub successors: Vec<LaneIdx>,
    /// Lanes that lead into this one.
    pub predecessors: Vec<LaneIdx>,
    /// Neighbour lane on the left with the same direction, if any.
    pub left: Option<LaneIdx>,
    /// Neighbour lane on the right with the same direction, if any.
    pub right: Option<LaneIdx>,
}

/// How a lane boundary is painted (OpenDRIVE `roadMark` types we use).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MarkKind {
    /// A continuous line.
    Solid,
    /// A dashed line.
    Broken,
    /// Two continuous lines.
    SolidSolid,
    /// Solid on one side, broken on the other.
    SolidBroken,
    /// Broken on one side, solid on the other.
    BrokenSolid,
    /// Two dashed lines.
    BrokenBroken,
    /// A curb: a raised edge, not paint.
    Curb,
}

/// The colour of a painted marking.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MarkColor {
    /// White paint.
    White,
    /// Yellow paint.
    Yellow,
}

/// A painted lane boundary: drawn by the renderer, counted by the
/// lane-crossing monitor. Boundaries without paint (`roadMark type="none"`)
/// are not listed.
#[derive(Debug, Clone)]
pub struct LaneMarking {
    /// The line's points (metres, world frame), in order along the road.
    pub points: Vec<Vec3>,
    /// Solid, broken, ...
    pub kind: MarkKind,
    /// White or yellow.
    pub color: MarkColor,
    /// Painted width (metres).
    pub width_m: f32,
    /// For broken lines: painted length and gap length (metres).
    pub dash_m: Option<(f32, f32)>,
}

/// A sidewalk strip beside a road.
#[derive(Debug, Clone)]
pub struct Sidewalk {
    /// The strip's edge on the road side (metres, world frame).
    pub inner: Vec<Vec3>,
    /// The strip's outer edge, pointwise matched with `inner`.
    pub outer: Vec<Vec3>,
    /// Height of the walking surface above the road (metres).
    pub height_m: f32,
}

/// A pedestrian crossing over a road.
#[derive(Debug, Clone)]
pub struct Crosswalk {
    /// The four corners, counter-clockwise (metres, world frame).
    pub corners: [Vec3; 4],
    /// Whether the map had it (`true`) or it was generated at a junction approach.
    pub from_map: bool,
}

/// A junction: where connecting lanes overlap.
#[derive(Debug, Clone)]
pub struct Junction {
    /// OpenDRIVE junction id.
    pub od_id: String,
    /// The area's outline, counter-clockwise (metres, world frame, z dropped).
    pub outline: Vec<Vec2>,
    /// The junction's lights, in controller-group order (empty if it has none).
    pub lights: Vec<LightIdx>,
    /// Right of way the map gives (OpenDRIVE `<priority>`): pairs (a
    /// connecting lane with priority, a connecting lane that gives way to
    /// it), e.g. a roundabout's ring over its entry. Empty: first come,
    /// first served.
    pub priorities: Vec<(LaneIdx, LaneIdx)>,
    /// How long its lights stay yellow, where the map decides it (seconds):
    /// lights generated for a file that has none get the yellow their
    /// fastest approach needs ([`crate::rules::change_interval_s`]). None: the
    /// light controller's (CARLA's 3 s).
    pub yellow_s: Option<f32>,
}

/// Where a light stops traffic on one lane.
#[derive(Debug, Clone)]
pub struct StopLine {
    /// The lane the stop line is on (the approach lane, where it enters the junction).
    pub lane: LaneIdx,
    /// Arc length along that lane (metres).
    pub s: f32,
    /// The line's two ends across the lane (metres, world frame): the left end
    /// first, the right end second, seen in the lane's driving direction.
    pub ends: [Vec3; 2],
}

/// A traffic light: a pole and a head, governing one or more lanes.
#[derive(Debug, Clone)]
pub struct TrafficLight {
    /// OpenDRIVE signal id (or a generated id).
    pub od_id: String,
    /// Position of the pole's foot (metres, world frame).
    pub position: Vec3,
    /// Direction the lamps face (radians, counter-clockwise from +x).
    pub heading: f32,
    /// Height of the lamp housing's centre above the pole's foot (metres).
    pub head_height_m: f32,
    /// The junction whose controller cycles this light.
    pub junction: Option<JunctionIdx>,
    /// The phase group within that controller (lights of one group share a state).
    pub group: u32,
    /// The stop lines of the lanes it governs.
    pub stop_lines: Vec<StopLine>,
}

/// A building's footprint on a lot beside the road.
#[derive(Debug, Clone)]
pub struct Building {
    /// Footprint polygon, counter-clockwise (metres, world frame).
    pub footprint: Vec<Vec2>,
    /// Height (metres).
    pub height_m: f32,
}

/// A triangle mesh in the world frame (metres).
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles, three indices each, counter-clockwise seen from above.
    pub indices: Vec<u32>,
}

/// A town: the road network and everything static in it.
#[derive(Debug, Clone)]
pub struct Town {
    /// A short name (the map file's stem, or the generator's name).
    pub name: String,
    /// Drivable lanes; the lane graph lives in their `successors`.
    pub lanes: Vec<DriveLane>,
    /// Painted lane boundaries.
    pub markings: Vec<LaneMarking>,
    /// Sidewalk strips.
    pub sidewalks: Vec<Sidewalk>,
    /// Pedestrian crossings.
    pub crosswalks: Vec<Crosswalk>,
    /// Junction areas.
    pub junctions: Vec<Junction>,
    /// Traffic lights.
    pub lights: Vec<TrafficLight>,
    /// Buildings beside the roads.
    pub buildings: Vec<Building>,
    /// The drivable road surface.
    pub road_surface: Mesh,
    /// Axis-aligned bounds of the road network: (min, max) corners (metres).
    pub bounds: (Vec2, Vec2),
}

impl Town {
    /// A town with nothing in it, named `name`: the base that tests and
    /// hand-made scenes fill in (`Town { lights, ..Town::empty("x") }`).
    pub fn empty(name: &str) -> Town {
        Town {
            name: name.to_string(),
            lanes: Vec::new(),
            markings: Vec::new(),
            sidewalks: Vec::new(),
            crosswalks: Vec::new(),
            junctions: Vec::new(),
            lights: Vec::new(),
            buildings: Vec::new(),
            road_surface: Mesh::default(),
            bounds: (Vec2::ZERO, Vec2::ZERO),
        }
    }

    /// The road's height (metres): that of the first lane's first point (our towns
    /// and CARLA's are flat), 0 for a town without lanes.
    pub fn ground_z(&self) -> f32 {
        self.lanes
            .first()
            .and_then(|l| l.centerline.first())
            .map_or(0.0, |p| p.z)
    }
}

/// The state of a traffic light's lamps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum LightState {
    /// Stop.
    #[default]
    Red,
    /// Stop if you can.
    Yellow,
    /// Go.
    Green,
}
