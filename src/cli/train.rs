//! `mrdrive train`: a training stage of the paper's pipeline (Original, NRA, RA) on a
//! labelled dataset, resumable, with loss curves; `--all`, the whole pipeline
//! ([`experiments::pipeline::TrainPlan`]); or `--synthetic`, a smoke run.

use anyhow::{Context, Result, bail};
use clap::Args;
use experiments::loss_plot::{loss_curves, loss_title};
use experiments::pipeline::{self, TrainPlan};
use policy::device::{self, DeviceKind};
use policy::train::publish::{LOSSES_PLOT_FILE, publish, published_checkpoint};
use policy::train::stage::{Job, LOSSES_FILE, run_stage_until};
use policy::train::synthetic::{SmokeRun, train_on_toy_batch};
use policy::train::{Preset, RecipeChanges, StageRequest};
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// `mrdrive train ...`
#[derive(Debug, Args)]
pub struct TrainArgs {
    /// The stage: `original`, `nra-<scale>` (e.g. nra-0.75) or `ra`.
    #[arg(long, required_unless_present_any = ["synthetic", "all"])]
    stage: Option<String>,
    /// The whole pipeline, skipping what is done: the Original's data a slice at a time,
    /// each slice followed by a round of the Original's training and its closed-loop
    /// check (the learning curve), the retargeting set, NRA 0.75, NRA 1.0 and RA, the
    /// closed-loop bar, RA5 (`cargo xtask train`).
    #[arg(long, conflicts_with_all = ["stage", "synthetic"])]
    all: bool,
    /// With `--all`: the folder whose models/ (with the bar's records,
    /// models/closed-loop/ and models/closed-loop-heldout/) the pipeline writes (`--into
    /// .` replaces the shipped models/).
    #[arg(long, requires = "all")]
    into: Option<PathBuf>,
    /// With `--all`: the same plumbing at toy size, into out/train-quick unless --into.
    #[arg(long, requires = "all")]
    quick: bool,
    /// With `--all`: train the Original in this many rounds of the learning curve, on
    /// that many slices of 40 episodes of its dataset [default: 19, every slice].
    #[arg(long, requires = "all", value_parser = clap::value_parser!(u32).range(1..=19))]
    slices: Option<u32>,
    /// With `--all`: 2 runs the retargeting stages two at a time on one thread each
    /// (the default on 2 or more cores), 1 one after another on every thread.
    #[arg(long, requires = "all", value_parser = clap::value_parser!(u8).range(1..=2))]
    lanes: Option<u8>,
    /// With `--all`: say how far the pipeline is and how long the rest will take (each
    /// kind of work at the rate measured on a 2-core EPYC), and stop; nothing runs.
    #[arg(long, requires = "all")]
    eta: bool,
    /// With `--all`: print the commands the pipeline would run from here, one a line
    /// (`lane N:` before those that run beside each other), and stop; nothing runs.
    #[arg(long, requires = "all")]
    print_plan: bool,
    /// The labelled dataset [default: <cache>/data/original for the Original,
    /// <cache>/data/retarget otherwise; the cache: $MRDRIVE_CACHE, else ~/.cache/mrdrive].
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
    /// Train on the dataset's first N episodes only (its first slices, while the rest
    /// is still being collected); the run refuses to start or resume until all N are
    /// labelled [default: every labelled episode].
    #[arg(long)]
    episodes: Option<usize>,
    /// Further labelled datasets to train on with --data, every episode of each,
    /// repeatable: a DAgger round's (`mrdrive collect --learner`).
    #[arg(long)]
    also: Vec<PathBuf>,
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
    /// This job's time limit (hours from now): a stage checkpoints and stops after
    /// the step in progress once it has passed, `--all` starts no step after it;
    /// the command then exits with status 75 and running it again goes on.
    #[arg(long)]
    hours: Option<f64>,
    /// The same as an absolute time (seconds since 1970, UTC): what `--all` hands its
    /// training steps so that they share one limit.
    #[arg(long)]
    until_unix: Option<u64>,
    /// Go on from this committed snapshot (`--snapshot`'s file) when the run folder
    /// of the stage it was taken from has no state of its own (the cache was lost):
    /// its weights at its step, Adam's moments afresh. Ignored by other stages.
    #[arg(long)]
    resume_state: Option<PathBuf>,
    /// With `--all`: at the job's end (done, stopped at the time limit, or failed),
    /// write the newest run's network in half precision to FILE (+ .json), to commit,
    /// and add a line to FILE's log (the same name ending in `.log.md`).
    #[arg(long, requires = "all")]
    snapshot: Option<PathBuf>,
}

