//! Collection: the expert drives planned episodes with noise while an
//! observer of the run keeps a frame every `frame_every_ticks` ticks.
//!
//! A frame holds the rig image at S0 from each camera view (WoR's three yaws:
//! the rig as mounted, and yawed +-30 deg), their WoR class images, the ego's
//! pose, speed, route command and progress, every other actor and every
//! light's state. Consecutive frames are 0.25 s apart, so the labeller reads
//! each frame's "on rails" future from the frames after it.
//!
//! An episode is written when it ends (shard, then index, each by rename),
//! so a killed collection loses only the episode in progress; run it again
//! and it skips the finished ones. The same plan, build and render backend
//! give the same bytes.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::build::Overrides;
use sim::build::{self, Drivers, Extras, RunRequest};
use sim::camera::Camera;
use sim::driver::Driver;
use sim::expert::{Expert, ExpertParams};
use sim::observe::{RunObserver, TickView};
use sim::render::classes::to_wor;
use sim::render::{EgoPose, Renderer, RigConfig};
use sim::runner::{Prepared, RunError};
use sim::scenario::{MapSpec, RouteSpec as ScenarioRoute, Scenario};
use sim::selector::Fixed;
use world::map::{LoadOptions, UnsignalledJunctions, load_xodr_file};
use world::route::{DenseRoute, PlannerConfig, plan_route};
use world::route::{Route, RouteFile, RouteWaypoint};
use world::{ActorKind, Town, Vec3};

use crate::dagger::{Dagger, DaggerParams};
use crate::format::{
    ActorRow, DataError, EgoRow, Episode, Index, RouteSpec, Shard, light_code, write_atomic,
};
use crate::noise::{NoiseParams, NoisyDriver};

/// Where an episode's route comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum RouteChoice {
    /// A route of a route file (CARLA XML or our TOML).
    File {
        /// The route file.
        file: PathBuf,
        /// The route's id.
        id: String,
    },
    /// A random route through the town: two lane points far apart, planned
    /// over the lane graph, drawn from `seed`.
    Random {
        /// The seed of the draw.
        seed: u64,
    },
}

/// One episode of a collection plan.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeSpec {
    /// Its index in the plan (and in the shard's name).
    pub id: u32,
    /// The OpenDRIVE map.
    pub map: PathBuf,
    /// Generate lights at unsignalled junctions (our generated towns).
    pub generate_lights: bool,
    /// The route.
    pub route: RouteChoice,
    /// The traffic seed (also seeds the lights' phases).
    pub seed: u64,
    /// Target NPC vehicles.
    pub vehicles: u32,
    /// Target pedestrians.
    pub pedestrians: u32,
    /// Walkers sent across the road ahead of the ego per minute
    /// (`sim::scenario::TrafficSpec::ego_crossings_per_min`).
    pub crossings_per_min: f32,
}

/// Walkers sent across the road ahead of the ego per minute in the presets'
/// plans: at the paper's densities a walker in the ego's way is otherwise
/// rare (see [`crowd`]). Episodes without pedestrians get none. Measured on
/// six 90 s episodes of the original plan: 12 walkers sent (about 2 per
/// minute where there are walkers; the rest of the draws find no crossing
/// ahead), and 5.4 % of the frames with a walker straight ahead within 20 m,
/// against 0.19 % with none sent.
pub const CROSSINGS_PER_MIN: f32 = 4.0;

/// How a collection records.
#[derive(Debug, Clone, PartialEq)]
pub struct CollectConfig {
    /// The dataset's name.
    pub name: String,
    /// The camera rig (its S0 is the dataset's).
    pub rig: RigConfig,
    /// Camera view yaws (degrees, counter-clockwise; the first 0).
    pub view_yaws_deg: Vec<f32>,
    /// Loop ticks between frames (10 at 40 Hz: WoR's 4 Hz).
    pub frame_every_ticks: u32,
    /// Longest episode (seconds simulated).
    pub max_s: f64,
    /// The expert's noise.
    pub noise: NoiseParams,
}

impl CollectConfig {
    /// The CPU default: S0 = 240 x 96, WoR's three views, 4 Hz, 90 s episodes.
    pub fn cpu_default(name: &str) -> CollectConfig {
        CollectConfig {
            name: name.to_string(),
            rig: RigConfig::cpu_default(),
            view_yaws_deg: vec![0.0, 30.0, -30.0],
            frame_every_ticks: 10,
            max_s: 90.0,
            noise: NoiseParams::default(),
        }
    }

