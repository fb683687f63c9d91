//! `mrdrive map ...`: summary, picture and generator of towns.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::{Args, Subcommand};
use world::map::generator::{Features, GridTownParams, LightRule, generate_grid_town};
use world::map::picture::{RenderOptions, render_town};
use world::{
    LightController, LightTiming, LoadOptions, PlannerConfig, RouteFile, UnsignalledJunctions,
    load_xodr_file, plan_route,
};

/// Map subcommands.
#[derive(Subcommand)]
pub enum MapCommand {
    /// Print a map's summary: roads, lanes, junctions, lights, lane length, warnings.
    Info(InfoArgs),
    /// Draw a top-down picture of a map (PNG).
    Render(RenderArgs),
    /// Write a generated grid town as OpenDRIVE.
    Generate(GenerateArgs),
}

/// Options shared by commands that load a map.
#[derive(Debug, Args, Clone)]
pub struct MapLoadArgs {
    /// A map whose file has no traffic lights (CARLA's Town03, Town04 and Town06:
    /// CARLA places their lights in the level, not the OpenDRIVE file) gets lights
    /// generated at every junction of three or more approach roads, one phase per
    /// approach; this flag leaves such a map without lights.
    #[arg(long)]
    pub no_generated_lights: bool,
    /// The default since 2026-12-06; kept so that older command lines still run.
    #[arg(long, hide = true, conflicts_with = "no_generated_lights")]
    pub generate_lights: bool,
}

impl MapLoadArgs {
    /// The loader options these flags ask for.
    pub fn options(&self) -> LoadOptions {
        LoadOptions {
            unsignalled: if self.no_generated_lights {
                UnsignalledJunctions::NoLights
            } else {
                UnsignalledJunctions::GenerateLights
            },
        }
    }
}

/// `map info` arguments.
#[derive(Args)]
pub struct InfoArgs {
    /// The OpenDRIVE file.
    pub file: PathBuf,
    #[command(flatten)]
    pub load: MapLoadArgs,
}

/// `map render` arguments.
#[derive(Args)]
pub struct RenderArgs {
    /// The OpenDRIVE file.
    pub file: PathBuf,
    /// Output PNG.
    #[arg(long)]
    pub out: PathBuf,
    /// Ground size of a pixel (metres).
    #[arg(long, default_value_t = 0.5)]
    pub metres_per_pixel: f32,
    /// A route file (CARLA XML or TOML) to draw.
    #[arg(long)]
    pub route: Option<PathBuf>,
    /// The route id within --route.
    #[arg(long, default_value = "0")]
    pub id: String,
    /// Show the lights as they are this many seconds into a run.
    #[arg(long, default_value_t = 0.0)]
    pub time_s: f64,
    /// Seed of the light controllers' phase offsets.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub load: MapLoadArgs,
}

