//! `mrdrive collect` and `mrdrive label`: driving data and its action values.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Args, ValueEnum};
use dataset::collect::{self, CollectConfig, Preset};
use dataset::labels::episode::label_dataset;

/// Which dataset to collect.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PresetArg {
    /// The original model's data: Town01 routes 2-9, random Town01 routes, then random routes through our towns.
    Original,
    /// The retargeting data: our generated towns and other random Town01 routes.
    Retarget,
}

/// `collect` arguments.
#[derive(Args)]
pub struct CollectArgs {
    /// Which dataset.
    #[arg(
        long,
        value_enum,
        required_unless_present = "scenario",
        conflicts_with = "scenario"
    )]
    pub preset: Option<PresetArg>,
    /// Instead of a preset: drive this scenario's route, one episode per seed and density
    /// (`--seeds`, `--densities`), to look at the data and labels of one situation. Never
    /// a training set: an evaluation route is allowed here.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// With `--scenario`: traffic seeds, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0",
        requires = "scenario"
    )]
    pub seeds: Vec<u64>,
    /// With `--scenario`: traffic densities VEHICLES:PEDESTRIANS, comma-separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0:0",
        requires = "scenario"
    )]
    pub densities: Vec<String>,
    /// A DAgger round: this policy checkpoint drives the preset's episodes while the
    /// expert watches, taking the wheel where the policy stands and the expert would go
    /// (`dataset::dagger`); `mrdrive label` then labels the states the policy visited.
    /// The dataset is named `<preset>-dagger`: collect it into its own directory.
    #[arg(long, requires = "preset")]
    pub learner: Option<PathBuf>,
    /// The dataset directory (made if missing; a finished episode is kept and skipped).
    #[arg(long)]
    pub out: PathBuf,
    /// Episodes in the plan.
    #[arg(long, default_value_t = 40)]
    pub episodes: usize,
    /// Longest episode (seconds simulated).
    #[arg(long, default_value_t = 90.0)]
    pub max_s: f64,
    /// Multiplies every episode's pedestrian count (the plan cycles through the paper's
    /// 0, 10 and 40), 0 to 20 (`dataset::collect::crowd`): a crowded set has more walkers
    /// in the ego's path to learn braking from. Collect it into its own directory.
    #[arg(long, default_value_t = 1.0)]
    pub pedestrians_scale: f64,
    /// Walkers sent across the road just ahead of the ego per minute of driving, 0 to 60
    /// (`world::traffic::crossings`; episodes without pedestrians get none): examples of
    /// braking for a walker in the way, rare otherwise. 0 collects as the data before label version 4 was.
    #[arg(long, default_value_t = collect::CROSSINGS_PER_MIN)]
    pub crossings_per_min: f32,
    /// Mean seconds between two perturbations of the expert (0: no noise).
    #[arg(long, default_value_t = 4.0)]
    pub noise_gap_s: f64,
    /// CARLA's maps and routes (Town01.xodr, routes_town01.xml).
    #[arg(long, default_value = "../shared/carla")]
    pub carla: PathBuf,
    /// No progress lines.
    #[arg(long)]
    pub quiet: bool,
}

/// `label` arguments.
#[derive(Args)]
pub struct LabelArgs {
    /// The dataset directory (`mrdrive collect --out`).
    pub dir: PathBuf,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs `collect`.
pub fn collect(a: CollectArgs) -> anyhow::Result<()> {
    let (mut plan, name) = match (&a.preset, &a.scenario) {
        (_, Some(file)) => {
            let scenario = sim::scenario::Scenario::from_file(file)?;
            let densities = a
                .densities
                .iter()
                .map(|d| sim::sweep::parse_density(d))
                .collect::<Result<Vec<_>, _>>()?;
            (
                collect::scenario_plan(&scenario, &a.seeds, &densities),
                "scenario",
            )
        }
        (Some(p), None) => {
            let preset = match p {
                PresetArg::Original => Preset::Original,
                PresetArg::Retarget => Preset::Retarget,
            };
            anyhow::ensure!(
                a.carla.join("Town01.xodr").is_file(),
                "--carla {}: no Town01.xodr there; point --carla at the folder with CARLA's Town01.xodr and routes_town01.xml",
                a.carla.display()
            );
            let repo = std::env::current_dir()?;
            (
                collect::plan(preset, a.episodes, &a.carla, &repo),
                preset.name(),
            )
        }
        (None, None) => anyhow::bail!("give --preset or --scenario"),
    };
    collect::crowd(&mut plan, a.pedestrians_scale)
        .map_err(|e| anyhow::anyhow!("--pedestrians-scale: {e}"))?;
    anyhow::ensure!(
        (0.0..=60.0).contains(&a.crossings_per_min),
        "--crossings-per-min {}: give a rate from 0 to 60 per minute",
        a.crossings_per_min
    );
    if a.scenario.is_none() {
        for spec in &mut plan {
            spec.crossings_per_min = a.crossings_per_min;
        }
    }
    let name = match &a.learner {
        Some(_) => format!("{name}-dagger"),
        None => name.to_string(),
    };
    let mut cfg = CollectConfig::cpu_default(&name);
    cfg.max_s = a.max_s;
    cfg.noise.mean_gap_s = a.noise_gap_s;
    let learner = a.learner.as_deref().map(|weights| {
        move || -> Result<Box<dyn sim::driver::Driver>, String> {
            let device = ::policy::device::open(::policy::device::DeviceKind::Cpu)
                .map_err(|e| e.to_string())?;
            let driver = ::policy::PolicyDriver::from_checkpoint(weights, device)
                .map_err(|e| format!("--learner {}: {e}", weights.display()))?;
            Ok(Box::new(driver))
        }
    });
    if let Some(make) = &learner {
        // A bad checkpoint is said once, before any episode.
        make().map_err(anyhow::Error::msg)?;
    }
    let started = std::time::Instant::now();
    let quiet = a.quiet;
    let index = collect::collect_with(
        &plan,
        &cfg,
        &a.out,
        learner.as_ref().map(|f| f as &collect::Learner),
        &mut |r, _| {
            if !quiet {
                println!("{}", r.line(plan.len()));
            }
        },
    )
    .with_context(|| format!("collecting into {}", a.out.display()))?;
    let wall = started.elapsed().as_secs_f64();
    println!(
        "{}: {} episodes, {} frames ({:.2} h driven) in {}; this run {:.0} s",
        a.out.display(),
        index.episodes.len(),
        index.frames(),
        index.frames() as f64 * index.frame_s() / 3600.0,
        index.name,
        wall
    );
    Ok(())
}

/// Runs `label`.
pub fn label(a: LabelArgs) -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    let quiet = a.quiet;
    let report = label_dataset(&a.dir, &mut |done, total| {
        if !quiet {
            eprint!("\rlabelled {done}/{total} episodes");
        }
    })
    .with_context(|| format!("labelling {}", a.dir.display()))?;
    if !quiet {
        eprintln!();
    }
    let wall = started.elapsed().as_secs_f64();
    println!(
        "{}: labelled {} episodes ({} frames) in {:.1} s ({:.1} frames/s, {} threads); {} already labelled",
        a.dir.display(),
        report.episodes,
        report.frames,
        wall,
        report.frames as f64 / wall.max(1e-9),
        rayon::current_num_threads(),
        report.skipped
    );
    for (path, why) in &report.failed {
        eprintln!("warning: skipped {}: {why}", path.display());
    }
    anyhow::ensure!(
        report.failed.is_empty(),
        "{} episodes could not be labelled (above); the others were",
        report.failed.len()
    );
    Ok(())
}
