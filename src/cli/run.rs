//! `mrdrive run SCENARIO`: drive one scenario and print its result.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use sim::build::{self, RunRequest};
use sim::record::RunRecord;
use sim::recorder::RecordOptions;
use sim::runner::Overrides;

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
    /// Write the result record as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Record an MCAP log to this file (Foxglove opens it).
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
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
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
        use sim::scenario::{DriverKind, DriverSpec};
        if self.expert {
            Some(DriverSpec::default())
        } else {
            self.checkpoint.as_ref().map(|c| DriverSpec {
                kind: DriverKind::Policy,
                checkpoint: Some(c.clone()),
                device: None,
                trigger: None,
            })
        }
    }
}

/// Runs `run`.
pub fn run(a: RunArgs) -> anyhow::Result<()> {
    let overrides = Overrides {
        driver: a.driver.driver(),
        ..a.traffic.overrides(a.delay_ms)
    };
    let bar = if a.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(100)
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos:>3}% of the route {msg}",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
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
        scenario: &a.scenario,
        overrides: &overrides,
        scale: a.scale,
        record: a.record.as_deref().map(|p| (p, record_opts)),
        render_every_frame: a.camera,
    };
    let done = build::run_scenario(&request, &super::drivers(), &mut |pct| {
        bar.set_position(pct.floor() as u64)
    })?;
    bar.finish_and_clear();
    for w in &done.warnings {
        eprintln!("warning: {w}");
    }
    let record = done.record;
    print_result(&record);
    if let Some(path) = &a.json {
        sim::record::write_atomically(path, &record)
            .with_context(|| format!("writing {}", path.display()))?;
        println!("record: {}", path.display());
    }
    if let Some(path) = &a.record {
        println!("log: {}", path.display());
    }
    Ok(())
}

/// Prints a run's result as a small table.
pub fn print_result(record: &RunRecord) {
    let r = &record.result;
    let p = &record.perf;
    println!(
        "scenario      {} ({})",
        r.provenance.scenario, r.provenance.route
    );
    println!(
        "driver        {}   resolution {}",
        r.provenance.driver, r.settings.resolution
    );
    println!(
        "delay         {} ms (max latency in force {} ms)",
        r.settings.delay_ms, r.max_latency_ms
    );
    println!(
        "traffic       {} vehicles, {} pedestrians (asked {}, {}), seed {}",
        r.traffic.vehicles,
        r.traffic.pedestrians,
        r.settings.vehicles,
        r.settings.pedestrians,
        r.settings.seed
    );
    println!(
        "result        {}  completion {:.1} % of {:.0} m  driving score {:.1}",
        if r.success { "SUCCESS" } else { "FAILURE" },
        r.completion_pct,
        r.route_length_m,
        r.driving_score
    );
    println!(
        "outside lanes {:.1} % of the distance driven",
        r.outside_lane_pct
    );
    if let Some(t) = r.termination {
        println!("ended by      {}", t.name());
    }
    println!("infractions");
    for (kind, n) in &r.counts {
        if !kind.terminates() || *n > 0 {
            println!("  {:<22} {n}", kind.name());
        }
    }
    println!(
        "time          {:.1} s simulated in {:.2} s wall ({:.0}x real time): traffic {:.2} s, render {:.2} s, driver {:.2} s, other {:.2} s",
        r.sim_time_s, p.wall_s, p.real_time_factor, p.traffic_s, p.render_s, p.driver_s, p.other_s
    );
}
