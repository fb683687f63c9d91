//! `mrdrive routes ...`: plan routes over a map and print what the planner made.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use world::{DenseRoute, PlannerConfig, Route, RouteFile, load_xodr_file, plan_route};

use super::map::MapLoadArgs;

/// `routes` arguments.
#[derive(Args)]
pub struct RoutesArgs {
    /// Route files (CARLA leaderboard XML or TOML).
    #[arg(required_unless_present = "random")]
    pub files: Vec<PathBuf>,
    /// Also draw random routes, one per seed ("0..8" or "1,5,9"): two points on
    /// the map's lanes 300-900 m apart along the planned route, the same for a
    /// seed on every machine (the dataset's random routes).
    #[arg(long)]
    pub random: Option<String>,
    /// Write every route planned here into this TOML route file (our form),
    /// for a scenario to name.
    #[arg(long)]
    pub write: Option<PathBuf>,
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
    let mut planned: Vec<(String, Route, DenseRoute)> = Vec::new();
    for path in &a.files {
        let file = RouteFile::load(path)?;
        let routes: Vec<_> = if a.id.is_empty() {
            file.routes.iter().collect()
        } else {
            a.id.iter()
                .map(|id| file.route(id))
                .collect::<Result<_, _>>()?
        };
        let name = path
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        for r in routes {
            planned.push((name.clone(), r.clone(), plan_route(&town, r, &cfg)?));
        }
    }
    if let Some(seeds) = &a.random {
        for seed in sim::sweep::parse_seeds(seeds)? {
            let (r, d) = dataset::collect::random_route(&town, seed).map_err(|e| {
                anyhow::anyhow!("{}: random route for seed {seed}: {e}", a.map.display())
            })?;
            planned.push(("(random)".into(), r, d));
        }
    }
    for (name, r, d) in &planned {
        let counts: Vec<String> = d
            .command_counts()
            .iter()
            .filter(|(_, n)| *n > 0)
            .map(|(c, n)| format!("{c:?}={n}"))
            .collect();
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
    if let Some(out) = &a.write {
        // The header names the command that wrote the file, so it can be made again.
        let command: Vec<String> = std::env::args().skip(1).collect();
        let mut text = format!(
            "# Written by `mrdrive {}`: {} on {}.\n\
             # Positions in the OpenDRIVE frame (metres), headings in degrees\n\
             # counter-clockwise from +x; a comment gives each route's planned length.\n",
            command.join(" "),
            if a.random.is_some() {
                "random routes, one per seed (the seed is in the id)"
            } else {
                "routes copied from the files given"
            },
            a.map.display(),
        );
        for (_, r, d) in &planned {
            text += &format!("\n# {:.0} m\n{}", d.length_m, r.toml());
        }
        std::fs::write(out, text).with_context(|| format!("writing {}", out.display()))?;
        println!("wrote {} route(s) to {}", planned.len(), out.display());
    }
    Ok(())
}
