//! The records of a paper run, each beside the settings that made it.

use std::collections::BTreeMap;
use std::path::Path;

use sim::record::{self, RunRecord};
use sim::sweep::RunSpec;

use crate::PaperError;
use crate::config::PaperConfig;
use crate::units::Unit;

/// A unit of the comparisons: route stem, density (vehicles, pedestrians), seed.
pub type PairKey = (String, Option<(u32, u32)>, u64);

/// One finished run.
#[derive(Debug, Clone)]
pub struct Run {
    /// The town it drove ("Town01").
    pub town: String,
    /// The route scenario's stem ("town01_route0"): with the density and
    /// seed, what pairs two runs of different configurations.
    pub route: String,
    /// Its settings.
    pub spec: RunSpec,
    /// What happened.
    pub record: RunRecord,
}

impl Run {
    /// What two runs compared pair by pair share: route, density, seed.
    pub fn pair_key(&self) -> PairKey {
        (self.route.clone(), self.spec.density, self.spec.seed)
    }

    /// Its fixed scale (`None` for a switcher or the expert).
    pub fn scale(&self) -> Option<f64> {
        self.spec.scale
    }
}

/// A unit's finished runs and how many its plan has.
#[derive(Debug, Clone, Default)]
pub struct UnitRuns {
    /// Runs of the plan in the folder.
    pub planned: usize,
    /// The finished ones, in plan order.
    pub runs: Vec<Run>,
}

/// Every unit's runs, by unit id.
#[derive(Debug, Clone, Default)]
pub struct Results {
    /// By [`Unit::id`].
    pub units: BTreeMap<String, UnitRuns>,
}

impl Results {
    /// Reads the finished runs of `units` from their folders under `out`
    /// (a unit never started has none).
    pub fn load(cfg: &PaperConfig, out: &Path, units: &[Unit]) -> Result<Self, PaperError> {
        let mut results = Results::default();
        for u in units {
            let dir = u.dir(cfg, out);
            let plan = u.plan(cfg, out)?;
            let mut runs = Vec::new();
            for spec in &plan.runs {
                let path = dir.record_path(spec);
                if !path.exists() {
                    continue;
                }
                let record = record::read(&path).map_err(sim::sweep::SweepError::from)?;
                let route = cfg.route_of(&spec.scenario);
                runs.push(Run {
                    town: route.map_or_else(|| "?".into(), |r| r.town.clone()),
                    route: route.map_or_else(
                        || spec.scenario.display().to_string(),
                        |r| {
                            r.scenario
                                .file_stem()
                                .map(|s| s.to_string_lossy().into_owned())
                                .unwrap_or_default()
                        },
                    ),
                    spec: spec.clone(),
                    record,
                });
            }
            results.units.insert(
                u.id(cfg),
                UnitRuns {
                    planned: plan.runs.len(),
                    runs,
                },
            );
        }
        Ok(results)
    }

