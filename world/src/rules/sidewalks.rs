//! The sidewalk under a point: one rule for the vehicle physics (a wheel
//! climbing a kerb or leaving it, `crate::agents::kerb`), the ego's height, and
//! the on-sidewalk monitor.
//!
//! A sidewalk is the strip between its road-side edge (the kerb) and its outer
//! edge ([`crate::map::Sidewalk`]), cut into quadrilaterals between matched
//! points of the two edges; a point is on it when it lies inside one of them.

use glam::Vec2;

use crate::map::town::Town;
use crate::road::geometry::point_in_polygon;

/// Side of the grid cells that index the sidewalk pieces (metres).
const CELL_M: f32 = 5.0;

/// Where a point is on a sidewalk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnSidewalk {
    /// Height of the walking surface above the road (metres).
    pub height_m: f32,
    /// Unit direction of the kerb (the road-side edge) there.
    pub kerb_dir: Vec2,
}

/// One quadrilateral piece of a sidewalk.
#[derive(Debug, Clone)]
struct Piece {
    corners: [Vec2; 4],
    height_m: f32,
    kerb_dir: Vec2,
}

/// The town's sidewalks, indexed on a grid for [`SidewalkGrid::under`].
#[derive(Debug, Clone)]
pub struct SidewalkGrid {
    pieces: Vec<Piece>,
    origin: Vec2,
    nx: usize,
    ny: usize,
    /// For each cell, the pieces whose bounding box touches it.
    cells: Vec<Vec<u32>>,
}

impl SidewalkGrid {
    /// Indexes the town's sidewalks (pieces with a non-finite corner are left out).
    pub fn new(town: &Town) -> SidewalkGrid {
        let mut pieces = Vec::new();
        for sw in &town.sidewalks {
            let n = sw.inner.len().min(sw.outer.len());
            for i in 1..n {
                let corners = [
                    sw.inner[i - 1].truncate(),
                    sw.inner[i].truncate(),
                    sw.outer[i].truncate(),
                    sw.outer[i - 1].truncate(),
                ];
                if !corners.iter().all(|c| c.is_finite()) {
                    continue;
                }
                pieces.push(Piece {
                    corners,
                    height_m: if sw.height_m.is_finite() {
                        sw.height_m
                    } else {
                        0.0
                    },
                    kerb_dir: (corners[1] - corners[0]).normalize_or_zero(),
                });
            }
        }
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for p in pieces.iter().flat_map(|p| p.corners) {
            lo = lo.min(p);
            hi = hi.max(p);
        }
        if pieces.is_empty() {
            (lo, hi) = (Vec2::ZERO, Vec2::ZERO);
        }
        let cells_along = |a: f32, b: f32| (((b - a) / CELL_M).floor() as usize + 1).min(100_000);
        let (nx, ny) = (cells_along(lo.x, hi.x), cells_along(lo.y, hi.y));
        let mut cells = vec![Vec::new(); nx * ny];
        let cell = |p: Vec2| {
            (
                (((p.x - lo.x) / CELL_M).floor() as usize).min(nx - 1),
                (((p.y - lo.y) / CELL_M).floor() as usize).min(ny - 1),
            )
        };
        for (k, piece) in pieces.iter().enumerate() {
            let (mut a, mut b) = (piece.corners[0], piece.corners[0]);
            for c in piece.corners {
                a = a.min(c);
                b = b.max(c);
            }
            let ((x0, y0), (x1, y1)) = (cell(a), cell(b));
            for y in y0..=y1 {
                for x in x0..=x1 {
                    cells[x + y * nx].push(k as u32);
                }
            }
        }
        SidewalkGrid {
            pieces,
            origin: lo,
            nx,
            ny,
            cells,
        }
    }

    /// The sidewalk under `p`, if any.
    pub fn under(&self, p: Vec2) -> Option<OnSidewalk> {
        let d = (p - self.origin) / CELL_M;
        if !(d.x >= 0.0 && d.y >= 0.0) {
            return None;
        }
        let (x, y) = (d.x as usize, d.y as usize);
        if x >= self.nx || y >= self.ny {
            return None;
        }
        self.cells[x + y * self.nx].iter().find_map(|&k| {
            let piece = &self.pieces[k as usize];
            point_in_polygon(&piece.corners, p).then_some(OnSidewalk {
                height_m: piece.height_m,
                kerb_dir: piece.kerb_dir,
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown;

    #[test]
    fn a_point_between_kerb_and_outer_edge_is_on_the_sidewalk() {
        // The test town's lanes: 3.5 m each side of y = 0 between junctions, then a
        // 2.5 m sidewalk 0.15 m high.
        let town = testtown::grid(3, 1, 100.0);
        let g = SidewalkGrid::new(&town);
        let on = g
            .under(Vec2::new(50.0, -4.5))
            .expect("on the southern sidewalk");
        assert_eq!(on.height_m, 0.15);
        assert!(on.kerb_dir.y.abs() < 1e-3 && (on.kerb_dir.x.abs() - 1.0).abs() < 1e-3);
        assert!(g.under(Vec2::new(50.0, 4.5)).is_some(), "the northern one");
        assert_eq!(g.under(Vec2::new(50.0, -1.75)), None, "a lane");
        assert_eq!(g.under(Vec2::new(50.0, -9.0)), None, "beyond the sidewalk");
        assert_eq!(g.under(Vec2::new(-1e6, 0.0)), None, "far away");
        assert_eq!(g.under(Vec2::new(f32::NAN, 0.0)), None);
    }
}
