//! `mrdrive policy ...`, `mrdrive train --synthetic`, `mrdrive bench policy`.

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use policy::bench;
use policy::checkpoint;
use policy::device::{self, DeviceKind};
use policy::train::Preset;
use std::path::PathBuf;

/// `mrdrive policy ...`
#[derive(Debug, Args)]
pub struct PolicyArgs {
    #[command(subcommand)]
    command: PolicyCommand,
}

#[derive(Debug, Subcommand)]
enum PolicyCommand {
    /// Print the parameter overhead of the BN banks.
    Overhead,
    /// Hash fused inference and a few training steps on fixed inputs: two machines
    /// whose digests agree compute them bit for bit alike.
    Fingerprint {
        /// The same network widths on a small picture (120 x 48): for an emulated CPU.
        #[arg(long)]
        quick: bool,
    },
    /// Write a randomly initialised checkpoint (its card says it is untrained).
    Init {
        /// Output weights path (NAME.safetensors; NAME.json is written beside it).
        #[arg(long)]
        out: PathBuf,
        /// Network preset.
        #[arg(long, default_value = "cpu")]
        preset: Preset,
        /// Scale set R, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "0.75,1.0")]
        scales: Vec<f32>,
        /// Initialisation seed.
        #[arg(long, default_value_t = 0)]
        seed: u64,
    },
    /// Build a checkpoint whose backbone comes from a torchvision ResNet state dict (safetensors).
    ImportTorchvision {
        /// The torchvision weights (.safetensors).
        #[arg(long)]
        weights: PathBuf,
        /// Output weights path.
        #[arg(long)]
        out: PathBuf,
        /// Prefix of the backbone keys in the file (e.g. `backbone_wide.`).
        #[arg(long, default_value = "")]
        prefix: String,
        /// Network preset (must match the file's depth and widths).
        #[arg(long, default_value = "paper")]
        preset: Preset,
        /// Scale set R, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "0.75,1.0")]
        scales: Vec<f32>,
    },
    /// Re-estimate every BN branch's running statistics on frames rendered along scenarios
    /// (docs/protocol.md §6: 200 batches), each branch on frames drawn at its own scale.
    Recalibrate(super::recalibrate::RecalibrateArgs),
    /// The closed-loop table of one sweep folder per driver (`<SWEEPS>/<label>/`): per
    /// town, success, runs with a collision, red lights, lane crossings, route %.
    Table {
        /// The folder holding one sweep folder per driver.
        sweeps: PathBuf,
        /// Also write the Markdown table to this file.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// How well a checkpoint fits a labelled dataset at each frame's command and speed:
    /// KL, argmax agreement and braking, standing and moving, follow and turn.
    Fit {
        /// Weights path.
        weights: PathBuf,
        /// The labelled dataset.
        #[arg(long)]
        data: PathBuf,
        /// Batches to look at.
        #[arg(long, default_value_t = 40)]
        batches: usize,
        /// Samples per batch.
        #[arg(long, default_value_t = 32)]
        batch: usize,
        /// The scale (its BN branch) to evaluate at.
        #[arg(long, default_value_t = 1.0)]
        scale: f32,
    },
    /// Fit a learned trigger for the `learned` selector: a logistic head on a policy's
    /// pooled feature that fires where its low- and high-scale branches disagree most, or
    /// where acting on the low branch loses the most value by the labels (`--target regret`;
    /// policy/src/trigger.rs).
    Trigger {
        /// The multi-resolution policy.
        #[arg(long, default_value = "models/ra.safetensors")]
        checkpoint: PathBuf,
        /// A dataset (labels are needed for `--target regret` only).
        #[arg(long)]
        data: PathBuf,
        /// The trigger file to write (JSON).
        #[arg(long)]
        out: PathBuf,
        /// Use every N-th frame.
        #[arg(long, default_value_t = 2)]
        every: usize,
        /// Share of frames called positive: the top of the target's score.
        #[arg(long, default_value_t = 0.25)]
        share: f32,
        /// What a positive is: `disagreement` (the branches' action distributions
        /// differ most) or `regret` (the low branch loses the most value by the labels).
        #[arg(long, default_value = "disagreement", value_parser = parse_target)]
        target: policy::trigger::Target,
        /// The low scale.
        #[arg(long, default_value_t = 0.75)]
        low: f32,
        /// The high scale.
        #[arg(long, default_value_t = 1.0)]
        high: f32,
    },
    /// Print a checkpoint's config and card.
    Info {
        /// Weights path.
        weights: PathBuf,
    },
    /// Draw a training run's loss curves from its losses CSV (`runs/NAME/losses.csv`,
    /// or a shipped `models/NAME.losses.csv`).
    Losses {
        /// The losses CSV.
        csv: PathBuf,
        /// The PNG to write [default: beside the CSV, extension .png].
        #[arg(long)]
        out: Option<PathBuf>,
        /// The plot's title (the model's name).
        #[arg(long)]
        title: String,
    },
}

/// Runs `mrdrive policy ...`.
pub fn run_policy(args: PolicyArgs) -> Result<()> {
    match args.command {
        PolicyCommand::Losses { csv, out, title } => {
            let png = out.unwrap_or_else(|| csv.with_extension("png"));
            experiments::loss_plot::loss_curves(&csv, &png, &title)?;
            println!("wrote {}", png.display());
            Ok(())
        }
        PolicyCommand::Fingerprint { quick } => {
            print!("{}", policy::fingerprint::fingerprint(quick).report());
            Ok(())
        }
        PolicyCommand::Overhead => {
            print!("{}", bench::report::overhead_table());
            Ok(())
        }
        PolicyCommand::Init {
            out,
            preset,
            scales,
            seed,
        } => {
            checkpoint::save_random_init(&preset.config(&scales), seed, &out)?;
            println!(
                "wrote {} and {} (random init, seed {seed})",
                out.display(),
                checkpoint::manifest_path(&out).display()
            );
            Ok(())
        }
        PolicyCommand::ImportTorchvision {
            weights,
            out,
            prefix,
            preset,
            scales,
        } => {
            checkpoint::import_torchvision(&weights, &prefix, &preset.config(&scales), &out)?;
            println!("wrote {}", out.display());
            Ok(())
        }
        PolicyCommand::Recalibrate(a) => super::recalibrate::recalibrate(&a),
        PolicyCommand::Table { sweeps, out } => {
            let table = experiments::bar::markdown(&experiments::bar::read(&sweeps)?);
            print!("{table}");
            if let Some(out) = out {
                std::fs::write(&out, &table)
                    .map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", out.display()))?;
            }
            Ok(())
        }
        PolicyCommand::Fit {
            weights,
            data,
            batches,
            batch,
            scale,
        } => {
            let dev = device::open(DeviceKind::Cpu)?;
            let (net, _) = checkpoint::load(&weights, &dev)?;
            let branch = net.config.branch_of(scale).ok_or_else(|| {
                anyhow::anyhow!(
                    "--scale {scale}: the checkpoint has scales {:?}",
                    net.config.scales
                )
            })?;
            let set =
                std::sync::Arc::new(policy::train::loader::TrainSet::open(&data, &net.config)?);
            let groups = policy::train::fit::fit(&net, branch, &set, batches, batch, &dev);
            print!("{}", policy::train::fit::markdown(&groups));
            Ok(())
        }
        PolicyCommand::Trigger {
            checkpoint: weights,
            data,
            out,
            every,
            share,
            target,
            low,
            high,
        } => fit_trigger(&weights, &data, &out, every, (share, target), (low, high)),
        PolicyCommand::Info { weights } => {
            let (cfg, card) = checkpoint::read_manifest(&weights)?;
            println!(
                "{}",
                serde_json::to_string_pretty(&serde_json::json!({"config": cfg, "card": card}))?
            );
            Ok(())
        }
    }
}

/// `mrdrive policy trigger`: reads the frames, fits, writes and prints the scores.
fn fit_trigger(
    weights: &std::path::Path,
    data: &std::path::Path,
    out: &std::path::Path,
    every: usize,
    (share, target): (f32, policy::trigger::Target),
    scales: (f32, f32),
) -> Result<()> {
    use policy::trigger::{self, FitConfig, Trigger, TriggerCard};
    let started = std::time::Instant::now();
    let digest = sim::record::CheckpointId::of(weights)
        .with_context(|| format!("reading {}", weights.display()))?
        .sha256;
    let card = TriggerCard {
        checkpoint_sha256: Some(digest),
        positive_share: share,
        target,
        ..TriggerCard::new(
            weights.display().to_string(),
            data.display().to_string(),
            every,
        )
    };
    // The same fit is not made again (the training pipeline asks for it every job).
    if let Ok(t) = Trigger::load(out)
        && t.card.fits_the_same(&card)
        && (t.low, t.high) == scales
    {
        print!("{}", t.card.report());
        println!(
            "{} is up to date: the same network, data and target",
            out.display()
        );
        return Ok(());
    }
    let (samples, skipped) = trigger::checkpoint_samples(weights, data, scales, every)?;
    for s in &skipped {
        eprintln!("skipped: {s}");
    }
    let cfg = FitConfig {
        positive_share: share,
        target,
        ..FitConfig::default()
    };
    let t = trigger::fit(&samples, scales, cfg, card)?;
    t.save(out)
        .map_err(|e| anyhow::anyhow!("{}: cannot write: {e}", out.display()))?;
    print!("{}", t.card.report());
    println!(
        "wrote {} in {:.0} s",
        out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// `--target disagreement|regret`.
fn parse_target(text: &str) -> Result<policy::trigger::Target, String> {
    use policy::trigger::Target;
    [Target::Disagreement, Target::Regret]
        .into_iter()
        .find(|t| t.name() == text)
        .ok_or_else(|| format!("`{text}`: choose disagreement or regret"))
}

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Policy inference latency per scale and multi-resolution training throughput.
    Policy {
        /// Timed repeats per scale (after 3 warm-up runs).
        #[arg(long, default_value_t = 20)]
        repeats: usize,
        /// Timed training steps (after 1 warm-up step); 0 skips training.
        #[arg(long, default_value_t = 3)]
        train_steps: usize,
        /// Training batch size.
        #[arg(long, default_value_t = 32)]
        batch: usize,
        /// Only the default model (skip ResNet-34/18 at the paper's S0).
        #[arg(long)]
        quick: bool,
        /// Device: cpu, wgpu or cuda (GPU devices need a build with that cargo feature).
        #[arg(long, default_value = "cpu")]
        device: DeviceKind,
    },
    /// A run's frame with its render and its policy pass one after the other
    /// (as the loop does them) against overlapped (the next frame rendered while
    /// the policy acts on this one): what pipelining the loop would win here.
    Overlap {
        /// Frames per timed round.
        #[arg(long, default_value_t = 60)]
        frames: usize,
        /// Timed rounds per layout (after one warm-up round), interleaved.
        #[arg(long, default_value_t = 5)]
        repeats: usize,
    },
}

/// Runs one policy benchmark.
pub fn run_bench_command(command: BenchCommand) -> Result<()> {
    let (repeats, train_steps, batch, quick, kind) = match command {
        BenchCommand::Policy {
            repeats,
            train_steps,
            batch,
            quick,
            device,
        } => (repeats, train_steps, batch, quick, device),
        BenchCommand::Overlap { frames, repeats } => {
            println!(
                "render then policy, against the policy on frame k while frame k + 1 renders \
                 (CPU rig, fused default policy, 4 x 4 demo town; {frames} frames, median of {repeats} rounds)"
            );
            for scale in [1.0, 0.75] {
                let o = bench::overlap::overlap(scale, frames, repeats)?;
                println!(
                    "scale {scale:.2} {:>4}x{:<4} sequential {:>6.1} fps  overlapped {:>6.1} fps  ratio {:.2}",
                    o.size.0,
                    o.size.1,
                    o.sequential_fps,
                    o.overlapped_fps,
                    o.overlapped_fps / o.sequential_fps
                );
            }
            return Ok(());
        }
    };
    let dev = device::open(kind)?;
    let b = bench::report::PolicyBench {
        repeats,
        train_steps,
        batch,
        quick,
    };
    bench::report::policy_bench(&b, kind, &dev, &mut std::io::stdout())?;
    Ok(())
}
