//! The geometry the camera draws: the town's static meshes, built once per
//! town and cut into ground cells so a frame only draws what is near, and the
//! per-frame instances of moving things (vehicles, pedestrians, lit lamps).
//!
//! Everything here is plain CPU data; the renderer uploads it.

use std::collections::BTreeMap;

use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use world::{ActorKind, ActorSnapshot, LightState, MarkColor, MarkKind, Town};

use super::classes::{self, ClassId};

/// Side of a ground cell for culling (metres).
pub const CELL_M: f32 = 25.0;
/// Lift of paint above the surface it lies on (metres), against z-fighting.
const PAINT_LIFT_M: f32 = 0.02;
/// Diameter of a traffic-light lamp (metres): the common 300 mm lens.
pub const LAMP_DIAMETER_M: f32 = 0.30;
/// Vertical spacing of the three lamps in a housing (metres).
const LAMP_SPACING_M: f32 = 0.38;
/// Housing size: width, depth, height (metres).
const HOUSING_M: Vec3 = Vec3::new(0.45, 0.35, 1.2);
/// Default dash pattern (paint, gap) for broken lines without one (metres).
const DEFAULT_DASH_M: (f32, f32) = (3.0, 6.0);

/// One vertex: position and a packed colour/class word (see [`pack`]).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Vertex {
    /// Position (metres; world frame for static geometry, model frame for unit meshes).
    pub pos: [f32; 3],
    /// Packed sRGB colour, class id and emissive flag.
    pub color: u32,
}

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

