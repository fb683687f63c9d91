//! Camera commands: `render SCENARIO --at`, `render-demo`, `render lamp-size`,
//! `render fingerprint`, `bench render`.

use std::path::PathBuf;

use anyhow::{Context, Result, bail, ensure};
use clap::{Args, Subcommand};
use sim::build::{self, RunRequest};
use sim::moment::{LIGHT_AHEAD_RANGE_M, MomentRequest, View, render_moment};
use sim::render::image::save_png;
use sim::render::{RigConfig, demo, measure};
use sim::runner;
use sim::scenario::Scenario;

/// `mrdrive render-demo`: a hand-made junction scene, rendered.
#[derive(Debug, Args)]
pub struct RenderDemoArgs {
    /// Where to write the PNG.
    #[arg(long)]
    pub out: PathBuf,
    /// Write the class image (in its label colours) instead of the colour image.
    #[arg(long)]
    pub labels: bool,
    /// Scale of S0.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f32,
    /// Use the paper's S0 (480x192) instead of the CPU default (240x96).
    #[arg(long)]
    pub paper: bool,
    /// Draw the top-down view (this many pixels square, 60 m across) instead of the rig.
    #[arg(long)]
    pub top_down: Option<u32>,
    #[command(flatten)]
    pub antialias: AntialiasFlags,
}

/// How the camera anti-aliases (the scenario's `camera.supersample` and `camera.msaa`).
#[derive(Debug, Args, Clone, Copy)]
pub struct AntialiasFlags {
    /// Supersampling factor per axis (1 = none).
    #[arg(long, default_value_t = sim::render::rig::DEFAULT_SUPERSAMPLE)]
    pub supersample: u32,
    /// Multisamples per drawn pixel: 1 (none) or 4.
    #[arg(long, default_value_t = sim::render::rig::DEFAULT_MSAA)]
    pub msaa: u32,
}

impl AntialiasFlags {
    fn pair(&self) -> (u32, u32) {
        (self.supersample, self.msaa)
    }
}

/// `mrdrive render SCENARIO --at SECONDS ...` or `mrdrive render lamp-size`.
#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
pub struct RenderArgs {
    /// Another render command.
    #[command(subcommand)]
    pub cmd: Option<RenderCmd>,
    /// Render a moment of a scenario.
    #[command(flatten)]
    pub at: RenderAtArgs,
}

/// `mrdrive render SCENARIO --at SECONDS --scale R --out PNG`: the policy's
/// view at a moment of a scenario, driven there by the scenario's driver (or
/// the one given, with the delay and driving scale given: the flags a sweep
/// passes, so any run of `mrdrive paper` can be replayed to a moment).
#[derive(Debug, Args)]
pub struct RenderAtArgs {
    /// The scenario file (see scenarios/README.md).
    #[arg(required = true)]
    pub scenario: Option<PathBuf>,
    /// The moment to render (seconds of simulated time from the start).
    #[arg(long, default_value_t = 0.0)]
    pub at: f64,
    /// Scale of S0 (the rig's base size) to render the picture at.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f32,
    /// Drive there at this fixed input scale (fraction of S0), over the
    /// scenario's selector (`--scale` is the picture's).
    #[arg(long)]
    pub drive_scale: Option<f64>,
    /// Injected delay D (milliseconds), over the scenario's.
    #[arg(long)]
    pub delay_ms: Option<f64>,
    #[command(flatten)]
    pub driver: super::run::DriverFlags,
    /// Where to write the PNG.
    #[arg(long, required = true)]
    pub out: Option<PathBuf>,
    /// Write the class image (in its label colours) instead of the colour image.
    #[arg(long)]
    pub labels: bool,
    /// Draw the top-down view (this many pixels square, 60 m across, centred on the ego,
    /// which is outlined in red, heading up) instead of the rig.
    #[arg(long)]
    pub top_down: Option<u32>,
    #[command(flatten)]
    pub traffic: super::run::TrafficFlags,
}

/// Subcommands of `mrdrive render`.
#[derive(Debug, Subcommand)]
pub enum RenderCmd {
    /// Print a traffic-light lamp's size in pixels at 10, 20, 30 m for each scale.
    LampSize {
        /// Scales of S0 to measure.
        #[arg(long, value_delimiter = ',', default_values_t = [1.0, 0.75, 0.5])]
        scales: Vec<f32>,
        /// Distances from the camera (metres).
        #[arg(long, value_delimiter = ',', default_values_t = [10.0, 20.0, 30.0])]
        distances: Vec<f32>,
        #[command(flatten)]
        antialias: AntialiasFlags,
    },
    /// Render fixed frames (no file needed) and print their SHA-256: two machines
    /// whose digests agree draw them bit for bit alike.
    Fingerprint {
        /// Also write each frame as a PNG into this folder.
        #[arg(long)]
        png: Option<PathBuf>,
    },
}

/// Subcommands of `mrdrive bench`.
#[derive(Debug, Subcommand)]
pub enum BenchCmd {
    /// Rig frames per second (render + anti-aliasing + readback) at S0, 0.75 S0 and 480x192.
    Render {
        /// Frames per repeat.
        #[arg(long, default_value_t = 200)]
        frames: usize,
        /// Repeats (the median is reported).
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        #[command(flatten)]
        antialias: AntialiasFlags,
        /// Render along this scenario's route (its town, its rig; lights red,
        /// no actors) instead of the demo town.
        #[arg(long)]
        scenario: Option<PathBuf>,
    },
}

