//! `mrdrive policy recalibrate`: BN recalibration (PROTOCOL §6) on frames
//! rendered along scenarios.
//!
//! The expert drives each scenario (with its traffic); every `--every-s`
//! seconds of simulated time the moment (ego pose, actors, light states) is
//! kept. Each branch of every BN bank then has its running statistics reset
//! and re-estimated as the mean of the batch statistics over `--batches`
//! batches of those moments, each rendered at that branch's scale, exactly as
//! the policy sees them in the loop (drawn at the scale, not resized).

use anyhow::{Context, Result, ensure};
use clap::Args;
use policy::burn::prelude::*;
use policy::checkpoint::{self, ModelCard};
use policy::device::{self, DeviceKind};
use policy::train::recalibrate::recalibrate_with;
use sim::build::{self, Drivers};
use sim::render::{EgoPose, Renderer};
use sim::runner::{self, RunInputs};
use sim::scenario::{DriverKind, Scenario};
use std::path::{Path, PathBuf};
use world::{ActorSnapshot, LightState};

use super::run;

/// `mrdrive policy recalibrate WEIGHTS --scenario S... --out OUT`
#[derive(Debug, Args)]
pub struct RecalibrateArgs {
    /// The checkpoint to recalibrate (NAME.safetensors with NAME.json beside it).
    pub weights: PathBuf,
    /// Where to write the recalibrated checkpoint.
    #[arg(long)]
    pub out: PathBuf,
    /// Scenario files to collect frames along (driven by the expert; never the evaluation routes).
    #[arg(long = "scenario", required = true, num_args = 1..)]
    pub scenarios: Vec<PathBuf>,
    /// Batches per branch (PROTOCOL §6: 200).
    #[arg(long, default_value_t = 200)]
    pub batches: usize,
    /// Frames per batch.
    #[arg(long, default_value_t = 8)]
    pub batch: usize,
    /// Simulated seconds between kept frames.
    #[arg(long, default_value_t = 0.1)]
    pub every_s: f64,
    /// Device for the forward passes: cpu, wgpu or cuda.
    #[arg(long, default_value = "cpu")]
    pub device: DeviceKind,
    #[command(flatten)]
    pub traffic: run::TrafficFlags,
}

/// One kept moment of a run.
struct Moment {
    actors: Vec<ActorSnapshot>,
    lights: Vec<LightState>,
}

/// Drives `path` (with the traffic overrides) by the expert, keeps a moment every
/// `every_s` seconds of simulated time, and returns them with a renderer for that
/// scenario's town on the rig of the checkpoint `weights` (an absolute path).
fn collect(
    path: &Path,
    weights: &Path,
    traffic: &run::TrafficFlags,
    every_s: f64,
    drivers: &Drivers,
) -> Result<(Renderer, Vec<Moment>)> {
    let scenario = traffic.overrides(None).apply(&Scenario::from_file(path)?);
    let every_ticks = ((every_s / scenario.timing.tick_s).round() as u64).max(1);
    let mut expert = scenario.clone();
    expert.driver.kind = DriverKind::Expert;
    let prepared =
        runner::prepare(&expert).with_context(|| format!("scenario {}", path.display()))?;
    let mut driver = drivers.driver(&expert, &prepared)?;
    let mut selector = build::selector_for(&expert, None)?;
    let mut moments = Vec::new();
    let mut keep = |tick: u64, actors: &[ActorSnapshot], lights: &[LightState]| {
        if tick.is_multiple_of(every_ticks) && !actors.is_empty() {
            moments.push(Moment {
                actors: actors.to_vec(),
                lights: lights.to_vec(),
            });
        }
    };
    let record = runner::run(
        &expert,
        path,
        RunInputs {
            prepared: &prepared,
            driver: driver.as_mut(),
            selector: selector.as_mut(),
            camera: None,
            recorder: None,
            progress: &mut |_| {},
            max_ticks: None,
            observer: Some(&mut keep),
            render_every_frame: false,
        },
    )?;
    println!(
        "{}: {} frames over {:.1} s ({})",
        path.display(),
        moments.len(),
        record.result.sim_time_s,
        record
            .result
            .termination
            .map_or("route completed", |t| t.name())
    );
    // The camera the policy would have: the checkpoint's S0 sets the rig.
    let mut as_policy = scenario;
    as_policy.driver.kind = DriverKind::Policy;
    as_policy.driver.checkpoint = Some(weights.to_path_buf());
    let camera = build::camera_for(&as_policy, &prepared, drivers)?;
    Ok((camera, moments))
}

