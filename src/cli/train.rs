//! `mrdrive train`: a training stage of the paper's pipeline (Original, NRA, RA) on a
//! labelled dataset, resumable, with loss curves; or `--synthetic`, a smoke run.

use anyhow::{Context, Result, bail};
use clap::Args;
use policy::device::{self, DeviceKind};
use policy::train::Preset;
use policy::train::stage::{FINAL_FILE, LOSSES_FILE, StageSpec, run_stage};
use policy::train::synthetic::{SmokeRun, train_on_toy_batch};
use std::path::{Path, PathBuf};

use super::plot;

/// `mrdrive train ...`
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// The stage: `original`, `nra-<scale>` (e.g. nra-0.75) or `ra`.
    #[arg(long, required_unless_present = "synthetic")]
    stage: Option<String>,
    /// The labelled dataset [default: data/original for the Original, data/retarget otherwise].
    #[arg(long)]
    data: Option<PathBuf>,
    /// The teacher of a retargeting stage [default: <out>/original.safetensors].
    #[arg(long)]
    teacher: Option<PathBuf>,
    /// Run folders (state, losses) go to <runs>/<name>.
    #[arg(long, default_value = "runs")]
    runs: PathBuf,
    /// The trained checkpoint is copied to <out>/<name>.safetensors (+ .json, loss CSV and PNG).
    #[arg(long, default_value = "models")]
    out: PathBuf,
    /// The name of the run folder and of the published files, for a second
    /// network of the same stage (e.g. `--stage ra --scales 0.5,0.625,0.75,0.875,1.0
    /// --name ra5`) [default: the stage].
    #[arg(long)]
    name: Option<String>,
    /// Steps [default: the recipe's].
    #[arg(long)]
    steps: Option<usize>,
    /// Samples per step [default: the recipe's].
    #[arg(long)]
    batch: Option<usize>,
    /// Learning rate [default: the recipe's].
    #[arg(long)]
    lr: Option<f64>,
    /// Seed [default: the recipe's].
    #[arg(long)]
    seed: Option<u64>,
    /// Steps between unfreezing stages of a retargeting stage [default: the recipe's].
    #[arg(long)]
    unfreeze_every: Option<usize>,
    /// Batches per scale for the final BN recalibration [default: the recipe's].
    #[arg(long)]
    recalibrate_batches: Option<usize>,
    /// Steps between checkpoints of the run state.
    #[arg(long)]
    checkpoint_every: Option<usize>,
    /// The share of standing frames (< 0.5 m/s) to keep, in [0, 1] [default: the recipe's, 1].
    #[arg(long)]
    standing_keep: Option<f64>,
    /// Copies of each kept starting frame (standing, target goes: a light turned green)
    /// per epoch [default: the recipe's, 1].
    #[arg(long)]
    start_repeat: Option<usize>,
    /// Copies of each kept frame with a pedestrian in the ego's corridor within 20 m
    /// straight ahead, per epoch [default: the recipe's, 1].
    #[arg(long)]
    pedestrian_repeat: Option<usize>,
    /// Copies of each kept frame with a stopped vehicle in the ego's corridor within 20 m
    /// straight ahead (a queue at a light), per epoch [default: the recipe's, 1].
    #[arg(long)]
    stopped_vehicle_repeat: Option<usize>,
    /// Draw commands evenly [default: the recipe's: no for the Original, yes for retargeting].
    #[arg(long)]
    balanced: Option<bool>,
    /// Start from this checkpoint's weights (same network) instead of a fresh initialisation.
    #[arg(long)]
    init: Option<PathBuf>,
    /// Network preset.
    #[arg(long, default_value = "cpu")]
    preset: Preset,
    /// Scale set R of `ra` (and of `--synthetic`), comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.75,1.0")]
    scales: Vec<f32>,
    /// Device: cpu, wgpu or cuda (GPU devices need a build with that cargo feature).
    #[arg(long, default_value = "cpu")]
    device: DeviceKind,
    /// Train on a synthetic toy batch (a smoke run: the loss must fall).
    #[arg(long)]
    synthetic: bool,
}