    /// The index a dataset of this configuration starts from.
    pub fn empty_index(&self, tick_s: f64) -> Index {
        let (w, h) = self.rig.base_size();
        Index::new(
            &self.name,
            [w, h],
            self.view_yaws_deg.clone(),
            self.frame_every_ticks,
            tick_s,
        )
    }
}

/// The two datasets of the study.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    /// The original model's data: Town01 routes 2-9 at every density, then
    /// random routes, three in five through Town01 and two through our
    /// generated towns (gen01 and gen02 in turn).
    Original,
    /// The retargeting data, disjoint from it: the generated towns' routes
    /// but the default scenario's, and other random Town01 routes.
    Retarget,
}

impl Preset {
    /// The preset's name.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Original => "original",
            Preset::Retarget => "retarget",
        }
    }
}

/// Traffic densities (vehicles, pedestrians) the plans cycle through: the paper's
/// three, then a denser one. At the paper's densities a stopped car stands in the
/// ego's way in under 1 % of the frames (measured on 9 episodes of this plan,
/// 2026-12-05: 0.19 %), so the policies met few queues at red lights and rear-ended
/// cars waiting there on Town02; 40 vehicles make queues (5.3 % of the frames of one
/// Town01 route against 3.2 % at 20, same seeds).
pub const DENSITIES: [(u32, u32); 4] = [(0, 0), (5, 10), (20, 40), (40, 40)];

/// Episodes at the start of the original plan that drive Town01's training
/// routes 2-9, each at every density.
pub const TOWN01_ROUTE_EPISODES: usize = 8 * DENSITIES.len();

/// The routes of our towns the retargeting plan drives: every shipped route but
/// gen01's route 0, which the default scenario drives (so that the shipped RA has
/// not seen it). (town index in `ours`, route id).
const RETARGET_TOWN_ROUTES: [(usize, &str); 5] = [(0, "1"), (0, "2"), (1, "0"), (1, "1"), (1, "2")];

/// Town01 routes kept for evaluation (docs/protocol.md §2): never collected.
pub const EVALUATION_ROUTES: [&str; 2] = ["0", "1"];

/// The plan of a preset: `episodes` episodes. `carla` is the folder with
/// CARLA's Town01 and its routes, `repo` the project's root (for our towns).
pub fn plan(preset: Preset, episodes: usize, carla: &Path, repo: &Path) -> Vec<EpisodeSpec> {
    let town01 = carla.join("Town01.xodr");
    let routes01 = carla.join("routes_town01.xml");
    let ours = [
        (repo.join("maps/gen01.xodr"), repo.join("routes/gen01.toml")),
        (repo.join("maps/gen02.xodr"), repo.join("routes/gen02.toml")),
    ];
    (0..episodes)
        .map(|i| {
            let id = i as u32;
            let (vehicles, pedestrians) = DENSITIES[i % DENSITIES.len()];
            let base = EpisodeSpec {
                id,
                map: town01.clone(),
                generate_lights: false,
                route: RouteChoice::Random { seed: 0 },
                seed: 1000 * (preset as u64 + 1) + id as u64,
                vehicles,
                pedestrians,
                crossings_per_min: CROSSINGS_PER_MIN,
            };
            match preset {
                // First the training routes at every density, then random routes.
                Preset::Original if i < TOWN01_ROUTE_EPISODES => EpisodeSpec {
                    route: RouteChoice::File {
                        file: routes01.clone(),
                        id: (2 + (i / DENSITIES.len()) % 8).to_string(),
                    },
                    ..base
                },
                Preset::Original if i % 5 < 3 => EpisodeSpec {
                    route: RouteChoice::Random { seed: id as u64 },
                    ..base
                },
                // Random routes through our towns, in turn; random seeds from 2e6
                // on never meet the retargeting set's routes.
                Preset::Original => EpisodeSpec {
                    map: ours[(i / 5) % 2].0.clone(),
                    generate_lights: true,
                    route: RouteChoice::Random {
                        seed: 2_000_000 + id as u64,
                    },
                    ..base
                },
                // Our towns' routes (not the default scenario's) and Town01 random
                // routes alternate; random seeds from 1e6 on never meet the original set's.
                Preset::Retarget if i % 2 == 0 => {
                    let (town, id) = RETARGET_TOWN_ROUTES[(i / 2) % RETARGET_TOWN_ROUTES.len()];
                    let (map, routes) = &ours[town];
                    EpisodeSpec {
                        map: map.clone(),
                        generate_lights: true,
                        route: RouteChoice::File {
                            file: routes.clone(),
                            id: id.to_string(),
                        },
                        ..base
                    }
                }
                Preset::Retarget => EpisodeSpec {
                    route: RouteChoice::Random {
                        seed: 1_000_000 + id as u64,
                    },
                    ..base
                },
            }
        })
        .collect()
}

