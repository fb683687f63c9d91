//! `mrdrive data info`: what a dataset holds, from its index and the
//! shards' state tensors (no image is read).
//!
//! "Approaching a red light" is a statistic of the data, not a rule of the
//! road: a frame approaches one when the next stop line on its route (the
//! rule book's `StopLines::on_route` on the episode's route planned again
//! with `collect::replan`) lies up to [`RED_LIGHT_RANGE_M`] metres ahead of
//! the ego's centre along the route, and that stop line's light says stop
//! (red or yellow, as in the labels: `labels::maps::light_stops`).

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use world::rules::{RouteStops, StopLines};
use world::{Command, LightState, Town};

use crate::action::NUM_COMMANDS;
use crate::collect::{TownCache, replan};
use crate::format::{
    DataError, Episode, FORMAT, Index, MappedShard, PEDESTRIAN_AHEAD_M, file_metadata,
    light_of_code, pedestrian_ahead, stopped_vehicle_ahead,
};
use crate::labels::LABEL_VERSION;
use crate::labels::maps::light_stops;

/// How far ahead a stop line counts for "approaching a red light" (metres).
pub const RED_LIGHT_RANGE_M: f32 = 30.0;
/// Upper edges of the speed histogram's bins (metres per second); the last
/// bin holds everything faster.
pub const SPEED_EDGES_MPS: [f32; 4] = [1.0, 3.0, 5.0, 7.0];
/// Bins of the speed histogram.
pub const SPEED_BINS: usize = SPEED_EDGES_MPS.len() + 1;

/// Gives the town an episode drove (loaded from its map, or hand-made in tests).
pub type TownSource<'a> = dyn FnMut(&Episode) -> Result<Arc<Town>, String> + 'a;

/// Loads each episode's town from the map file its index entry names,
/// once per file.
pub fn towns_from_maps() -> impl FnMut(&Episode) -> Result<Arc<Town>, String> {
    let mut cache = TownCache::default();
    move |e: &Episode| {
        cache.get(Path::new(&e.map), e.generate_lights).map_err(|err| {
            format!(
                "map {} (as recorded in the index): {err}; run from the directory the collection ran in",
                e.map
            )
        })
    }
}

/// The histogram bin of a speed (metres per second).
pub fn speed_bin(speed_mps: f32) -> usize {
    SPEED_EDGES_MPS
        .iter()
        .position(|&edge| speed_mps < edge)
        .unwrap_or(SPEED_EDGES_MPS.len())
}

/// Whether an ego at route distance `ego_s` (metres) approaches a red
/// light, given the route's stop lines and the frame's light codes (see
/// the module docs).
pub fn approaching_red(stops: &RouteStops, ego_s: f32, lights: &[u8]) -> bool {
    light_ahead(stops, ego_s, lights).is_some_and(light_stops)
}

/// The state of the next stop line's light within [`RED_LIGHT_RANGE_M`]
/// ahead of route distance `ego_s` (metres), if the frame has one.
pub fn light_ahead(stops: &RouteStops, ego_s: f32, lights: &[u8]) -> Option<LightState> {
    let (s, _) = stops.light_ahead(ego_s, RED_LIGHT_RANGE_M)?;
    lights
        .get(s.light.0 as usize)
        .map(|&code| light_of_code(code))
}

/// What a dataset holds.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Summary {
    /// The dataset's directory.
    pub dir: PathBuf,
    /// The dataset's name.
    pub name: String,
    /// Image size S0: width, height (pixels).
    pub s0: [u32; 2],
    /// Camera views per frame.
    pub views: usize,
    /// Episodes in the index.
    pub episodes: usize,
    /// Frames in the shards that could be read.
    pub frames: u64,
    /// Simulated time driven, over every episode in the index (seconds).
    pub driven_s: f64,
    /// Frames per command (`world::Command` as index).
    pub commands: [u64; NUM_COMMANDS],
    /// Frames approaching a red light.
    pub red_light: u64,
    /// Of those, the frames whose light is yellow.
    pub yellow_light: u64,
    /// Frames whose route could be planned again, so that `red_light` could be decided.
    pub red_light_known: u64,
    /// Frames with a pedestrian in the ego's corridor straight ahead
    /// ([`crate::format::pedestrian_ahead`], the rule the loader's `pedestrian_repeat` uses).
    pub pedestrian_ahead: u64,
    /// Frames with a stopped vehicle in the ego's corridor straight ahead
    /// ([`crate::format::stopped_vehicle_ahead`]): queues at lights, cars waiting.
    pub stopped_vehicle_ahead: u64,
    /// Walkers sent across the road ahead of the ego (`Episode::walkers_sent`, summed).
    pub walkers_sent: u64,
    /// Frames per speed bin ([`SPEED_EDGES_MPS`]).
    pub speeds: [u64; SPEED_BINS],
    /// Frames per town.
    pub towns: BTreeMap<String, u64>,
    /// Frames per route: `file#id` for routes from a file, `random` for the random routes.
    pub routes: BTreeMap<String, u64>,
    /// Distinct random routes.
    pub random_routes: usize,
    /// Episodes with labels of this build's version.
    pub labelled: usize,
    /// Episodes without them.
    pub unlabelled: usize,
    /// Bytes of every file in the directory.
    pub disk_bytes: u64,
    /// Files that could not be used, and why (the rest is summarised).
    pub problems: Vec<(PathBuf, String)>,
}