/// The stage's spec from its name and the overrides.
fn spec_of(args: &TrainArgs, stage: &str) -> Result<StageSpec> {
    let data_or = |d: &str| args.data.clone().unwrap_or_else(|| PathBuf::from(d));
    let teacher = args
        .teacher
        .clone()
        .unwrap_or_else(|| args.out.join("original.safetensors"));
    let mut spec = if stage == "original" {
        StageSpec::original(&data_or("data/original"), args.preset)
    } else if stage == "ra" {
        StageSpec::retarget(
            stage,
            &args.scales,
            &data_or("data/retarget"),
            &teacher,
            args.preset,
        )
    } else if let Some(r) = stage.strip_prefix("nra-") {
        let r: f32 = r
            .parse()
            .ok()
            .filter(|r: &f32| *r > 0.0 && *r <= 1.0)
            .with_context(|| {
                format!(
                    "--stage {stage}: `{r}` is not a scale in (0, 1]; fix: e.g. --stage nra-0.75"
                )
            })?;
        StageSpec::retarget(
            stage,
            &[r],
            &data_or("data/retarget"),
            &teacher,
            args.preset,
        )
    } else {
        bail!(
            "--stage {stage}: unknown stage; fix: use original, nra-<scale> (e.g. nra-0.75) or ra"
        );
    };
    if spec.teacher.is_some() && !teacher.exists() {
        bail!(
            "{}: the teacher of stage {stage} does not exist; fix: train the Original first (`mrdrive train --stage original`) or pass --teacher",
            teacher.display()
        );
    }
    if let Some(v) = args.steps {
        spec.steps = v;
    }
    if let Some(v) = args.batch {
        spec.batch = v;
    }
    if let Some(v) = args.lr {
        spec.train.lr = v;
    }
    if let Some(v) = args.seed {
        spec.seed = v;
    }
    if let Some(v) = args.unfreeze_every {
        spec.train.unfreeze_every = (v > 0).then_some(v);
    }
    if let Some(v) = args.recalibrate_batches {
        spec.recalibrate_batches = v;
    }
    if let Some(v) = args.checkpoint_every {
        spec.checkpoint_every = v;
    }
    if let Some(v) = args.standing_keep {
        if !(0.0..=1.0).contains(&v) {
            bail!("--standing-keep {v}: a share in [0, 1]");
        }
        spec.sampling.standing_keep = v;
    }
    if let Some(v) = args.start_repeat {
        if v == 0 {
            bail!("--start-repeat 0: at least 1 (1 draws each starting frame once per epoch)");
        }
        spec.sampling.start_repeat = v;
    }
    if let Some(v) = args.pedestrian_repeat {
        if v == 0 {
            bail!(
                "--pedestrian-repeat 0: at least 1 (1 draws each frame with a pedestrian ahead once per epoch)"
            );
        }
        spec.sampling.pedestrian_repeat = v;
    }
    if let Some(v) = args.stopped_vehicle_repeat {
        if v == 0 {
            bail!(
                "--stopped-vehicle-repeat 0: at least 1 (1 draws each frame with a stopped vehicle ahead once per epoch)"
            );
        }
        spec.sampling.stopped_vehicle_repeat = v;
    }
    if let Some(v) = args.balanced {
        spec.sampling.balanced = v;
    }
    if let Some(v) = &args.init {
        spec.init = Some(v.clone());
    }
    if spec.steps == 0 || spec.batch == 0 {
        bail!(
            "--steps {} --batch {}: both must be at least 1",
            spec.steps,
            spec.batch
        );
    }
    Ok(spec)
}

/// The title of a training run's loss plot: the model's name, and the stage when the
/// name is another (`ra5 (stage ra)`).
fn loss_title(name: &str, stage: &str) -> String {
    if name == stage {
        name.to_string()
    } else {
        format!("{name} (stage {stage})")
    }
}

