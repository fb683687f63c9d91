//! `mrdrive run SCENARIO`: drive one scenario, show its progress, print its result
//! and draw its picture.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context;
use clap::Args;
use sim::build::Overrides;
use sim::build::{self, RunRequest};
use sim::observe::RunProgress;
use sim::recorder::RecordOptions;

/// `run` arguments.
#[derive(Args)]
pub struct RunArgs {
    /// The scenario file (see scenarios/README.md).
    #[arg(default_value = "scenarios/default.toml")]
    pub scenario: PathBuf,
    /// Injected delay D (milliseconds), over the scenario's.
    #[arg(long)]
    pub delay_ms: Option<f64>,
    /// A fixed input scale (fraction of S0), over the scenario's selector.
    #[arg(long)]
    pub scale: Option<f64>,
    #[command(flatten)]
    pub traffic: TrafficFlags,
    #[command(flatten)]
    pub driver: DriverFlags,
    /// Write the result record as JSON to this file (its folder is made if missing).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Where to draw the run's picture (the route on the map, the path driven coloured
    /// by input scale, each infraction): by default beside the JSON record, else
    /// `out/SCENARIO.png`.
    #[arg(long, conflicts_with = "no_picture")]
    pub picture: Option<PathBuf>,
    /// Draw no picture.
    #[arg(long)]
    pub no_picture: bool,
    /// Record an MCAP log to this file (Foxglove opens it; its folder is made if missing).
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// With --record: also log the class image.
    #[arg(long, conflicts_with = "no_images")]
    pub labels: bool,
    /// Render the camera rig at every camera tick even if the driver does not
    /// need it (the cost of data collection; shows in the time split).
    #[arg(long)]
    pub camera: bool,
    /// With --record: log no images (no camera view, no bird's-eye view),
    /// only the state topics.
    #[arg(long)]
    pub no_images: bool,
    /// No progress display.
    #[arg(long)]
    pub quiet: bool,
}

/// Shows where a run stands: a line that updates in place on a terminal, or
/// otherwise (a log file, CI) a plain line at the start and every [`LOG_EVERY`].
struct ProgressDisplay {
    bar: Option<indicatif::ProgressBar>,
    quiet: bool,
    started: Instant,
    last_line: Option<Instant>,
}

/// Wall time between two progress lines when standard error is not a terminal.
const LOG_EVERY: Duration = Duration::from_secs(10);

impl ProgressDisplay {
    fn new(quiet: bool) -> Self {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let bar = indicatif::ProgressBar::new(100);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:30}] {pos:>3}% of the route  {msg}",
                )
                .expect("a valid template")
                .progress_chars("=> "),
            );
            bar
        });
        ProgressDisplay {
            bar,
            quiet,
            started: Instant::now(),
            last_line: None,
        }
    }

    /// The status text: simulated time, real-time factor, scale in force.
    fn status(&self, p: &RunProgress) -> String {
        let wall = self.started.elapsed().as_secs_f64();
        format!(
            "{:.1} s simulated, {:.1}x real time, scale {}",
            p.sim_time_s,
            p.sim_time_s / wall.max(1e-9),
            p.scale
        )
    }

    fn update(&mut self, p: &RunProgress) {
        if let Some(bar) = &self.bar {
            bar.set_position(p.completion_pct.floor() as u64);
            bar.set_message(self.status(p));
        } else if !self.quiet && self.last_line.is_none_or(|t| t.elapsed() >= LOG_EVERY) {
            eprintln!(
                "progress: {:.0} % of the route, {}",
                p.completion_pct,
                self.status(p)
            );
            self.last_line = Some(Instant::now());
        }
    }

    fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

/// Makes the folder `path` goes in, if it has one and it is missing.
fn make_folder_for(path: &Path) -> anyhow::Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("making the folder {}", dir.display()))?;
    }
    Ok(())
}

/// Where the picture of a run goes: `--picture`, else beside the JSON record, else
/// `out/SCENARIO.png`; `None` with `--no-picture`.
fn picture_path(a: &RunArgs, scenario_name: &str) -> Option<PathBuf> {
    if a.no_picture {
        return None;
    }
    Some(match (&a.picture, &a.json) {
        (Some(p), _) => p.clone(),
        (None, Some(json)) => json.with_extension("png"),
        (None, None) => Path::new("out").join(format!("{scenario_name}.png")),
    })
}

/// Traffic settings given on the command line over a scenario's.
#[derive(Args, Debug, Clone, Default)]
pub struct TrafficFlags {
    /// The traffic seed, over the scenario's.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Target NPC vehicles, over the scenario's.
    #[arg(long)]
    pub vehicles: Option<u32>,
    /// Target pedestrians, over the scenario's.
    #[arg(long)]
    pub pedestrians: Option<u32>,
}

impl TrafficFlags {
    /// These flags (and a delay) as overrides of a scenario.
    pub fn overrides(&self, delay_ms: Option<f64>) -> Overrides {
        Overrides {
            delay_ms,
            seed: self.seed,
            vehicles: self.vehicles,
            pedestrians: self.pedestrians,
            driver: None,
        }
    }
}

/// The driver given on the command line over a scenario's `[driver]`.
#[derive(Args, Debug, Clone, Default)]
pub struct DriverFlags {
    /// Drive with this policy checkpoint (e.g. models/ra.safetensors), over the scenario's driver.
    #[arg(long, conflicts_with = "expert")]
    pub checkpoint: Option<PathBuf>,
    /// Drive with the privileged expert, over the scenario's driver.
    #[arg(long)]
    pub expert: bool,
}

impl DriverFlags {
    /// The driver these flags name, if any.
    pub fn driver(&self) -> Option<sim::scenario::DriverSpec> {
        use sim::scenario::DriverSpec;
        if self.expert {
            Some(DriverSpec::default())
        } else {
            self.checkpoint.clone().map(DriverSpec::policy)
        }
    }
}

/// Runs `run`.
pub fn run(a: RunArgs) -> anyhow::Result<()> {
    let overrides = Overrides {
        driver: a.driver.driver(),
        ..a.traffic.overrides(a.delay_ms)
    };
    for path in [&a.json, &a.record, &a.picture].into_iter().flatten() {
        make_folder_for(path)?;
    }
    let mut display = ProgressDisplay::new(a.quiet);
    let record_opts = if a.no_images {
        RecordOptions {
            camera: false,
            labels: false,
            bev: false,
        }
    } else {
        RecordOptions {
            labels: a.labels,
            ..Default::default()
        }
    };
    let request = RunRequest {
        scale: a.scale,
        record: a.record.as_deref().map(|p| (p, record_opts)),
        render_every_frame: a.camera,
        ..RunRequest::new(&a.scenario, &overrides)
    };
    let done = build::run_scenario(&request, &super::drivers(), &mut |p| display.update(p))?;
    display.finish();
    for w in &done.warnings {
        eprintln!("warning: {w}");
    }
    let record = done.record;
    print!("{}", record.table());
    if let Some(path) = &a.json {
        sim::record::write_atomically(path, &record)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("record: {}", path.display());
    }
    if let Some(path) = picture_path(&a, &record.result.provenance.scenario) {
        let img = sim::picture::picture_of(&record.result)?;
        sim::picture::save(&img, &path)?;
        println!("picture: {}", path.display());
    }
    if let Some(path) = &a.record {
        println!(
            "log: {}  (open it in Foxglove: File > Open local file; topics in docs/logs.md)",
            path.display()
        );
    }
    Ok(())
}