impl Summary {
    /// Summarises the dataset in `dir`; `towns` gives each episode's town
    /// (for the red-light share; an episode whose town or route fails is
    /// left out of that share and listed in `problems`).
    pub fn of(dir: &Path, towns: &mut TownSource<'_>) -> Result<Summary, DataError> {
        let index = Index::load(dir)?;
        let mut s = Summary {
            dir: dir.to_path_buf(),
            name: index.name.clone(),
            s0: index.s0,
            views: index.view_yaws_deg.len(),
            episodes: index.episodes.len(),
            driven_s: index.episodes.iter().map(|e| e.sim_time_s).sum(),
            walkers_sent: index
                .episodes
                .iter()
                .map(|e| u64::from(e.walkers_sent))
                .sum(),
            ..Summary::default()
        };
        let mut random = std::collections::BTreeSet::new();
        for e in &index.episodes {
            match label_state(dir, e) {
                Ok(true) => s.labelled += 1,
                Ok(false) => s.unlabelled += 1,
                Err((file, why)) => {
                    s.unlabelled += 1;
                    s.problems.push((file, why));
                }
            }
            let path = dir.join(&e.shard);
            let shard = match MappedShard::open(&path, index.s0, s.views) {
                Ok(m) => m.state,
                Err(err) => {
                    s.problems.push((path, err.to_string()));
                    continue;
                }
            };
            let n = shard.len() as u64;
            s.frames += n;
            for &c in &shard.command {
                s.commands[usize::from(c)] += 1;
            }
            for (ego, actors) in shard.ego.iter().zip(&shard.actors) {
                s.speeds[speed_bin(ego.speed)] += 1;
                if pedestrian_ahead(ego, actors).is_some() {
                    s.pedestrian_ahead += 1;
                }
                if stopped_vehicle_ahead(ego, actors).is_some() {
                    s.stopped_vehicle_ahead += 1;
                }
            }
            *s.towns.entry(e.town.clone()).or_default() += n;
            if e.route.file.is_none() {
                random.insert(e.route.id.clone());
            }
            *s.routes.entry(e.route.key()).or_default() += n;
            match towns(e).and_then(|town| replan(&town, &e.route).map(|r| (town, r))) {
                Ok((town, route)) => {
                    let stops = StopLines::new(&town).on_route(&route);
                    s.red_light_known += n;
                    for i in 0..shard.len() {
                        let state = light_ahead(&stops, shard.route[i][1], &shard.lights[i]);
                        if state.is_some_and(light_stops) {
                            s.red_light += 1;
                            s.yellow_light += u64::from(state == Some(LightState::Yellow));
                        }
                    }
                }
                Err(err) => s
                    .problems
                    .push((path, format!("left out of the red-light share: {err}"))),
            }
        }
        s.random_routes = random.len();
        s.disk_bytes = disk_bytes(dir)?;
        Ok(s)
    }

    /// Hours driven.
    pub fn hours(&self) -> f64 {
        self.driven_s / 3600.0
    }
}

/// Whether an episode has labels of this build's version (`Ok(false)`: none
/// yet); a label file that is there but unusable is an error with the fix.
fn label_state(dir: &Path, e: &Episode) -> Result<bool, (PathBuf, String)> {
    let Some(name) = &e.labels else {
        return Ok(false);
    };
    let path = dir.join(name);
    let meta = file_metadata(&path).map_err(|err| (path.clone(), err.to_string()))?;
    let version = meta.get("label_version").map_or("none", String::as_str);
    if meta.get("format").map(String::as_str) != Some(FORMAT)
        || version != LABEL_VERSION.to_string()
    {
        return Err((
            path,
            format!(
                "labels are version {version}, this build makes version {LABEL_VERSION}; run `mrdrive label` on the dataset again"
            ),
        ));
    }
    Ok(true)
}

/// Bytes of the regular files directly in `dir`.
fn disk_bytes(dir: &Path) -> Result<u64, DataError> {
    let io = |e| DataError::Io {
        path: dir.to_path_buf(),
        source: e,
    };
    let mut total = 0;
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let meta = entry.map_err(io)?.metadata().map_err(io)?;
        if meta.is_file() {
            total += meta.len();
        }
    }
    Ok(total)
}

