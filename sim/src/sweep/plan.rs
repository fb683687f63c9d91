//! The runs of a sweep and how they are cut into shards.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::SweepError;
use crate::build::Overrides;

/// One run of a sweep: a scenario file and the settings that override it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSpec {
    /// The scenario file.
    pub scenario: PathBuf,
    /// Injected delay (milliseconds); `None` keeps the scenario's.
    pub delay_ms: Option<f64>,
    /// Input scale (fraction of S0); `None` keeps the scenario's selector.
    pub scale: Option<f64>,
    /// Target (vehicles, pedestrians); `None` keeps the scenario's.
    pub density: Option<(u32, u32)>,
    /// Traffic seed.
    pub seed: u64,
    /// Who drives, over the scenario's `[driver]`; `None` keeps the scenario's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub driver: Option<crate::scenario::DriverSpec>,
}

impl RunSpec {
    /// A file-name-safe key, unique within a sweep.
    pub fn key(&self) -> String {
        let stem = self
            .scenario
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let scale = self.scale.map_or("sel".to_string(), |s| format!("{s:.3}"));
        let delay = self
            .delay_ms
            .map_or("sc".to_string(), |d| format!("{:03}", d.round() as u64));
        let density = self
            .density
            .map_or("sc".to_string(), |(v, p)| format!("v{v}p{p}"));
        format!("{stem}__d{delay}_s{scale}_{density}_seed{}", self.seed)
    }

    /// The delay, seed and density of this run as overrides of its scenario
    /// (the scale goes to the selector).
    pub fn overrides(&self) -> Overrides {
        Overrides {
            delay_ms: self.delay_ms,
            seed: Some(self.seed),
            vehicles: self.density.map(|d| d.0),
            pedestrians: self.density.map(|d| d.1),
            driver: self.driver.clone(),
        }
    }
}

/// The axes of a sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepPlan {
    /// Every run, in a fixed order.
    pub runs: Vec<RunSpec>,
}

impl SweepPlan {
    /// The cross product, scenarios outermost, seeds innermost.
    pub fn cross(
        scenarios: &[PathBuf],
        delays_ms: &[Option<f64>],
        scales: &[Option<f64>],
        densities: &[Option<(u32, u32)>],
        seeds: &[u64],
    ) -> Self {
        let mut runs = Vec::new();
        for scenario in scenarios {
            for &delay_ms in delays_ms {
                for &scale in scales {
                    for &density in densities {
                        for &seed in seeds {
                            runs.push(RunSpec {
                                scenario: scenario.clone(),
                                delay_ms,
                                scale,
                                density,
                                seed,
                                driver: None,
                            });
                        }
                    }
                }
            }
        }
        Self { runs }
    }

    /// The cross product of the lists a command line gives (`mrdrive sweep`):
    /// an empty list of delays, scales or densities keeps each scenario's;
    /// `driver`, when given, drives every run over the scenarios' own.
    pub fn of_lists(
        scenarios: &[PathBuf],
        delays_ms: &[f64],
        scales: &[f64],
        densities: &[(u32, u32)],
        seeds: &[u64],
        driver: Option<&crate::scenario::DriverSpec>,
    ) -> Self {
        fn or_scenarios<T: Copy>(v: &[T]) -> Vec<Option<T>> {
            if v.is_empty() {
                vec![None]
            } else {
                v.iter().copied().map(Some).collect()
            }
        }
        let mut plan = Self::cross(
            scenarios,
            &or_scenarios(delays_ms),
            &or_scenarios(scales),
            &or_scenarios(densities),
            seeds,
        );
        for r in &mut plan.runs {
            r.driver = driver.cloned();
        }
        plan
    }

    /// The runs of shard `index` of `count` (every `count`-th run from `index`).
    pub fn shard(&self, index: usize, count: usize) -> Vec<&RunSpec> {
        self.runs
            .iter()
            .enumerate()
            .filter(|(i, _)| i % count.max(1) == index)
            .map(|(_, r)| r)
            .collect()
    }
}

/// Parses `i/n` for `--shard`.
pub fn parse_shard(text: &str) -> Result<(usize, usize), SweepError> {
    let bad = |problem| SweepError::Shard {
        text: text.to_string(),
        problem,
    };
    let (i, n) = text.split_once('/').ok_or_else(|| bad("no `/`"))?;
    let i: usize = i.trim().parse().map_err(|_| bad("INDEX is not a number"))?;
    let n: usize = n.trim().parse().map_err(|_| bad("COUNT is not a number"))?;
    if n == 0 || i >= n {
        return Err(bad("INDEX is not below COUNT"));
    }
    Ok((i, n))
}

/// Parses `--seeds`: numbers, comma-separated, or a range `A..B` (B excluded).
pub fn parse_seeds(text: &str) -> Result<Vec<u64>, SweepError> {
    let bad = |problem, source| SweepError::Axis {
        flag: "seeds",
        text: text.to_string(),
        problem,
        source,
    };
    if let Some((a, b)) = text.split_once("..") {
        let a: u64 = a
            .trim()
            .parse()
            .map_err(|e| bad("the range start must be a number", Some(e)))?;
        let b: u64 = b
            .trim()
            .parse()
            .map_err(|e| bad("the range end must be a number", Some(e)))?;
        if a >= b {
            return Err(bad("the range is empty", None));
        }
        return Ok((a..b).collect());
    }
    text.split(',')
        .map(|s| {
            s.trim()
                .parse()
                .map_err(|e| bad("seeds are numbers", Some(e)))
        })
        .collect()
}

