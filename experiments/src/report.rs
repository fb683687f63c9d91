//! The statistics of a group of runs, and Tables I-III and the figures' data
//! as Markdown and CSV.
//!
//! Every interval is clustered at the route (issue 50): runs on one route share
//! much of what happens on it, so the route, not the run, is the unit an
//! interval treats as independent. A rate or a per-run mean carries a 95 %
//! Student t interval over its routes' means with G - 1 degrees of freedom
//! (`sim::sweep::cluster::cluster_t_interval`), clipped to the values the
//! outcome can take; with one route there is none. Configurations that share
//! routes, densities and seeds are compared pair by pair ([`Comparison`]) with
//! an exact test, whose p-value the page adjusts for the other tests it shows
//! ([`resolve_holm`]), and the same interval over the routes' mean differences.

use std::path::Path;

use sim::monitors::InfractionKind::{LaneCrossing, RedLight};
use sim::sweep::cluster::{cluster_ids, cluster_t_interval};
use sim::sweep::exact::holm;
use sim::sweep::stats::Paired;
use sim::sweep::tables::mean_sd;

use crate::PaperError;
use crate::results::Run;

/// A 95 % interval clustered at the route, (low, high); `None` with fewer than
/// two routes.
pub type Interval = Option<(f64, f64)>;

/// The 95 % t interval over the route means of `values` (`routes[i]` the route
/// of `values[i]`), clipped to `[floor, ceil]`. Its centre is the mean of the
/// route means, which is the plain mean when every route has as many runs (as
/// in the registered design).
fn route_interval(values: &[f64], routes: &[usize], (floor, ceil): (f64, f64)) -> Interval {
    cluster_t_interval(values, routes, 0.95).map(|(_, lo, hi)| (lo.max(floor), hi.min(ceil)))
}

/// "[0.17, 0.67]" with `digits` decimals, or "(1 route)" without an interval.
pub fn interval_text(ci: Interval, digits: usize) -> String {
    ci.map_or("(1 route)".into(), |(lo, hi)| {
        format!("[{lo:.digits$}, {hi:.digits$}]")
    })
}

/// What a group of runs did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Stats {
    /// Runs.
    pub n: usize,
    /// Runs that succeeded.
    pub success: usize,
    /// Runs with at least one collision.
    pub collided: usize,
    /// Red-light infractions over all runs.
    pub red_total: u32,
    /// The routes the runs were driven on.
    pub routes: usize,
    /// The success rate's interval (percent).
    pub success_ci: Interval,
    /// The interval of the rate of runs with a collision (percent).
    pub collision_ci: Interval,
    /// Red lights per run: mean, sd.
    pub red: (f64, f64),
    /// Its interval.
    pub red_ci: Interval,
    /// Lane crossings per run: mean, sd.
    pub lane: (f64, f64),
    /// Its interval.
    pub lane_ci: Interval,
    /// Route completion (percent): mean, sd.
    pub completion: (f64, f64),
    /// Mean share of control boundaries at the high scale (percent), for switchers.
    pub high_share_pct: f64,
    /// The largest latency in force in any run (milliseconds).
    pub max_latency_ms: f64,
}

