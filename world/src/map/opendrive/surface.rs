//! The road surface mesh of the driving lanes (triangles wound
//! counter-clockwise seen from above) and the town's bounds.

use std::collections::HashMap;

use glam::Vec2;

use super::{Builder, p3};
use crate::map::Mesh;

impl Builder<'_> {
    pub(super) fn surface(&mut self) {
        let mesh = self.ctx.net.surface_mesh();
        let mut out = Mesh::default();
        let mut remap: HashMap<u32, u32> = HashMap::new();
        for span in &mesh.lanes {
            if !self.lane_of.contains_key(&span.lane) {
                continue;
            }
            for tri in
                mesh.indices[span.indices.start as usize..span.indices.end as usize].chunks_exact(3)
            {
                let mut idx = [0u32; 3];
                for k in 0..3 {
                    let v = tri[k];
                    idx[k] = *remap.entry(v).or_insert_with(|| {
                        out.positions.push(p3(mesh.vertices[v as usize]));
                        (out.positions.len() - 1) as u32
                    });
                }
                let a = out.positions[idx[0] as usize].truncate();
                let b = out.positions[idx[1] as usize].truncate();
                let c = out.positions[idx[2] as usize].truncate();
                if (b - a).perp_dot(c - a) < 0.0 {
                    idx.swap(1, 2);
                }
                out.indices.extend_from_slice(&idx);
            }
        }
        self.town.road_surface = out;
    }

    pub(super) fn bounds(&mut self) {
        let mut lo = Vec2::splat(f32::MAX);
        let mut hi = Vec2::splat(f32::MIN);
        for l in self.ctx.net.lanes() {
            for p in l.center.points() {
                let q = Vec2::new(p.x, p.y);
                lo = lo.min(q - Vec2::splat(l.width * 0.5));
                hi = hi.max(q + Vec2::splat(l.width * 0.5));
            }
        }
        if lo.x > hi.x {
            lo = Vec2::ZERO;
            hi = Vec2::ZERO;
        }
        self.town.bounds = (lo, hi);
    }
}