/// Parses one traffic density of `--densities`: `VEHICLES:PEDESTRIANS`.
pub fn parse_density(text: &str) -> Result<(u32, u32), SweepError> {
    let bad = |problem, source| SweepError::Axis {
        flag: "densities",
        text: text.to_string(),
        problem,
        source,
    };
    let (v, p) = text
        .split_once(':')
        .ok_or_else(|| bad("write VEHICLES:PEDESTRIANS, e.g. 20:40", None))?;
    Ok((
        v.trim()
            .parse()
            .map_err(|e| bad("VEHICLES must be a number", Some(e)))?,
        p.trim()
            .parse()
            .map_err(|e| bad("PEDESTRIANS must be a number", Some(e)))?,
    ))
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::plan;
    use super::*;

    #[test]
    fn cross_product_has_every_combination_with_unique_keys() {
        let p = plan();
        assert_eq!(p.runs.len(), 2 * 2 * 2 * 2 * 2);
        let keys: std::collections::BTreeSet<String> = p.runs.iter().map(RunSpec::key).collect();
        assert_eq!(keys.len(), p.runs.len());
    }

    #[test]
    fn empty_lists_keep_the_scenarios_settings() {
        let expert = crate::scenario::DriverSpec::default();
        let p = SweepPlan::of_lists(
            &["a.toml".into()],
            &[],
            &[0.75, 1.0],
            &[],
            &[0, 1],
            Some(&expert),
        );
        assert_eq!(p.runs.len(), 4);
        assert!(
            p.runs
                .iter()
                .all(|r| r.delay_ms.is_none() && r.density.is_none())
        );
        assert!(p.runs.iter().all(|r| r.driver.as_ref() == Some(&expert)));
        assert_eq!((p.runs[1].scale, p.runs[1].seed), (Some(0.75), 1));
    }

    #[test]
    fn shards_partition_the_plan() {
        let p = plan();
        let mut all: Vec<String> = (0..3)
            .flat_map(|i| p.shard(i, 3))
            .map(RunSpec::key)
            .collect();
        all.sort();
        let mut want: Vec<String> = p.runs.iter().map(RunSpec::key).collect();
        want.sort();
        assert_eq!(all, want);
        assert_eq!(parse_shard("1/4").unwrap(), (1, 4));
        let e = parse_shard("4/4").unwrap_err().to_string();
        assert!(e.contains("--shard 4/4") && e.contains("below"), "{e}");
        assert!(parse_shard("x").is_err());
    }

    #[test]
    fn seeds_are_a_list_or_a_range_and_densities_two_numbers() {
        assert_eq!(parse_seeds("3").unwrap(), vec![3]);
        assert_eq!(parse_seeds("0, 2,5").unwrap(), vec![0, 2, 5]);
        assert_eq!(parse_seeds("2..5").unwrap(), vec![2, 3, 4]);
        let e = parse_seeds("5..5").unwrap_err().to_string();
        assert_eq!(e, "--seeds 5..5: the range is empty");
        let e = parse_seeds("1,x").unwrap_err();
        assert_eq!(e.to_string(), "--seeds 1,x: seeds are numbers");
        assert!(std::error::Error::source(&e).is_some());
        assert_eq!(parse_density(" 20 : 40").unwrap(), (20, 40));
        let e = parse_density("20").unwrap_err().to_string();
        assert_eq!(e, "--densities 20: write VEHICLES:PEDESTRIANS, e.g. 20:40");
        let e = parse_density("20:many").unwrap_err().to_string();
        assert_eq!(e, "--densities 20:many: PEDESTRIANS must be a number");
    }

    #[test]
    fn a_spec_overrides_delay_seed_and_density() {
        let spec = &plan().runs[31];
        let o = spec.overrides();
        assert_eq!(o.delay_ms, Some(100.0));
        assert_eq!(o.seed, Some(2));
        assert_eq!((o.vehicles, o.pedestrians), (Some(5), Some(10)));
        assert_eq!(o.driver, None);
        // A driver named for the sweep replaces the scenario's, and survives the plan file.
        let policy = crate::scenario::DriverSpec {
            kind: crate::scenario::DriverKind::Policy,
            checkpoint: Some("models/ra.safetensors".into()),
            device: None,
            trigger: None,
        };
        let spec = RunSpec {
            driver: Some(policy.clone()),
            ..spec.clone()
        };
        let json = serde_json::to_string(&spec).unwrap();
        let back: RunSpec = serde_json::from_str(&json).unwrap();
        assert_eq!(back, spec);
        let scenario = crate::scenario::Scenario::from_toml_str(
            "[map]\nfile = \"m.xodr\"\n[route]\nfile = \"r.toml\"\nid = 0\n",
            std::path::Path::new("/s"),
        )
        .unwrap();
        assert_eq!(scenario.driver.kind, crate::scenario::DriverKind::Expert);
        assert_eq!(spec.overrides().apply(&scenario).driver, policy);
    }
}
