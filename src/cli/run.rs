//! `mrdrive run SCENARIO`: drive one scenario and print its result.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;
use policy::PolicyDriver;
use sim::driver::Driver;
use sim::expert::{Expert, ExpertParams};
use sim::record::RunRecord;
use sim::recorder::{RecordOptions, Recorder};
use sim::render::{Renderer, RigConfig};
use sim::runner::{self, Overrides, Prepared, RunInputs};
use sim::scenario::{DriverKind, RigKind, Scenario, SelectorKind};
use sim::selector::{Fixed, LatencyBudget, LatencyTable, Lookahead, Oracle, ResolutionSelector};

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
        }
    }
}

/// The latency table of a scenario (`timing.latency_ms`), if it has one.
fn latency_table(scenario: &Scenario) -> anyhow::Result<Option<LatencyTable>> {
    if scenario.timing.latency_ms.is_empty() {
        return Ok(None);
    }
    let pairs: Vec<(f32, f64)> = scenario
        .timing
        .latency_ms
        .iter()
        .map(|(k, v)| k.parse::<f32>().map(|s| (s, *v)))
        .collect::<Result<_, _>>()
        .with_context(|| {
            format!(
                "scenario {}: timing.latency_ms keys are scales like \"0.75\"",
                scenario.name
            )
        })?;
    Ok(Some(LatencyTable::new(&pairs).with_context(|| {
        format!("scenario {}: timing.latency_ms", scenario.name)
    })?))
}

/// The selector a scenario asks for (the scale flag overrides it).
pub fn selector_for(
    scenario: &Scenario,
    scale: Option<f64>,
) -> anyhow::Result<Box<dyn ResolutionSelector>> {
    if let Some(s) = scale {
        anyhow::ensure!(
            s > 0.0 && s <= 1.0,
            "--scale {s}: scales are fractions of S0 in (0, 1]"
        );
        return Ok(Box::new(Fixed { scale: s as f32 }));
    }
    let r = &scenario.resolution;
    let (low, high) = (r.low as f32, r.high as f32);
    let needs_table = |what: &str| {
        format!(
            "scenario {}: resolution.selector = \"{what}\" needs timing.latency_ms for the scales {low} and {high}, e.g. latency_ms = {{ \"{low}\" = 50.0, \"{high}\" = 100.0 }}",
            scenario.name
        )
    };
    Ok(match r.selector {
        SelectorKind::Fixed => Box::new(Fixed {
            scale: r.scale as f32,
        }),
        SelectorKind::Oracle => Box::new(Oracle {
            low,
            high,
            enter_m: r.near_m as f32,
            exit_m: r.far_m as f32,
            active: false,
        }),
        SelectorKind::Lookahead => {
            let table = latency_table(scenario)?.with_context(|| needs_table("lookahead"))?;
            let mut l =
                Lookahead::covering(low, high, &table).with_context(|| needs_table("lookahead"))?;
            l.enter_m = r.near_m as f32;
            l.exit_m = r.far_m as f32;
            Box::new(l)
        }
        SelectorKind::Budget => {
            let table = latency_table(scenario)?.with_context(|| needs_table("budget"))?;
            Box::new(LatencyBudget {
                table,
                budget_ms: r.budget_ms.unwrap_or(f64::INFINITY),
            })
        }
    })
}

/// The driver a scenario asks for.
pub fn driver_for(scenario: &Scenario) -> anyhow::Result<Box<dyn Driver>> {
    match scenario.driver.kind {
        DriverKind::Expert => Ok(Box::new(Expert::new(ExpertParams::default()))),
        DriverKind::Policy => {
            let path = scenario
                .driver
                .checkpoint
                .as_deref()
                .context("driver.checkpoint is required for a policy")?;
            let name = scenario.driver.device.as_deref().unwrap_or("cpu");
            let device = name
                .parse()
                .and_then(policy::device::open)
                .with_context(|| format!("scenario {}: driver.device", scenario.name))?;
            Ok(Box::new(PolicyDriver::from_checkpoint(path, device)?))
        }
    }
}

/// The base size S0 (height, width) a policy checkpoint was trained at, if
/// the scenario's driver is a policy.
fn policy_s0(scenario: &Scenario) -> anyhow::Result<Option<(u32, u32)>> {
    if scenario.driver.kind != DriverKind::Policy {
        return Ok(None);
    }
    let path = scenario
        .driver
        .checkpoint
        .as_deref()
        .context("driver.checkpoint is required for a policy")?;
    let (cfg, _) = policy::checkpoint::read_manifest(path)?;
    let [h, w] = cfg.input_size(1.0);
    Ok(Some((h as u32, w as u32)))
}