fn percent(part: u64, whole: u64) -> f64 {
    if whole == 0 {
        0.0
    } else {
        100.0 * part as f64 / whole as f64
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "dataset {:?} in {}: {} episodes, {} frames, S0 {} x {}, {} views",
            self.name,
            self.dir.display(),
            self.episodes,
            self.frames,
            self.s0[0],
            self.s0[1],
            self.views
        )?;
        writeln!(
            f,
            "driven: {:.2} h ({:.0} s simulated)",
            self.hours(),
            self.driven_s
        )?;
        write!(f, "commands:")?;
        for (c, &n) in self.commands.iter().enumerate() {
            let name = Command::from_index(c).map_or("?", Command::name);
            write!(f, "  {name} {:.1} %", percent(n, self.frames))?;
        }
        writeln!(f)?;
        write!(
            f,
            "approaching a red light (stop line <= {RED_LIGHT_RANGE_M} m ahead on the route, red or yellow): {:.1} % of {} frames",
            percent(self.red_light, self.red_light_known),
            self.red_light_known
        )?;
        write!(
            f,
            ", yellow in {:.1} %",
            percent(self.yellow_light, self.red_light_known)
        )?;
        if self.red_light_known < self.frames {
            write!(
                f,
                " ({} frames left out: see problems)",
                self.frames - self.red_light_known
            )?;
        }
        writeln!(f)?;
        writeln!(
            f,
            "a pedestrian in the corridor straight ahead (<= {PEDESTRIAN_AHEAD_M} m): {:.2} % ({} frames)",
            percent(self.pedestrian_ahead, self.frames),
            self.pedestrian_ahead
        )?;
        writeln!(
            f,
            "a stopped vehicle in the corridor straight ahead (<= {PEDESTRIAN_AHEAD_M} m): {:.2} % ({} frames)",
            percent(self.stopped_vehicle_ahead, self.frames),
            self.stopped_vehicle_ahead
        )?;
        writeln!(
            f,
            "walkers sent across the road ahead of the ego: {} ({:.2} per simulated minute)",
            self.walkers_sent,
            self.walkers_sent as f64 / (self.driven_s / 60.0).max(1e-9)
        )?;
        write!(f, "speed (m/s):")?;
        for (b, &n) in self.speeds.iter().enumerate() {
            let range = match b {
                0 => format!("0-{}", SPEED_EDGES_MPS[0]),
                b if b == SPEED_EDGES_MPS.len() => format!(">{}", SPEED_EDGES_MPS[b - 1]),
                b => format!("{}-{}", SPEED_EDGES_MPS[b - 1], SPEED_EDGES_MPS[b]),
            };
            write!(f, "  {range} {:.1} %", percent(n, self.frames))?;
        }
        writeln!(f)?;
        writeln!(f, "towns (frames):")?;
        for (town, n) in &self.towns {
            writeln!(f, "  {town:<24} {n:>8}")?;
        }
        writeln!(f, "routes (frames):")?;
        for (route, n) in &self.routes {
            if route == "random" {
                let label = format!("random ({} routes)", self.random_routes);
                writeln!(f, "  {label:<24} {n:>8}")?;
            } else {
                writeln!(f, "  {route:<24} {n:>8}")?;
            }
        }
        writeln!(
            f,
            "labels (version {LABEL_VERSION}): {} episodes labelled, {} unlabelled",
            self.labelled, self.unlabelled
        )?;
        writeln!(
            f,
            "disk: {:.1} MiB",
            self.disk_bytes as f64 / (1024.0 * 1024.0)
        )?;
        if !self.problems.is_empty() {
            writeln!(f, "problems ({}):", self.problems.len())?;
            for (path, why) in &self.problems {
                writeln!(f, "  {}: {why}", path.display())?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{self, SyntheticSpec};

    fn synthetic_towns() -> impl FnMut(&Episode) -> Result<Arc<Town>, String> {
        let town = Arc::new(synthetic::town());
        move |_| Ok(town.clone())
    }

    #[test]
    fn a_hand_made_dataset_is_summarised_with_known_counts() {
        let dir = tempfile::tempdir().unwrap();
        synthetic::write(dir.path(), &SyntheticSpec::tiny(2, 30)).unwrap();
        let s = Summary::of(dir.path(), &mut synthetic_towns()).unwrap();
        assert_eq!((s.episodes, s.frames, s.views), (2, 60, 3));
        assert_eq!(s.driven_s, 15.0);
        // Every 5th frame is LEFT, the rest LANEFOLLOW.
        let mut commands = [0; NUM_COMMANDS];
        commands[Command::Left as usize] = 12;
        commands[Command::LaneFollow as usize] = 48;
        assert_eq!(s.commands, commands);
        // One frame in five in each speed bin.
        assert_eq!(s.speeds, [12; SPEED_BINS]);
        // The stop line is at x = 86, the ego at x = 20 + 2 i: within 30 m
        // for i = 18..=33; the lights are red for i in 0..10 and 20..30,
        // so frames 20..=29 of each episode approach a red light.
        assert_eq!((s.red_light, s.red_light_known), (20, 60));
        // The pedestrian stands in the ego's lane 8 m ahead when i mod 7 = 3: i = 3, 10,
        // 17, 24 of each episode's 30 frames.
        assert_eq!(s.pedestrian_ahead, 8);
        // The fixture's car 15 m ahead stands when i mod 6 = 2: i = 2, 8, 14, 20, 26.
        assert_eq!(s.stopped_vehicle_ahead, 10);
        assert_eq!(s.towns.get("fixture-grid-3x3"), Some(&60));
        assert_eq!(s.routes.get("random"), Some(&60));
        assert_eq!(s.random_routes, 1);
        assert_eq!((s.labelled, s.unlabelled), (2, 0));
        let files: u64 = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().metadata().unwrap().len())
            .sum();
        assert_eq!(s.disk_bytes, files);
        assert!(s.problems.is_empty(), "{:?}", s.problems);
        let text = s.to_string();
        assert!(text.contains("LEFT 20.0 %"), "{text}");
        assert!(
            text.contains("33.3 % of 60 frames, yellow in 0.0 %"),
            "{text}"
        );
        assert!(text.contains("(<= 20 m): 13.33 % (8 frames)"), "{text}");
        assert!(text.contains("ahead of the ego: 0 (0.00 per"), "{text}");
    }

    #[test]
    fn a_stop_line_behind_or_too_far_or_green_is_not_approached() {
        let town = synthetic::town();
        let stops = StopLines::new(&town).on_route(&synthetic::dense_route(&town));
        // One stop line on the route: x = 86, 66 m from the route's start at x = 20.
        assert_eq!(stops.all().len(), 1);
        let line = stops.all()[0].route_s;
        assert!((line - 66.0).abs() < 0.01, "{line}");
        let (red, yellow, green) = (0u8, 1u8, 2u8);
        let lights = |code| vec![code; town.lights.len()];
        assert!(approaching_red(&stops, line - 30.0, &lights(red)));
        assert!(
            approaching_red(&stops, line - 1.0, &lights(yellow)),
            "yellow stops"
        );
        assert!(
            !approaching_red(&stops, line - 30.5, &lights(red)),
            "30.5 m away"
        );
        assert!(
            !approaching_red(&stops, line - 10.0, &lights(green)),
            "green"
        );
        assert!(!approaching_red(&stops, line + 1.0, &lights(red)), "passed");
        // The light's own state, which `data info` splits into red and yellow.
        assert_eq!(
            light_ahead(&stops, line - 1.0, &lights(yellow)),
            Some(LightState::Yellow)
        );
        assert_eq!(
            light_ahead(&stops, line - 10.0, &lights(green)),
            Some(LightState::Green)
        );
        assert_eq!(light_ahead(&stops, line - 30.5, &lights(red)), None);
    }

    #[test]
    fn unreadable_shards_and_old_labels_are_listed_and_the_rest_summarised() {
        let dir = tempfile::tempdir().unwrap();
        let index = synthetic::write(dir.path(), &SyntheticSpec::tiny(3, 10)).unwrap();
        let shard = dir.path().join(&index.episodes[1].shard);
        let bytes = std::fs::read(&shard).unwrap();
        std::fs::write(&shard, &bytes[..bytes.len() / 2]).unwrap();
        let labels = dir.path().join(index.episodes[2].labels.as_ref().unwrap());
        let old = synthetic::labels(10, 3).to_bytes(LABEL_VERSION + 1, "x");
        std::fs::write(&labels, old).unwrap();
        let s = Summary::of(dir.path(), &mut synthetic_towns()).unwrap();
        assert_eq!(s.frames, 20);
        assert_eq!((s.labelled, s.unlabelled), (2, 1));
        assert_eq!(s.problems.len(), 2, "{:?}", s.problems);
        assert!(s.problems[0].1.contains("truncated"), "{:?}", s.problems);
        assert!(
            s.problems[1].1.contains("mrdrive label"),
            "{:?}",
            s.problems
        );
        let mut no_town = |_: &Episode| Err("no such map".to_string());
        let s = Summary::of(dir.path(), &mut no_town).unwrap();
        assert_eq!(s.red_light_known, 0);
        assert!(s.to_string().contains("left out"), "{s}");
    }
}