/// Multiplies every episode's pedestrian count by `factor` (rounded to whole walkers).
///
/// At the paper's densities a walker in the ego's path is rare (0.26 % of the original
/// set's frames), so a policy sees few examples of braking for one; a crowded set (for
/// example `factor` 4: 0, 40 and 160 walkers) has more. Everything else in the plan, seeds
/// included, stays the same. `factor` must be in [0, 20].
pub fn crowd(plan: &mut [EpisodeSpec], factor: f64) -> Result<(), String> {
    if !(factor.is_finite() && (0.0..=20.0).contains(&factor)) {
        return Err(format!(
            "pedestrian factor {factor}: give a factor from 0 to 20 (1 keeps the paper's densities)"
        ));
    }
    for spec in plan {
        spec.pedestrians = (f64::from(spec.pedestrians) * factor).round() as u32;
    }
    Ok(())
}

/// A plan of one episode per seed and traffic density on a scenario's map and
/// route, the expert driving: for looking at the data and labels of one situation
/// (an evaluation route included), never for a training set. Episode ids count
/// from 0 in the order seeds x densities.
pub fn scenario_plan(
    scenario: &Scenario,
    seeds: &[u64],
    densities: &[(u32, u32)],
) -> Vec<EpisodeSpec> {
    seeds
        .iter()
        .flat_map(|&seed| densities.iter().map(move |&d| (seed, d)))
        .enumerate()
        .map(|(i, (seed, (vehicles, pedestrians)))| EpisodeSpec {
            id: i as u32,
            map: scenario.map.file.clone(),
            generate_lights: scenario.map.generates_lights(),
            route: RouteChoice::File {
                file: scenario.route.file.clone(),
                id: scenario.route.id.clone(),
            },
            seed,
            vehicles,
            pedestrians,
            crossings_per_min: scenario.traffic.ego_crossings_per_min,
        })
        .collect()
}

/// A random route: start and end on non-junction lanes of one strongly
/// connected part of the lane graph, 300-900 m apart along the planned route.
pub fn random_route(town: &Town, seed: u64) -> Result<(Route, DenseRoute), String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x0072_6f75_7465);
    let comps = town.lane_components();
    let biggest = comps
        .iter()
        .max_by_key(|c| c.len())
        .ok_or("the town has no lanes")?;
    let candidates: Vec<_> = biggest
        .iter()
        .copied()
        .filter(|&l| town.lane(l).junction.is_none() && town.lane(l).length_m() > 20.0)
        .collect();
    if candidates.len() < 2 {
        return Err(format!(
            "town {} has too few lanes for a random route",
            town.name
        ));
    }
    for _ in 0..200 {
        let a = candidates[rng.random_range(0..candidates.len())];
        let b = candidates[rng.random_range(0..candidates.len())];
        let point = |l: world::LaneIdx, rng: &mut ChaCha8Rng| {
            let lane = town.lane(l);
            let s = rng.random_range(5.0..lane.length_m() - 5.0);
            let p = lane.point_at(s);
            RouteWaypoint {
                position: p,
                yaw_rad: Some(lane.heading_at(s)),
            }
        };
        let route = Route {
            id: format!("random-{seed}"),
            town: Some(town.name.clone()),
            waypoints: vec![point(a, &mut rng), point(b, &mut rng)],
            source: PathBuf::from(format!("random route, seed {seed}")),
        };
        if let Ok(dense) = plan_route(town, &route, &PlannerConfig::default())
            && (300.0..900.0).contains(&dense.length_m)
        {
            return Ok((route, dense));
        }
    }
    Err(format!(
        "no random route of 300-900 m found in town {} for seed {seed}",
        town.name
    ))
}

