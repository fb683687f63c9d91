//! Labelling a collected dataset: every frame of every episode, each
//! episode's label file written when it is done (so a killed run keeps what
//! it finished), frames in parallel (each frame's arithmetic is sequential,
//! so the values do not depend on the thread count).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use sim::runner::{AHEAD_CORRIDOR_M, AHEAD_RANGE_M};
use world::agents::VehicleParams;
use world::route::DenseRoute;
use world::rules::{ActorView, nearest_ahead, walker_horizon_s};
use world::rules::{RouteStops, route_ahead};
use world::{Town, Vec2};

use super::{FrameInput, Hazards, LABEL_VERSION, Labeller, Q};
use crate::action::NUM_ACTIONS;
use crate::collect::{TownCache, replan};
use crate::format::{
    ActorRow, DataError, Episode, Index, Labels, Q_PER_VIEW, Shard, light_of_code, write_atomic,
};

/// The label file's name of an episode's shard.
pub fn labels_name(episode: &Episode) -> String {
    format!("labels-{:05}.safetensors", episode.id)
}

/// What is in the ego's way in frame `i` (see [`Hazards::measure`]): the
/// actor ahead found as the loop finds it for the expert.
pub fn hazards(
    shard: &Shard,
    i: usize,
    route: &DenseRoute,
    stops: &RouteStops,
    labeller: &Labeller,
) -> Hazards {
    let ego = shard.ego[i];
    let [index, ego_s] = shard.route[i];
    let mut path = Vec::new();
    route_ahead(
        route,
        index as usize,
        Vec2::new(ego.x, ego.y),
        AHEAD_RANGE_M,
        &mut path,
    );
    let views: Vec<ActorView> = shard.actors[i].iter().map(ActorRow::view).collect();
    let ahead = nearest_ahead(
        &path,
        &views,
        None,
        AHEAD_CORRIDOR_M,
        AHEAD_RANGE_M,
        walker_horizon_s(ego.speed),
    );
    let light = |l: world::LightIdx| {
        shard.lights[i]
            .get(l.0 as usize)
            .copied()
            .map_or(world::LightState::Green, light_of_code)
    };
    Hazards::measure(&labeller.params, stops, ego_s, light, ahead)
}

/// Labels every frame of one episode whose future is in the shard; frames
/// too near the end are marked invalid (their values are 0).
pub fn label_episode(
    town: &Town,
    route: &DenseRoute,
    shard: &Shard,
    labeller: &Labeller,
    view_yaws_deg: &[f32],
) -> Labels {
    let steps = labeller.steps;
    let n = shard.len();
    let views: Vec<f32> = view_yaws_deg.iter().map(|d| d.to_radians()).collect();
    let stops = labeller.stop_lines().on_route(route);
    let per_frame: Vec<Option<Vec<Q>>> = (0..n)
        .into_par_iter()
        .map(|i| {
            if i + steps >= n {
                return None;
            }
            let actors: Vec<&[ActorRow]> = (i..=i + steps)
                .map(|k| shard.actors[k].as_slice())
                .collect();
            let lights: Vec<&[u8]> = (i..=i + steps)
                .map(|k| shard.lights[k].as_slice())
                .collect();
            let index = shard.route[i][0] as usize;
            let lane = route.points.get(index).map(|p| (p.lane, p.s));
            let input = FrameInput {
                ego: shard.ego[i],
                actors: &actors,
                lights: &lights,
                hazards: hazards(shard, i, route, &stops, labeller),
                lane,
            };
            Some(labeller.label(town, &input, &views))
        })
        .collect();
    let mut q = Vec::with_capacity(n * views.len() * Q_PER_VIEW);
    let mut valid = Vec::with_capacity(n);
    for frame in &per_frame {
        valid.push(frame.is_some());
        for v in 0..views.len() {
            match frame {
                Some(qs) => q.extend(qs[v].iter().flatten().flatten()),
                None => q.extend(std::iter::repeat_n(0.0, Q_PER_VIEW)),
            }
        }
    }
    debug_assert_eq!(q.len(), n * views.len() * 6 * 4 * NUM_ACTIONS);
    Labels {
        views: views.len(),
        q,
        valid,
    }
}

/// How a labelling run went.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LabelReport {
    /// Episodes labelled by this run.
    pub episodes: usize,
    /// Frames labelled by this run.
    pub frames: u64,
    /// Episodes that already had labels of this version.
    pub skipped: usize,
    /// Episodes that could not be read, with why (the rest were labelled).
    pub failed: Vec<(PathBuf, String)>,
}

/// Labels every episode of the dataset in `dir` that has no labels of this
/// version; `progress(done, total)` after each episode.
pub fn label_dataset(
    dir: &Path,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<LabelReport, DataError> {
    let mut index = Index::load(dir)?;
    let frame_s = index.frame_s() as f32;
    let mut towns = TownCache::default();
    let mut labellers: HashMap<String, Labeller> = HashMap::new();
    let mut report = LabelReport::default();
    let total = index.episodes.len();
    for k in 0..total {
        let episode = index.episodes[k].clone();
        let name = labels_name(&episode);
        let path = dir.join(&name);
        if episode.labels.as_deref() == Some(name.as_str())
            && Labels::read(
                &path,
                LABEL_VERSION,
                episode.frames as usize,
                index.view_yaws_deg.len(),
            )
            .is_ok()
        {
            report.skipped += 1;
            progress(k + 1, total);
            continue;
        }
        let shard_path = dir.join(&episode.shard);
        let shard = match Shard::read(&shard_path, index.s0, index.view_yaws_deg.len()) {
            Ok(s) => s,
            Err(e) => {
                report.failed.push((shard_path, e.to_string()));
                continue;
            }
        };
        let prepared = towns
            .get(Path::new(&episode.map), episode.generate_lights)
            .and_then(|town| replan(&town, &episode.route).map(|r| (town, r)));
        let (town, route) = match prepared {
            Ok(x) => x,
            Err(e) => {
                report
                    .failed
                    .push((shard_path, format!("map {} or its route: {e}", episode.map)));
                continue;
            }
        };
        let key = format!("{}|{}", episode.map, episode.generate_lights);
        let labeller = labellers.entry(key).or_insert_with(|| {
            Labeller::new(
                &town,
                &VehicleParams::default(),
                Default::default(),
                5,
                frame_s,
                index.tick_s as f32,
            )
        });
        let labels = label_episode(&town, &route, &shard, labeller, &index.view_yaws_deg);
        write_atomic(&path, &labels.to_bytes(LABEL_VERSION, &episode.shard))?;
        index.episodes[k].labels = Some(name);
        index.save(dir)?;
        report.episodes += 1;
        report.frames += labels.valid.iter().filter(|v| **v).count() as u64;
        progress(k + 1, total);
    }
    Ok(report)
}
