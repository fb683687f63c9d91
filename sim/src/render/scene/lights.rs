//! Traffic lights: poles and housings with dark lamps (static), the slots
//! where the lit lamp is drawn each frame, and the lit lamps' paint.

use glam::Vec3;
use world::{LightState, Town};

use super::primitives::{Tris, pack, paint};
use crate::render::classes::{self, ClassId};

/// Diameter of a traffic-light lamp (metres): the common 300 mm lens.
pub const LAMP_DIAMETER_M: f32 = 0.30;
/// Vertical spacing of the three lamps in a housing (metres).
const LAMP_SPACING_M: f32 = 0.38;
/// Housing size: width, depth, height (metres).
const HOUSING_M: Vec3 = Vec3::new(0.45, 0.35, 1.2);

/// Where the three lamps of one traffic light sit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LampSlots {
    /// Centres of the red, yellow and green lamps (metres, world frame), just in front of the housing.
    pub centers: [Vec3; 3],
    /// The direction the lamps face (radians, counter-clockwise from +x).
    pub heading: f32,
}

/// Lit-lamp colours (sRGB) and classes by light state.
pub fn lamp_paint(state: LightState) -> ([u8; 3], ClassId, usize) {
    match state {
        LightState::Red => ([255, 40, 20], classes::LAMP_RED, 0),
        LightState::Yellow => ([255, 200, 0], classes::LAMP_YELLOW, 1),
        LightState::Green => ([40, 255, 90], classes::LAMP_GREEN, 2),
    }
}

/// Traffic-light poles and housings with dark lamps; returns the lamp slots.
pub(super) fn lights(town: &Town, t: &mut Tris) -> Vec<LampSlots> {
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