/// Loads towns once per map file.
#[derive(Default)]
pub struct TownCache {
    towns: HashMap<(PathBuf, bool), Arc<Town>>,
}

impl TownCache {
    /// The town of `map` (loaded on first use).
    pub fn get(&mut self, map: &Path, generate_lights: bool) -> Result<Arc<Town>, String> {
        let key = (map.to_path_buf(), generate_lights);
        if let Some(t) = self.towns.get(&key) {
            return Ok(t.clone());
        }
        let opts = LoadOptions {
            unsignalled: if generate_lights {
                UnsignalledJunctions::GenerateLights
            } else {
                UnsignalledJunctions::NoLights
            },
        };
        let (town, _) = load_xodr_file(map, &opts).map_err(|e| e.to_string())?;
        let town = Arc::new(town);
        self.towns.insert(key, town.clone());
        Ok(town)
    }
}

/// The town and the planned route of an episode, and its route as stored.
pub fn prepare(spec: &EpisodeSpec, towns: &mut TownCache) -> Result<(Prepared, RouteSpec), String> {
    if let RouteChoice::File { file, id } = &spec.route
        && file.file_name().is_some_and(|f| f == "routes_town01.xml")
        && EVALUATION_ROUTES.contains(&id.as_str())
    {
        return Err(format!(
            "{} route {id} is an evaluation route: never collect on it",
            file.display()
        ));
    }
    let town = towns.get(&spec.map, spec.generate_lights)?;
    let (route, route_file) = match &spec.route {
        RouteChoice::File { file, id } => {
            let routes = RouteFile::load(file).map_err(|e| e.to_string())?;
            (
                routes.route(id).map_err(|e| e.to_string())?.clone(),
                Some(file.clone()),
            )
        }
        RouteChoice::Random { seed } => (random_route(&town, *seed)?.0, None),
    };
    let dense = plan_route(&town, &route, &PlannerConfig::default()).map_err(|e| e.to_string())?;
    let stored = RouteSpec {
        file: route_file.as_ref().map(|f| f.display().to_string()),
        id: route.id.clone(),
        waypoints: route
            .waypoints
            .iter()
            .map(|w| {
                [
                    w.position.x,
                    w.position.y,
                    w.yaw_rad.unwrap_or(0.0).to_degrees(),
                ]
            })
            .collect(),
    };
    Ok((
        Prepared {
            town,
            route: dense,
            route_file: route_file.unwrap_or_else(|| route.source.clone()),
        },
        stored,
    ))
}

/// The route a stored episode drove, planned again (deterministically) on its town.
pub fn replan(town: &Town, route: &RouteSpec) -> Result<DenseRoute, String> {
    let r = Route {
        id: route.id.clone(),
        town: Some(town.name.clone()),
        waypoints: route
            .waypoints
            .iter()
            .map(|w| RouteWaypoint {
                position: Vec3::new(w[0], w[1], 0.0),
                yaw_rad: Some(w[2].to_radians()),
            })
            .collect(),
        source: PathBuf::from(route.file.clone().unwrap_or_default()),
    };
    plan_route(town, &r, &PlannerConfig::default()).map_err(|e| e.to_string())
}

/// The frames of one episode as the run goes: renders each view and keeps the state.
pub struct EpisodeRecorder {
    renderer: Renderer,
    view_yaws_rad: Vec<f32>,
    frame_every_ticks: u64,
    /// The frames so far.
    pub shard: Shard,
}

impl EpisodeRecorder {
    /// A recorder with its own renderer for `town`.
    pub fn new(town: &Town, cfg: &CollectConfig, seed: u64) -> Result<EpisodeRecorder, String> {
        let renderer = Renderer::new(town, cfg.rig, seed).map_err(|e| e.to_string())?;
        Ok(EpisodeRecorder {
            renderer,
            view_yaws_rad: cfg.view_yaws_deg.iter().map(|d| d.to_radians()).collect(),
            frame_every_ticks: u64::from(cfg.frame_every_ticks),
            shard: Shard::new(cfg.rig.base_size(), cfg.view_yaws_deg.len()),
        })
    }
}