impl Stats {
    /// The statistics of `runs`; `high` names the high scale for the share.
    pub fn of(runs: &[&Run], high: f64) -> Self {
        let n = runs.len();
        if n == 0 {
            return Stats::default();
        }
        let red: Vec<f64> = runs
            .iter()
            .map(|r| f64::from(r.record.result.count(RedLight)))
            .collect();
        let lane: Vec<f64> = runs
            .iter()
            .map(|r| f64::from(r.record.result.count(LaneCrossing)))
            .collect();
        let completion: Vec<f64> = runs
            .iter()
            .map(|r| r.record.result.completion_pct)
            .collect();
        let routes = cluster_ids(runs.iter().map(|r| r.route.clone()));
        let pct_of = |f: &dyn Fn(&Run) -> bool| -> Vec<f64> {
            runs.iter()
                .map(|r| if f(r) { 100.0 } else { 0.0 })
                .collect()
        };
        let success = pct_of(&|r| r.record.result.success);
        let collided = pct_of(&|r| r.record.result.collisions() > 0);
        let (rate, count) = ((0.0, 100.0), (0.0, f64::INFINITY));
        let high_key = crate::units::scale_label(high);
        let share: Vec<f64> = runs
            .iter()
            .map(|r| {
                r.record
                    .result
                    .scale_share
                    .iter()
                    .find(|(k, _)| {
                        k.parse::<f64>().is_ok_and(|s| (s - high).abs() < 1e-9) || **k == high_key
                    })
                    .map_or(0.0, |(_, v)| *v)
            })
            .collect();
        Stats {
            n,
            success: runs.iter().filter(|r| r.record.result.success).count(),
            collided: runs
                .iter()
                .filter(|r| r.record.result.collisions() > 0)
                .count(),
            red_total: runs.iter().map(|r| r.record.result.count(RedLight)).sum(),
            routes: routes.iter().max().map_or(0, |m| m + 1),
            success_ci: route_interval(&success, &routes, rate),
            collision_ci: route_interval(&collided, &routes, rate),
            red: mean_sd(&red),
            red_ci: route_interval(&red, &routes, count),
            lane: mean_sd(&lane),
            lane_ci: route_interval(&lane, &routes, count),
            completion: mean_sd(&completion),
            high_share_pct: 100.0 * mean_sd(&share).0,
            max_latency_ms: runs
                .iter()
                .map(|r| r.record.result.max_latency_ms)
                .fold(0.0, f64::max),
        }
    }

    /// Success (percent).
    pub fn success_pct(&self) -> f64 {
        pct(self.success, self.n)
    }

    /// Runs with a collision (percent).
    pub fn collision_pct(&self) -> f64 {
        pct(self.collided, self.n)
    }

    /// "83 [44, 97]": the success rate (percent) with its interval, or "–"
    /// without runs.
    pub fn success_cell(&self) -> String {
        self.rate_cell(self.success_pct(), self.success_ci)
    }

    /// "17 [0, 48]": the rate of runs with a collision (percent) with its
    /// interval, or "–" without runs.
    pub fn collided_cell(&self) -> String {
        self.rate_cell(self.collision_pct(), self.collision_ci)
    }

    /// "0.42 [0.17, 0.67]": red lights per run with its interval, or "–"
    /// without runs.
    pub fn red_cell(&self) -> String {
        if self.n == 0 {
            return "–".into();
        }
        format!("{:.2} {}", self.red.0, interval_text(self.red_ci, 2))
    }

    fn rate_cell(&self, pct: f64, ci: Interval) -> String {
        if self.n == 0 {
            return "–".into();
        }
        format!("{pct:.0} {}", interval_text(ci, 0))
    }
}

fn pct(k: usize, n: usize) -> f64 {
    if n == 0 {
        f64::NAN
    } else {
        100.0 * k as f64 / n as f64
    }
}

/// "1.50 ± 0.80": a mean and sd.
pub fn mean_sd_cell((m, sd): (f64, f64), n: usize) -> String {
    if n == 0 {
        "–".into()
    } else {
        format!("{m:.2} ± {sd:.2}")
    }
}

/// Configuration `b` against `a` on the runs they share (route, density, seed),
/// each difference with its exact p-value and its interval over the routes'
/// mean differences.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// Red lights per run, b - a.
    pub red: Paired,
    /// Lane crossings per run, b - a.
    pub lane: Paired,
    /// Collided (0/1) per run, b - a.
    pub collided: Paired,
    /// Succeeded (0/1) per run, b - a.
    pub success: Paired,
    /// The distinct routes the pairs were driven on.
    pub routes: usize,
}

