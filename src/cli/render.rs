//! Camera commands: `render-demo`, `render lamp-size`, `bench render`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use sim::RgbImage;
use sim::render::image::save_png;
use sim::render::measure::{bench_rig, lamp_sizes};
use sim::render::{RigConfig, Renderer, demo};

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
    /// Supersampling factor per axis (1 = no anti-aliasing).
    #[arg(long, default_value_t = 2)]
    pub supersample: u32,
}

/// `mrdrive render ...`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// What to render.
    #[command(subcommand)]
    pub cmd: RenderCmd,
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
    },
}

/// `mrdrive bench ...`.
#[derive(Debug, Args)]
pub struct BenchArgs {
    /// What to benchmark.
    #[command(subcommand)]
    pub cmd: BenchCmd,
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
        /// Supersampling factor per axis.
        #[arg(long, default_value_t = 2)]
        supersample: u32,
    },
}

/// Runs `render-demo`.
pub fn render_demo(a: &RenderDemoArgs) -> Result<()> {
    let base = if a.paper { RigConfig::paper() } else { RigConfig::cpu_default() };
    let rig = RigConfig { supersample: a.supersample, ..base };
    let town = demo::grid_town(3, 3, 100.0, 7);
    let (ego, actors, states) = demo::demo_state(&town);
    let mut r = Renderer::new(&town, rig, 7)?;
    let (rgb, labels) = match a.top_down {
        Some(px) => r.render_top_down(&ego, &actors, &states, px, px, 60.0)?,
        None => r.render_rig(&ego, &actors, &states, a.scale)?,
    };
    let mut picture = RgbImage::default();
    let img = if a.labels {
        labels.to_label_rgb(&mut picture);
        &picture
    } else {
        rgb
    };
    save_png(img, &a.out).with_context(|| format!("writing {}", a.out.display()))?;
    println!("wrote {} ({}x{}) on {}", a.out.display(), img.width, img.height, r.backend());
    Ok(())
}

/// Runs `render ...`.
pub fn render(a: &RenderArgs) -> Result<()> {
    match &a.cmd {
        RenderCmd::LampSize { scales, distances } => {
            println!("lamp: 0.30 m disc, red, on the centre camera's axis; supersampling 2x");
            println!(
                "{:<10} {:>5} {:>9} {:>7} {:>10} {:>10} {:>9} {:>11} {:>10}",
                "rig", "scale", "size", "dist_m", "class_px", "tinted_px", "peak_tint", "analytic_d", "analytic_a"
            );
            for (name, rig) in [("cpu-S0", RigConfig::cpu_default()), ("paper-S0", RigConfig::paper())] {
                for s in lamp_sizes(rig, scales, distances)? {
                    println!(
                        "{:<10} {:>5.2} {:>9} {:>7.1} {:>10} {:>10} {:>9} {:>11.2} {:>10.2}",
                        name,
                        s.scale,
                        format!("{}x{}", s.size.0, s.size.1),
                        s.distance_m,
                        s.class_px,
                        s.tinted_px,
                        s.peak_tint,
                        s.analytic_diameter_px,
                        s.analytic_area_px
                    );
                }
            }
            Ok(())
        }
    }
}

/// Runs `bench ...`.
pub fn bench(a: &BenchArgs) -> Result<()> {
    match &a.cmd {
        BenchCmd::Render { frames, repeats, supersample } => {
            let town = demo::grid_town(4, 4, 100.0, 7);
            let (ego, actors, states) = demo::demo_state(&town);
            for (name, base, scales) in [
                ("cpu-S0", RigConfig::cpu_default(), vec![1.0, 0.75]),
                ("paper-S0", RigConfig::paper(), vec![1.0, 0.75]),
            ] {
                let rig = RigConfig { supersample: *supersample, ..base };
                let mut r = Renderer::new(&town, rig, 7)?;
                if name == "cpu-S0" {
                    println!(
                        "backend: {}; town {} with {} static triangles; {} actors; supersampling {}x",
                        r.backend(),
                        town.name,
                        r.scene().triangle_count(),
                        actors.len(),
                        rig.supersample
                    );
                }
                for s in bench_rig(&mut r, (ego, &actors, &states), &scales, *frames, *repeats)? {
                    let fps: Vec<String> = s.fps.iter().map(|f| format!("{f:.0}")).collect();
                    println!(
                        "{name:<9} scale {:.2} {:>4}x{:<4} median {:>7.1} rig fps  (repeats: {})",
                        s.scale,
                        s.size.0,
                        s.size.1,
                        s.median_fps(),
                        fps.join(" ")
                    );
                }
            }
            Ok(())
        }
    }
}
