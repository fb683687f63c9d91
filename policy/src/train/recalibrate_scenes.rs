//! BN recalibration (docs/protocol.md §6) on frames rendered along scenarios.
//!
//! The expert drives each scenario (with its traffic); every `every_s`
//! seconds of simulated time the moment (ego pose, actors, light states) is
//! kept. Each branch of every BN bank then has its running statistics reset
//! and re-estimated as the mean of the batch statistics over `batches`
//! batches of those moments, each rendered at that branch's scale, exactly as
//! the policy sees them in the loop (drawn at the scale, not resized).

use std::path::{Path, PathBuf};

use burn::prelude::*;
use sim::build::Overrides;
use sim::build::{self, BuildError, Drivers, Extras, RunRequest};
use sim::observe::{Moment, Moments};
use sim::render::{EgoPose, Renderer};
use sim::runner;
use sim::scenario::{DriverKind, Scenario};

use super::recalibrate::recalibrate_with;
use crate::checkpoint::{self, CheckpointError, ModelCard};
use crate::driver::PolicyFactory;
use crate::model::PolicyNet;

/// What to recalibrate on.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneRecalibration {
    /// Scenario files to collect frames along (never the evaluation routes).
    pub scenarios: Vec<PathBuf>,
    /// Traffic given over each scenario's.
    pub overrides: Overrides,
    /// Batches per branch (docs/protocol.md §6: 200).
    pub batches: usize,
    /// Frames per batch.
    pub batch: usize,
    /// Simulated seconds between kept frames.
    pub every_s: f64,
}

/// The frames one scenario gave.
#[derive(Debug, Clone, PartialEq)]
pub struct Collected {
    /// The scenario file.
    pub scenario: PathBuf,
    /// Moments kept.
    pub frames: usize,
    /// Simulated time the expert drove (seconds).
    pub sim_time_s: f64,
    /// What ended the run ("route completed" or the infraction's name).
    pub ended: String,
}

/// A recalibrated network and how it was done.
#[derive(Debug)]
pub struct Recalibrated {
    /// The network with its BN running statistics re-estimated.
    pub net: PolicyNet,
    /// Its card: the input's, with what was done appended.
    pub card: ModelCard,
    /// Batches of frames used per branch (fewer than asked when the
    /// scenarios gave too few frames).
    pub batches: usize,
    /// Frames rendered, over every branch.
    pub rendered: usize,
}

/// Recalibration could not be done.
#[derive(Debug, thiserror::Error)]
pub enum SceneRecalibrationError {
    /// Batches or batch size zero.
    #[error(
        "--batches {batches} --batch {batch}: both must be at least 1 (docs/protocol.md §6 uses 200 batches)"
    )]
    Sizes {
        /// Batches per branch asked for.
        batches: usize,
        /// Frames per batch asked for.
        batch: usize,
    },
    /// The spacing of kept frames is not a positive time.
    #[error("--every-s {0}: give a positive spacing in seconds, e.g. --every-s 0.1")]
    Spacing(f64),
    /// The checkpoint path cannot be resolved.
    #[error("{path}: cannot resolve the checkpoint path")]
    Resolve {
        /// The checkpoint as given.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The checkpoint cannot be read.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// A scenario cannot be driven or rendered.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// Not even one batch of frames.
    #[error(
        "only {frames} frames along {scenarios} scenario(s), fewer than one batch of {batch}; fix: add scenarios or lower --every-s"
    )]
    TooFewFrames {
        /// Frames collected.
        frames: usize,
        /// Scenarios driven.
        scenarios: usize,
        /// Frames per batch.
        batch: usize,
    },
    /// A frame could not be rendered.
    #[error("rendering a recalibration frame failed: {0}")]
    Render(String),
}

/// Drives `path` (with `overrides`) by the expert, keeps a moment every
/// `every_s` seconds of simulated time, and returns them with a renderer for
/// that scenario's town on the rig of the checkpoint `weights` (an absolute
/// path).
fn collect(
    path: &Path,
    weights: &Path,
    overrides: &Overrides,
    every_s: f64,
    drivers: &Drivers,
) -> Result<(Renderer, Vec<Moment>, Collected), SceneRecalibrationError> {
    let scenario = overrides.apply(&Scenario::from_file(path).map_err(BuildError::from)?);
    let every_ticks = ((every_s / scenario.timing.tick_s).round() as u64).max(1);
    let mut expert = scenario.clone();
    expert.driver.kind = DriverKind::Expert;
    let failed = |source| BuildError::Run {
        path: path.to_path_buf(),
        source: Box::new(source),
    };
    let prepared = runner::prepare(&expert).map_err(failed)?;
    let mut moments = Moments::every(every_ticks);
    let extras = Extras {
        observer: Some(&mut moments),
        prebuilt: Some((&expert, &prepared)),
        ..Extras::default()
    };
    let record = build::run_scenario_with(
        &RunRequest::new(path, overrides),
        drivers,
        &mut |_| {},
        extras,
    )?
    .record;
    let collected = Collected {
        scenario: path.to_path_buf(),
        frames: moments.kept.len(),
        sim_time_s: record.result.sim_time_s,
        ended: record
            .result
            .termination
            .map_or("route completed", |t| t.name())
            .to_string(),
    };
    // The camera the policy would have: the checkpoint's S0 sets the rig.
    let mut as_policy = scenario;
    as_policy.driver.kind = DriverKind::Policy;
    as_policy.driver.checkpoint = Some(weights.to_path_buf());
    let camera = build::camera_for(&as_policy, &prepared, drivers)?;
    Ok((camera, moments.kept, collected))
}