impl RunObserver for EpisodeRecorder {
    /// Every `frame_every_ticks`-th tick becomes a frame: each view
    /// rendered at S0 by the recorder's own renderer, and the state.
    fn on_tick(
        &mut self,
        v: &TickView<'_>,
        _camera: Option<&mut dyn Camera>,
    ) -> Result<(), RunError> {
        if !v.tick.is_multiple_of(self.frame_every_ticks) {
            return Ok(());
        }
        let (tick, actors, lights) = (v.tick, v.actors, v.lights);
        let ego = v.ego();
        for &yaw in &self.view_yaws_rad {
            let pose = EgoPose {
                position: ego.position,
                heading: ego.heading + yaw,
            };
            let (rgb, classes) = self
                .renderer
                .render_rig(&pose, actors, lights, 1.0)
                .map_err(|e| RunError::Camera(e.to_string()))?;
            self.shard.rgb.extend_from_slice(&rgb.data);
            self.shard
                .classes
                .extend(classes.data.iter().map(|&c| to_wor(c) as u8));
        }
        self.shard.ego.push(EgoRow::of(ego));
        self.shard.command.push(v.command as u8);
        self.shard.route.push([v.route_index as f32, v.route_s]);
        self.shard.tick.push(tick as u32);
        self.shard.actors.push(
            actors
                .iter()
                .filter(|a| a.kind != ActorKind::Ego)
                .map(ActorRow::of)
                .collect(),
        );
        self.shard
            .lights
            .push(lights.iter().map(|&s| light_code(s)).collect());
        Ok(())
    }
}

/// The shard's file name of episode `id`.
pub fn shard_name(id: u32) -> String {
    format!("episode-{id:05}.safetensors")
}

/// The scenario an episode runs: the expert, no delay, the default timing.
fn scenario_of(spec: &EpisodeSpec, prepared: &Prepared) -> Scenario {
    let mut s = Scenario::from_toml_str(
        "[map]\nfile = \"x\"\n[route]\nfile = \"x\"\nid = \"x\"\n",
        Path::new("collect.toml"),
    )
    .expect("the built-in scenario parses");
    s.name = format!("collect-{:05}", spec.id);
    s.map = MapSpec {
        file: spec.map.clone(),
        generate_lights: Some(spec.generate_lights),
    };
    s.route = ScenarioRoute {
        file: prepared.route_file.clone(),
        id: prepared.route.id.clone(),
    };
    s.traffic.vehicles = spec.vehicles;
    s.traffic.pedestrians = spec.pedestrians;
    s.traffic.ego_crossings_per_min = spec.crossings_per_min;
    s.traffic.seed = spec.seed;
    s
}

/// How one episode went.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeReport {
    /// The index entry written.
    pub episode: Episode,
    /// Wall time (seconds).
    pub wall_s: f64,
    /// Whether the route was completed.
    pub success: bool,
    /// In a DAgger round ([`collect_with`] with a learner): who drove.
    pub dagger: Option<DaggerShare>,
}

/// Who drove a DAgger episode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DaggerShare {
    /// Control boundaries at which the learner drove.
    pub learner: u64,
    /// Control boundaries at which the expert drove.
    pub expert: u64,
    /// Times the expert took over.
    pub takeovers: u64,
}

impl EpisodeReport {
    /// One line for a progress log (`mrdrive collect`): the episode's number of
    /// `planned`, town, route, traffic, frames and rate.
    pub fn line(&self, planned: usize) -> String {
        let e = &self.episode;
        format!(
            "episode {:>3}/{} {} route {:<12} traffic {:>2}+{:<2} {:>4} frames in {:>5.1} s ({:.0} frames/s){}{}",
            e.id + 1,
            planned,
            e.town,
            e.route.id,
            e.vehicles,
            e.pedestrians,
            e.frames,
            self.wall_s,
            f64::from(e.frames) / self.wall_s.max(1e-9),
            if self.success {
                ""
            } else {
                "  (route not completed)"
            },
            match self.dagger {
                Some(d) => format!(
                    "  (the learner drove {:.1} %; {} takeovers)",
                    100.0 * d.learner as f64 / (d.learner + d.expert).max(1) as f64,
                    d.takeovers
                ),
                None => String::new(),
            }
        )
    }
}

/// Makes the learner of a DAgger collection afresh for each episode (a policy
/// loaded from its checkpoint): it drives, the expert watches ([`crate::dagger`]).
pub type Learner<'a> = dyn Fn() -> Result<Box<dyn Driver>, String> + 'a;

