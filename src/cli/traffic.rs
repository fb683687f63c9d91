//! `mrdrive traffic ...`: traffic soak runs and the realised-count table.

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::sync::Arc;
use world::map::testtown::{FixtureLights, grid};
use world::traffic::{EgoStart, TrafficConfig, soak, table_one};
use world::traffic::{LightController, LightTiming};
use world::{LightIdx, PlannerConfig, RouteFile, plan_route};

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
        (Some(path), _) => world::Town::from_xodr_file(path).with_context(|| {
            format!(
                "--map {}: could not load the map (or run the built-in grid town with --fixture)",
                path.display()
            )
        }),
        (None, Some(spec)) => {
            let (nx, ny) = spec
                .split_once('x')
                .and_then(|(a, b)| Some((a.parse::<usize>().ok()?, b.parse::<usize>().ok()?)))
                .with_context(|| format!("--fixture {spec:?}: expected NXxNY, e.g. 4x4"))?;
            if nx * ny < 2 || nx > 50 || ny > 50 {
                bail!("--fixture {spec:?}: between 2 and 2500 junctions, at most 50 per side");
            }
            if t.block_m < 40.0 || t.block_m > 1000.0 {
                bail!(
                    "--block-m {}: must be between 40 and 1000 metres",
                    t.block_m
                );
            }
            Ok(grid(nx, ny, t.block_m))
        }
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
            println!(
                "realised vehicles       {} / {}",
                r.vehicles.1, r.vehicles.0
            );
            println!(
                "realised pedestrians    {} / {}",
                r.pedestrians.1, r.pedestrians.0
            );
            println!(
                "simulated               {:.0} s ({} ticks)",
                r.sim_s, r.ticks
            );
            println!("NPC-NPC collisions      {}", r.stats.npc_npc_collisions);
            println!("red lights run by NPCs  {}", r.stats.npc_red_runs);
            println!("deadlocks (stuck > 60s) {}", r.stats.deadlocks);
            println!("pedestrians alive       {}", r.pedestrians_alive);
            println!(
                "NPCs into pedestrians   {}",
                r.stats.npc_pedestrian_collisions
            );
            println!(
                "pedestrians into cars   {}",
                r.stats.pedestrian_vehicle_bumps
            );
            println!("NPC-static contacts     {}", r.stats.npc_static_collisions);
            println!("NPC respawns            {}", r.stats.respawns);
            println!("step wall time          {:.2} s", r.step_wall_s);
            println!(
                "ticks/s                 {:.0} per wall second of stepping (physics + behaviours, one thread)",
                r.ticks_per_s
            );
            if let Some(cpu) = r.cpu_s.filter(|&c| c > 0.0) {
                println!(
                    "ticks per CPU second    {:.0} ({:.2} s of CPU for the soak loop; differs from wall when cores are shared)",
                    r.ticks as f64 / cpu,
                    cpu
                );
            }
            if a.incidents {
                println!("incidents               {} listed", r.incidents.len());
                for i in &r.incidents {
                    println!("  {i}");
                }
            }
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
            println!("Table I on {} ({} resets per density)", town.name, a.resets);
            println!(
                "{:>12} {:>16} {:>16}",
                "requested", "vehicles", "pedestrians"
            );
            for r in rows {
                println!(
                    "{:>12} {:>9.1} +- {:<4.1} {:>9.1} +- {:<4.1}",
                    format!("({}, {})", r.requested.0, r.requested.1),
                    r.vehicles.mean,
                    r.vehicles.sd,
                    r.pedestrians.mean,
                    r.pedestrians.sd
                );
            }
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
    println!(
        "Table I on {} ({} resets per density; vehicles, pedestrians)",
        town.name,
        seeds.len()
    );
    print!("{:>10}", "target");
    for id in ids {
        print!(" | route {id:<22}");
    }
    println!();
    for (row, d) in densities.iter().enumerate() {
        print!("{:>10}", format!("({}, {})", d.0, d.1));
        for col in &columns {
            let r = &col[row];
            print!(
                " | {:>4.1} +- {:<3.1}  {:>4.1} +- {:<3.1}",
                r.vehicles.mean, r.vehicles.sd, r.pedestrians.mean, r.pedestrians.sd
            );
        }
        println!();
    }
    Ok(())
}