/// Recalibrates the checkpoint `weights` on frames rendered along
/// `settings.scenarios`, on `device` (its autodiff twin runs the passes);
/// `on_collected` hears about each scenario once it is driven.
pub fn recalibrate_on_scenarios(
    weights: &Path,
    settings: &SceneRecalibration,
    device: &Device,
    mut on_collected: impl FnMut(&Collected),
) -> Result<Recalibrated, SceneRecalibrationError> {
    let SceneRecalibration {
        scenarios,
        overrides,
        batches,
        batch,
        every_s,
    } = settings;
    let (batches, batch, every_s) = (*batches, *batch, *every_s);
    if batches == 0 || batch == 0 {
        return Err(SceneRecalibrationError::Sizes { batches, batch });
    }
    if !(every_s.is_finite() && every_s > 0.0) {
        return Err(SceneRecalibrationError::Spacing(every_s));
    }
    let (config, card) = checkpoint::read_manifest(weights)?;
    let absolute =
        std::fs::canonicalize(weights).map_err(|source| SceneRecalibrationError::Resolve {
            path: weights.to_path_buf(),
            source,
        })?;
    let drivers = Drivers::new().with(DriverKind::Policy, PolicyFactory);
    let want = batches * batch;
    // (scenario index, moment) pairs and one renderer per scenario (each has its own town).
    let mut moments = Vec::new();
    let mut cameras = Vec::new();
    for (i, path) in scenarios.iter().enumerate() {
        let (camera, kept, collected) = collect(path, &absolute, overrides, every_s, &drivers)?;
        on_collected(&collected);
        moments.extend(kept.into_iter().map(|m| (i, m)));
        cameras.push(camera);
    }
    // More than needed: keep `want`, evenly spread over everything driven.
    if moments.len() > want {
        let n = moments.len();
        let mut all: Vec<Option<(usize, Moment)>> = moments.into_iter().map(Some).collect();
        moments = (0..want)
            .map(|i| all[i * n / want].take().expect("distinct indices"))
            .collect();
    }
    let n_batches = moments.len() / batch;
    if n_batches == 0 {
        return Err(SceneRecalibrationError::TooFewFrames {
            frames: moments.len(),
            scenarios: scenarios.len(),
            batch,
        });
    }
    let (net, _) = checkpoint::load(weights, device)?;
    let autodiff = device.clone().autodiff();
    let mut rendered = 0usize;
    let mut failure = None;
    let net = recalibrate_with(net, n_batches, &autodiff, |branch, k| {
        let scale = config.scales[branch];
        let [h, w] = config.input_size(scale);
        let mut data = Vec::with_capacity(batch * 3 * h * w);
        // Batch k takes frames k, k + n, k + 2n, ...: spread along the routes, not consecutive.
        for j in 0..batch {
            let (scn, m) = &moments[k + j * n_batches];
            let ego = EgoPose::from(&m.actors[0]);
            match cameras[*scn].render_rig(&ego, &m.actors, &m.lights, scale) {
                Ok((rgb, _)) => data.extend(config.normalize_rgb8(&rgb.data, h, w)),
                Err(e) => {
                    // Reported after the pass (the closure cannot return an error).
                    failure.get_or_insert(e.to_string());
                    data.resize(data.len() + 3 * h * w, 0.0);
                }
            }
            rendered += 1;
        }
        Tensor::<4>::from_data(TensorData::new(data, [batch, 3, h, w]), &autodiff)
    });
    if let Some(e) = failure {
        return Err(SceneRecalibrationError::Render(e));
    }
    let names: Vec<String> = scenarios.iter().map(|p| p.display().to_string()).collect();
    let card = ModelCard {
        trained: card.trained,
        description: format!(
            "{} BN running statistics recalibrated on {} frames per scale ({n_batches} batches of {batch}, expert-driven, every {every_s} s) along {}.",
            card.description.trim_end_matches('.').to_string() + ";",
            n_batches * batch,
            names.join(", ")
        ),
        source: weights.display().to_string(),
        training: card.training.clone(),
    };
    Ok(Recalibrated {
        net,
        card,
        batches: n_batches,
        rendered,
    })
}
