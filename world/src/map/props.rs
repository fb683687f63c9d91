//! Street furniture beside the road: trees and street lamps, placed from a seed.
//!
//! One placement for everything that needs it: the renderer draws them and the
//! physics makes them solid (a car that leaves the road over a kerb hits a tree
//! trunk or a lamp post as it would a building). Spots lie 1 m beyond each
//! sidewalk's outer edge, about every 14 m of its length, never within 2 m of a
//! lane's paved width; each spot holds a tree (half of them), a street lamp (a
//! fifth) or nothing.

use std::collections::BTreeMap;

use glam::Vec2;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::map::town::Town;

/// Side of a tree trunk's square section (metres).
pub const TRUNK_M: f32 = 0.3;
/// Side of a street lamp post's square section (metres).
pub const LAMP_POST_M: f32 = 0.16;
/// Height of a street lamp post (metres).
pub const LAMP_HEIGHT_M: f32 = 6.5;

/// What stands at a spot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PropKind {
    /// A tree: trunk `trunk_m` high (metres), crown of radius `crown_radius_m`.
    Tree {
        /// Height of the crown's base above the ground (metres); the trunk reaches 0.5 m into it.
        crown_base_m: f32,
        /// The crown's radius (metres).
        crown_radius_m: f32,
    },
    /// A street lamp: a post with an arm over the sidewalk.
    StreetLamp,
}

/// A prop and where it stands.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prop {
    /// Foot of the trunk or post (metres, ground plane).
    pub position: Vec2,
    /// Unit vector away from the road (the sidewalk's outward normal there).
    pub outward: Vec2,
    /// Tree or lamp.
    pub kind: PropKind,
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

/// The town's trees and street lamps for `seed` (a run's traffic seed), in a fixed order.
pub fn place_props(town: &Town, seed: u64) -> Vec<Prop> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7733);
    let index = RoadIndex::new(town);
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
    let mut props = Vec::new();
    for (position, outward) in spots {
        if !position.is_finite() || index.near_road(position, 2.0) {
            continue;
        }
        let roll: f32 = rng.random_range(0.0..1.0);
        let kind = if roll < 0.5 {
            let crown_base_m = rng.random_range(2.0..3.0f32);
            let crown_radius_m = rng.random_range(1.2..2.0f32);
            PropKind::Tree {
                crown_base_m,
                crown_radius_m,
            }
        } else if roll < 0.7 {
            PropKind::StreetLamp
        } else {
            continue;
        };
        props.push(Prop {
            position,
            outward,
            kind,
        });
    }
    props
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown;

    #[test]
    fn props_stand_off_the_road_beyond_the_sidewalks_and_follow_the_seed() {
        let town = testtown::grid(3, 3, 100.0);
        let a = place_props(&town, 3);
        assert!(a.len() > 20, "{} props", a.len());
        assert_eq!(a, place_props(&town, 3), "the same seed, the same props");
        assert_ne!(a, place_props(&town, 4), "another seed, other props");
        let index = RoadIndex::new(&town);
        assert!(a.iter().all(|p| !index.near_road(p.position, 2.0)));
        assert!(a.iter().any(|p| matches!(p.kind, PropKind::Tree { .. })));
        assert!(a.iter().any(|p| p.kind == PropKind::StreetLamp));
    }
}