/// Packs an sRGB colour, a class id (< 128) and an emissive flag into a word:
/// `r | g << 8 | b << 16 | class << 24 | emissive << 31`.
pub fn pack(rgb: [u8; 3], class: ClassId, emissive: bool) -> u32 {
    debug_assert!(class < 128);
    u32::from(rgb[0])
        | u32::from(rgb[1]) << 8
        | u32::from(rgb[2]) << 16
        | u32::from(class & 0x7f) << 24
        | u32::from(emissive) << 31
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

/// Where the three lamps of one traffic light sit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LampSlots {
    /// Centres of the red, yellow and green lamps (metres, world frame), just in front of the housing.
    pub centers: [Vec3; 3],
    /// The direction the lamps face (radians, counter-clockwise from +x).
    pub heading: f32,
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

/// A triangle-list builder.
#[derive(Debug, Default)]
struct Tris {
    v: Vec<Vertex>,
}

impl Tris {
    fn tri(&mut self, a: Vec3, b: Vec3, c: Vec3, color: u32) {
        for p in [a, b, c] {
            self.v.push(Vertex {
                pos: p.to_array(),
                color,
            });
        }
    }
    fn quad(&mut self, a: Vec3, b: Vec3, c: Vec3, d: Vec3, color: u32) {
        self.tri(a, b, c, color);
        self.tri(a, c, d, color);
    }
    /// An upright box: bottom centre, size (length along heading, width, height).
    fn boxed(&mut self, base: Vec3, size: Vec3, heading: f32, color: u32) {
        let (s, c) = heading.sin_cos();
        let fx = Vec3::new(c, s, 0.0) * size.x * 0.5;
        let fy = Vec3::new(-s, c, 0.0) * size.y * 0.5;
        let up = Vec3::Z * size.z;
        let b = [
            base - fx - fy,
            base + fx - fy,
            base + fx + fy,
            base - fx + fy,
        ];
        let t = b.map(|p| p + up);
        for i in 0..4 {
            let j = (i + 1) % 4;
            self.quad(b[i], b[j], t[j], t[i], color);
        }
        self.quad(t[0], t[1], t[2], t[3], color);
        self.quad(b[3], b[2], b[1], b[0], color);
    }
    /// An upright octagonal prism: bottom centre, radius, height.
    fn prism(&mut self, base: Vec3, radius: f32, height: f32, color: u32) {
        self.prism_n(base, radius, height, 8, color);
    }
    /// An upright prism with `sides` sides: bottom centre, radius, height.
    fn prism_n(&mut self, base: Vec3, radius: f32, height: f32, sides: usize, color: u32) {
        let ring: Vec<Vec3> = (0..sides)
            .map(|i| {
                let a = i as f32 * std::f32::consts::TAU / sides as f32;
                base + Vec3::new(a.cos(), a.sin(), 0.0) * radius
            })
            .collect();
        let up = Vec3::Z * height;
        for i in 0..sides {
            let j = (i + 1) % sides;
            self.quad(ring[i], ring[j], ring[j] + up, ring[i] + up, color);
            self.tri(base + up, ring[i] + up, ring[j] + up, color);
            self.tri(base, ring[j], ring[i], color);
        }
    }
    /// An octagonal disc facing `normal` (horizontal), centre `c`.
    fn disc(&mut self, c: Vec3, radius: f32, heading: f32, color: u32) {
        let (s, co) = heading.sin_cos();
        let side = Vec3::new(-s, co, 0.0);
        let ring: Vec<Vec3> = (0..8)
            .map(|i| {
                let a = (i as f32 + 0.5) * std::f32::consts::TAU / 8.0;
                c + side * (a.cos() * radius) + Vec3::Z * (a.sin() * radius)
            })
            .collect();
        for i in 0..8 {
            self.tri(c, ring[i], ring[(i + 1) % 8], color);
        }
    }
}

/// Colours (sRGB).
mod paint {
    pub const ASPHALT: [u8; 3] = [88, 88, 92];
    pub const WHITE: [u8; 3] = [235, 235, 230];
    pub const YELLOW: [u8; 3] = [235, 190, 40];
    pub const SIDEWALK: [u8; 3] = [170, 165, 160];
    pub const CURB: [u8; 3] = [150, 148, 145];
    pub const TERRAIN: [u8; 3] = [96, 128, 70];
    pub const TRUNK: [u8; 3] = [95, 70, 45];
    pub const LEAVES: [u8; 3] = [60, 110, 45];
    pub const METAL: [u8; 3] = [120, 120, 125];
    pub const HOUSING: [u8; 3] = [45, 45, 40];
    pub const DARK_LAMP: [u8; 3] = [25, 25, 25];
    pub const BUILDINGS: [[u8; 3]; 6] = [
        [176, 160, 140],
        [150, 110, 90],
        [200, 196, 186],
        [120, 130, 140],
        [170, 120, 100],
        [210, 200, 160],
    ];
}

/// Lit-lamp colours (sRGB) and classes by light state.
pub fn lamp_paint(state: LightState) -> ([u8; 3], ClassId, usize) {
    match state {
        LightState::Red => ([255, 40, 20], classes::LAMP_RED, 0),
        LightState::Yellow => ([255, 200, 0], classes::LAMP_YELLOW, 1),
        LightState::Green => ([40, 255, 90], classes::LAMP_GREEN, 2),
    }
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

/// A polyline with arc lengths and per-point unit side normals (to the left).
struct Line {
    p: Vec<Vec3>,
    s: Vec<f32>,
    n: Vec<Vec3>,
}

impl Line {
    fn new(points: &[Vec3]) -> Option<Line> {
        let raw: Vec<Vec3> = points.iter().copied().filter(|q| q.is_finite()).collect();
        if raw.len() < 2 {
            return None;
        }
        // Drop points that lie within 1 cm of the chord from the last kept
        // point to the next one: straight stretches become one quad.
        let mut p = vec![raw[0]];
        for i in 1..raw.len() - 1 {
            let (a, b) = (p[p.len() - 1], raw[i + 1]);
            let ab = b - a;
            let t = ((raw[i] - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
            let off = (a + ab * t).distance(raw[i]);
            // Also keep points so no span exceeds 25 m (long quads clip badly in lavapipe's fixed point).
            if off > 0.01 || a.distance(b) > 25.0 {
                p.push(raw[i]);
            }
        }
        p.push(raw[raw.len() - 1]);
        let mut s = vec![0.0];
        for w in p.windows(2) {
            s.push(s[s.len() - 1] + w[0].distance(w[1]));
        }
        let dirs: Vec<Vec2> = p
            .windows(2)
            .map(|w| (w[1] - w[0]).truncate().normalize_or_zero())
            .collect();
        let n = (0..p.len())
            .map(|i| {
                let a = dirs[i.saturating_sub(1).min(dirs.len() - 1)];
                let b = dirs[i.min(dirs.len() - 1)];
                let d = (a + b).normalize_or(b);
                Vec3::new(-d.y, d.x, 0.0)
            })
            .collect();
        Some(Line { p, s, n })
    }

    /// Emits a strip `offset` to the left, `width` wide, over the painted
    /// intervals (all of it when `dash` is `None`), `lift` above the line.
    fn strip(
        &self,
        t: &mut Tris,
        offset: f32,
        width: f32,
        dash: Option<(f32, f32)>,
        lift: f32,
        color: u32,
    ) {
        let half = width * 0.5;
        let at = |i: usize, u: f32| {
            let j = (i + 1).min(self.p.len() - 1);
            let p = self.p[i].lerp(self.p[j], u) + Vec3::Z * lift;
            let n = self.n[i].lerp(self.n[j], u).normalize_or(self.n[i]);
            (p + n * (offset - half), p + n * (offset + half))
        };
        for i in 0..self.p.len() - 1 {
            let (s0, s1) = (self.s[i], self.s[i + 1]);
            let len = s1 - s0;
            if len <= 1e-6 {
                continue;
            }
            let mut emit = |a: f32, b: f32| {
                let (r0, l0) = at(i, (a - s0) / len);
                let (r1, l1) = at(i, (b - s0) / len);
                t.quad(r0, r1, l1, l0, color);
            };
            match dash {
                None => emit(s0, s1),
                Some((on, off)) => {
                    let period = on + off;
                    let mut k = (s0 / period).floor();
                    loop {
                        let a = (k * period).max(s0);
                        let b = (k * period + on).min(s1);
                        if k * period >= s1 {
                            break;
                        }
                        if b > a {
                            emit(a, b);
                        }
                        k += 1.0;
                    }
                }
            }
        }
    }
}

/// Ear-clipping triangulation of a simple polygon (either winding).
fn triangulate(poly: &[Vec2]) -> Vec<[usize; 3]> {
    let n = poly.len();
    if n < 3 {
        return Vec::new();
    }
    let area: f32 = (0..n).map(|i| poly[i].perp_dot(poly[(i + 1) % n])).sum();
    let sign = if area >= 0.0 { 1.0 } else { -1.0 };
    let mut idx: Vec<usize> = (0..n).collect();
    let mut out = Vec::new();
    let mut guard = 0;
    while idx.len() > 3 && guard < n * n {
        guard += 1;
        let m = idx.len();
        let mut clipped = false;
        for k in 0..m {
            let (a, b, c) = (idx[(k + m - 1) % m], idx[k], idx[(k + 1) % m]);
            let (pa, pb, pc) = (poly[a], poly[b], poly[c]);
            if (pb - pa).perp_dot(pc - pb) * sign <= 0.0 {
                continue;
            }
            let inside = idx.iter().any(|&q| {
                if q == a || q == b || q == c {
                    return false;
                }
                let p = poly[q];
                let d1 = (pb - pa).perp_dot(p - pa) * sign;
                let d2 = (pc - pb).perp_dot(p - pb) * sign;
                let d3 = (pa - pc).perp_dot(p - pc) * sign;
                d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0
            });
            if !inside {
                out.push([a, b, c]);
                idx.remove(k);
                clipped = true;
                break;
            }
        }
        if !clipped {
            break;
        }
    }
    if idx.len() == 3 {
        out.push([idx[0], idx[1], idx[2]]);
    }
    out
}

impl StaticScene {
    /// Builds the static scene of a town; trees and street lamps are placed
    /// beside the road from `seed`.
    pub fn build(town: &Town, seed: u64) -> StaticScene {
        let mut t = Tris::default();
        // Small things (paint, trees, street lamps), drawn nearer.
        let mut detail = Tris::default();
        let ground_z = ground_level(town);
        road(town, &mut t);
        markings(town, &mut detail);
        sidewalks(town, ground_z, &mut t);
        crosswalks(town, &mut detail);
        buildings(town, ground_z, seed, &mut t);
        props(town, ground_z, seed, &mut detail);
        let lamps = lights(town, &mut t);
        terrain(town, ground_z, &mut t);
        let (mut vertices, cells) = into_cells(t.v, detail.v);
        let mut units = [(0, 0); UNIT_MESHES];
        for (kind, slot) in [UnitMesh::Box, UnitMesh::Prism, UnitMesh::Disc]
            .iter()
            .zip(&mut units)
        {
            let mut u = Tris::default();
            let white = pack([255, 255, 255], classes::BUILDING, false);
            match kind {
                UnitMesh::Box => u.boxed(Vec3::ZERO, Vec3::ONE, 0.0, white),
                UnitMesh::Prism => u.prism(Vec3::ZERO, 0.5, 1.0, white),
                UnitMesh::Disc => u.disc(Vec3::ZERO, 0.5, 0.0, white),
            }
            *slot = (vertices.len() as u32, u.v.len() as u32);
            vertices.extend(u.v);
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

fn road(town: &Town, t: &mut Tris) {
    let col = pack(paint::ASPHALT, classes::ROAD, false);
    let m = &town.road_surface;
    if !m.indices.is_empty() {
        let n = m.positions.len() as u32;
        let tris: Vec<[u32; 3]> = m
            .indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .filter(|c| c.iter().all(|&i| i < n))
            .collect();
        merged_mesh(&m.positions, &tris, t, col);
        return;
    }
    // No mesh: pave each lane's width along its centreline.
    for lane in &town.lanes {
        let Some(line) = Line::new(&lane.centerline) else {
            continue;
        };
        for i in 0..line.p.len() - 1 {
            let w0 = lane.width.get(i).copied().unwrap_or(3.5) * 0.5;
            let w1 = lane.width.get(i + 1).copied().unwrap_or(3.5) * 0.5;
            let (p0, p1, n0, n1) = (line.p[i], line.p[i + 1], line.n[i], line.n[i + 1]);
            t.quad(p0 - n0 * w0, p1 - n1 * w1, p1 + n1 * w1, p0 + n0 * w0, col);
        }
    }
}

/// Most a dropped rib's ends may lie off the straight edge that replaces them (metres).
const MERGE_TOLERANCE_M: f32 = 0.01;
/// Longest quad edge merging may make (metres): long quads clip badly in
/// lavapipe's fixed point.
const MERGE_MAX_SPAN_M: f32 = 25.0;

/// The ribs of a strip to keep: rib `i` runs from `a(i)` to `b(i)`, and
/// consecutive ribs bound one quad. An interior rib is dropped when both of
/// its ends, and those of every rib dropped since the last kept one, lie
/// within [`MERGE_TOLERANCE_M`] of the straight edges from the last kept rib
/// to the next one, and those edges are at most [`MERGE_MAX_SPAN_M`] long:
/// straight stretches become one quad, curves keep their samples. The first
/// and last ribs are always kept; non-finite points are never dropped.
fn kept_ribs(n: usize, a: impl Fn(usize) -> Vec3, b: impl Fn(usize) -> Vec3) -> Vec<usize> {
    if n <= 2 {
        return (0..n).collect();
    }
    let off = |p: Vec3, s: Vec3, e: Vec3| {
        let d = e - s;
        let u = ((p - s).dot(d) / d.length_squared().max(1e-12)).clamp(0.0, 1.0);
        (s + d * u).distance(p)
    };
    let mut kept = vec![0];
    for i in 1..n - 1 {
        let last = kept[kept.len() - 1];
        let straight = |side: &dyn Fn(usize) -> Vec3| {
            let (s, e) = (side(last), side(i + 1));
            s.distance(e) <= MERGE_MAX_SPAN_M
                && (last + 1..=i).all(|j| off(side(j), s, e) <= MERGE_TOLERANCE_M)
        };
        if !(straight(&a) && straight(&b)) {
            kept.push(i);
        }
    }
    kept.push(n - 1);
    kept
}

/// Two triangles sharing an edge, as their quad's corners in boundary order;
/// `None` unless they share exactly one edge and lie on either side of it.
fn quad_of(t0: [u32; 3], t1: [u32; 3], pos: &[Vec3]) -> Option<[u32; 4]> {
    let distinct = |t: [u32; 3]| t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
    if !distinct(t0) || !distinct(t1) {
        return None;
    }
    let shared: Vec<u32> = t0.iter().copied().filter(|v| t1.contains(v)).collect();
    let [u, v] = shared[..] else {
        return None;
    };
    let p = t0.iter().copied().find(|x| !t1.contains(x))?;
    let q = t1.iter().copied().find(|x| !t0.contains(x))?;
    let at = |i: u32| pos[i as usize].truncate();
    let side = |x: u32| (at(v) - at(u)).perp_dot(at(x) - at(u));
    (side(p) * side(q) < 0.0).then_some([p, u, q, v])
}

/// Draws a triangle mesh, merging its quad strips (pairs of triangles
/// sharing an edge, consecutive quads sharing a side) where they run
/// straight (see [`kept_ribs`]); whatever is not part of a strip is drawn
/// as it is. Real maps' road surfaces come as one quad per metre of lane.
fn merged_mesh(pos: &[Vec3], tris: &[[u32; 3]], t: &mut Tris, col: u32) {
    enum Piece {
        Quad([u32; 4]),
        Tri([u32; 3]),
    }
    let mut pieces = Vec::with_capacity(tris.len());
    let mut i = 0;
    while i < tris.len() {
        if let Some(q) = tris.get(i + 1).and_then(|&t1| quad_of(tris[i], t1, pos)) {
            pieces.push(Piece::Quad(q));
            i += 2;
        } else {
            pieces.push(Piece::Tri(tris[i]));
            i += 1;
        }
    }
    let p = |i: u32| pos[i as usize];
    // The rib after `rib` in quad `q` (its other side), ends matched along
    // the quad's edges; `None` unless `rib` is a side of `q`.
    let across = |q: [u32; 4], rib: [u32; 2]| {
        let j = q.iter().position(|&x| x == rib[0])?;
        if q[(j + 1) % 4] == rib[1] {
            Some([q[(j + 3) % 4], q[(j + 2) % 4]])
        } else if q[(j + 3) % 4] == rib[1] {
            Some([q[(j + 1) % 4], q[(j + 2) % 4]])
        } else {
            None
        }
    };
    let mut k = 0;
    while k < pieces.len() {
        let q = match pieces[k] {
            Piece::Tri([a, b, c]) => {
                t.tri(p(a), p(b), p(c), col);
                k += 1;
                continue;
            }
            Piece::Quad(q) => q,
        };
        k += 1;
        // The side shared with the next quad starts the strip's second rib.
        let start = match pieces.get(k) {
            Some(&Piece::Quad(next)) => (0..4).find_map(|j| {
                let rib = [q[j], q[(j + 1) % 4]];
                across(next, rib).and_then(|_| across(q, rib).map(|first| [first, rib]))
            }),
            _ => None,
        };
        let Some([first, second]) = start else {
            t.quad(p(q[0]), p(q[1]), p(q[2]), p(q[3]), col);
            continue;
        };
        let mut ribs = vec![first, second];
        while let Some(&Piece::Quad(next)) = pieces.get(k) {
            let Some(rib) = across(next, ribs[ribs.len() - 1]) else {
                break;
            };
            ribs.push(rib);
            k += 1;
        }
        let kept = kept_ribs(ribs.len(), |i| p(ribs[i][0]), |i| p(ribs[i][1]));
        for w in kept.windows(2) {
            let (r0, r1) = (ribs[w[0]], ribs[w[1]]);
            t.quad(p(r0[0]), p(r1[0]), p(r1[1]), p(r0[1]), col);
        }
    }
}

/// A line's paint pattern: `None` solid, `Some((paint, gap))` dashed (metres).
type Pattern = Option<(f32, f32)>;

fn markings(town: &Town, t: &mut Tris) {
    for m in &town.markings {
        let Some(line) = Line::new(&m.points) else {
            continue;
        };
        let rgb = match m.color {
            MarkColor::White => paint::WHITE,
            MarkColor::Yellow => paint::YELLOW,
        };
        let col = pack(rgb, classes::LANE_MARKING, false);
        let w = if m.width_m.is_finite() && m.width_m > 0.0 {
            m.width_m
        } else {
            0.12
        };
        let dash = Some(m.dash_m.unwrap_or(DEFAULT_DASH_M)).filter(|d| d.0 > 0.0 && d.1 >= 0.0);
        let solid = None;
        // (left line, right line) relative to the points' direction; None = no line.
        let lines: [(f32, Option<Pattern>); 2] = match m.kind {
            MarkKind::Solid => [(0.0, Some(solid)), (0.0, None)],
            MarkKind::Broken => [(0.0, Some(dash)), (0.0, None)],
            MarkKind::SolidSolid => [(w, Some(solid)), (-w, Some(solid))],
            MarkKind::SolidBroken => [(w, Some(solid)), (-w, Some(dash))],
            MarkKind::BrokenSolid => [(w, Some(dash)), (-w, Some(solid))],
            MarkKind::BrokenBroken => [(w, Some(dash)), (-w, Some(dash))],
            MarkKind::Curb => continue,
        };
        for (offset, pattern) in lines {
            if let Some(pattern) = pattern {
                line.strip(t, offset, w, pattern, PAINT_LIFT_M, col);
            }
        }
    }
}

fn sidewalks(town: &Town, ground_z: f32, t: &mut Tris) {
    let top = pack(paint::SIDEWALK, classes::SIDEWALK, false);
    let curb = pack(paint::CURB, classes::SIDEWALK, false);
    for sw in &town.sidewalks {
        let n = sw.inner.len().min(sw.outer.len());
        let h = if sw.height_m.is_finite() {
            sw.height_m.clamp(0.0, 1.0)
        } else {
            0.15
        };
        let kept = kept_ribs(n, |i| sw.inner[i], |i| sw.outer[i]);
        for w in kept.windows(2) {
            let (i, k) = (w[0], w[1]);
            let (a, b) = (sw.inner[i], sw.inner[k]);
            let (c, d) = (sw.outer[k], sw.outer[i]);
            if ![a, b, c, d].iter().all(|p| p.is_finite()) {
                continue;
            }
            let up = Vec3::Z * h;
            t.quad(a + up, b + up, c + up, d + up, top);
            t.quad(a, b, b + up, a + up, curb);
            let down = |p: Vec3| Vec3::new(p.x, p.y, ground_z);
            t.quad(down(d), down(c), c + up, d + up, curb);
        }
    }
}

fn crosswalks(town: &Town, t: &mut Tris) {
    let col = pack(paint::WHITE, classes::CROSSWALK, false);
    for cw in &town.crosswalks {
        let c = cw.corners;
        if !c.iter().all(|p| p.is_finite()) {
            continue;
        }
        // Stripes run across the long side (the one spanning the road).
        let (a, b, d) = if c[0].distance(c[1]) >= c[1].distance(c[2]) {
            (c[0], c[1], c[3])
        } else {
            (c[1], c[2], c[0])
        };
        let long = b - a;
        let short = d - a;
        let len = long.length();
        let (paint_m, gap_m) = (0.5, 0.5);
        let mut x = gap_m * 0.5;
        while x + paint_m <= len {
            let u0 = long * (x / len);
            let u1 = long * ((x + paint_m) / len);
            let lift = Vec3::Z * PAINT_LIFT_M;
            t.quad(
                a + u0 + lift,
                a + u1 + lift,
                a + u1 + short + lift,
                a + u0 + short + lift,
                col,
            );
            x += paint_m + gap_m;
        }
    }
}

fn buildings(town: &Town, ground_z: f32, seed: u64, t: &mut Tris) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xb011d);
    for b in &town.buildings {
        let rgb = paint::BUILDINGS[rng.random_range(0..paint::BUILDINGS.len())];
        let col = pack(rgb, classes::BUILDING, false);
        let fp = &b.footprint;
        if fp.len() < 3 || !fp.iter().all(|p| p.is_finite()) || !b.height_m.is_finite() {
            continue;
        }
        let z0 = ground_z - 1.0;
        let z1 = ground_z + b.height_m.clamp(0.5, 300.0);
        for i in 0..fp.len() {
            let (p, q) = (fp[i], fp[(i + 1) % fp.len()]);
            t.quad(p.extend(z0), q.extend(z0), q.extend(z1), p.extend(z1), col);
        }
        for [i, j, k] in triangulate(fp) {
            t.tri(fp[i].extend(z1), fp[j].extend(z1), fp[k].extend(z1), col);
        }
    }
}

/// Lane-centre points on a coarse grid, to keep props off the road.
struct RoadIndex {
    grid: BTreeMap<(i32, i32), Vec<(Vec2, f32)>>,
}

impl RoadIndex {
    const CELL: f32 = 10.0;
    fn new(town: &Town) -> RoadIndex {
        let mut grid: BTreeMap<(i32, i32), Vec<(Vec2, f32)>> = BTreeMap::new();
        for lane in &town.lanes {
            for (i, p) in lane.centerline.iter().enumerate() {
                let half = lane.width.get(i).copied().unwrap_or(3.5) * 0.5;
                let key = (
                    (p.x / Self::CELL).floor() as i32,
                    (p.y / Self::CELL).floor() as i32,
                );
                grid.entry(key).or_default().push((p.truncate(), half));
            }
        }
        RoadIndex { grid }
    }
    /// Whether `p` is within `margin` metres of a lane's paved width.
    fn near_road(&self, p: Vec2, margin: f32) -> bool {
        let (cx, cy) = (
            (p.x / Self::CELL).floor() as i32,
            (p.y / Self::CELL).floor() as i32,
        );
        (-1..=1).any(|dx| {
            (-1..=1).any(|dy| {
                self.grid
                    .get(&(cx + dx, cy + dy))
                    .is_some_and(|v| v.iter().any(|&(q, half)| q.distance(p) < half + margin))
            })
        })
    }
}

/// Trees and street lamps beside the road, placed from `seed`.
fn props(town: &Town, ground_z: f32, seed: u64, t: &mut Tris) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7733);
    let index = RoadIndex::new(town);
    let trunk = pack(paint::TRUNK, classes::VEGETATION, false);
    let leaves = pack(paint::LEAVES, classes::VEGETATION, false);
    let metal = pack(paint::METAL, classes::BUILDING, false);
    // Candidate spots: 1 m beyond each sidewalk's outer edge, every ~14 m
    // of its length (jittered).
    let mut spots = Vec::new();
    for sw in &town.sidewalks {
        let n = sw.inner.len().min(sw.outer.len());
        let mut next = rng.random_range(2.0..14.0f32);
        let mut walked = 0.0;
        for i in 1..n {
            let (a, b) = (sw.outer[i - 1], sw.outer[i]);
            let len = a.distance(b);
            if !len.is_finite() {
                continue;
            }
            while next <= walked + len {
                let u = (next - walked) / len.max(1e-6);
                let out = (b - sw.inner[i]).truncate().normalize_or_zero();
                spots.push((a.lerp(b, u).truncate() + out, out));
                next += rng.random_range(11.0..17.0f32);
            }
            walked += len;
        }
    }
    for (p, out) in spots {
        if !p.is_finite() || index.near_road(p, 2.0) {
            continue;
        }
        let base = p.extend(ground_z);
        let roll: f32 = rng.random_range(0.0..1.0);
        if roll < 0.5 {
            let h = rng.random_range(2.0..3.0f32);
            let r = rng.random_range(1.2..2.0f32);
            t.boxed(base, Vec3::new(0.3, 0.3, h + 0.5), 0.0, trunk);
            t.prism_n(base + Vec3::Z * h, r, r * 1.6, 6, leaves);
        } else if roll < 0.7 {
            let heading = (-out).to_angle();
            t.boxed(base, Vec3::new(0.16, 0.16, 6.5), 0.0, metal);
            let arm = base + Vec3::Z * 6.3 + (-out).extend(0.0) * 0.9;
            t.boxed(arm, Vec3::new(1.8, 0.12, 0.12), heading, metal);
        }
    }
}

/// Traffic-light poles and housings with dark lamps; returns the lamp slots.
fn lights(town: &Town, t: &mut Tris) -> Vec<LampSlots> {
    let pole = pack(paint::METAL, classes::LIGHT_POLE, false);
    let housing = pack(paint::HOUSING, classes::LIGHT_POLE, false);
    let dark = pack(paint::DARK_LAMP, classes::LIGHT_POLE, false);
    let mut out = Vec::with_capacity(town.lights.len());
    for l in &town.lights {
        let heading = if l.heading.is_finite() {
            l.heading
        } else {
            0.0
        };
        let h = if l.head_height_m.is_finite() {
            l.head_height_m.clamp(1.0, 20.0)
        } else {
            3.0
        };
        let fwd = Vec3::new(heading.cos(), heading.sin(), 0.0);
        let foot = if l.position.is_finite() {
            l.position
        } else {
            Vec3::ZERO
        };
        let head = foot + Vec3::Z * h;
        t.boxed(
            foot,
            Vec3::new(0.16, 0.16, h - HOUSING_M.z * 0.5),
            heading,
            pole,
        );
        t.boxed(
            head - Vec3::Z * (HOUSING_M.z * 0.5),
            Vec3::new(HOUSING_M.y, HOUSING_M.x, HOUSING_M.z),
            heading,
            housing,
        );
        let front = fwd * (HOUSING_M.y * 0.5 + 0.005);
        let centers = [1.0, 0.0, -1.0].map(|k| head + front + Vec3::Z * (k * LAMP_SPACING_M));
        for c in centers {
            t.disc(c, LAMP_DIAMETER_M * 0.5, heading, dark);
        }
        out.push(LampSlots {
            centers: centers.map(|c| c + fwd * 0.01),
            heading,
        });
    }
    out
}

/// A ground plane around the town, in cell-sized tiles.
fn terrain(town: &Town, ground_z: f32, t: &mut Tris) {
    let col = pack(paint::TERRAIN, classes::TERRAIN, false);
    let (lo, hi) = town.bounds;
    if !lo.is_finite() || !hi.is_finite() || (hi - lo).max_element() > 1e5 {
        return;
    }
    let margin = 200.0;
    let x0 = ((lo.x - margin) / CELL_M).floor() as i32;
    let x1 = ((hi.x + margin) / CELL_M).ceil() as i32;
    let y0 = ((lo.y - margin) / CELL_M).floor() as i32;
    let y1 = ((hi.y + margin) / CELL_M).ceil() as i32;
    for i in x0..x1 {
        for j in y0..y1 {
            let (a, b) = (i as f32 * CELL_M, (i + 1) as f32 * CELL_M);
            let (c, d) = (j as f32 * CELL_M, (j + 1) as f32 * CELL_M);
            let z = ground_z;
            t.quad(
                Vec3::new(a, c, z),
                Vec3::new(b, c, z),
                Vec3::new(b, d, z),
                Vec3::new(a, d, z),
                col,
            );
        }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pack_puts_class_in_the_top_byte() {
        let w = pack([1, 2, 3], classes::LAMP_RED, true);
        assert_eq!(w & 0xff_ffff, 0x03_02_01);
        assert_eq!((w >> 24) & 0x7f, u32::from(classes::LAMP_RED));
        assert_eq!(w >> 31, 1);
    }

    #[test]
    fn triangulates_a_concave_l_shape() {
        let l = [
            Vec2::new(0.0, 0.0),
            Vec2::new(2.0, 0.0),
            Vec2::new(2.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(1.0, 2.0),
            Vec2::new(0.0, 2.0),
        ];
        let tris = triangulate(&l);
        assert_eq!(tris.len(), 4);
        let area: f32 = tris
            .iter()
            .map(|&[a, b, c]| 0.5 * (l[b] - l[a]).perp_dot(l[c] - l[a]).abs())
            .sum();
        assert!((area - 3.0).abs() < 1e-5, "area {area}");
    }

    fn area(v: &[Vertex]) -> f32 {
        v.chunks_exact(3)
            .map(|q| {
                let (a, b, c) = (
                    Vec3::from(q[0].pos),
                    Vec3::from(q[1].pos),
                    Vec3::from(q[2].pos),
                );
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// A lane-like strip: ribs `[left, right]` at each centre point, two
    /// triangles per quad as xodr emits them.
    fn strip_mesh(centre: &[Vec3], half_w: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut pos = Vec::new();
        for (i, p) in centre.iter().enumerate() {
            let (a, b) = (
                centre[i.saturating_sub(1)],
                centre[(i + 1).min(centre.len() - 1)],
            );
            let d = (b - a).normalize();
            let n = Vec3::new(-d.y, d.x, 0.0);
            pos.push(*p + n * half_w);
            pos.push(*p - n * half_w);
        }
        let mut tris = Vec::new();
        for i in 0..centre.len() as u32 - 1 {
            let (l0, r0, l1, r1) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
            tris.push([l0, r0, r1]);
            tris.push([l0, r1, l1]);
        }
        (pos, tris)
    }

    #[test]
    fn straight_road_strips_merge_into_long_quads() {
        // 60 m of lane sampled every metre: 60 quads become 3 (25 m cap).
        let centre: Vec<Vec3> = (0..=60).map(|i| Vec3::new(i as f32, 5.0, 0.3)).collect();
        let (pos, tris) = strip_mesh(&centre, 1.75);
        let mut t = Tris::default();
        merged_mesh(&pos, &tris, &mut t, 0);
        assert_eq!(t.v.len() / 6, 3, "quads after merging");
        assert!(
            (area(&t.v) - 60.0 * 3.5).abs() < 1e-2,
            "area {}",
            area(&t.v)
        );
        for v in &t.v {
            assert!((v.pos[2] - 0.3).abs() < 1e-6);
            assert!((v.pos[1] - 5.0).abs() - 1.75 < 1e-4, "{:?}", v.pos);
        }
    }

    /// A strip along an arc of `radius_m`, one sample per metre for 31 m:
    /// (quads after merging, area before, area after).
    fn merged_arc(radius_m: f32) -> (usize, f32, f32) {
        let centre: Vec<Vec3> = (0..=31)
            .map(|i| {
                let a = i as f32 / radius_m;
                Vec3::new(radius_m * a.cos(), radius_m * a.sin(), 0.0)
            })
            .collect();
        let (pos, tris) = strip_mesh(&centre, 1.75);
        let mut plain = Tris::default();
        for &[a, b, c] in &tris {
            plain.tri(pos[a as usize], pos[b as usize], pos[c as usize], 0);
        }
        let mut t = Tris::default();
        merged_mesh(&pos, &tris, &mut t, 0);
        (t.v.len() / 6, area(&plain.v), area(&t.v))
    }

    #[test]
    fn curved_road_strips_keep_their_samples() {
        // Radius 20 m: the chord over two samples is 25 mm off the middle
        // one, more than the 10 mm tolerance: every rib stays.
        let (quads, a0, a1) = merged_arc(20.0);
        assert_eq!(quads, 31);
        assert!((a0 - a1).abs() < 1e-3, "{a0} vs {a1}");
        // Radius 400 m: chords up to ~5.6 m stay within 10 mm of the arc.
        let (quads, a0, a1) = merged_arc(400.0);
        assert!((5..=10).contains(&quads), "{quads} quads of 31");
        // The merged surface covers the same ground to within the tolerance.
        assert!((a0 - a1).abs() < 0.01 * 31.0 * 2.0, "{a0} vs {a1}");
    }

    #[test]
    fn lone_triangles_and_odd_pairs_are_drawn_as_they_are() {
        let pos = vec![
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(5.0, 5.0, 0.0),
            Vec3::new(6.0, 5.0, 0.0),
            Vec3::new(5.0, 6.0, 0.0),
        ];
        let tris = vec![[0, 1, 2], [3, 4, 5]];
        let mut t = Tris::default();
        merged_mesh(&pos, &tris, &mut t, 0);
        assert_eq!(t.v.len(), 6);
        assert!((area(&t.v) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn straight_sidewalks_merge() {
        let inner: Vec<Vec3> = (0..=40).map(|i| Vec3::new(i as f32, 0.0, 0.0)).collect();
        let outer: Vec<Vec3> = (0..=40).map(|i| Vec3::new(i as f32, 3.0, 0.0)).collect();
        assert_eq!(kept_ribs(41, |i| inner[i], |i| outer[i]), vec![0, 25, 40]);
        // A kink in the outer edge keeps its rib.
        let mut bent = outer.clone();
        bent[10].y = 3.5;
        let kept = kept_ribs(41, |i| inner[i], |i| bent[i]);
        assert!(kept.contains(&10), "{kept:?}");
        let mut nan = outer;
        nan[5].x = f32::NAN;
        assert!(kept_ribs(41, |i| inner[i], |i| nan[i]).contains(&5));
    }

    #[test]
    fn dashes_cover_the_painted_share() {
        let line = Line::new(&[Vec3::ZERO, Vec3::new(90.0, 0.0, 0.0)]).unwrap();
        let mut t = Tris::default();
        line.strip(&mut t, 0.0, 0.1, Some((3.0, 6.0)), 0.0, 0);
        // 10 dashes of 3 m x 0.1 m = 3 m^2.
        let area: f32 =
            t.v.chunks_exact(3)
                .map(|q| {
                    let (a, b, c) = (
                        Vec3::from(q[0].pos),
                        Vec3::from(q[1].pos),
                        Vec3::from(q[2].pos),
                    );
                    0.5 * (b - a).cross(c - a).length()
                })
                .sum();
        assert!((area - 3.0).abs() < 1e-3, "area {area}");
    }
}
