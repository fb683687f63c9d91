//! Moving things: the unit meshes (box, prism, disc) and the per-frame
//! instances of them that draw vehicles, pedestrians and lit lamps.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use world::{ActorKind, ActorSnapshot, LightState};

use super::lights::{LAMP_DIAMETER_M, LampSlots, lamp_paint};
use super::primitives::{Tris, Vertex, pack};
use crate::render::classes;

/// One instance of a unit mesh: placed, turned about z, scaled.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Instance {
    /// Where the mesh's origin goes (metres, world frame).
    pub pos: [f32; 3],
    /// Turn about +z (radians, counter-clockwise from +x).
    pub heading: f32,
    /// Scale along the mesh's own x, y, z.
    pub scale: [f32; 3],
    /// Packed colour/class overriding the mesh's, or 0 to keep the mesh's.
    pub color: u32,
}

impl Instance {
    /// The identity instance, used to draw static geometry as it is.
    pub const IDENTITY: Instance = Instance {
        pos: [0.0; 3],
        heading: 0.0,
        scale: [1.0; 3],
        color: 0,
    };
}

/// The unit meshes that instances are drawn from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum UnitMesh {
    /// A box, x and y in [-0.5, 0.5], z in [0, 1].
    Box,
    /// An octagonal prism of radius 0.5, z in [0, 1].
    Prism,
    /// An octagonal disc of radius 0.5 in the y-z plane, facing +x.
    Disc,
}

/// Number of unit meshes.
pub const UNIT_MESHES: usize = 3;

/// The triangles of a unit mesh, white, class building (instances override both).
pub fn unit_mesh(kind: UnitMesh) -> Vec<Vertex> {
    let mut u = Tris::default();
    let white = pack([255, 255, 255], classes::BUILDING, false);
    match kind {
        UnitMesh::Box => u.boxed(Vec3::ZERO, Vec3::ONE, 0.0, white),
        UnitMesh::Prism => u.prism(Vec3::ZERO, 0.5, 1.0, white),
        UnitMesh::Disc => u.disc(Vec3::ZERO, 0.5, 0.0, white),
    }
    u.v
}

/// Vehicle body colours (sRGB), chosen by `ActorSnapshot::color`.
pub const VEHICLE_PAINTS: [[u8; 3]; 8] = [
    [180, 20, 25],
    [230, 230, 235],
    [25, 25, 30],
    [30, 70, 160],
    [140, 145, 150],
    [200, 160, 30],
    [40, 110, 60],
    [110, 40, 110],
];
/// Pedestrian clothing colours (sRGB), chosen by `ActorSnapshot::color`.
pub const PEDESTRIAN_PAINTS: [[u8; 3]; 6] = [
    [60, 60, 140],
    [150, 40, 40],
    [40, 40, 40],
    [200, 180, 140],
    [60, 120, 60],
    [220, 220, 220],
];

/// Per-frame instances, grouped by unit mesh; the buffers are reused.
#[derive(Debug, Default)]
pub struct Dynamic {
    /// Instances per unit mesh, indexed by `UnitMesh as usize`.
    pub groups: [Vec<Instance>; UNIT_MESHES],
}

impl Dynamic {
    /// Refills the instances for this frame: vehicles (body and cabin),
    /// pedestrians (body and head) and the lit lamp of each light. The ego
    /// is not drawn (the cameras sit on it).
    pub fn fill(&mut self, actors: &[ActorSnapshot], lamps: &[LampSlots], states: &[LightState]) {
        for g in &mut self.groups {
            g.clear();
        }
        for a in actors {
            if !a.position.is_finite() || !a.extent.is_finite() || !a.heading.is_finite() {
                continue;
            }
            let e = a.extent.max(Vec3::splat(0.05));
            match a.kind {
                ActorKind::Ego => {}
                ActorKind::Vehicle => {
                    let rgb = VEHICLE_PAINTS[a.color as usize % VEHICLE_PAINTS.len()];
                    let body = pack(rgb, classes::VEHICLE, false);
                    let glass = pack([40, 48, 56], classes::VEHICLE, false);
                    let (s, c) = a.heading.sin_cos();
                    let fwd = Vec3::new(c, s, 0.0);
                    let bottom = a.position + Vec3::Z * (0.12 * e.z);
                    let boxes = &mut self.groups[UnitMesh::Box as usize];
                    boxes.push(Instance {
                        pos: bottom.to_array(),
                        heading: a.heading,
                        scale: [e.x, e.y, 0.5 * e.z],
                        color: body,
                    });
                    boxes.push(Instance {
                        pos: (a.position - fwd * (0.08 * e.x) + Vec3::Z * (0.62 * e.z)).to_array(),
                        heading: a.heading,
                        scale: [0.55 * e.x, 0.9 * e.y, 0.38 * e.z],
                        color: glass,
                    });
                }
                ActorKind::Pedestrian => {
                    let rgb = PEDESTRIAN_PAINTS[a.color as usize % PEDESTRIAN_PAINTS.len()];
                    let d = e.x.min(e.y);
                    let prisms = &mut self.groups[UnitMesh::Prism as usize];
                    prisms.push(Instance {
                        pos: a.position.to_array(),
                        heading: a.heading,
                        scale: [d, d, 0.84 * e.z],
                        color: pack(rgb, classes::PEDESTRIAN, false),
                    });
                    prisms.push(Instance {
                        pos: (a.position + Vec3::Z * (0.85 * e.z)).to_array(),
                        heading: a.heading,
                        scale: [0.55 * d, 0.55 * d, 0.15 * e.z],
                        color: pack([200, 160, 130], classes::PEDESTRIAN, false),
                    });
                }
            }
        }
        for (slots, state) in lamps.iter().zip(states) {
            let (rgb, class, which) = lamp_paint(*state);
            self.groups[UnitMesh::Disc as usize].push(Instance {
                pos: slots.centers[which].to_array(),
                heading: slots.heading,
                scale: [1.0, LAMP_DIAMETER_M, LAMP_DIAMETER_M],
                color: pack(rgb, class, true),
            });
        }
    }

    /// Total number of instances.
    pub fn len(&self) -> usize {
        self.groups.iter().map(Vec::len).sum()
    }

    /// Whether there are no instances.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