impl Comparison {
    /// Pairs the runs of `a` and `b` that share route, density and seed.
    pub fn of(a: &[&Run], b: &[&Run]) -> Self {
        let mut pairs: Vec<(&Run, &Run)> = Vec::new();
        for x in a {
            if let Some(y) = b.iter().find(|y| y.pair_key() == x.pair_key()) {
                pairs.push((x, y));
            }
        }
        let col = |f: &dyn Fn(&Run) -> f64| -> (Vec<f64>, Vec<f64>) {
            (
                pairs.iter().map(|(x, _)| f(x)).collect(),
                pairs.iter().map(|(_, y)| f(y)).collect(),
            )
        };
        let routes: Vec<&String> = pairs.iter().map(|(x, _)| &x.route).collect();
        let cmp = |f: &dyn Fn(&Run) -> f64| {
            let (xa, xb) = col(f);
            Paired::by_route(&xa, &xb, &routes)
        };
        Comparison {
            red: cmp(&|r| f64::from(r.record.result.count(RedLight))),
            lane: cmp(&|r| f64::from(r.record.result.count(LaneCrossing))),
            collided: cmp(&|r| f64::from(u8::from(r.record.result.collisions() > 0))),
            success: cmp(&|r| f64::from(u8::from(r.record.result.success))),
            routes: cluster_ids(routes.iter())
                .into_iter()
                .max()
                .map_or(0, |m| m + 1),
        }
    }
}

/// "+0.42 [+0.17, +0.67] (36 pairs on 4 routes; 5 up, 0 down; p = 0.062⟦…⟧)": a
/// paired difference, its interval over the routes' mean differences and its
/// exact p-value, with a mark that [`resolve_holm`] turns into the page-wide
/// Holm-adjusted p (and a `*` where that is below 0.05) and CSV files drop.
pub fn paired_cell(p: &Paired) -> String {
    if p.n == 0 {
        return "–".into();
    }
    let (up, down, _) = p.better_worse_same;
    let interval =
        p.ci.map_or(String::new(), |(lo, hi)| format!(" [{lo:+.2}, {hi:+.2}]"));
    let routes = p.routes();
    format!(
        "{:+.2}{interval} ({} pairs on {routes} route{}; {up} up, {down} down; p {}{HOLM_OPEN}{:e}{HOLM_CLOSE})",
        p.mean_diff,
        p.n,
        if routes == 1 { "" } else { "s" },
        p_text(p.p),
        p.p,
    )
}

/// A p-value as the page writes it after "p", to two significant digits:
/// "= 0.25", "= 0.031", "= 0.0044", or "< 0.001".
pub fn p_text(p: f64) -> String {
    match p {
        p if p < 0.001 => "< 0.001".into(),
        p if p < 0.01 => format!("= {p:.4}"),
        p if p < 0.1 => format!("= {p:.3}"),
        p => format!("= {p:.2}"),
    }
}

const HOLM_OPEN: char = '⟦';
const HOLM_CLOSE: char = '⟧';

/// Replaces every mark [`paired_cell`] left in `text` with the Holm-adjusted
/// p-value of its test within the family of all the marked tests (", Holm p = 0.62",
/// or ", Holm p = 0.004 *" below 0.05); returns the text and the family's size. A
/// test shown twice counts twice, which can only make the adjustment stricter.
pub fn resolve_holm(text: &str) -> (String, usize) {
    let raw: Vec<f64> = marks(text).map(|(_, p)| p).collect();
    let adjusted = holm(&raw);
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    for q in &adjusted {
        let (start, end) = match (rest.find(HOLM_OPEN), rest.find(HOLM_CLOSE)) {
            (Some(s), Some(e)) => (s, e + HOLM_CLOSE.len_utf8()),
            _ => break,
        };
        out += &rest[..start];
        out += &format!(
            ", Holm p {}{}",
            p_text(*q),
            if *q < 0.05 { " *" } else { "" }
        );
        rest = &rest[end..];
    }
    out += rest;
    (out, raw.len())
}