/// Runs `render-demo`.
pub fn render_demo(a: &RenderDemoArgs) -> Result<()> {
    let base = if a.paper {
        RigConfig::paper()
    } else {
        RigConfig::cpu_default()
    };
    let rig = RigConfig {
        supersample: a.antialias.supersample,
        msaa: a.antialias.msaa,
        ..base
    };
    let (img, backend) = demo::render_demo(rig, a.scale, a.top_down, a.labels)?;
    save_png(&img, &a.out).with_context(|| format!("writing {}", a.out.display()))?;
    println!(
        "wrote {} ({}x{}) on {backend}",
        a.out.display(),
        img.width,
        img.height
    );
    Ok(())
}

/// Runs `render ...`.
pub fn render(a: &RenderArgs) -> Result<()> {
    match &a.cmd {
        Some(RenderCmd::LampSize {
            scales,
            distances,
            antialias,
        }) => {
            print!(
                "{}",
                measure::lamp_size_report(scales, distances, antialias.pair())?
            );
            Ok(())
        }
        Some(RenderCmd::Fingerprint { png }) => {
            if let Some(dir) = png {
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
            }
            print!(
                "{}",
                sim::render::fingerprint::fingerprint(png.as_deref())?.report()
            );
            Ok(())
        }
        None => render_at(&a.at),
    }
}

/// Runs `render SCENARIO --at SECONDS`.
fn render_at(a: &RenderAtArgs) -> Result<()> {
    let (Some(path), Some(out)) = (&a.scenario, &a.out) else {
        bail!(
            "render needs a scenario and --out, e.g. mrdrive render scenarios/default.toml --at 10 --out frame.png"
        );
    };
    ensure!(
        a.at.is_finite() && a.at >= 0.0,
        "--at {}: give the moment as seconds of simulated time, 0 or more, e.g. --at 12.5",
        a.at
    );
    ensure!(
        a.scale.is_finite() && a.scale > 0.0 && a.scale <= 8.0,
        "--scale {}: scales are fractions of S0 in (0, 8], e.g. --scale 0.75",
        a.scale
    );
    if let Some(s) = a.drive_scale {
        ensure!(
            s > 0.0 && s <= 1.0,
            "--drive-scale {s}: the driving scale is a fraction of S0 in (0, 1], e.g. --drive-scale 0.75"
        );
    }
    if let Some(px) = a.top_down {
        ensure!(
            (1..=8192).contains(&px),
            "--top-down {px}: give the view's side in pixels, 1 to 8192, e.g. --top-down 256"
        );
    }
    let overrides = sim::build::Overrides {
        driver: a.driver.driver(),
        ..a.traffic.overrides(a.delay_ms)
    };
    let request = MomentRequest {
        run: RunRequest {
            scale: a.drive_scale,
            ..RunRequest::new(path, &overrides)
        },
        at_s: a.at,
        view: match a.top_down {
            Some(px) => View::TopDown { px },
            None => View::Rig { scale: a.scale },
        },
        labels: a.labels,
    };
    let m = render_moment(&request, &super::drivers())?;
    save_png(&m.image, out).with_context(|| format!("writing {}", out.display()))?;
    println!(
        "wrote {} ({}x{}) at {:.2} s: ego at ({:.1}, {:.1}) heading {:.0} deg, {:.1} m/s",
        out.display(),
        m.image.width,
        m.image.height,
        m.reached_s,
        m.ego.position.x,
        m.ego.position.y,
        m.ego.heading.to_degrees(),
        m.speed_mps,
    );
    println!(
        "driver        {}   resolution {}",
        m.record.result.provenance.driver, m.record.result.settings.resolution
    );
    match m.light_ahead {
        Some((d, state)) => println!("light ahead   {d:.1} m, {state:?}"),
        None => println!("light ahead   no stop line on the route within {LIGHT_AHEAD_RANGE_M} m"),
    }
    println!("camera        {}", m.backend);
    Ok(())
}

/// `bench render --scenario`: rig fps along a scenario's route, one pose
/// per metre, at 1.0 and 0.75 of the scenario's S0.
fn bench_scenario(
    path: &std::path::Path,
    frames: usize,
    repeats: usize,
    antialias: AntialiasFlags,
) -> Result<()> {
    let scenario = Scenario::from_file(path)?;
    let prepared =
        runner::prepare(&scenario).with_context(|| format!("scenario {}", path.display()))?;
    let rig = RigConfig {
        supersample: antialias.supersample,
        msaa: antialias.msaa,
        ..build::rig_for(&scenario, &super::drivers())?
    };
    print!(
        "{}",
        measure::route_report(
            &prepared.town,
            &prepared.route,
            rig,
            scenario.traffic.seed,
            frames,
            repeats
        )?
    );
    Ok(())
}

/// Runs one render benchmark.
pub fn bench_command(cmd: &BenchCmd) -> Result<()> {
    match cmd {
        BenchCmd::Render {
            frames,
            repeats,
            antialias,
            scenario: None,
        } => {
            print!(
                "{}",
                measure::bench_report(*frames, *repeats, antialias.pair())?
            );
            Ok(())
        }
        BenchCmd::Render {
            frames,
            repeats,
            antialias,
            scenario: Some(path),
        } => bench_scenario(path, *frames, *repeats, *antialias),
    }
}