    /// The finished runs of `unit` at fixed scale `scale` (any scale: `None`)
    /// in `town` (any town: `None`).
    pub fn select(
        &self,
        cfg: &PaperConfig,
        unit: &Unit,
        scale: Option<f64>,
        town: Option<&str>,
    ) -> Vec<&Run> {
        self.units
            .get(&unit.id(cfg))
            .map(|u| {
                u.runs
                    .iter()
                    .filter(|r| {
                        scale.is_none_or(|s| r.scale().is_some_and(|x| (x - s).abs() < 1e-9))
                    })
                    .filter(|r| town.is_none_or(|t| r.town == t))
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The units (route, density, seed) that every policy run on them failed, and
    /// those runs: they cannot tell one configuration from another. The expert's
    /// runs do not count (it drives from the map's truth). Empty until a unit has
    /// runs of at least two configurations.
    pub fn failed_everywhere(&self) -> Vec<(PairKey, Vec<&Run>)> {
        let mut by_key: BTreeMap<PairKey, (Vec<&Run>, usize)> = BTreeMap::new();
        for u in self.units.values() {
            let mut seen = std::collections::BTreeSet::new();
            for r in &u.runs {
                if r.record.result.provenance.driver == "expert" {
                    continue;
                }
                let e = by_key.entry(r.pair_key()).or_default();
                e.0.push(r);
                if seen.insert(r.pair_key()) {
                    e.1 += 1;
                }
            }
        }
        by_key
            .into_iter()
            .filter(|(_, (runs, units))| {
                *units >= 2 && runs.iter().all(|r| !r.record.result.success)
            })
            .map(|(k, (runs, _))| (k, runs))
            .collect()
    }

    /// These results with every run's collisions counted by `rule`
    /// ([`sim::output::record::RunResult::counted_by`]); `None` when a run's
    /// record predates the per-rule counts.
    pub fn counted_by(&self, rule: sim::monitors::counting::CountingRule) -> Option<Results> {
        let mut r = self.clone();
        for run in r.units.values_mut().flat_map(|u| &mut u.runs) {
            run.record.result = run.record.result.counted_by(rule)?;
        }
        Some(r)
    }

    /// These results without the runs of the units `keys`.
    pub fn without(&self, keys: &[PairKey]) -> Results {
        let mut r = self.clone();
        for u in r.units.values_mut() {
            u.runs.retain(|run| !keys.contains(&run.pair_key()));
        }
        r
    }

    /// The distinct values of a provenance field over every finished run.
    pub fn provenance(
        &self,
        field: impl Fn(&sim::record::Provenance) -> &String,
    ) -> std::collections::BTreeSet<String> {
        self.units
            .values()
            .flat_map(|u| {
                u.runs
                    .iter()
                    .map(|r| field(&r.record.result.provenance).clone())
            })
            .collect()
    }

    /// The checkpoints and learned triggers (file name and the first digits
    /// of its SHA-256) that drove the finished runs, like
    /// "ra.safetensors sha256 1a2b3c4d5e6f".
    pub fn checkpoints(&self) -> std::collections::BTreeSet<String> {
        self.units
            .values()
            .flat_map(|u| u.runs.iter())
            .flat_map(|r| r.record.result.provenance.model_files())
            .map(|id| {
                let name = std::path::Path::new(&id.file)
                    .file_name()
                    .map_or(id.file.clone(), |n| n.to_string_lossy().into_owned());
                format!("{name} sha256 {}", id.short())
            })
            .collect()
    }

    /// How many finished runs each CPU made (its model name; "not recorded" for records
    /// older than [`sim::record::Provenance::cpu`]).
    pub fn cpus(&self) -> std::collections::BTreeMap<String, usize> {
        let mut counts = std::collections::BTreeMap::new();
        for run in self.units.values().flat_map(|u| u.runs.iter()) {
            let cpu = run.record.result.provenance.cpu.as_deref();
            *counts
                .entry(cpu.unwrap_or("not recorded").to_string())
                .or_insert(0) += 1;
        }
        counts
    }

    /// The render backends of the finished runs that rendered (the expert's
    /// "none" left out).
    pub fn backends(&self) -> std::collections::BTreeSet<String> {
        let mut b = self.provenance(|p| &p.render_backend);
        b.remove("none");
        b
    }

    /// (finished, planned) runs over `units`.
    pub fn progress(&self, cfg: &PaperConfig, units: &[Unit]) -> (usize, usize) {
        units
            .iter()
            .filter_map(|u| self.units.get(&u.id(cfg)))
            .fold((0, 0), |(d, p), u| (d + u.runs.len(), p + u.planned))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::tests::run;
    use crate::{Driver, Unit};

    #[test]
    fn the_cpus_are_counted_with_the_records_that_name_none() {
        let cfg = PaperConfig::full();
        let cpus = [Some("AMD EPYC"), None, Some("AMD EPYC"), Some("Intel Xeon")];
        let runs: Vec<_> = cpus
            .iter()
            .zip(0..)
            .map(|(cpu, seed)| {
                let mut x = run("a", seed, true, 0, 0, 0, 0.0);
                x.record.result.provenance.cpu = cpu.map(String::from);
                x
            })
            .collect();
        let mut r = Results::default();
        let unit = UnitRuns { planned: 4, runs };
        r.units.insert(Unit::fixed(Driver::Ra, 0.0).id(&cfg), unit);
        let counts: Vec<(String, usize)> = r.cpus().into_iter().collect();
        let want = [("AMD EPYC", 2), ("Intel Xeon", 1), ("not recorded", 1)];
        assert_eq!(counts, want.map(|(c, n)| (c.to_string(), n)));
    }
}
