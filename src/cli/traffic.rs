//! `mrdrive traffic ...`: traffic soak runs and the realised-count table.

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::sync::Arc;
use world::map::load_xodr_file;
use world::map::testtown::{FixtureLights, grid_of_spec};
use world::traffic::{
    EgoStart, TrafficConfig, soak, table_one, table_one_text, table_per_route_text,
};
use world::traffic::{LightController, LightTiming};
use world::{LightIdx, PlannerConfig, RouteFile, plan_route};

use super::map::MapLoadArgs;

/// Traffic commands.
#[derive(Debug, Args)]
pub struct TrafficArgs {
    #[command(subcommand)]
    command: TrafficCommand,
}

#[derive(Debug, Subcommand)]
enum TrafficCommand {
    /// Run NPC vehicles and pedestrians for a while and print collisions, red runs, deadlocks and ticks/s.
    Soak(SoakArgs),
    /// Print Table I: realised vehicle and pedestrian counts (mean +- sd) per density over several seeds.
    Table(TableArgs),
}

/// Which town to run.
#[derive(Debug, Args)]
struct TownArgs {
    /// OpenDRIVE map file.
    #[arg(long, conflicts_with = "fixture")]
    map: Option<PathBuf>,
    /// Use the built-in test grid town instead of a map: NXxNY junctions, e.g. 4x4.
    #[arg(long, value_name = "NXxNY", num_args = 0..=1, default_missing_value = "4x4")]
    fixture: Option<String>,
    /// Block size of the fixture grid (metres).
    #[arg(long, default_value_t = 80.0)]
    block_m: f32,
    #[command(flatten)]
    load: MapLoadArgs,
}

#[derive(Debug, Args)]
struct SoakArgs {
    #[command(flatten)]
    town: TownArgs,
    /// NPC vehicles to spawn.
    #[arg(long, default_value_t = 20)]
    vehicles: usize,
    /// Pedestrians to spawn.
    #[arg(long, default_value_t = 40)]
    pedestrians: usize,
    /// Simulated minutes.
    #[arg(long, default_value_t = 10.0)]
    minutes: f64,
    /// Traffic seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// List the incidents counted (the first 50 of each kind): tick, time, who, where, lanes, speeds.
    #[arg(long)]
    incidents: bool,
}

#[derive(Debug, Args)]
struct TableArgs {
    #[command(flatten)]
    town: TownArgs,
    /// Resets (seeds 0..N) per density.
    #[arg(long, default_value_t = 10)]
    resets: u64,
    /// Route file: one column per route, the ego at the route's start (as the paper's Table I).
    #[arg(long, requires = "map")]
    routes: Option<PathBuf>,
    /// Route ids to use (default: 0 and 1).
    #[arg(long, value_delimiter = ',', default_value = "0,1")]
    ids: Vec<String>,
}

fn load_town(t: &TownArgs) -> Result<world::Town> {
    match (&t.map, &t.fixture) {
        (Some(path), _) => load_xodr_file(path, &t.load.options()).map(|(town, _)| town).with_context(|| {
            format!(
                "--map {}: could not load the map (or run the built-in grid town with --fixture)",
                path.display()
            )
        }),
        (None, Some(spec)) => Ok(grid_of_spec(spec, t.block_m).map_err(anyhow::Error::msg)?),
        (None, None) => bail!("give a town: --map FILE or --fixture [NXxNY]"),
    }
}

/// Runs a `traffic` subcommand.
pub fn run(args: TrafficArgs) -> Result<()> {
    match args.command {
        TrafficCommand::Soak(a) => {
            let town = load_town(&a.town)?;
            let fixture = a.town.fixture.is_some();
            let label = if fixture { "FIXTURE town" } else { "map" };
            let fixed = FixtureLights::new(&town);
            // Maps get the real controller (seeded like a run); the fixture
            // its fixed-time test lights.
            let mut controller = LightController::new(&town, LightTiming::default(), a.seed);
            let cfg = TrafficConfig {
                vehicles: a.vehicles,
                pedestrians: a.pedestrians,
                seed: a.seed,
                ..Default::default()
            };
            println!(
                "soak on {label} {} ({} lanes, {} lights, {} lights), {} vehicles, {} pedestrians, {} min, seed {}",
                town.name,
                town.lanes.len(),
                town.lights.len(),
                if fixture { "fixed-time" } else { "cycling" },
                a.vehicles,
                a.pedestrians,
                a.minutes,
                a.seed
            );
            let n_lights = town.lights.len();
            let r = soak(Arc::new(town), cfg, a.minutes, &mut |tick, out| {
                if fixture {
                    fixed.states_at(tick, out)
                } else {
                    if tick > 0 {
                        controller.step(f64::from(world::physics::DT_S));
                    }
                    out.clear();
                    out.extend((0..n_lights).map(|i| controller.state(LightIdx(i as u32))));
                }
            });
            print!("{}", r.text(a.incidents));
        }
        TrafficCommand::Table(a) => {
            let town = Arc::new(load_town(&a.town)?);
            let seeds: Vec<u64> = (0..a.resets).collect();
            let densities = [(0, 0), (5, 10), (20, 40)];
            if let Some(routes) = &a.routes {
                return table_per_route(&town, routes, &a.ids, &densities, &seeds);
            }
            let rows = table_one(
                town.clone(),
                &TrafficConfig::default(),
                None,
                &densities,
                &seeds,
            );
            print!("{}", table_one_text(&town.name, seeds.len(), &rows));
        }
    }
    Ok(())
}

/// Table I as the paper lays it out: a column per route (the ego at its
/// start), a row per density, realised counts as mean +- sd over the resets.
fn table_per_route(
    town: &Arc<world::Town>,
    routes: &std::path::Path,
    ids: &[String],
    densities: &[(usize, usize)],
    seeds: &[u64],
) -> Result<()> {
    let file = RouteFile::load(routes)?;
    let mut columns = Vec::new();
    for id in ids {
        let dense = plan_route(town, file.route(id)?, &PlannerConfig::default())?;
        let ego = EgoStart::at_start_of(&dense)
            .with_context(|| format!("{} route {id}: no points", routes.display()))?;
        columns.push(table_one(
            town.clone(),
            &TrafficConfig::default(),
            Some(ego),
            densities,
            seeds,
        ));
    }
    print!(
        "{}",
        table_per_route_text(&town.name, seeds.len(), ids, &columns)
    );
    Ok(())
}
