//! A hand-made town for demos, tests and benchmarks: a grid of four-way
//! junctions with two-lane roads, markings, sidewalks, crosswalks, traffic
//! lights on the near-right corner of every approach, and buildings.
//! Right-hand traffic; no connecting lanes inside junctions (the camera does
//! not need them).

use glam::{Vec2, Vec3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use world::{
    ActorKind, ActorSnapshot, Building, Crosswalk, DriveLane, Junction, JunctionIdx, LaneIdx,
    LaneMarking, LightIdx, LightState, MarkColor, MarkKind, Sidewalk, StopLine, Town, TrafficLight,
};

use world::EgoPose;

/// Lane width (metres).
pub const LANE_W_M: f32 = 3.5;
/// Sidewalk width (metres).
const WALK_W_M: f32 = 3.0;
/// Height of a traffic light's housing centre (metres).
pub const HEAD_HEIGHT_M: f32 = 3.0;

/// A grid town: `nx` x `ny` junctions `block_m` apart, the junction (0, 0) at the origin.
pub fn grid_town(nx: u32, ny: u32, block_m: f32, seed: u64) -> Town {
    let mut b = Builder {
        town: Town::empty(""),
    };
    let half = LANE_W_M;
    let ext = block_m * 0.5;
    let xs: Vec<f32> = (0..nx).map(|i| i as f32 * block_m).collect();
    let ys: Vec<f32> = (0..ny).map(|j| j as f32 * block_m).collect();
    // Roads along x (at each y) and along y (at each x), between junctions and past the ends.
    for (j, &y) in ys.iter().enumerate() {
        let mut stops = vec![xs[0] - ext];
        stops.extend(xs.iter().copied());
        stops.push(xs[xs.len() - 1] + ext);
        for w in stops.windows(2) {
            let a = if w[0] < xs[0] { w[0] } else { w[0] + half };
            let e = if w[1] > xs[xs.len() - 1] {
                w[1]
            } else {
                w[1] - half
            };
            b.road(Vec2::new(a, y), Vec2::new(e, y), j as u32);
        }
    }
    for (i, &x) in xs.iter().enumerate() {
        let mut stops = vec![ys[0] - ext];
        stops.extend(ys.iter().copied());
        stops.push(ys[ys.len() - 1] + ext);
        for w in stops.windows(2) {
            let a = if w[0] < ys[0] { w[0] } else { w[0] + half };
            let e = if w[1] > ys[ys.len() - 1] {
                w[1]
            } else {
                w[1] - half
            };
            b.road(Vec2::new(x, a), Vec2::new(x, e), 1000 + i as u32);
        }
    }
    for &x in &xs {
        for &y in &ys {
            b.junction(Vec2::new(x, y));
        }
    }
    // Buildings: a 2 x 2 grid of lots in each block.
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let margin = half + WALK_W_M + 3.0;
    for w in xs.windows(2) {
        for v in ys.windows(2) {
            let (x0, x1) = (w[0] + margin, w[1] - margin);
            let (y0, y1) = (v[0] + margin, v[1] - margin);
            let (mx, my) = ((x0 + x1) * 0.5, (y0 + y1) * 0.5);
            for (a, c) in [(x0, mx), (mx, x1)] {
                for (d, e) in [(y0, my), (my, y1)] {
                    let g = 2.0;
                    let fp = vec![
                        Vec2::new(a + g, d + g),
                        Vec2::new(c - g, d + g),
                        Vec2::new(c - g, e - g),
                        Vec2::new(a + g, e - g),
                    ];
                    let height_m = rng.random_range(6.0..24.0f32);
                    b.town.buildings.push(Building {
                        footprint: fp,
                        height_m,
                    });
                }
            }
        }
    }
    let lo = Vec2::new(xs[0] - ext, ys[0] - ext);
    let hi = Vec2::new(xs[xs.len() - 1] + ext, ys[ys.len() - 1] + ext);
    b.town.bounds = (lo, hi);
    b.town.name = format!("demo-grid-{nx}x{ny}");
    b.town
}

struct Builder {
    town: Town,
}

impl Builder {
    fn quad(&mut self, c: [Vec2; 4]) {
        let m = &mut self.town.road_surface;
        let base = m.positions.len() as u32;
        m.positions.extend(c.iter().map(|p| p.extend(0.0)));
        m.indices
            .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }

    /// A straight two-lane road from `a` to `b` (its centre line).
    fn road(&mut self, a: Vec2, b: Vec2, road: u32) {
        let dir = (b - a).normalize();
        let left = dir.perp();
        let len = a.distance(b);
        let h = LANE_W_M;
        self.quad([a - left * h, b - left * h, b + left * h, a + left * h]);
        let n = len.ceil().max(1.0) as usize;
        let pts = |off: f32, rev: bool| -> Vec<Vec3> {
            let mut v: Vec<Vec3> = (0..=n)
                .map(|i| (a + dir * (len * i as f32 / n as f32) + left * off).extend(0.0))
                .collect();
            if rev {
                v.reverse();
            }
            v
        };
        for (od_lane, off, rev) in [(-1, -h * 0.5, false), (1, h * 0.5, true)] {
            let centerline = pts(off, rev);
            let s = (0..=n).map(|i| len * i as f32 / n as f32).collect();
            self.town.lanes.push(DriveLane {
                road_id: road.to_string(),
                od_lane,
                width: vec![LANE_W_M; centerline.len()],
                centerline,
                s,
                speed_limit_mps: 8.33,
                junction: None,
                successors: Vec::new(),
                predecessors: Vec::new(),
                left: None,
                right: None,
            });
        }
        let mark = |points, kind, dash_m| LaneMarking {
            points,
            kind,
            color: MarkColor::White,
            width_m: 0.15,
            dash_m,
        };
        self.town
            .markings
            .push(mark(pts(0.0, false), MarkKind::Broken, Some((3.0, 5.0))));
        self.town
            .markings
            .push(mark(pts(-h + 0.2, false), MarkKind::Solid, None));
        self.town
            .markings
            .push(mark(pts(h - 0.2, false), MarkKind::Solid, None));
        for side in [-1.0, 1.0] {
            let inner = [a, b].map(|p| (p + left * side * h).extend(0.0)).to_vec();
            let outer = [a, b]
                .map(|p| (p + left * side * (h + WALK_W_M)).extend(0.0))
                .to_vec();
            self.town.sidewalks.push(Sidewalk {
                inner,
                outer,
                height_m: 0.15,
            });
        }
    }

    /// A junction square at `c` with a crosswalk and a light on each approach.
    fn junction(&mut self, c: Vec2) {
        let h = LANE_W_M;
        self.quad([
            c + Vec2::new(-h, -h),
            c + Vec2::new(h, -h),
            c + Vec2::new(h, h),
            c + Vec2::new(-h, h),
        ]);
        let ji = JunctionIdx(self.town.junctions.len() as u32);
        let mut lights = Vec::new();
        // Approach directions: traffic heading +x, +y, -x, -y.
        for (k, dir) in [Vec2::X, Vec2::Y, -Vec2::X, -Vec2::Y]
            .into_iter()
            .enumerate()
        {
            let right = -dir.perp();
            // The crosswalk spans the road 0.5..3.5 m before the junction square.
            let near = c - dir * (h + 0.5);
            let far = c - dir * (h + 3.5);
            let corners = [
                near - right * h,
                near + right * h,
                far + right * h,
                far - right * h,
            ]
            .map(|p| p.extend(0.0));
            self.town.crosswalks.push(Crosswalk {
                corners,
                from_map: false,
            });
            let stop = c - dir * (h + 4.5);
            let lane = self.find_lane(stop + right * (h * 0.5), dir);
            let pole = c - dir * (h + 4.0) + right * (h + 1.0);
            let li = LightIdx(self.town.lights.len() as u32);
            lights.push(li);
            self.town.lights.push(TrafficLight {
                od_id: format!("demo-{}-{k}", ji.0),
                position: pole.extend(0.15),
                heading: (-dir).to_angle(),
                head_height_m: HEAD_HEIGHT_M,
                junction: Some(ji),
                group: (k % 2) as u32,
                stop_lines: lane
                    .map(|lane| StopLine {
                        lane,
                        s: 0.0,
                        ends: [stop.extend(0.0), (stop + right * h).extend(0.0)],
                    })
                    .into_iter()
                    .collect(),
            });
        }
        let outline = [(-h, -h), (h, -h), (h, h), (-h, h)]
            .map(|(x, y)| c + Vec2::new(x, y))
            .to_vec();
        self.town.junctions.push(Junction {
            od_id: format!("demo-{}", ji.0),
            outline,
            lights,
            priorities: Vec::new(),
            yellow_s: None,
        });
    }

    /// The lane whose centreline passes near `p` heading along `dir`.
    fn find_lane(&self, p: Vec2, dir: Vec2) -> Option<LaneIdx> {
        self.town
            .lanes
            .iter()
            .position(|l| {
                let (Some(a), Some(b)) = (l.centerline.first(), l.centerline.last()) else {
                    return false;
                };
                let d = (*b - *a).truncate().normalize_or_zero();
                d.dot(dir) > 0.9 && l.centerline.iter().any(|q| q.truncate().distance(p) < 1.0)
            })
            .map(|i| LaneIdx(i as u32))
    }
}

/// The demo moment at the junction nearest the town's middle: the ego 25 m
/// before its stop line on the eastbound lane, red for it, green for the
/// cross street; cars and pedestrians around. Returns (ego, actors, light states).
pub fn demo_state(town: &Town) -> (EgoPose, Vec<ActorSnapshot>, Vec<LightState>) {
    let mid = (town.bounds.0 + town.bounds.1) * 0.5;
    let c = town
        .junctions
        .iter()
        .map(|j| j.outline.iter().copied().sum::<Vec2>() / j.outline.len().max(1) as f32)
        .min_by(|a, b| a.distance(mid).total_cmp(&b.distance(mid)))
        .unwrap_or(Vec2::ZERO);
    let lane_y = c.y - LANE_W_M * 0.5;
    let ego = EgoPose {
        position: Vec3::new(c.x - 33.0, lane_y, 0.0),
        heading: 0.0,
    };
    let car = |id: u32, x: f32, y: f32, heading: f32, color: u8| ActorSnapshot {
        id,
        kind: ActorKind::Vehicle,
        position: Vec3::new(c.x + x, c.y + y, 0.0),
        heading,
        extent: Vec3::new(4.6, 2.0, 1.5),
        speed_mps: 0.0,
        color,
    };
    let walker = |id: u32, x: f32, y: f32, color: u8| ActorSnapshot {
        id,
        kind: ActorKind::Pedestrian,
        position: Vec3::new(c.x + x, c.y + y, 0.15),
        heading: 0.0,
        extent: Vec3::new(0.5, 0.5, 1.8),
        speed_mps: 1.4,
        color,
    };
    let pi = std::f32::consts::PI;
    let actors = vec![
        ActorSnapshot {
            id: 0,
            kind: ActorKind::Ego,
            ..car(0, -33.0, -LANE_W_M * 0.5, 0.0, 0)
        },
        car(1, -16.0, -LANE_W_M * 0.5 - 0.1, 0.0, 3),
        car(2, -20.0, LANE_W_M * 0.5, pi, 1),
        car(3, LANE_W_M * 0.5, -2.0, pi * 0.5, 0),
        car(4, -LANE_W_M * 0.5, 14.0, -pi * 0.5, 5),
        car(5, 40.0, LANE_W_M * 0.5, pi, 2),
        walker(6, 6.0, -6.0, 0),
        walker(7, -12.0, 5.5, 1),
        ActorSnapshot {
            position: Vec3::new(c.x + 5.5, c.y + 1.0, 0.0),
            ..walker(8, 0.0, 0.0, 3)
        },
        walker(9, -25.0, -5.0, 4),
    ];
    // Group 0 (traffic along x) red, group 1 (along y) green.
    let states = town
        .lights
        .iter()
        .map(|l| {
            if l.group == 0 {
                LightState::Red
            } else {
                LightState::Green
            }
        })
        .collect();
    (ego, actors, states)
}

/// Renders the demo moment on a 3 x 3 grid town: the rig at `scale`, or the
/// top-down view `top_down_px` square and 60 m across; the class image in
/// label colours when `labels`. Returns the picture and the backend's name.
pub fn render_demo(
    rig: super::rig::RigConfig,
    scale: f32,
    top_down_px: Option<u32>,
    labels: bool,
) -> Result<(crate::RgbImage, String), super::RenderError> {
    let town = grid_town(3, 3, 100.0, 7);
    let (ego, actors, states) = demo_state(&town);
    let mut r = super::Renderer::new(&town, rig, 7)?;
    let backend = r.backend();
    let (rgb, class) = match top_down_px {
        Some(px) => r.render_top_down(&ego, &actors, &states, px, px, 60.0)?,
        None => r.render_rig(&ego, &actors, &states, scale)?,
    };
    let mut picture = crate::RgbImage::default();
    if labels {
        class.to_label_rgb(&mut picture);
    } else {
        picture = rgb.clone();
    }
    Ok((picture, backend))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_town_has_lights_on_every_approach_and_lanes_one_metre_apart() {
        let t = grid_town(2, 2, 100.0, 1);
        assert_eq!(t.junctions.len(), 4);
        assert_eq!(t.lights.len(), 16);
        assert!(
            t.lights.iter().all(|l| l.stop_lines.len() == 1),
            "every light governs a lane"
        );
        for l in &t.lanes {
            for w in l.centerline.windows(2) {
                assert!(w[0].distance(w[1]) <= 1.0 + 1e-4);
            }
        }
        assert_eq!(t.buildings.len(), 4);
    }
}