/// Drops the Holm marks from a cell (for CSV files, which give the raw p).
pub fn strip_holm(cell: &str) -> String {
    let mut out = String::with_capacity(cell.len());
    let mut rest = cell;
    while let (Some(s), Some(e)) = (rest.find(HOLM_OPEN), rest.find(HOLM_CLOSE)) {
        out += &rest[..s];
        rest = &rest[e + HOLM_CLOSE.len_utf8()..];
    }
    out + rest
}

/// The marks in `text`, in order: (byte offset, raw p).
fn marks(text: &str) -> impl Iterator<Item = (usize, f64)> + '_ {
    text.match_indices(HOLM_OPEN).filter_map(move |(i, _)| {
        let body = &text[i + HOLM_OPEN.len_utf8()..];
        let end = body.find(HOLM_CLOSE)?;
        body[..end].parse().ok().map(|p| (i, p))
    })
}

/// A table: a header and rows of cells, written as Markdown or CSV.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    /// Column names.
    pub header: Vec<String>,
    /// Rows, each as long as the header.
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with these columns and no rows.
    pub fn new(header: &[&str]) -> Self {
        Table {
            header: header.iter().map(|s| s.to_string()).collect(),
            rows: Vec::new(),
        }
    }

    /// Adds a row.
    pub fn push(&mut self, row: Vec<String>) {
        debug_assert_eq!(row.len(), self.header.len());
        self.rows.push(row);
    }

    /// As a Markdown table.
    pub fn markdown(&self) -> String {
        let mut s = format!("| {} |\n|", self.header.join(" | "));
        s += &" --- |".repeat(self.header.len());
        s.push('\n');
        for r in &self.rows {
            s += &format!("| {} |\n", r.join(" | "));
        }
        s
    }

    /// Writes it as CSV to `path`.
    pub fn write_csv(&self, path: &Path) -> Result<(), PaperError> {
        let mut w = csv::Writer::from_path(path)?;
        w.write_record(&self.header)?;
        for r in &self.rows {
            w.write_record(r.iter().map(|c| strip_holm(c)))?;
        }
        w.flush().map_err(|e| PaperError::io("write", path, e))?;
        Ok(())
    }
}

/// The long-format CSV of a figure or table's groups: one row per group with
/// every statistic, the same columns for every experiment.
#[derive(Debug, Clone, Default)]
pub struct Cells {
    table: Table,
}

impl Cells {
    /// An empty list.
    pub fn new() -> Self {
        Cells {
            table: Table::new(&[
                "config",
                "town",
                "delay_ms",
                "scale",
                "runs",
                "success",
                "success_pct",
                "success_ci_low",
                "success_ci_high",
                "collided",
                "collision_pct",
                "collision_ci_low",
                "collision_ci_high",
                "red_lights_total",
                "red_lights_mean",
                "red_lights_sd",
                "red_lights_ci_low",
                "red_lights_ci_high",
                "lane_crossings_mean",
                "lane_crossings_sd",
                "lane_crossings_ci_low",
                "lane_crossings_ci_high",
                "completion_mean",
                "high_scale_share_pct",
                "max_latency_ms",
            ]),
        }
    }

    /// Adds a group.
    pub fn push(
        &mut self,
        config: &str,
        town: &str,
        delay_ms: Option<f64>,
        scale: Option<f64>,
        s: &Stats,
    ) {
        let f = |v: f64| format!("{v:.4}");
        let opt = |v: Option<f64>| v.map_or(String::new(), |x| x.to_string());
        let lo = |ci: Interval| ci.map_or(String::new(), |(l, _)| f(l));
        let hi = |ci: Interval| ci.map_or(String::new(), |(_, h)| f(h));
        self.table.push(vec![
            config.into(),
            town.into(),
            opt(delay_ms),
            opt(scale),
            s.n.to_string(),
            s.success.to_string(),
            f(s.success_pct()),
            lo(s.success_ci),
            hi(s.success_ci),
            s.collided.to_string(),
            f(s.collision_pct()),
            lo(s.collision_ci),
            hi(s.collision_ci),
            s.red_total.to_string(),
            f(s.red.0),
            f(s.red.1),
            lo(s.red_ci),
            hi(s.red_ci),
            f(s.lane.0),
            f(s.lane.1),
            lo(s.lane_ci),
            hi(s.lane_ci),
            f(s.completion.0),
            f(s.high_share_pct),
            f(s.max_latency_ms),
        ]);
    }

