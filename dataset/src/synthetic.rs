//! A small hand-made dataset with known contents, for tests and benchmarks
//! of the readers (`mrdrive data info`, `data show`, the training loader):
//! no simulator run, every number below follows from the frame index.
//!
//! The town is [`town`] (`world::map::testtown::grid(3, 3, 100)`); every episode
//! drives its road `y = 0` eastwards on the right-hand lane (`y = -1.75`),
//! route [`ROUTE_ID`] from `x = 20` to `x = 180` through the lit junction at
//! `x = 100`, whose stop line for this lane is at `x = 86`. Frame `i` of
//! every episode:
//!
//! | what | value |
//! | --- | --- |
//! | ego | `x = 20 + 2 (i mod 60)` m, `y = -1.75`, yaw 0, speed `SPEEDS_MPS[i mod 5]` |
//! | command | LEFT when `i mod 5 = 4`, else LANEFOLLOW |
//! | route | the ego's point on the route and its route distance (metres) |
//! | lights | all red when `(i / 10)` is even, else all green |
//! | actors | a vehicle 15 m ahead of the ego, a pedestrian 8 m ahead: on the sidewalk (`y = -5`), or in the ego's lane when `i mod 7 = 3` |
//! | rgb | byte `(7 x + 3 y + 50 c + 11 i + 29 v + 13 e) mod 256` at column x, row y, channel c, view v, episode e |
//! | classes | `(x * 6 / W + i + v) mod 6` |
//! | q (labels) | [`q_value`]; valid for all but the last 5 frames |

use std::collections::HashMap;
use std::path::Path;

use world::Town;
use world::map::testtown::LANE_WIDTH_M;
use world::route::DenseRoute;

use crate::action::{NUM_ACTIONS, NUM_COMMANDS, NUM_SPEED_BINS};
use crate::format::{
    ActorRow, DataError, EgoRow, Episode, Index, Labels, Q_PER_VIEW, RouteSpec, Shard, write_atomic,
};

/// The ego's speed by `frame mod 5` (metres per second): one standing, one in each bin
/// of `mrdrive data info`'s histogram.
pub const SPEEDS_MPS: [f32; 5] = [0.0, 2.0, 4.0, 6.0, 8.0];
/// The route's id in the index.
pub const ROUTE_ID: &str = "east";
/// The map name recorded in the index (not a file: readers that need the
/// town get [`town`] from the caller).
pub const MAP: &str = "testtown:grid(3,3,100)";
/// Frames at the end of an episode without a label (no driven future).
pub const UNLABELLED_TAIL: usize = 5;
/// The label version the synthetic label files carry.
pub const LABEL_VERSION: u32 = crate::labels::LABEL_VERSION;

/// What to write.
#[derive(Debug, Clone, PartialEq)]
pub struct SyntheticSpec {
    /// The dataset's name.
    pub name: String,
    /// Image size S0: width, height (pixels).
    pub s0: [u32; 2],
    /// Camera view yaws (degrees).
    pub view_yaws_deg: Vec<f32>,
    /// Episodes.
    pub episodes: u32,
    /// Frames per episode.
    pub frames: u32,
    /// Whether to write label files (and name them in the index).
    pub labelled: bool,
}

impl SyntheticSpec {
    /// A tiny set: S0 24 x 8, three views, `episodes` x `frames`, labelled.
    pub fn tiny(episodes: u32, frames: u32) -> SyntheticSpec {
        SyntheticSpec {
            name: "synthetic".into(),
            s0: [24, 8],
            view_yaws_deg: vec![0.0, 30.0, -30.0],
            episodes,
            frames,
            labelled: true,
        }
    }
}

/// The town the synthetic episodes drive.
pub fn town() -> Town {
    world::map::testtown::grid(3, 3, 100.0)
}

/// The route the synthetic episodes drive, as stored in the index.
pub fn route_spec() -> RouteSpec {
    let y = -LANE_WIDTH_M / 2.0;
    RouteSpec {
        file: None,
        id: ROUTE_ID.into(),
        waypoints: vec![[20.0, y, 0.0], [180.0, y, 0.0]],
    }
}

/// The route planned on [`town`].
pub fn dense_route(town: &Town) -> DenseRoute {
    crate::collect::replan(town, &route_spec()).expect("the synthetic route plans")
}

/// The ego of frame `i`.
pub fn ego(i: usize) -> EgoRow {
    EgoRow {
        x: 20.0 + 2.0 * (i % 60) as f32,
        y: -LANE_WIDTH_M / 2.0,
        yaw: 0.0,
        speed: SPEEDS_MPS[i % 5],
    }
}

/// The speed of the car 15 m ahead in frame `i` (metres per second): stopped when
/// `i mod 6 = 2`, else 3 m/s.
pub fn vehicle_speed(i: usize) -> f32 {
    if i % 6 == 2 { 0.0 } else { 3.0 }
}

/// The pedestrian's `y` in frame `i` (metres): in the ego's lane, crossing,
/// when `i mod 7 = 3`, else on the sidewalk.
pub fn pedestrian_y(i: usize) -> f32 {
    if i % 7 == 3 {
        -LANE_WIDTH_M / 2.0
    } else {
        -5.0
    }
}

/// The pedestrian's speed in frame `i` (metres per second): walking while it
/// crosses, waiting on the sidewalk otherwise (a walker walking towards the
/// lane would count as ahead: the rule book predicts its path).
pub fn pedestrian_speed(i: usize) -> f32 {
    if i % 7 == 3 { 1.2 } else { 0.0 }
}

/// The command of frame `i` (`world::Command` as u8).
pub fn command(i: usize) -> u8 {
    if i % 5 == 4 {
        world::Command::Left as u8
    } else {
        world::Command::LaneFollow as u8
    }
}