/// The exit status of a job stopped at its time limit (BSD's `EX_TEMPFAIL`: run it
/// again to go on).
pub const STOPPED_AT_TIME_LIMIT: u8 = 75;

/// The job's time limit: the earlier of `--hours` from now and `--until-unix`.
fn deadline(args: &TrainArgs) -> Result<Option<SystemTime>> {
    let from_hours = match args.hours {
        Some(h) if h.is_finite() && h > 0.0 => {
            Some(SystemTime::now() + Duration::from_secs_f64(h * 3600.0))
        }
        Some(h) => {
            bail!("--hours {h}: give a positive number of hours (e.g. 2.5 for a 3-hour slot)")
        }
        None => None,
    };
    let until = args.until_unix.map(|s| UNIX_EPOCH + Duration::from_secs(s));
    Ok(from_hours.into_iter().chain(until).min())
}

/// The stage asked for by `--stage` and the flags that change its recipe.
fn request_of(args: &TrainArgs, stage: &str) -> StageRequest {
    StageRequest {
        stage: stage.into(),
        preset: args.preset,
        scales: args.scales.clone(),
        data: args.data.clone(),
        teacher: args
            .teacher
            .clone()
            .unwrap_or_else(|| args.out.join("original.safetensors")),
        changes: RecipeChanges {
            steps: args.steps,
            batch: args.batch,
            lr: args.lr,
            seed: args.seed,
            unfreeze_every: args.unfreeze_every,
            recalibrate_batches: args.recalibrate_batches,
            checkpoint_every: args.checkpoint_every,
            standing_keep: args.standing_keep,
            start_repeat: args.start_repeat,
            pedestrian_repeat: args.pedestrian_repeat,
            stopped_vehicle_repeat: args.stopped_vehicle_repeat,
            balanced: args.balanced,
            init: args.init.clone(),
            episodes: args.episodes,
            also: args.also.clone(),
        },
    }
}