/// Runs `mrdrive policy recalibrate`.
pub fn recalibrate(a: &RecalibrateArgs) -> Result<()> {
    ensure!(
        a.batches > 0 && a.batch > 0,
        "--batches {} --batch {}: both must be at least 1 (PROTOCOL §6 uses 200 batches)",
        a.batches,
        a.batch
    );
    ensure!(
        a.every_s.is_finite() && a.every_s > 0.0,
        "--every-s {}: give a positive spacing in seconds, e.g. --every-s 0.1",
        a.every_s
    );
    let (config, card) = checkpoint::read_manifest(&a.weights)?;
    let weights = std::fs::canonicalize(&a.weights).with_context(|| {
        format!(
            "{}: cannot resolve the checkpoint path",
            a.weights.display()
        )
    })?;
    let want = a.batches * a.batch;
    // (scenario index, moment) pairs and one renderer per scenario (each has its own town).
    let mut moments = Vec::new();
    let mut cameras = Vec::new();
    let drivers = super::drivers();
    for (i, path) in a.scenarios.iter().enumerate() {
        let (camera, kept) = collect(path, &weights, &a.traffic, a.every_s, &drivers)?;
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
    let n_batches = moments.len() / a.batch;
    ensure!(
        n_batches > 0,
        "only {} frames along {} scenario(s), fewer than one batch of {}: add scenarios or lower --every-s",
        moments.len(),
        a.scenarios.len(),
        a.batch
    );
    if n_batches < a.batches {
        println!(
            "note: {} frames make {n_batches} batches of {}, not the {} asked for (add scenarios or lower --every-s for more)",
            moments.len(),
            a.batch,
            a.batches
        );
    }
    let dev = device::open(a.device)?;
    let (net, _) = checkpoint::load(&a.weights, &dev)?;
    let autodiff = dev.autodiff();
    let mut rendered = 0usize;
    let mut failure = None;
    let t0 = std::time::Instant::now();
    let net = recalibrate_with(net, n_batches, &autodiff, |branch, k| {
        let scale = config.scales[branch];
        let [h, w] = config.input_size(scale);
        let mut data = Vec::with_capacity(a.batch * 3 * h * w);
        // Batch k takes frames k, k + n, k + 2n, ...: spread along the routes, not consecutive.
        for j in 0..a.batch {
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
        Tensor::<4>::from_data(TensorData::new(data, [a.batch, 3, h, w]), &autodiff)
    });
    if let Some(e) = failure {
        anyhow::bail!("rendering a recalibration frame failed: {e}");
    }
    let names: Vec<String> = a
        .scenarios
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    let out_card = ModelCard {
        trained: card.trained,
        description: format!(
            "{} BN running statistics recalibrated on {} frames per scale ({n_batches} batches of {}, expert-driven, every {} s) along {}.",
            card.description.trim_end_matches('.').to_string() + ";",
            n_batches * a.batch,
            a.batch,
            a.every_s,
            names.join(", ")
        ),
        source: a.weights.display().to_string(),
    };
    checkpoint::save(&net, &out_card, &a.out)?;
    println!(
        "recalibrated {} branches ({:?}) on {n_batches} batches of {} ({rendered} renders, {:.1} s); wrote {}",
        config.scales.len(),
        config.scales,
        a.batch,
        t0.elapsed().as_secs_f64(),
        a.out.display()
    );
    Ok(())
}
