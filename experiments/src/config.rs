//! What a paper run covers: routes, densities, seeds, delays, scales, latency
//! envelopes and the four checkpoints. [`PaperConfig::full`] is the paper's
//! protocol with three seeds; [`PaperConfig::quick`] is a smoke test of every
//! table and figure in a couple of minutes.

use sim::scenario::SelectorKind;
use std::path::{Path, PathBuf};

/// One evaluation route: a scenario file and the town and route it drives.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    /// The scenario file (relative to the working folder, as a sweep plan keeps it).
    pub scenario: PathBuf,
    /// The town's name in tables ("Town01").
    pub town: String,
    /// The route's name in tables ("route 0").
    pub route: String,
}

/// The checkpoints the paper compares.
#[derive(Debug, Clone, PartialEq)]
pub struct Models {
    /// The single-resolution network (1.0x).
    pub original: PathBuf,
    /// The Original retargeted to the low scale, no BN banks.
    pub nra_low: PathBuf,
    /// The Original retargeted to the high scale, no BN banks.
    pub nra_high: PathBuf,
    /// The multi-resolution network with a BN branch per scale.
    pub ra: PathBuf,
    /// The RA network's learned trigger (`mrdrive policy trigger`), for
    /// the `learned` selector's rows; `None` leaves them out.
    pub trigger: Option<PathBuf>,
    /// An RA network with a BN branch for every scale of
    /// [`PaperConfig::ladder`] (`mrdrive train --stage ra --scales ...`), for
    /// the more-scales study; `None` leaves it out.
    pub ladder: Option<PathBuf>,
}

/// A latency envelope of Table III: the high scale runs at `high_ms`, the
/// low scale at `low_ms` (milliseconds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Envelope {
    /// Execution latency at the high scale, the worst case (milliseconds).
    pub high_ms: f64,
    /// Execution latency at the low scale (milliseconds).
    pub low_ms: f64,
}

impl Envelope {
    /// "100->50 ms".
    pub fn label(&self) -> String {
        format!("{}->{} ms", self.high_ms, self.low_ms)
    }

    /// The execution latency of any scale (milliseconds): the straight line
    /// through the envelope's two points, `low_ms` at `low` and `high_ms` at
    /// `high`, never below 0. Under 150->100 ms with scales 0.75 and 1.0 it
    /// gives 0.5x 50 ms, 0.625x 75 ms and 0.875x 125 ms.
    pub fn latency_ms_at(&self, scale: f64, low: f64, high: f64) -> f64 {
        if (high - low).abs() < 1e-12 {
            return self.high_ms;
        }
        let slope = (self.high_ms - self.low_ms) / (high - low);
        (self.low_ms + slope * (scale - low)).max(0.0)
    }
}

/// Everything that fixes a paper run.
#[derive(Debug, Clone, PartialEq)]
pub struct PaperConfig {
    /// The evaluation routes (two per town in the paper).
    pub routes: Vec<Route>,
    /// Target (vehicles, pedestrians) densities.
    pub densities: Vec<(u32, u32)>,
    /// Traffic seeds per (route, density); the seed also sets the lights' phases.
    pub seeds: Vec<u64>,
    /// Injected delays D of Fig. 5 (milliseconds); Table II runs at the first,
    /// Fig. 3 and 4 at the first two.
    pub delays_ms: Vec<f64>,
    /// The low input scale (fraction of S0).
    pub low: f64,
    /// The scales of the more-scales study, ascending (each driven alone by
    /// [`Models::ladder`] at its own latency under each envelope).
    pub ladder: Vec<f64>,
    /// The high input scale (the training scale).
    pub high: f64,
    /// Table III's latency envelopes.
    pub envelopes: Vec<Envelope>,
    /// The checkpoints.
    pub models: Models,
    /// Log-normal spreads of the execution latency for the jitter
    /// experiment (run under the first envelope; 0 is Table III itself).
    pub jitters: Vec<f64>,
    /// Resets per (route, density) for Table I.
    pub resets: u64,
    /// A cap on each run's simulated time (seconds), for smoke tests; `None`
    /// keeps the scenarios' own timeouts.
    pub timeout_s: Option<f64>,
}

impl PaperConfig {
    /// The paper's protocol (docs/protocol.md §2, §7) with three seeds per (route,
    /// density); paths are relative to the workspace root.
    pub fn full() -> Self {
        let route = |town: &str, id: u32| Route {
            scenario: PathBuf::from(format!(
                "scenarios/paper/{}_route{id}.toml",
                town.to_lowercase()
            )),
            town: town.to_string(),
            route: format!("route {id}"),
        };
        let model = |name: &str| PathBuf::from(format!("models/{name}.safetensors"));
        PaperConfig {
            routes: vec![
                route("Town01", 0),
                route("Town01", 1),
                route("Town02", 0),
                route("Town02", 1),
            ],
            densities: vec![(0, 0), (5, 10), (20, 40)],
            seeds: vec![0, 1, 2],
            delays_ms: vec![0.0, 50.0, 100.0, 150.0, 200.0],
            low: 0.75,
            ladder: vec![0.5, 0.625, 0.75, 0.875, 1.0],
            high: 1.0,
            envelopes: vec![
                Envelope {
                    high_ms: 100.0,
                    low_ms: 50.0,
                },
                Envelope {
                    high_ms: 150.0,
                    low_ms: 100.0,
                },
            ],
            models: Models {
                original: model("original"),
                nra_low: model("nra-0.75"),
                nra_high: model("nra-1.0"),
                ra: model("ra"),
                trigger: Some(PathBuf::from("models/ra.trigger.json")),
                ladder: Some(model("ra5")),
            },
            jitters: vec![0.25, 0.5],
            resets: 10,
            timeout_s: None,
        }
    }