    /// Writes the CSV.
    pub fn write(&self, path: &Path) -> Result<(), PaperError> {
        self.table.write_csv(path)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use std::collections::BTreeMap;

    use sim::monitors::InfractionKind;
    use sim::record::*;
    use sim::sweep::RunSpec;

    use super::*;

    /// A finished run on `route` at density (5, 10) and `seed` with these
    /// outcomes, `high` the share of boundaries at 1.0x.
    pub fn run(
        route: &str,
        seed: u64,
        success: bool,
        collisions: u32,
        red: u32,
        lane: u32,
        high: f64,
    ) -> Run {
        let mut counts: BTreeMap<InfractionKind, u32> =
            InfractionKind::ALL.into_iter().map(|k| (k, 0)).collect();
        counts.insert(InfractionKind::CollisionVehicle, collisions);
        counts.insert(InfractionKind::RedLight, red);
        counts.insert(InfractionKind::LaneCrossing, lane);
        let spec = RunSpec {
            scenario: format!("scenarios/paper/{route}.toml").into(),
            delay_ms: Some(0.0),
            scale: None,
            density: Some((5, 10)),
            seed,
            driver: None,
        };
        Run {
            town: "Town01".into(),
            route: route.into(),
            spec,
            record: RunRecord {
                result: RunResult {
                    provenance: Provenance {
                        scenario: route.into(),
                        scenario_file: String::new(),
                        map: String::new(),
                        route: String::new(),
                        driver: "expert".into(),
                        build: "test".into(),
                        render_backend: "none".into(),
                        render_fingerprint: None,
                        cpu: None,
                        checkpoint: None,
                        trigger: None,
                    },
                    settings: RunSettings {
                        seed,
                        delay_ms: 0.0,
                        control_period_ms: 50.0,
                        resolution: "oracle".into(),
                        vehicles: 5,
                        pedestrians: 10,
                    },
                    traffic: RealisedTraffic {
                        vehicles: 5,
                        pedestrians: 10,
                        walkers_sent: 0,
                    },
                    completion_pct: if success { 100.0 } else { 50.0 },
                    success,
                    driving_score: 0.0,
                    outside_lane_pct: 0.0,
                    counts,
                    termination: None,
                    route_length_m: 100.0,
                    sim_time_s: 10.0,
                    ticks: 400,
                    scale_share: [("0.75".to_string(), 1.0 - high), ("1".to_string(), high)].into(),
                    max_latency_ms: 100.0,
                    infractions: Vec::new(),
                    collisions: Default::default(),
                    contacts: Vec::new(),
                    trace: Vec::new(),
                },
                perf: RunPerf::default(),
            },
        }
    }

    #[test]
    fn stats_count_rates_totals_and_the_time_at_the_high_scale() {
        let runs = [
            run("a", 0, true, 0, 2, 1, 0.2),
            run("a", 1, false, 3, 0, 3, 0.4),
            run("b", 0, true, 1, 1, 2, 0.0),
        ];
        let refs: Vec<&Run> = runs.iter().collect();
        let s = Stats::of(&refs, 1.0);
        assert_eq!((s.n, s.success, s.collided, s.red_total), (3, 2, 2, 3));
        assert_eq!(s.red, (1.0, 1.0));
        assert_eq!(s.lane, (2.0, 1.0));
        assert!(
            (s.high_share_pct - 20.0).abs() < 1e-9,
            "{}",
            s.high_share_pct
        );
        // Two routes: route a succeeds in 1 of 2 runs (50 %), route b in 1 of 1
        // (100 %): their mean 75 %, t with 1 degree of freedom, clipped to 0-100 %.
        assert_eq!(s.routes, 2);
        assert_eq!(s.success_ci, Some((0.0, 100.0)));
        assert_eq!(s.success_cell(), "67 [0, 100]");
        // Red lights: both routes average one a run, so the interval has no width.
        assert_eq!(s.red_ci, Some((1.0, 1.0)));
        assert_eq!(s.red_cell(), "1.00 [1.00, 1.00]");
        // One route: no interval.
        let one = Stats::of(&refs[..2], 1.0);
        assert_eq!((one.routes, one.success_ci), (1, None));
        assert_eq!(one.collided_cell(), "50 (1 route)");
        assert_eq!(Stats::default().success_cell(), "–");
        assert_eq!(Stats::of(&[], 1.0).n, 0);
    }

    #[test]
    fn a_comparison_pairs_runs_by_route_density_and_seed() {
        // b has one red light more than a on each shared run; a's extra run has no partner.
        let a = [
            run("a", 0, true, 0, 0, 0, 0.0),
            run("a", 1, true, 0, 1, 0, 0.0),
            run("c", 9, true, 0, 5, 0, 0.0),
        ];
        let b = [
            run("a", 1, true, 0, 2, 0, 0.0),
            run("a", 0, true, 1, 1, 0, 0.0),
        ];
        let (ra, rb): (Vec<&Run>, Vec<&Run>) = (a.iter().collect(), b.iter().collect());
        let c = Comparison::of(&ra, &rb);
        assert_eq!(c.red.n, 2);
        assert_eq!(c.red.mean_diff, 1.0);
        assert_eq!(c.red.better_worse_same, (2, 0, 0));
        assert_eq!(c.collided.mean_diff, 0.5);
        assert_eq!(c.success.better_worse_same, (0, 0, 2));
        assert_eq!(c.routes, 1);
        assert_eq!(
            strip_holm(&paired_cell(&c.red)),
            "+1.00 (2 pairs on 1 route; 2 up, 0 down; p = 0.50)"
        );
    }

    #[test]
    fn the_page_adjusts_every_marked_test_by_holm() {
        let up = |n: usize, of: usize| {
            let a = vec![0.0; of];
            let b: Vec<f64> = (0..of).map(|i| f64::from(u8::from(i < n))).collect();
            Paired::by_route(&a, &b, &(0..of).collect::<Vec<_>>())
        };
        // 12 of 12 up (p = 2^-11) and 3 of 3 up (p = 0.25): Holm multiplies the smaller by 2.
        let (strong, weak) = (up(12, 12), up(3, 3));
        let text = format!("a {}\nb {}\n", paired_cell(&strong), paired_cell(&weak));
        let (page, family) = resolve_holm(&text);
        assert_eq!(family, 2);
        assert_eq!(
            page,
            "a +1.00 [+1.00, +1.00] (12 pairs on 12 routes; 12 up, 0 down; p < 0.001, Holm p < 0.001 *)\n\
             b +1.00 [+1.00, +1.00] (3 pairs on 3 routes; 3 up, 0 down; p = 0.25, Holm p = 0.25)\n"
        );
        let (page, _) = resolve_holm(&paired_cell(&up(7, 8)));
        // 7 of 8 up: p = 2 / 2^7 = 0.0156 alone.
        assert!(page.ends_with("p = 0.016, Holm p = 0.016 *)"), "{page}");
        assert_eq!(resolve_holm("no tests"), ("no tests".to_string(), 0));
    }

    #[test]
    fn tables_write_markdown_and_csv() {
        let mut t = Table::new(&["a", "b"]);
        t.push(vec!["1".into(), "x, y".into()]);
        assert_eq!(t.markdown(), "| a | b |\n| --- | --- |\n| 1 | x, y |\n");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.csv");
        t.write_csv(&p).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "a,b\n1,\"x, y\"\n");
    }
}