/// Drives one episode and returns its frames and index entry (not yet written):
/// the expert with noise, or with a `learner` the learner watched by the expert.
pub fn drive(
    spec: &EpisodeSpec,
    cfg: &CollectConfig,
    towns: &mut TownCache,
    learner: Option<&Learner>,
) -> Result<(Shard, Episode, bool, Option<DaggerShare>), String> {
    let (prepared, stored) = prepare(spec, towns)?;
    let scenario = scenario_of(spec, &prepared);
    let town = prepared.town.clone();
    let expert = Expert::new(ExpertParams::default());
    let mut noisy;
    let mut dagger = None;
    let driver: &mut dyn Driver = match learner {
        None => {
            noisy = NoisyDriver::new(expert, cfg.noise, spec.seed ^ 0x006e_6f69_7365);
            &mut noisy
        }
        Some(make) => dagger.insert(Dagger::new(make()?, expert, DaggerParams::default())),
    };
    let mut recorder = EpisodeRecorder::new(&town, cfg, spec.seed)?;
    let tick_s = scenario.timing.tick_s;
    let overrides = Overrides::default();
    let request = RunRequest {
        max_ticks: Some((cfg.max_s / tick_s).round() as u64),
        ..RunRequest::new(Path::new("collect.toml"), &overrides)
    };
    let extras = Extras {
        observer: Some(&mut recorder),
        selector: Some(Box::new(Fixed { scale: 1.0 })),
        driver: Some(driver),
        prebuilt: Some((&scenario, &prepared)),
    };
    let record = build::run_scenario_with(&request, &Drivers::new(), &mut |_| {}, extras)
        .map_err(|e| build::error_chain(&e))?
        .record;
    let episode = Episode {
        id: spec.id,
        shard: shard_name(spec.id),
        frames: recorder.shard.len() as u32,
        town: town.name.clone(),
        // Absolute, so `label`, `data info` and the loader find the map from any folder.
        map: std::fs::canonicalize(&spec.map)
            .unwrap_or_else(|_| spec.map.clone())
            .display()
            .to_string(),
        generate_lights: spec.generate_lights,
        route: stored,
        seed: spec.seed,
        vehicles: spec.vehicles,
        pedestrians: spec.pedestrians,
        crossings_per_min: spec.crossings_per_min,
        walkers_sent: record.result.traffic.walkers_sent,
        sim_time_s: record.result.sim_time_s,
        labels: None,
    };
    let share = dagger.map(|d| DaggerShare {
        learner: d.learner_boundaries,
        expert: d.expert_boundaries,
        takeovers: d.takeovers,
    });
    Ok((recorder.shard, episode, record.result.success, share))
}

/// Collects every episode of `plan` not yet in `dir`'s index, the expert with
/// noise driving; calls `report` after each. Returns the index.
pub fn collect(
    plan: &[EpisodeSpec],
    cfg: &CollectConfig,
    dir: &Path,
    report: &mut dyn FnMut(&EpisodeReport, &Index),
) -> Result<Index, DataError> {
    collect_with(plan, cfg, dir, None, report)
}

