//! `mrdrive routes ...`: plan routes over a map and print what the planner made.

use std::path::PathBuf;

use clap::Args;
use world::{PlannerConfig, RouteFile, load_xodr_file, plan_route};

use super::map::MapLoadArgs;

/// `routes` arguments.
#[derive(Args)]
pub struct RoutesArgs {
    /// Route files (CARLA leaderboard XML or TOML).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// The OpenDRIVE map the routes are on.
    #[arg(long)]
    pub map: PathBuf,
    /// Plan only these route ids (default: all).
    #[arg(long)]
    pub id: Vec<String>,
    /// Also print where each command starts (index, position).
    #[arg(long)]
    pub verbose: bool,
    #[command(flatten)]
    pub load: MapLoadArgs,
}

/// Runs `routes`.
pub fn run(a: RoutesArgs) -> anyhow::Result<()> {
    let (town, _) = load_xodr_file(&a.map, &a.load.options())?;
    let cfg = PlannerConfig::default();
    println!("map: {}", a.map.display());
    println!(
        "{:<28} {:>4} {:>9} {:>6} {:>10} {:>8}  commands",
        "file", "id", "waypoints", "dense", "length_m", "max_gap"
    );
    for path in &a.files {
        let file = RouteFile::load(path)?;
        let routes: Vec<_> = if a.id.is_empty() {
            file.routes.iter().collect()
        } else {
            a.id.iter()
                .map(|id| file.route(id))
                .collect::<Result<_, _>>()?
        };
        for r in routes {
            let d = plan_route(&town, r, &cfg)?;
            let counts: Vec<String> = d
                .command_counts()
                .iter()
                .filter(|(_, n)| *n > 0)
                .map(|(c, n)| format!("{c:?}={n}"))
                .collect();
            let name = path
                .file_name()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            println!(
                "{:<28} {:>4} {:>9} {:>6} {:>10.1} {:>8.2}  {}",
                name,
                r.id,
                r.waypoints.len(),
                d.points.len(),
                d.length_m,
                d.max_gap_m(),
                counts.join(" ")
            );
            if a.verbose {
                for (i, p) in d.points.iter().enumerate() {
                    if i == 0 || d.points[i - 1].command != p.command {
                        println!(
                            "    [{i:>5}] {:>8.1} m  ({:>7.1}, {:>7.1})  {:?}",
                            p.route_s, p.position.x, p.position.y, p.command
                        );
                    }
                }
            }
        }
    }
    Ok(())
}
