//! The map's objects: buildings (outlines or boxes) and painted crosswalks.

use glam::Vec2;

use super::Builder;
use super::validate::MAX_COORD_M;
use crate::map::{Building, Crosswalk};
use crate::road::geometry::signed_area;

impl Builder<'_> {
    pub(super) fn objects(&mut self) {
        for o in self.ctx.net.objects() {
            let poly: Option<(Vec<Vec2>, f32)> = match &o.shape {
                xodr::Shape::Outline {
                    corners,
                    closed: true,
                    ..
                } if corners.len() >= 3 => {
                    let h = corners
                        .iter()
                        .map(|c| c.top.z - c.base.z)
                        .fold(0.0, f32::max);
                    Some((
                        corners
                            .iter()
                            .map(|c| Vec2::new(c.base.x, c.base.y))
                            .collect(),
                        h,
                    ))
                }
                xodr::Shape::Solid {
                    position,
                    heading,
                    extent:
                        Some(xodr::Extent::Box {
                            length,
                            width,
                            height,
                        }),
                    ..
                } => {
                    let f = Vec2::from_angle(*heading);
                    let l = f.perp();
                    let c = Vec2::new(position.x, position.y);
                    let (hl, hw) = (length * 0.5, width * 0.5);
                    Some((
                        vec![
                            c - f * hl - l * hw,
                            c + f * hl - l * hw,
                            c + f * hl + l * hw,
                            c - f * hl + l * hw,
                        ],
                        *height,
                    ))
                }
                _ => None,
            };
            let Some((mut poly, h)) = poly else { continue };
            if poly
                .iter()
                .any(|p| !p.is_finite() || p.x.abs() > MAX_COORD_M || p.y.abs() > MAX_COORD_M)
            {
                continue;
            }
            if signed_area(&poly) < 0.0 {
                poly.reverse();
            }
            match o.kind {
                xodr::ObjectType::Building => self.town.buildings.push(Building {
                    footprint: poly,
                    height_m: if h > 0.0 { h } else { 10.0 },
                }),
                xodr::ObjectType::Crosswalk if poly.len() == 4 => {
                    let z = 0.0;
                    let c = [
                        poly[0].extend(z),
                        poly[1].extend(z),
                        poly[2].extend(z),
                        poly[3].extend(z),
                    ];
                    self.town.crosswalks.push(Crosswalk {
                        corners: c,
                        from_map: true,
                    });
                }
                _ => {}
            }
        }
    }
}