    /// A smoke test of every table and figure: Town01 route 0 only, two
    /// densities, one seed, D in {0, 50, 100}, one envelope, one jitter,
    /// runs capped at 8 simulated seconds, 2 resets for Table I, the
    /// more-scales study at its two ends.
    pub fn quick() -> Self {
        let full = Self::full();
        PaperConfig {
            routes: full.routes[..1].to_vec(),
            ladder: vec![0.5, 1.0],
            densities: vec![(0, 0), (5, 10)],
            seeds: vec![0],
            delays_ms: vec![0.0, 50.0, 100.0],
            envelopes: full.envelopes[..1].to_vec(),
            jitters: vec![0.5],
            resets: 2,
            timeout_s: Some(8.0),
            ..full
        }
    }

    /// The study on routes no training run drove: eight random routes on
    /// CARLA's Town02 (no dataset of ours drives Town02) and four on held01, a
    /// generated town held out of every dataset (`scenarios/heldout/`, routes
    /// written by `mrdrive routes --random` with seeds 0-7 and 0-3). With the
    /// paper's four, the switcher's claim rests on 16 routes. One seed (0) at
    /// each of the three densities: 36 pairs a comparison, as on the paper's
    /// routes, spread over 12 routes instead of 4 (routes are what the
    /// intervals cluster on, so more routes buy more than more seeds; the
    /// registration's budget, docs/paper/registration.md). Everything else is
    /// [`PaperConfig::full`]'s; `mrdrive paper --held-out` runs Fig. 3 and
    /// Table III on them.
    pub fn held_out() -> Self {
        let route = |town: &str, stem: &str, seed: u32| Route {
            scenario: PathBuf::from(format!("scenarios/heldout/{stem}_random{seed}.toml")),
            town: town.to_string(),
            route: format!("random {seed}"),
        };
        let mut routes: Vec<Route> = (0..8).map(|s| route("Town02", "town02", s)).collect();
        routes.extend((0..4).map(|s| route("held01", "held01", s)));
        PaperConfig {
            routes,
            seeds: vec![0],
            ..Self::full()
        }
    }

    /// The switchers of Table III and the frontier: the paper's oracle, the
    /// map lookahead, with a trigger the learned one, and the lookahead that
    /// switches up before the braking point.
    pub fn selectors(&self) -> Vec<SelectorKind> {
        let mut s = vec![SelectorKind::Oracle, SelectorKind::Lookahead];
        if self.models.trigger.is_some() {
            s.push(SelectorKind::Learned);
        }
        s.push(SelectorKind::Braking);
        s
    }

    /// The latencies of the ladder's two ends under `e` (see
    /// [`Envelope::latency_ms_at`]): the envelope a switcher between them
    /// runs under. 150->100 ms with the ladder 0.5x-1.0x gives 150->50 ms.
    pub fn ladder_envelope(&self, e: Envelope) -> Option<Envelope> {
        let (lo, hi) = (*self.ladder.first()?, *self.ladder.last()?);
        Some(Envelope {
            high_ms: e.latency_ms_at(hi, self.low, self.high),
            low_ms: e.latency_ms_at(lo, self.low, self.high),
        })
    }

    /// The towns in route order, each once.
    pub fn towns(&self) -> Vec<String> {
        let mut towns: Vec<String> = Vec::new();
        for r in &self.routes {
            if !towns.contains(&r.town) {
                towns.push(r.town.clone());
            }
        }
        towns
    }

    /// The route of a scenario file (base or derived from it), if it is one of ours.
    pub fn route_of(&self, scenario: &Path) -> Option<&Route> {
        let stem = scenario.file_stem()?.to_string_lossy().into_owned();
        let base = stem.split("__").next().unwrap_or_default();
        self.routes.iter().find(|r| {
            r.scenario
                .file_stem()
                .is_some_and(|s| s.to_string_lossy() == base)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::scenario::Scenario;
    use world::{LoadOptions, PlannerConfig, RouteFile, load_xodr_file, plan_route};

    /// Plans `scenario`'s route on its map: its length (metres).
    fn planned_length_m(scenario: &Scenario) -> f64 {
        let (town, _) = load_xodr_file(&scenario.map.file, &LoadOptions::default()).unwrap();
        let file = RouteFile::load(&scenario.route.file).unwrap();
        let route = file.route(&scenario.route.id).unwrap();
        f64::from(
            plan_route(&town, route, &PlannerConfig::default())
                .unwrap()
                .length_m,
        )
    }

    #[test]
    fn the_held_out_routes_load_and_plan_on_towns_no_dataset_drives() {
        let root = world::testdata::workspace_root();
        let cfg = PaperConfig::held_out();
        assert_eq!(cfg.routes.len(), 12);
        assert_eq!((cfg.seeds.as_slice(), cfg.densities.len()), (&[0][..], 3));
        assert_eq!(cfg.towns(), ["Town02", "held01"]);
        let carla = world::testdata::carla_dir(
            "the_held_out_routes_load_and_plan_on_towns_no_dataset_drives",
        );
        for r in &cfg.routes {
            let s = Scenario::from_file(&root.join(&r.scenario)).unwrap();
            assert_eq!(cfg.route_of(&r.scenario), Some(r));
            // Town02's file lives in ../shared/carla: planned when it is there.
            if r.town == "Town02" && carla.is_none() {
                continue;
            }
            let length = planned_length_m(&s);
            assert!(
                (300.0..900.0).contains(&length),
                "{}: {length} m",
                r.scenario.display()
            );
        }
    }
}
