//! The closed-loop table of the training issue's bar (`mrdrive policy table`),
//! from one sweep folder per driver (`<sweeps>/<label>/`): per town, success,
//! runs with a collision, red-light infractions, lane crossings and route
//! completion.

use sim::monitors::InfractionKind::{LaneCrossing, RedLight};
use sim::record::RunRecord;
use sim::sweep::{SweepDir, SweepError, read_records};
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// One row: a driver (the sweep folder's name) in one town.
#[derive(Debug, Clone, PartialEq)]
pub struct BarRow {
    /// The sweep folder's name, e.g. `ra@0.75`.
    pub label: String,
    /// The town (the scenario name before `_route`).
    pub town: String,
    /// Runs.
    pub runs: usize,
    /// Successful runs.
    pub success: usize,
    /// Runs with at least one collision.
    pub collision_runs: usize,
    /// Red-light infractions, summed.
    pub red_lights: u32,
    /// Lane crossings, summed.
    pub lane_crossings: u32,
    /// Mean route completion (percent).
    pub completion_pct: f64,
}

/// What can go wrong reading the sweep folders.
#[derive(Debug, thiserror::Error)]
pub enum BarError {
    /// The folder of sweep folders could not be listed.
    #[error("{}: cannot list the sweep folders", path.display())]
    List {
        /// The folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A sweep folder's records could not be read.
    #[error("{}: cannot read the records", path.display())]
    Records {
        /// The sweep folder.
        path: PathBuf,
        /// Why (boxed: a sweep error is large, and this one is rare).
        #[source]
        source: Box<SweepError>,
    },
}

/// The town of a scenario name: `town01_route0` -> `town01`.
fn town_of(scenario: &str) -> String {
    scenario
        .split_once("_route")
        .map_or(scenario, |(t, _)| t)
        .to_string()
}

/// The rows of `records` labelled `label`, one per town (in name order).
pub fn rows(label: &str, records: &[RunRecord]) -> Vec<BarRow> {
    let mut by_town: BTreeMap<String, Vec<&RunRecord>> = BTreeMap::new();
    for r in records {
        by_town
            .entry(town_of(&r.result.provenance.scenario))
            .or_default()
            .push(r);
    }
    by_town
        .into_iter()
        .map(|(town, rs)| BarRow {
            label: label.to_string(),
            town,
            runs: rs.len(),
            success: rs.iter().filter(|r| r.result.success).count(),
            collision_runs: rs.iter().filter(|r| r.result.collisions() > 0).count(),
            red_lights: rs.iter().map(|r| r.result.count(RedLight)).sum(),
            lane_crossings: rs.iter().map(|r| r.result.count(LaneCrossing)).sum(),
            completion_pct: rs.iter().map(|r| r.result.completion_pct).sum::<f64>()
                / rs.len().max(1) as f64,
        })
        .collect()
}

/// Reads every sweep folder under `sweeps` (sorted by name) into rows.
pub fn read(sweeps: &Path) -> Result<Vec<BarRow>, BarError> {
    let mut dirs: Vec<_> = std::fs::read_dir(sweeps)
        .map_err(|source| BarError::List {
            path: sweeps.to_path_buf(),
            source,
        })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("plan.json").exists())
        .collect();
    dirs.sort();
    let mut out = Vec::new();
    for d in dirs {
        let label = d
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        let records =
            read_records(&SweepDir { root: d.clone() }).map_err(|source| BarError::Records {
                path: d.clone(),
                source: Box::new(source),
            })?;
        out.extend(rows(&label, &records));
    }
    Ok(out)
}

/// The rows as a Markdown table.
pub fn markdown(rows: &[BarRow]) -> String {
    let mut s = String::from(
        "| driver | town | success | runs with a collision | red lights | lane crossings | route % |\n| --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {}/{} | {}/{} | {} | {} | {:.1} |",
            r.label,
            r.town,
            r.success,
            r.runs,
            r.collision_runs,
            r.runs,
            r.red_lights,
            r.lane_crossings,
            r.completion_pct
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn towns_come_from_scenario_names() {
        assert_eq!(town_of("town01_route0"), "town01");
        assert_eq!(town_of("town02_route1"), "town02");
        assert_eq!(town_of("default"), "default");
    }

    #[test]
    fn an_empty_sweeps_folder_gives_an_empty_table_and_a_missing_one_an_error() {
        let dir = tempfile::tempdir().unwrap();
        assert!(read(dir.path()).unwrap().is_empty());
        let e = read(&dir.path().join("nope")).unwrap_err().to_string();
        assert!(e.contains("nope"), "{e}");
        assert_eq!(markdown(&[]).lines().count(), 2);
    }
}
