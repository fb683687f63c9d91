//! What the sections beyond the paper (the frontier, jitter and more scales)
//! share: their plot panels, RA's fixed-scale lines and their table cells.

use super::configs::{model_at, point, x};
use crate::config::PaperConfig;
use crate::figures::{Panel, Point, Series};
use crate::report::{Comparison, Stats, mean_sd_cell, paired_cell};
use crate::results::Results;
use sim::sweep::stats::Paired;

/// Three panels (success, runs with a collision, red lights per run) of
/// labelled lines of (x, group statistics); switchers dashed.
pub(super) fn safety_panels(lines: &[(String, Vec<(f64, Stats)>)], x_label: &str) -> [Panel; 3] {
    let series = |f: &dyn Fn(&Stats) -> Point| -> Vec<Series> {
        lines
            .iter()
            .map(|(label, pts)| Series {
                label: label.clone(),
                points: pts.iter().map(|(x, s)| Point { x: *x, ..f(s) }).collect(),
                dashed: label.contains("switcher"),
            })
            .collect()
    };
    let panel = |title: &str, y_label: &str, f: &dyn Fn(&Stats) -> Point, y_range| Panel {
        title: title.into(),
        x_label: x_label.into(),
        y_label: y_label.into(),
        series: series(f),
        y_range,
        paper: Vec::new(),
    };
    [
        panel(
            "Success",
            "success %",
            &|s| point(0.0, s.success_pct(), s.success_ci),
            Some((0.0, 105.0)),
        ),
        panel(
            "Runs with a collision",
            "collided %",
            &|s| point(0.0, s.collision_pct(), s.collision_ci),
            Some((0.0, 105.0)),
        ),
        panel(
            "Red lights",
            "red lights per run",
            &|s| point(0.0, s.red.0, s.red_ci),
            None,
        ),
    ]
}

/// RA at each fixed scale over every injected delay (its worst-case latency),
/// a plot line per scale labelled "RA fixed 0.75x{suffix}".
pub(super) fn ra_fixed_lines(
    cfg: &PaperConfig,
    results: &Results,
    suffix: &str,
) -> Vec<(String, Vec<(f64, Stats)>)> {
    [cfg.low, cfg.high]
        .into_iter()
        .map(|scale| {
            let pts = cfg
                .delays_ms
                .iter()
                .map(|&d| (d, model_at(cfg, true, scale, d).stats(cfg, results, None)))
                .filter(|(_, s)| s.n > 0)
                .collect();
            (format!("RA fixed {}{suffix}", x(scale)), pts)
        })
        .collect()
}

/// Success and collision rates, red lights per run (with its interval) and
/// lane crossings per run: the outcome columns of the extension tables.
pub(super) fn outcome_cells(s: &Stats) -> [String; 4] {
    [
        s.success_cell(),
        s.collided_cell(),
        s.red_cell(),
        mean_sd_cell(s.lane, s.n),
    ]
}

/// The paired success, collision and red-light cells of a comparison ("–" without one).
pub(super) fn paired_cells(c: Option<&Comparison>) -> [String; 3] {
    let cell = |f: fn(&Comparison) -> &Paired| c.map_or("–".into(), |c| paired_cell(f(c)));
    [
        cell(|c| &c.success),
        cell(|c| &c.collided),
        cell(|c| &c.red),
    ]
}
