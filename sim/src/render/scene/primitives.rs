//! The pieces every builder uses: the packed vertex, the triangle-list
//! builder, painted strips along polylines, and the palette.

use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};

use crate::render::classes::ClassId;

/// Lift of paint above the surface it lies on (metres), against z-fighting.
pub(super) const PAINT_LIFT_M: f32 = 0.02;

/// One vertex: position and a packed colour/class word (see [`pack`]).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct Vertex {
    /// Position (metres; world frame for static geometry, model frame for unit meshes).
    pub pos: [f32; 3],
    /// Packed sRGB colour, class id and emissive flag.
    pub color: u32,
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

/// A triangle-list builder.
#[derive(Debug, Default)]
pub(super) struct Tris {
    pub(super) v: Vec<Vertex>,
}

impl Tris {
    pub(super) fn tri(&mut self, a: Vec3, b: Vec3, c: Vec3, color: u32) {
        for p in [a, b, c] {
            self.v.push(Vertex {
                pos: p.to_array(),
                color,
            });
        }
    }
    pub(super) fn quad(&mut self, a: Vec3, b: Vec3, c: Vec3, d: Vec3, color: u32) {
        self.tri(a, b, c, color);
        self.tri(a, c, d, color);
    }
    /// An upright box: bottom centre, size (length along heading, width, height).
    pub(super) fn boxed(&mut self, base: Vec3, size: Vec3, heading: f32, color: u32) {
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
    pub(super) fn prism(&mut self, base: Vec3, radius: f32, height: f32, color: u32) {
        self.prism_n(base, radius, height, 8, color);
    }
    /// An upright prism with `sides` sides: bottom centre, radius, height.
    pub(super) fn prism_n(
        &mut self,
        base: Vec3,
        radius: f32,
        height: f32,
        sides: usize,
        color: u32,
    ) {
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
    pub(super) fn disc(&mut self, c: Vec3, radius: f32, heading: f32, color: u32) {
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
pub(super) mod paint {
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

/// A polyline with arc lengths and per-point unit side normals (to the left).
pub(super) struct Line {
    pub(super) p: Vec<Vec3>,
    s: Vec<f32>,
    pub(super) n: Vec<Vec3>,
}

impl Line {
    pub(super) fn new(points: &[Vec3]) -> Option<Line> {
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
    pub(super) fn strip(
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

/// The area of a triangle list (square metres), for tests of the builders.
#[cfg(test)]
pub(super) fn area(v: &[Vertex]) -> f32 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::classes;

    #[test]
    fn pack_puts_class_in_the_top_byte() {
        let w = pack([1, 2, 3], classes::LAMP_RED, true);
        assert_eq!(w & 0xff_ffff, 0x03_02_01);
        assert_eq!((w >> 24) & 0x7f, u32::from(classes::LAMP_RED));
        assert_eq!(w >> 31, 1);
    }

    #[test]
    fn dashes_cover_the_painted_share() {
        let line = Line::new(&[Vec3::ZERO, Vec3::new(90.0, 0.0, 0.0)]).unwrap();
        let mut t = Tris::default();
        line.strip(&mut t, 0.0, 0.1, Some((3.0, 6.0)), 0.0, 0);
        // 10 dashes of 3 m x 0.1 m = 3 m^2.
        let area = area(&t.v);
        assert!((area - 3.0).abs() < 1e-3, "area {area}");
    }
}