/// The rig a scenario asks for: a policy's own S0 if it drives, else the
/// scenario's `[camera]` rig. The crop keeps WoR's proportions (the top
/// fifth of each camera's image is cut).
pub fn rig_for(scenario: &Scenario) -> anyhow::Result<RigConfig> {
    let base = match scenario.camera.rig {
        RigKind::Cpu => RigConfig::cpu_default(),
        RigKind::Paper => RigConfig::paper(),
    };
    let base = match policy_s0(scenario)? {
        Some((h0, w0)) => {
            anyhow::ensure!(
                w0 % 3 == 0 && h0 % 4 == 0,
                "checkpoint S0 {w0}x{h0}: the rig needs a width divisible by 3 and a height by 4"
            );
            RigConfig {
                cam_width_px: w0 / 3,
                cam_height_px: h0 * 5 / 4,
                crop_top_px: h0 / 4,
                ..base
            }
        }
        None => base,
    };
    Ok(RigConfig {
        supersample: scenario.camera.supersample,
        ..base
    })
}

/// The wgpu renderer for a scenario's town (seeded from its traffic seed).
pub fn camera_for(scenario: &Scenario, prepared: &Prepared) -> anyhow::Result<Renderer> {
    Ok(Renderer::new(
        &prepared.town,
        rig_for(scenario)?,
        scenario.traffic.seed,
    )?)
}

/// Runs one scenario file with overrides: the shared path of `run` and `sweep`.
pub fn run_one(
    path: &Path,
    overrides: &Overrides,
    scale: Option<f64>,
    record: Option<(&Path, RecordOptions)>,
    render_every_frame: bool,
    progress: &mut dyn FnMut(f64),
) -> anyhow::Result<RunRecord> {
    let scenario = Scenario::from_file(path)?;
    let scenario = overrides.apply(&scenario);
    let prepared =
        runner::prepare(&scenario).with_context(|| format!("scenario {}", path.display()))?;
    let mut driver = driver_for(&scenario)?;
    let mut selector = selector_for(&scenario, scale)?;
    let record_path = record.map(|(p, o)| (p.to_path_buf(), o)).or_else(|| {
        scenario.outputs.record.clone().map(|p| {
            (
                p,
                RecordOptions {
                    labels: scenario.outputs.record_labels,
                    ..Default::default()
                },
            )
        })
    });
    let mut record_opts = record_path.as_ref().map(|(_, o)| *o);
    let wants_images = record_opts.is_some_and(|o| o.camera || o.labels || o.bev);
    let mut camera = if driver.needs().camera || wants_images || render_every_frame {
        match camera_for(&scenario, &prepared) {
            Ok(r) => Some(r),
            Err(e) if !driver.needs().camera => {
                eprintln!("warning: recording without camera images: {e:#}");
                record_opts = record_opts.map(|_| RecordOptions {
                    camera: false,
                    labels: false,
                    bev: false,
                });
                None
            }
            Err(e) => return Err(e),
        }
    } else {
        None
    };
    let mut recorder = match (&record_path, record_opts) {
        (Some((p, _)), Some(o)) => Some(Recorder::create(p, o, &prepared.town)?),
        _ => None,
    };
    let record = runner::run(
        &scenario,
        path,
        RunInputs {
            prepared: &prepared,
            driver: driver.as_mut(),
            selector: selector.as_mut(),
            camera: camera.as_mut().map(|c| c as &mut dyn sim::runner::Camera),
            recorder: recorder.as_mut(),
            progress,
            max_ticks: None,
            observer: None,
            render_every_frame,
        },
    )?;
    if let Some(rec) = recorder {
        rec.finish(&record.result)?;
    }
    Ok(record)
}

/// Runs `run`.
pub fn run(a: RunArgs) -> anyhow::Result<()> {
    let overrides = a.traffic.overrides(a.delay_ms);
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
    let record = run_one(
        &a.scenario,
        &overrides,
        a.scale,
        a.record.as_deref().map(|p| (p, record_opts)),
        a.camera,
        &mut |pct| bar.set_position(pct.floor() as u64),
    )?;
    bar.finish_and_clear();
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