/// `map generate` arguments.
#[derive(Args)]
pub struct GenerateArgs {
    /// Blocks along x.
    #[arg(long, default_value_t = 5)]
    pub blocks_x: u32,
    /// Blocks along y.
    #[arg(long, default_value_t = 4)]
    pub blocks_y: u32,
    /// Distance between junction centres (metres).
    #[arg(long, default_value_t = 82.0)]
    pub block_size: f64,
    /// Seed for removed streets and buildings.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Rows of nodes (0 = southmost) whose east-west streets are arterials of
    /// two lanes each way, comma-separated.
    #[arg(long, value_delimiter = ',')]
    pub arterial_rows: Vec<u32>,
    /// Columns of nodes (0 = westmost) whose north-south streets are arterials, comma-separated.
    #[arg(long, value_delimiter = ',')]
    pub arterial_cols: Vec<u32>,
    /// A roundabout at interior node COLUMN,ROW off the arterials (repeatable).
    #[arg(long, value_name = "COLUMN,ROW", value_parser = parse_node)]
    pub roundabout: Vec<(u32, u32)>,
    /// Lights only where two arterials cross (every other junction unsignalled);
    /// without it every junction with three or more arms has lights.
    #[arg(long)]
    pub lights_where_arterials_cross: bool,
    /// A shipped town's parameters instead of the flags above: gen01, gen02, held01 or gen03.
    #[arg(long)]
    pub preset: Option<String>,
    /// Town name written into the file (default: the output file's stem).
    #[arg(long)]
    pub name: Option<String>,
    /// Output .xodr file.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs a map subcommand.
pub fn run(cmd: MapCommand) -> anyhow::Result<()> {
    match cmd {
        MapCommand::Info(a) => info(a),
        MapCommand::Render(a) => render(a),
        MapCommand::Generate(a) => generate(a),
    }
}

fn info(a: InfoArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let (town, report) = load_xodr_file(&a.file, &a.load.options())?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    print!("{}", report.summary(&town, ms));
    Ok(())
}

fn render(a: RenderArgs) -> anyhow::Result<()> {
    let (town, _) = load_xodr_file(&a.file, &a.load.options())?;
    let route = match &a.route {
        Some(path) => {
            let file = RouteFile::load(path)?;
            let r = file.route(&a.id)?;
            let dense = plan_route(&town, r, &PlannerConfig::default())?;
            Some(dense.points.iter().map(|p| p.position).collect())
        }
        None => None,
    };
    let mut lights = LightController::new(&town, LightTiming::default(), a.seed);
    lights.step(a.time_s);
    let opts = RenderOptions {
        metres_per_pixel: a.metres_per_pixel,
        light_states: Some(lights.states()),
        route,
        ..Default::default()
    };
    let img = render_town(&town, &opts);
    img.save(&a.out)
        .with_context(|| format!("writing {}", a.out.display()))?;
    println!(
        "wrote {} ({} x {} px, {} m/px)",
        a.out.display(),
        img.width(),
        img.height(),
        a.metres_per_pixel
    );
    Ok(())
}

fn generate(a: GenerateArgs) -> anyhow::Result<()> {
    let name = a.name.clone().unwrap_or_else(|| {
        a.out
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "town".into())
    });
    let p = match a.preset.as_deref() {
        Some(preset) => {
            let p = match preset {
                "gen01" => GridTownParams::gen01(),
                "gen02" => GridTownParams::gen02(),
                "held01" => GridTownParams::held01(),
                "gen03" => GridTownParams::gen03(),
                other => anyhow::bail!(
                    "--preset {other}: no such town. Fix: use gen01, gen02, held01 or gen03"
                ),
            };
            GridTownParams {
                name: a.name.clone().unwrap_or(p.name.clone()),
                ..p
            }
        }
        None => GridTownParams {
            name,
            blocks_x: a.blocks_x,
            blocks_y: a.blocks_y,
            block_size_m: a.block_size,
            seed: a.seed,
            features: Features {
                arterial_rows: a.arterial_rows.clone(),
                arterial_cols: a.arterial_cols.clone(),
                roundabouts: a.roundabout.clone(),
                lights: if a.lights_where_arterials_cross {
                    LightRule::WhereArterialsCross
                } else {
                    LightRule::ThreeOrMoreArms
                },
            },
        },
    };
    let xml = generate_grid_town(&p)?;
    std::fs::write(&a.out, &xml).with_context(|| format!("writing {}", a.out.display()))?;
    println!("wrote {} ({} bytes)", a.out.display(), xml.len());
    Ok(())
}

/// Parses a grid node `COLUMN,ROW`.
fn parse_node(s: &str) -> Result<(u32, u32), String> {
    let (i, j) = s
        .split_once(',')
        .ok_or_else(|| format!("{s:?}: expected COLUMN,ROW, e.g. 1,2"))?;
    let n = |x: &str| {
        x.trim()
            .parse::<u32>()
            .map_err(|e| format!("{s:?}: {x:?} is not a node index ({e}); expected COLUMN,ROW"))
    };
    Ok((n(i)?, n(j)?))
}
