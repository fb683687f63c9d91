//! What stands beside the road: buildings, trees and street lamps (placed by
//! `world::map::props` from the seed), and the terrain around the town.

use glam::Vec3;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use world::Town;
use world::map::props::{LAMP_HEIGHT_M, LAMP_POST_M, PropKind, TRUNK_M, place_props};

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

/// Trees and street lamps beside the road, where [`place_props`] puts them for `seed`
/// (the physics makes the same ones solid).
pub(super) fn props(town: &Town, ground_z: f32, seed: u64, t: &mut Tris) {
    let trunk = pack(paint::TRUNK, classes::VEGETATION, false);
    let leaves = pack(paint::LEAVES, classes::VEGETATION, false);
    let metal = pack(paint::METAL, classes::BUILDING, false);
    for p in place_props(town, seed) {
        let base = p.position.extend(ground_z);
        match p.kind {
            PropKind::Tree {
                crown_base_m: h,
                crown_radius_m: r,
            } => {
                t.boxed(base, Vec3::new(TRUNK_M, TRUNK_M, h + 0.5), 0.0, trunk);
                t.prism_n(base + Vec3::Z * h, r, r * 1.6, 6, leaves);
            }
            PropKind::StreetLamp => {
                let heading = (-p.outward).to_angle();
                t.boxed(
                    base,
                    Vec3::new(LAMP_POST_M, LAMP_POST_M, LAMP_HEIGHT_M),
                    0.0,
                    metal,
                );
                let arm = base + Vec3::Z * 6.3 + (-p.outward).extend(0.0) * 0.9;
                t.boxed(arm, Vec3::new(1.8, 0.12, 0.12), heading, metal);
            }
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
