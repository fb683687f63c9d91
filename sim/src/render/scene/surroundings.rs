//! What stands beside the road: buildings, trees and street lamps placed
//! from the seed, and the terrain around the town.

use std::collections::BTreeMap;

use glam::{Vec2, Vec3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use world::Town;

use super::CELL_M;
use super::primitives::{Tris, pack, paint};
use super::triangulate::triangulate;
use crate::render::classes;

/// Buildings: walls and a triangulated roof, colours from `seed`.
pub(super) fn buildings(town: &Town, ground_z: f32, seed: u64, t: &mut Tris) {
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
pub(super) fn props(town: &Town, ground_z: f32, seed: u64, t: &mut Tris) {
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

/// A ground plane around the town, in cell-sized tiles.
pub(super) fn terrain(town: &Town, ground_z: f32, t: &mut Tris) {
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
