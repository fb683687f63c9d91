//! `mrdrive policy recalibrate`: BN recalibration (docs/protocol.md §6) on frames
//! rendered along scenarios (`policy::train::recalibrate_scenes`).

use anyhow::Result;
use clap::Args;
use policy::checkpoint;
use policy::device::{self, DeviceKind};
use policy::train::recalibrate_scenes::{SceneRecalibration, recalibrate_on_scenarios};
use std::path::PathBuf;

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
    /// Batches per branch (docs/protocol.md §6: 200).
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

/// Runs `mrdrive policy recalibrate`.
pub fn recalibrate(a: &RecalibrateArgs) -> Result<()> {
    let settings = SceneRecalibration {
        scenarios: a.scenarios.clone(),
        overrides: a.traffic.overrides(None),
        batches: a.batches,
        batch: a.batch,
        every_s: a.every_s,
    };
    let dev = device::open(a.device)?;
    let t0 = std::time::Instant::now();
    let done = recalibrate_on_scenarios(&a.weights, &settings, &dev, |c| {
        println!(
            "{}: {} frames over {:.1} s ({})",
            c.scenario.display(),
            c.frames,
            c.sim_time_s,
            c.ended
        );
    })?;
    if done.batches < a.batches {
        println!(
            "note: the scenarios gave {} batches of {}, not the {} asked for (add scenarios or lower --every-s for more)",
            done.batches, a.batch, a.batches
        );
    }
    checkpoint::save(&done.net, &done.card, &a.out)?;
    let scales = &done.net.config.scales;
    println!(
        "recalibrated {} branches ({scales:?}) on {} batches of {} ({} renders, {:.1} s); wrote {}",
        scales.len(),
        done.batches,
        a.batch,
        done.rendered,
        t0.elapsed().as_secs_f64(),
        a.out.display()
    );
    Ok(())
}