/// Runs `mrdrive train`.
pub fn run_train(args: TrainArgs) -> Result<()> {
    if args.synthetic {
        return run_synthetic(&args);
    }
    let stage = args.stage.clone().expect("clap requires --stage");
    let spec = spec_of(&args, &stage)?;
    let name = args.name.clone().unwrap_or_else(|| spec.name.clone());
    let run_dir = args.runs.join(&name);
    eprintln!(
        "training stage {} ({} preset, scales {:?}) on {}: {} steps of {}, run folder {}",
        spec.name,
        spec.preset,
        spec.scales,
        spec.data.display(),
        spec.steps,
        spec.batch,
        run_dir.display()
    );
    let dev = device::open(args.device)?.autodiff();
    let bar = indicatif::ProgressBar::new(spec.steps as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] step {pos}/{len} ETA {eta_precise} {msg}",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
    let losses = run_dir.join(LOSSES_FILE);
    let png = run_dir.join("losses.png");
    let mut first = true;
    let outcome = run_stage(&spec, &run_dir, &dev, |u| {
        if std::mem::take(&mut first) {
            for s in u.skipped {
                let line = format!("warning: training without {}: {}", s.path.display(), s.why);
                if bar.is_hidden() {
                    eprintln!("{line}");
                } else {
                    bar.println(line);
                }
            }
        }
        bar.set_position(u.report.step as u64 + 1);
        let losses_now = format!(
            "loss {:.4} (act {:.4} seg {:.3} kd {:.4} feat {:.4}), {:.1} samples/s",
            u.report.loss,
            u.report.parts.act,
            u.report.parts.seg,
            u.report.parts.kd,
            u.report.parts.feat,
            u.samples_per_s
        );
        bar.set_message(losses_now.clone());
        if u.checkpointed {
            if let Err(e) = plot::loss_curves(&losses, &png, &loss_title(&name, &spec.name)) {
                bar.println(format!("warning: {}: could not plot: {e:#}", png.display()));
            }
            let line = format!(
                "checkpoint at step {}/{}: {losses_now}",
                u.report.step + 1,
                u.steps
            );
            if bar.is_hidden() {
                eprintln!("{line}");
            } else {
                bar.println(line);
            }
        }
    })?;
    bar.finish_and_clear();
    plot::loss_curves(&losses, &png, &loss_title(&name, &spec.name))?;
    publish(&run_dir, &args.out, &name)?;
    println!(
        "stage {}: done ({} steps now, {:.0} s of training in all); checkpoint {}",
        spec.name,
        outcome.steps_now,
        outcome.wall_s,
        args.out.join(format!("{name}.safetensors")).display()
    );
    Ok(())
}

/// Copies a finished run's checkpoint, card, loss CSV and plot to `out` as `<name>.*`.
fn publish(run_dir: &Path, out: &Path, name: &str) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let from_weights = run_dir.join(FINAL_FILE);
    let copies = [
        (from_weights.clone(), format!("{name}.safetensors")),
        (from_weights.with_extension("json"), format!("{name}.json")),
        (run_dir.join(LOSSES_FILE), format!("{name}.losses.csv")),
        (run_dir.join("losses.png"), format!("{name}.losses.png")),
    ];
    for (from, to) in copies {
        let to = out.join(to);
        std::fs::copy(&from, &to)
            .with_context(|| format!("copying {} to {}", from.display(), to.display()))?;
    }
    Ok(())
}

/// `mrdrive train --synthetic`: a smoke run on one toy batch.
fn run_synthetic(args: &TrainArgs) -> Result<()> {
    let run = SmokeRun {
        config: args.preset.config(&args.scales),
        batch: args.batch.unwrap_or(8),
        steps: args.steps.unwrap_or(30),
        lr: args.lr.unwrap_or(1e-3),
        seed: args.seed.unwrap_or(0),
    };
    println!(
        "synthetic multi-resolution training: {} scales {:?}, batch {}, {} steps (one fixed toy batch)",
        run.config.depth.name(),
        run.config.scales,
        run.batch,
        run.steps
    );
    let dev = device::open(args.device)?.autodiff();
    let outcome = train_on_toy_batch(&run, &dev, |r| {
        let per: Vec<String> = r
            .per_scale
            .iter()
            .zip(&run.config.scales)
            .map(|(l, s)| format!("{s}x {l:.4}"))
            .collect();
        println!(
            "step {:>4}  loss {:.4}  ({})",
            r.step,
            r.loss,
            per.join(", ")
        );
    })?;
    println!(
        "loss {:.4} -> {:.4} ({})",
        outcome.first_loss,
        outcome.last_loss,
        if outcome.fell() {
            "falling"
        } else {
            "NOT falling"
        }
    );
    if !outcome.fell() {
        bail!("the loss did not fall on the toy batch");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_loss_plot_names_the_model_then_its_stage() {
        assert_eq!(loss_title("ra5", "ra"), "ra5 (stage ra)");
        assert_eq!(loss_title("ra", "ra"), "ra");
    }
}