/// Runs `mrdrive train`.
pub fn run_train(args: TrainArgs) -> Result<()> {
    if args.synthetic {
        return run_synthetic(&args);
    }
    if args.all {
        return run_all(&args);
    }
    let stage = args.stage.clone().expect("clap requires --stage");
    let spec = request_of(&args, &stage).spec()?;
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
    let png = run_dir.join(LOSSES_PLOT_FILE);
    let mut first = true;
    let job = Job {
        stop_at: deadline(&args)?,
        resume_state: args.resume_state.clone(),
    };
    let outcome = run_stage_until(&spec, &run_dir, &dev, &job, |u| {
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
            if let Err(e) = loss_curves(&losses, &png, &loss_title(&name, &spec.name)) {
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
    // A stage gone on from a snapshot at its last step (the cache was lost) has no
    // loss rows of its own to draw: say so, and publish it.
    if let Err(e) = loss_curves(&losses, &png, &loss_title(&name, &spec.name)) {
        eprintln!("warning: {}: could not plot: {e:#}", png.display());
    }
    if let Some(step) = outcome.stopped_at {
        eprintln!(
            "stage {}: stopped at the time limit after step {step} of {} (state checkpointed in {}); \
             run the same command to go on",
            spec.name,
            spec.steps,
            run_dir.display()
        );
        std::process::exit(i32::from(STOPPED_AT_TIME_LIMIT));
    }
    publish(&run_dir, &args.out, &name)?;
    println!(
        "stage {}: done ({} steps now, {:.0} s of training in all); checkpoint {}",
        spec.name,
        outcome.steps_now,
        outcome.wall_s,
        published_checkpoint(&args.out, &name).display()
    );
    Ok(())
}

/// The `training.data` of a published model's card (`models/NAME.json`), if it has one.
fn published_data(card: &Path) -> Option<String> {
    let text = std::fs::read_to_string(card).ok()?;
    let card: serde_json::Value = serde_json::from_str(&text).ok()?;
    card.pointer("/card/training/data")?
        .as_str()
        .map(String::from)
}

/// `mrdrive train --all`: the pipeline's plan, run step by step.
fn run_all(args: &TrainArgs) -> Result<()> {
    let base = match (&args.into, args.quick) {
        (Some(dir), _) => dir.clone(),
        (None, true) => PathBuf::from("out/train-quick"),
        (None, false) => bail!(
            "the pipeline needs --into DIR: --into out/scratch trains beside the shipped \
             checkpoints, --into . replaces the shipped models/ (their records on the paper \
             page name their SHA-256)"
        ),
    };
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let lanes = args.lanes.unwrap_or(if cores >= 2 { 2 } else { 1 });
    let cache = dataset::cache::root();
    let mut plan = if args.quick {
        TrainPlan::quick(&base, &cache, lanes == 2)
    } else {
        TrainPlan::full(&base, &cache, lanes == 2)
    };
    if let Some(n) = args.slices {
        plan = plan.with_rounds(n);
    }
    eprintln!(
        "train --all: data and run state in {} (${} sets another folder), models into {}",
        cache.display(),
        dataset::cache::ENV,
        base.join("models").display()
    );
    // A committed snapshot of round k (or of a later stage): the curve's rounds before
    // it are done and their records committed, so they are not trained again when the
    // cache was lost (their slices are still made: later rounds train on them). After
    // the Original's last round (a retargeting stage's snapshot) its data is not made.
    let mut from_round = 1;
    if let Some(file) = &args.snapshot
        && policy::train::stage::resume_path(file).exists()
    {
        let r = policy::train::stage::read_resume(file)?;
        from_round = plan.round_of(&r.run).unwrap_or(1);
        // The last DAgger round's snapshot once it has published the Original: done.
        let last_dagger = plan.curve.rounds + plan.dagger.rounds;
        if plan.dagger.rounds > 0
            && from_round == last_dagger
            && published_data(&base.join("models/original.json"))
                .is_some_and(|d| plan.dagger_published(&d))
        {
            from_round = last_dagger + 1;
        }
        if from_round > 1 {
            eprintln!(
                "train --all: the snapshot {} is of {} at step {}: rounds 1-{} of the \
                 learning curve are done{}",
                file.display(),
                r.run.display(),
                r.step,
                (from_round - 1).min(plan.curve.rounds),
                if from_round > plan.curve.rounds + plan.dagger.rounds {
                    ", and the DAgger rounds: the Original is published"
                } else {
                    ""
                }
            );
        }
    }
    if !args.print_plan
        && !args.eta
        && let Some(why) = foreign_state(&base, args.snapshot.as_deref())
    {
        bail!(why);
    }
    let mut groups = plan.steps(from_round);
    if args.eta {
        let rates = experiments::progress::JobRates::default();
        let left = experiments::pipeline::left(&groups, Path::new("."), &rates);
        println!("train --all: {} steps; {}", groups.len(), left.line(&rates));
        return Ok(());
    }
    let stop_at = deadline(args)?;
    if let Some(t) = stop_at {
        let secs = t.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
        pipeline::add_to_training(&mut groups, &["--until-unix".into(), secs.to_string()]);
    }
    // A committed snapshot: the stage it was taken from goes on from it when the cache
    // lost that stage's run folder (the others ignore it).
    if let Some(file) = &args.snapshot
        && policy::train::stage::resume_path(file).exists()
    {
        let file = file.display().to_string();
        pipeline::add_to_training(&mut groups, &["--resume-state".into(), file]);
    }
    // The data's own build, where the snapshot's folder pins one: collect and label
    // run it, so that they stay the bytes `data.sha256` lists after the simulator
    // changed (`experiments::collector`).
    if let Some(dir) = args.snapshot.as_deref().and_then(Path::parent) {
        // Printing the plan names the data's binary without building it.
        let bin = if args.print_plan {
            let this = sim::output::provenance::build_id();
            experiments::collector::pinned(dir)?.and_then(|commit| {
                let this_commit = experiments::registration::build_commit(&this);
                experiments::collector::binary(&commit, this_commit, &cache)
            })
        } else {
            experiments::collector::data_build(dir, Path::new("."), &cache, &|s| {
                eprintln!("train --all: {s}")
            })?
        };
        if let Some(bin) = bin {
            pipeline::data_by(&mut groups, &bin);
        }
    }
    let exe = std::env::current_exe().context("finding this program")?;
    if args.print_plan {
        print!("{}", pipeline::commands(&groups, &exe));
        return Ok(());
    }
    let started = std::time::Instant::now();
    let ran = pipeline::execute_until(&exe, Path::new("."), &groups, stop_at, &|s| {
        eprintln!("train --all: {s}")
    });
    if let Some(file) = &args.snapshot {
        let how = match &ran {
            Ok(()) => "done".to_string(),
            Err(e) if e.stopped_at_time_limit() => "stopped at the time limit".to_string(),
            Err(e) => format!("failed at {}", e.step),
        };
        let check = newest_round(&plan.curve_table());
        end_of_job(
            &plan.runs,
            file,
            &how,
            started.elapsed().as_secs_f64(),
            &check,
        )?;
    }
    match ran {
        Err(e) if e.stopped_at_time_limit() => {
            eprintln!(
                "train --all: stopped at the time limit ({}); run the same command to go on",
                e.step
            );
            std::process::exit(i32::from(STOPPED_AT_TIME_LIMIT));
        }
        other => other?,
    }
    let tables: Vec<String> = plan
        .bar_sets
        .iter()
        .map(|s| base.join(&s.table).display().to_string())
        .collect();
    eprintln!(
        "train --all: done; the closed-loop tables are {}",
        tables.join(" and ")
    );
    Ok(())
}

/// Why a chain must not run: `base/models/train-state` holds a chain's state (its
/// pinned data build, `collector`, and its resume point) but `snapshot` is not in that
/// folder, so the plan would read none of it, train the learning curve again from
/// round 1 and collect with this build instead of the pinned one. `None` when it may
/// run (no such state, or the snapshot is in it).
fn foreign_state(base: &Path, snapshot: Option<&Path>) -> Option<String> {
    let state = base.join("models/train-state");
    if !state.join("collector").exists() {
        return None;
    }
    let same = |dir: &Path| {
        let canon = |p: &Path| std::fs::canonicalize(p).ok();
        canon(dir).is_some_and(|d| Some(d) == canon(&state))
    };
    let dir = snapshot.map(|f| match f.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    });
    if dir.as_deref().is_some_and(same) {
        return None;
    }
    Some(format!(
        "{} holds a training chain's state (its pinned data build and where it stopped), \
         which this command would not read{}: it would train the learning curve again from \
         round 1 and collect with this build; fix: run it with --snapshot {}",
        state.display(),
        snapshot.map_or(String::new(), |f| format!(" (--snapshot {})", f.display())),
        state.join("train-state.safetensors").display()
    ))
}

/// A job's end (`--snapshot FILE`): the newest run's network in half precision to
/// FILE, and a line in its log (`.log.md`): when, where, how the job ended, what was
/// trained and its last losses.
/// The closed-loop check of the learning curve's newest round, from its table
/// (`models/original.curve.md`): "slice-02 town02: 12/12 succeed, 1/12 with a
/// collision, 4 red lights, 99.0 % of the route"; "none yet" without a round. The
/// DAgger rounds (`dagger-kk`) come after every slice of the curve, though the table
/// sorts them first.
fn newest_round(table: &Path) -> String {
    let text = std::fs::read_to_string(table).unwrap_or_default();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .map(|l| {
            l.trim()
                .trim_matches('|')
                .split('|')
                .map(str::trim)
                .collect::<Vec<&str>>()
        })
        .filter(|cells| cells.len() == 7)
        .collect();
    let last = |prefix: &str| rows.iter().rev().find(|c| c[0].starts_with(prefix));
    let row = last("dagger-").or_else(|| last("slice-"));
    match row {
        Some(c) => format!(
            "{} {}: {} succeed, {} with a collision, {} red lights, {} % of the route",
            c[0], c[1], c[2], c[3], c[4], c[6]
        ),
        None => "none yet".into(),
    }
}

fn end_of_job(runs: &Path, file: &Path, how: &str, wall_s: f64, check: &str) -> Result<()> {
    let snap = policy::train::stage::snapshot(runs, file)?;
    let log = file.with_extension("log.md");
    let fresh = !log.exists();
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&log)
        .with_context(|| format!("opening {}", log.display()))?;
    use std::io::Write;
    if fresh {
        writeln!(
            f,
            "# The training chain's jobs\n\nOne line per job of `mrdrive train --all --snapshot`: \
             its end, the machine, the job's wall time and how it ended, the run it left in \
             progress (its step), that run's last row of `losses.csv` \
             (step,epoch,loss,act,seg,kd,feat,per scale...,unfrozen,samples/s,wall_s), and the \
             closed-loop check of the learning curve's newest round (`models/original.curve.md`).\n\n\
             | job ended (UTC) | machine | job | ended | run in progress | last losses | closed loop (newest round) |\n\
             | --- | --- | --- | --- | --- | --- | --- |"
        )?;
    }
    let now = super::time_utc(SystemTime::now());
    let (run, losses) = match &snap {
        Some(s) => (
            format!("{} at step {}", s.run.display(), s.progress.step),
            s.last_losses.clone().unwrap_or_default(),
        ),
        None => ("none yet".into(), String::new()),
    };
    writeln!(
        f,
        "| {now} | {} | {:.2} h | {how} | {run} | `{losses}` | {check} |",
        policy::train::stage::machine(),
        wall_s / 3600.0
    )?;
    match snap {
        Some(s) => eprintln!(
            "train --all: the state of {} (step {}) is in {} (half precision); commit it with {}",
            s.run.display(),
            s.progress.step,
            file.display(),
            log.display()
        ),
        None => eprintln!(
            "train --all: no run has a state yet; {} noted the job",
            log.display()
        ),
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
    println!("{}", run.describe());
    let dev = device::open(args.device)?.autodiff();
    let outcome = train_on_toy_batch(&run, &dev, |r| println!("{}", run.step_line(r)))?;
    println!("{outcome}");
    if !outcome.fell() {
        bail!("the loss did not fall on the toy batch");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_published_cards_data_is_read_and_a_missing_card_is_none() {
        let dir = tempfile::tempdir().unwrap();
        let card = dir.path().join("original.json");
        std::fs::write(
            &card,
            r#"{"format":"f","card":{"training":{"data":"/c/data/original + /c/data/original-dagger-01"}}}"#,
        )
        .unwrap();
        let data = published_data(&card).unwrap();
        assert_eq!(data, "/c/data/original + /c/data/original-dagger-01");
        let plan = TrainPlan::full(dir.path(), Path::new("/c"), true);
        assert!(plan.dagger_published(&data));
        assert_eq!(published_data(&dir.path().join("absent.json")), None);
        std::fs::write(&card, r#"{"card":{"trained":false}}"#).unwrap();
        assert_eq!(published_data(&card), None);
    }

    #[test]
    fn the_pipelines_learning_curve_is_the_file_a_published_card_points_to() {
        let plan = TrainPlan::full(Path::new("b"), Path::new("/c"), true);
        let table = plan.curve_table();
        assert_eq!(
            table.file_name().unwrap().to_str(),
            Some(policy::train::publish::LEARNING_CURVE_FILE)
        );
        assert_eq!(table.parent(), Some(Path::new("b/models")));
    }

    #[test]
    fn a_chains_state_is_only_driven_on_through_its_own_snapshot_path() {
        let dir = tempfile::tempdir().unwrap();
        let base = dir.path();
        let state = base.join("models/train-state");
        std::fs::create_dir_all(&state).unwrap();
        let own = state.join("train-state.safetensors");
        // No pinned build yet: no chain state to lose, any snapshot path will do.
        assert_eq!(foreign_state(base, None), None);
        std::fs::write(state.join("collector"), "540f94d\n").unwrap();
        assert_eq!(foreign_state(base, Some(&own)), None);
        let elsewhere = base.join("late/train-state.safetensors");
        std::fs::create_dir_all(base.join("late")).unwrap();
        for snapshot in [None, Some(elsewhere.as_path())] {
            let why = foreign_state(base, snapshot).expect("refused");
            assert!(
                why.contains("round 1") && why.ends_with("train-state.safetensors"),
                "{why}"
            );
        }
    }

    #[test]
    fn the_job_log_takes_the_newest_round_of_the_curve() {
        let dir = tempfile::tempdir().unwrap();
        let table = dir.path().join("original.curve.md");
        assert_eq!(newest_round(&table), "none yet");
        let slices = "| slice-01 | town02 | 0/12 | 0/12 | 6 | 0 | 20.7 |\n\
                      | slice-02 | town02 | 12/12 | 1/12 | 4 | 3 | 99.0 |\n";
        let write = |rows: &str| {
            let head = "| driver | town | success | runs with a collision | red lights | \
                        lane crossings | route % |\n| --- | --- | --- | --- | --- | --- | --- |\n";
            std::fs::write(&table, format!("{head}{rows}")).unwrap();
        };
        write(slices);
        assert_eq!(
            newest_round(&table),
            "slice-02 town02: 12/12 succeed, 1/12 with a collision, 4 red lights, 99.0 % of the route"
        );
        // A DAgger round is newer than every slice, though the table lists it first.
        write(&format!(
            "| dagger-01 | town02 | 12/12 | 0/12 | 6 | 3 | 99.0 |\n{slices}"
        ));
        assert_eq!(
            newest_round(&table),
            "dagger-01 town02: 12/12 succeed, 0/12 with a collision, 6 red lights, 99.0 % of the route"
        );
    }
}
