//! `mrdrive traffic ...`: traffic soak runs and the realised-count table.

use anyhow::{Context, Result, bail};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::sync::Arc;
use world::testtown::{FixtureLights, grid};
use world::traffic::{TrafficConfig, soak, table_one};

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
    /// OpenDRIVE map file (needs the map loader).
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
}

#[derive(Debug, Args)]
struct TableArgs {
    #[command(flatten)]
    town: TownArgs,
    /// Resets (seeds 0..N) per density.
    #[arg(long, default_value_t = 10)]
    resets: u64,
}

fn load_town(t: &TownArgs) -> Result<world::Town> {
    match (&t.map, &t.fixture) {
        (Some(path), _) => bail!(
            "{}: loading OpenDRIVE maps is not wired into `mrdrive traffic` yet (the map loader lands on another branch); run with --fixture for the built-in grid town",
            path.display()
        ),
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
            let label = if a.town.fixture.is_some() {
                "FIXTURE town"
            } else {
                "map"
            };
            let lights = FixtureLights::new(&town);
            let cfg = TrafficConfig {
                vehicles: a.vehicles,
                pedestrians: a.pedestrians,
                seed: a.seed,
                ..Default::default()
            };
            println!(
                "soak on {label} {} ({} lanes, {} lights, fixed-time lights), {} vehicles, {} pedestrians, {} min, seed {}",
                town.name,
                town.lanes.len(),
                town.lights.len(),
                a.vehicles,
                a.pedestrians,
                a.minutes,
                a.seed
            );
            let r = soak(Arc::new(town), cfg, a.minutes, &mut |tick, out| {
                lights.states_at(tick, out)
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
        }
        TrafficCommand::Table(a) => {
            let town = Arc::new(load_town(&a.town)?);
            let seeds: Vec<u64> = (0..a.resets).collect();
            let rows = table_one(
                town.clone(),
                &TrafficConfig::default(),
                None,
                &[(0, 0), (5, 10), (20, 40)],
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
