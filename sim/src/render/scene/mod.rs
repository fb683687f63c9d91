//! The geometry the camera draws: the town's static meshes, built once per
//! town and cut into ground cells so a frame only draws what is near, and the
//! per-frame instances of moving things (vehicles, pedestrians, lit lamps).
//!
//! Everything here is plain CPU data; the renderer uploads it.
//!
//! - [`primitives`]: the packed vertex colour, the triangle-list builder
//!   and painted polyline strips, the palette.
//! - [`triangulate`]: ear clipping of building footprints.
//! - [`merge`]: merging a map's per-metre road quads where they run straight.
//! - [`road`]: road surface, lane markings, sidewalks, crosswalks.
//! - [`surroundings`]: buildings, trees and street lamps, terrain.
//! - [`lights`]: traffic-light poles, housings and lamp slots.
//! - [`dynamic`]: unit meshes and the per-frame instances drawn from them.

pub mod dynamic;
pub mod lights;
pub mod merge;
pub mod primitives;
pub mod road;
pub mod surroundings;
pub mod triangulate;

use std::collections::BTreeMap;

use glam::{Vec2, Vec3};
use world::Town;

use primitives::Tris;

pub use dynamic::{
    Dynamic, Instance, PEDESTRIAN_PAINTS, UNIT_MESHES, UnitMesh, VEHICLE_PAINTS, unit_mesh,
};
pub use lights::{LAMP_DIAMETER_M, LampSlots, lamp_paint};
pub use primitives::{Vertex, pack};

/// Side of a ground cell for culling (metres).
pub const CELL_M: f32 = 25.0;

/// A run of static vertices in one ground cell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// The cell's ground bounds (metres): min and max corner.
    pub min: Vec2,
    /// See `min`.
    pub max: Vec2,
    /// Vertex range in [`StaticScene::vertices`].
    pub first: u32,
    /// Number of vertices.
    pub count: u32,
    /// Whether the cell holds small things (lane paint, crosswalks, trees,
    /// street lamps), drawn only within the renderer's detail distance.
    pub detail: bool,
}

/// The town's static geometry, built once.
#[derive(Debug, Clone, Default)]
pub struct StaticScene {
    /// Triangle list: static cells first, then the unit meshes.
    pub vertices: Vec<Vertex>,
    /// Ground cells with their vertex runs, sorted by (row, column).
    pub cells: Vec<Cell>,
    /// Vertex range (first, count) of each unit mesh, indexed by `UnitMesh as usize`.
    pub units: [(u32, u32); UNIT_MESHES],
    /// Lamp positions for each light of the town, indexed like `Town::lights`.
    pub lamps: Vec<LampSlots>,
}

impl StaticScene {
    /// Builds the static scene of a town; trees and street lamps are placed
    /// beside the road from `seed`.
    pub fn build(town: &Town, seed: u64) -> StaticScene {
        let mut t = Tris::default();
        // Small things (paint, trees, street lamps), drawn nearer.
        let mut detail = Tris::default();
        let ground_z = ground_level(town);
        road::road(town, &mut t);
        road::markings(town, &mut detail);
        road::sidewalks(town, ground_z, &mut t);
        road::crosswalks(town, &mut detail);
        surroundings::buildings(town, ground_z, seed, &mut t);
        surroundings::props(town, ground_z, seed, &mut detail);
        let lamps = lights::lights(town, &mut t);
        surroundings::terrain(town, ground_z, &mut t);
        let (mut vertices, cells) = into_cells(t.v, detail.v);
        let mut units = [(0, 0); UNIT_MESHES];
        for (kind, slot) in [UnitMesh::Box, UnitMesh::Prism, UnitMesh::Disc]
            .into_iter()
            .zip(&mut units)
        {
            let u = unit_mesh(kind);
            *slot = (vertices.len() as u32, u.len() as u32);
            vertices.extend(u);
        }
        StaticScene {
            vertices,
            cells,
            units,
            lamps,
        }
    }

    /// Number of static triangles (unit meshes excluded).
    pub fn triangle_count(&self) -> usize {
        self.cells.iter().map(|c| c.count as usize).sum::<usize>() / 3
    }
}

/// The ground plane's height: just below the lowest road point (metres).
fn ground_level(town: &Town) -> f32 {
    let lanes = town.lanes.iter().flat_map(|l| l.centerline.iter());
    let z = lanes
        .chain(&town.road_surface.positions)
        .map(|p| p.z)
        .filter(|z| z.is_finite());
    let lowest = z.fold(f32::INFINITY, f32::min);
    if lowest.is_finite() {
        lowest.clamp(-1e4, 1e4) - 0.03
    } else {
        -0.03
    }
}

/// Sorts triangles into ground cells by centroid: the large things' cells
/// in (row, column) order, then the small things' (`detail`) cells.
fn into_cells(large: Vec<Vertex>, detail: Vec<Vertex>) -> (Vec<Vertex>, Vec<Cell>) {
    let mut by_cell: BTreeMap<(bool, i32, i32), Vec<Vertex>> = BTreeMap::new();
    for (is_detail, v) in [(false, &large), (true, &detail)] {
        for tri in v.chunks_exact(3) {
            let c = tri.iter().fold(Vec3::ZERO, |a, q| a + Vec3::from(q.pos)) / 3.0;
            let key = (
                is_detail,
                (c.y / CELL_M).floor() as i32,
                (c.x / CELL_M).floor() as i32,
            );
            by_cell.entry(key).or_default().extend_from_slice(tri);
        }
    }
    let mut out = Vec::with_capacity(large.len() + detail.len());
    let mut cells = Vec::with_capacity(by_cell.len());
    for ((detail, row, col), tris) in by_cell {
        // Bounds from the triangles themselves: big ones may poke out of the cell.
        let mut min = Vec2::new(col as f32, row as f32) * CELL_M;
        let mut max = min + Vec2::splat(CELL_M);
        for q in &tris {
            min = min.min(Vec2::new(q.pos[0], q.pos[1]));
            max = max.max(Vec2::new(q.pos[0], q.pos[1]));
        }
        cells.push(Cell {
            min,
            max,
            first: out.len() as u32,
            count: tris.len() as u32,
            detail,
        });
        out.extend(tris);
    }
    (out, cells)
}