/// The state of every light in frame `i`: 0 red, 2 green.
pub fn light(i: usize) -> u8 {
    if (i / 10).is_multiple_of(2) { 0 } else { 2 }
}

/// The action value of frame `i`, view `v`, command `c`, speed bin `b`,
/// action `a`: the best action is the brake (27) where the ego stands at a
/// red light (`i mod 5 = 0` and `(i / 10)` even), else `(i + v + c + b) mod 28`;
/// it is worth 1.0, the others `0.01 a`.
pub fn q_value(i: usize, v: usize, c: usize, b: usize, a: usize) -> f32 {
    let best = if i.is_multiple_of(5) && (i / 10).is_multiple_of(2) {
        NUM_ACTIONS - 1
    } else {
        (i + v + c + b) % NUM_ACTIONS
    };
    if a == best { 1.0 } else { 0.01 * a as f32 }
}

/// The RGB byte at column `x`, row `y`, channel `c` of frame `i`, view `v`, episode `e`.
pub fn rgb_byte(x: usize, y: usize, c: usize, i: usize, v: usize, e: usize) -> u8 {
    ((7 * x + 3 * y + 50 * c + 11 * i + 29 * v + 13 * e) % 256) as u8
}

/// The class id at column `x` of frame `i`, view `v`, for an image `w` wide.
pub fn class_id(x: usize, w: usize, i: usize, v: usize) -> u8 {
    ((x * 6 / w + i + v) % 6) as u8
}

/// The shard of episode `e`.
pub fn shard(spec: &SyntheticSpec, e: usize, route: &DenseRoute) -> Shard {
    let (w, h) = (spec.s0[0] as usize, spec.s0[1] as usize);
    let views = spec.view_yaws_deg.len();
    let lights = town().lights.len();
    let mut s = Shard::new((spec.s0[0], spec.s0[1]), views);
    for i in 0..spec.frames as usize {
        for v in 0..views {
            for y in 0..h {
                for x in 0..w {
                    for c in 0..3 {
                        s.rgb.push(rgb_byte(x, y, c, i, v, e));
                    }
                }
            }
            for _y in 0..h {
                s.classes.extend((0..w).map(|x| class_id(x, w, i, v)));
            }
        }
        let ego = ego(i);
        let p = world::Vec2::new(ego.x, ego.y);
        let (k, q) = route
            .points
            .iter()
            .enumerate()
            .min_by(|a, b| {
                let da = a.1.position.truncate().distance_squared(p);
                let db = b.1.position.truncate().distance_squared(p);
                da.total_cmp(&db)
            })
            .expect("the route has points");
        let along = (p - q.position.truncate()).dot(world::Vec2::from_angle(q.heading));
        s.ego.push(ego);
        s.command.push(command(i));
        s.route.push([k as f32, q.route_s + along]);
        s.tick.push(10 * i as u32);
        s.actors.push(vec![
            ActorRow {
                kind: ActorRow::VEHICLE,
                id: 1,
                x: ego.x + 15.0,
                y: ego.y,
                yaw: 0.0,
                length: 4.5,
                width: 1.9,
                speed: vehicle_speed(i),
            },
            ActorRow {
                kind: ActorRow::PEDESTRIAN,
                id: 2,
                x: ego.x + 8.0,
                y: pedestrian_y(i),
                yaw: 1.5,
                length: 0.5,
                width: 0.5,
                speed: pedestrian_speed(i),
            },
        ]);
        s.lights.push(vec![light(i); lights]);
    }
    s
}

/// The labels of a synthetic episode of `frames` frames and `views` views.
pub fn labels(frames: usize, views: usize) -> Labels {
    let mut q = Vec::with_capacity(frames * views * Q_PER_VIEW);
    for i in 0..frames {
        for v in 0..views {
            for c in 0..NUM_COMMANDS {
                for b in 0..NUM_SPEED_BINS {
                    q.extend((0..NUM_ACTIONS).map(|a| q_value(i, v, c, b, a)));
                }
            }
        }
    }
    Labels {
        views,
        q,
        valid: (0..frames).map(|i| i + UNLABELLED_TAIL < frames).collect(),
    }
}

/// Writes the dataset into `dir` (created if missing) and returns its index.
pub fn write(dir: &Path, spec: &SyntheticSpec) -> Result<Index, DataError> {
    std::fs::create_dir_all(dir).map_err(|e| DataError::Io {
        path: dir.to_path_buf(),
        source: e,
    })?;
    let town = town();
    let route = dense_route(&town);
    let mut index = Index::new(&spec.name, spec.s0, spec.view_yaws_deg.clone(), 10, 0.025);
    for e in 0..spec.episodes {
        let name = crate::collect::shard_name(e);
        let shard = shard(spec, e as usize, &route);
        write_atomic(&dir.join(&name), &shard.to_bytes(&HashMap::new()))?;
        let mut episode = Episode {
            id: e,
            shard: name,
            frames: spec.frames,
            town: town.name.clone(),
            map: MAP.into(),
            generate_lights: false,
            route: route_spec(),
            seed: u64::from(e),
            vehicles: 1,
            pedestrians: 1,
            crossings_per_min: 0.0,
            walkers_sent: 0,
            sim_time_s: f64::from(spec.frames) * 0.25,
            labels: None,
        };
        if spec.labelled {
            let file = crate::labels::episode::labels_name(&episode);
            let l = labels(spec.frames as usize, spec.view_yaws_deg.len());
            write_atomic(&dir.join(&file), &l.to_bytes(LABEL_VERSION, &episode.shard))?;
            episode.labels = Some(file);
        }
        index.episodes.push(episode);
    }
    index.save(dir)?;
    Ok(index)
}