/// [`collect`], and with a `learner` a DAgger round: the learner drives every
/// episode, the expert watching ([`crate::dagger`]).
pub fn collect_with(
    plan: &[EpisodeSpec],
    cfg: &CollectConfig,
    dir: &Path,
    learner: Option<&Learner>,
    report: &mut dyn FnMut(&EpisodeReport, &Index),
) -> Result<Index, DataError> {
    std::fs::create_dir_all(dir).map_err(|e| DataError::Io {
        path: dir.to_path_buf(),
        source: e,
    })?;
    let tick_s = sim::scenario::TimingSpec::default().tick_s;
    let mut index = match Index::load(dir) {
        Ok(existing) => {
            let want = cfg.empty_index(tick_s);
            if (
                &existing.name,
                existing.s0,
                &existing.view_yaws_deg,
                existing.frame_every_ticks,
            ) != (
                &want.name,
                want.s0,
                &want.view_yaws_deg,
                want.frame_every_ticks,
            ) {
                return Err(DataError::Index {
                    path: dir.join(crate::format::INDEX_FILE),
                    msg: format!(
                        "this directory holds dataset {:?} at S0 {:?} with views {:?}, not {:?} at {:?} with {:?}: collect into another directory",
                        existing.name,
                        existing.s0,
                        existing.view_yaws_deg,
                        want.name,
                        want.s0,
                        want.view_yaws_deg
                    ),
                });
            }
            existing
        }
        Err(_) if !dir.join(crate::format::INDEX_FILE).exists() => cfg.empty_index(tick_s),
        Err(e) => return Err(e),
    };
    let mut towns = TownCache::default();
    for spec in plan {
        if let Some(e) = index.episodes.iter().find(|e| e.id == spec.id) {
            // A kept episode must be the plan's: resuming with other traffic would mix two datasets.
            if (e.seed, e.vehicles, e.pedestrians, e.crossings_per_min)
                != (
                    spec.seed,
                    spec.vehicles,
                    spec.pedestrians,
                    spec.crossings_per_min,
                )
            {
                return Err(DataError::Index {
                    path: dir.join(crate::format::INDEX_FILE),
                    msg: format!(
                        "episode {} was collected with seed {}, traffic {}+{} and {} crossings per minute, but the plan asks for seed {}, {}+{} and {}: collect into another directory, or give the same --pedestrians-scale and --crossings-per-min",
                        e.id,
                        e.seed,
                        e.vehicles,
                        e.pedestrians,
                        e.crossings_per_min,
                        spec.seed,
                        spec.vehicles,
                        spec.pedestrians,
                        spec.crossings_per_min
                    ),
                });
            }
            continue;
        }
        let started = std::time::Instant::now();
        let (shard, episode, success, dagger) =
            drive(spec, cfg, &mut towns, learner).map_err(|msg| DataError::Index {
                path: dir.join(shard_name(spec.id)),
                msg: format!("episode {} ({}): {msg}", spec.id, spec.map.display()),
            })?;
        let metadata = HashMap::from([
            ("town".to_string(), episode.town.clone()),
            ("route".to_string(), episode.route.id.clone()),
        ]);
        write_atomic(&dir.join(&episode.shard), &shard.to_bytes(&metadata))?;
        index.episodes.push(episode.clone());
        index.episodes.sort_by_key(|e| e.id);
        index.save(dir)?;
        report(
            &EpisodeReport {
                episode,
                wall_s: started.elapsed().as_secs_f64(),
                success,
                dagger,
            },
            &index,
        );
    }
    Ok(index)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_dataset_drives_the_held_out_towns() {
        // The study's held-out routes (experiments::PaperConfig::held_out) are on
        // CARLA's Town02 and our held01: no episode of either preset may drive them.
        for preset in [Preset::Original, Preset::Retarget] {
            for e in plan(preset, 5000, Path::new("carla"), Path::new("repo")) {
                let map = e.map.to_string_lossy().into_owned();
                assert!(
                    !map.ends_with("Town02.xodr") && !map.ends_with("held01.xodr"),
                    "{} episode {} drives {map}",
                    preset.name(),
                    e.id
                );
            }
        }
    }

    #[test]
    fn a_scenario_plan_drives_its_route_once_per_seed_and_density() {
        let text = "[map]\nfile = \"maps/gen02.xodr\"\ngenerate_lights = true\n\
                    [route]\nfile = \"routes/gen02.toml\"\nid = 1\n\
                    [traffic]\nego_crossings_per_min = 2.0\n";
        let scenario = Scenario::from_toml_str(text, Path::new("s.toml")).unwrap();
        let plan = scenario_plan(&scenario, &[2, 5], &[(0, 0), (20, 40)]);
        let got: Vec<(u32, u64, u32, u32)> = plan
            .iter()
            .map(|s| (s.id, s.seed, s.vehicles, s.pedestrians))
            .collect();
        assert_eq!(
            got,
            [(0, 2, 0, 0), (1, 2, 20, 40), (2, 5, 0, 0), (3, 5, 20, 40)]
        );
        for s in &plan {
            assert_eq!(s.map, Path::new("maps/gen02.xodr"));
            assert!(s.generate_lights);
            assert_eq!(s.crossings_per_min, 2.0);
            assert_eq!(
                s.route,
                RouteChoice::File {
                    file: "routes/gen02.toml".into(),
                    id: "1".into()
                }
            );
        }
    }

    #[test]
    fn no_plan_drives_an_evaluation_route_or_town02_and_the_sets_are_disjoint() {
        let (carla, repo) = (Path::new("/carla"), Path::new("/repo"));
        let original = plan(Preset::Original, 500, carla, repo);
        let retarget = plan(Preset::Retarget, 500, carla, repo);
        for spec in original.iter().chain(&retarget) {
            assert!(!spec.map.to_string_lossy().contains("Town02"), "{spec:?}");
            if let RouteChoice::File { file, id } = &spec.route {
                let town01 = file.ends_with("routes_town01.xml");
                assert!(
                    !(town01 && EVALUATION_ROUTES.contains(&id.as_str())),
                    "{spec:?}"
                );
            }
        }
        // The retargeting set shares no route with the original set.
        let routes = |p: &[EpisodeSpec]| {
            p.iter()
                .map(|s| format!("{:?}", s.route))
                .collect::<std::collections::HashSet<_>>()
        };
        assert!(routes(&original).is_disjoint(&routes(&retarget)));
        // Three in five of the original set's random routes are in Town01, the rest in
        // our towns; neither set drives the default scenario's route (gen01 route 0).
        let random = &original[TOWN01_ROUTE_EPISODES..];
        let town01 = random
            .iter()
            .filter(|s| s.map.ends_with("Town01.xodr"))
            .count();
        let three_in_five = (TOWN01_ROUTE_EPISODES..500).filter(|i| i % 5 < 3).count();
        assert_eq!(town01, three_in_five, "{town01} of {}", random.len());
        for spec in original.iter().chain(&retarget) {
            let default_route = RouteChoice::File {
                file: repo.join("routes/gen01.toml"),
                id: "0".into(),
            };
            assert_ne!(spec.route, default_route, "{spec:?}");
        }
        // Every training route of Town01 (2-9) at every density is in the original set.
        for id in 2..=9 {
            for &(v, p) in &DENSITIES {
                assert!(original.iter().any(|s| s.route
                    == RouteChoice::File {
                        file: carla.join("routes_town01.xml"),
                        id: id.to_string()
                    }
                    && (s.vehicles, s.pedestrians) == (v, p)));
            }
        }
    }

    #[test]
    fn a_crowded_plan_multiplies_the_walkers_and_keeps_the_rest() {
        let (carla, repo) = (Path::new("/carla"), Path::new("/repo"));
        let base = plan(Preset::Original, 6, carla, repo);
        let mut crowded = base.clone();
        crowd(&mut crowded, 4.0).unwrap();
        let walkers: Vec<u32> = crowded.iter().map(|s| s.pedestrians).collect();
        assert_eq!(walkers, [0, 40, 160, 160, 0, 40]);
        for (a, b) in base.iter().zip(&crowded) {
            assert_eq!(
                (a.id, &a.route, a.seed, a.vehicles),
                (b.id, &b.route, b.seed, b.vehicles)
            );
        }
        for bad in [-1.0, 21.0, f64::NAN] {
            let err = crowd(&mut crowded.clone(), bad).unwrap_err();
            assert!(err.contains("from 0 to 20"), "{err}");
        }
    }

    #[test]
    fn an_evaluation_route_is_refused_by_name() {
        let spec = EpisodeSpec {
            id: 0,
            map: PathBuf::from("Town01.xodr"),
            generate_lights: false,
            route: RouteChoice::File {
                file: PathBuf::from("../shared/carla/routes_town01.xml"),
                id: "1".into(),
            },
            seed: 0,
            vehicles: 0,
            pedestrians: 0,
            crossings_per_min: 0.0,
        };
        let err = match prepare(&spec, &mut TownCache::default()) {
            Err(e) => e,
            Ok(_) => panic!("an evaluation route was prepared"),
        };
        assert!(err.contains("evaluation route"), "{err}");
    }

    #[test]
    fn random_routes_are_deterministic_and_long_enough() {
        let town = world::map::testtown::grid(4, 4, 100.0);
        let (a, da) = random_route(&town, 7).unwrap();
        let (b, _) = random_route(&town, 7).unwrap();
        assert_eq!(format!("{a:?}"), format!("{b:?}"));
        assert!((300.0..900.0).contains(&da.length_m));
        let replanned = replan(
            &town,
            &RouteSpec {
                file: None,
                id: a.id.clone(),
                waypoints: a
                    .waypoints
                    .iter()
                    .map(|w| [w.position.x, w.position.y, w.yaw_rad.unwrap().to_degrees()])
                    .collect(),
            },
        )
        .unwrap();
        assert_eq!(replanned.length_m, da.length_m);
    }
}
