//! Camera commands: `render-demo`, `render lamp-size`, `bench render`.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use sim::render::image::save_png;
use sim::render::{RigConfig, demo, measure};

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
    let base = if a.paper {
        RigConfig::paper()
    } else {
        RigConfig::cpu_default()
    };
    let rig = RigConfig {
        supersample: a.supersample,
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
        RenderCmd::LampSize { scales, distances } => {
            print!("{}", measure::lamp_size_report(scales, distances)?);
            Ok(())
        }
    }
}

/// Runs one render benchmark.
pub fn bench_command(cmd: &BenchCmd) -> Result<()> {
    match cmd {
        BenchCmd::Render {
            frames,
            repeats,
            supersample,
        } => {
            print!(
                "{}",
                measure::bench_report(*frames, *repeats, *supersample)?
            );
            Ok(())
        }
    }
}
