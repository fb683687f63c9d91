//! Figs. 3 and 4: red-light infractions and lane crossings against the input
//! scale at the first two delays.

use super::configs::{model_at, point, x};
use super::writer::Writer;
use crate::PaperError;
use crate::config::PaperConfig;
use crate::figures::{Panel, Series};
use crate::report::{Cells, Comparison, Stats, Table, paired_cell};
use crate::results::{Results, Run};

/// Fig. 3 (red lights, `red` = true) or Fig. 4 (lane crossings) against scale at the first two delays.
pub(super) fn fig34(
    cfg: &PaperConfig,
    results: &Results,
    w: &mut Writer,
    red: bool,
) -> Result<String, PaperError> {
    let (id, what, unit) = if red {
        ("fig3", "red-light infractions", "red lights per run")
    } else {
        ("fig4", "lane crossings", "lane crossings per run")
    };
    let delays: Vec<f64> = cfg.delays_ms.iter().copied().take(2).collect();
    let mut cells = Cells::new();
    let mut series = Vec::new();
    let mut t = Table::new(&[
        "model",
        "D (ms)",
        &format!("{} [95 % CI]", x(cfg.low)),
        &format!("{} [95 % CI]", x(cfg.high)),
        "total low / high",
        &format!("paired {} - {}", x(cfg.low), x(cfg.high)),
    ]);
    for ra in [false, true] {
        for &d in &delays {
            let lo_cfg = model_at(cfg, ra, cfg.low, d);
            let hi_cfg = model_at(cfg, ra, cfg.high, d);
            let (lo_runs, hi_runs) = (
                lo_cfg.runs(cfg, results, None),
                hi_cfg.runs(cfg, results, None),
            );
            let (sl, sh) = (Stats::of(&lo_runs, cfg.high), Stats::of(&hi_runs, cfg.high));
            cells.push(&lo_cfg.label, "all", Some(d), Some(cfg.low), &sl);
            cells.push(&hi_cfg.label, "all", Some(d), Some(cfg.high), &sh);
            let metric = |s: &Stats| {
                if red {
                    (s.red, s.red_ci)
                } else {
                    (s.lane, s.lane_ci)
                }
            };
            let total = |s: &Stats, runs: &[&Run]| -> f64 {
                if red {
                    f64::from(s.red_total)
                } else {
                    runs.iter()
                        .map(|r| {
                            f64::from(
                                r.record
                                    .result
                                    .count(sim::monitors::InfractionKind::LaneCrossing),
                            )
                        })
                        .sum()
                }
            };
            let label = format!("{}, D = {d} ms", if ra { "RA" } else { "NRA" });
            let mut points = Vec::new();
            for (scale, s) in [(cfg.low, &sl), (cfg.high, &sh)] {
                if s.n > 0 {
                    let ((m, _), ci) = metric(s);
                    points.push(point(scale, m, ci));
                }
            }
            series.push(Series {
                label: label.clone(),
                points,
                dashed: d > 0.0,
            });
            // low - high: positive means more at the low scale.
            let c = Comparison::of(&hi_runs, &lo_runs);
            let pair = if red { &c.red } else { &c.lane };
            let cell = |s: &Stats| {
                let ((m, _), ci) = metric(s);
                if s.n == 0 {
                    "–".into()
                } else {
                    let interval = crate::report::interval_text(ci, 2);
                    format!("{m:.2} {interval} (n = {})", s.n)
                }
            };
            t.push(vec![
                if ra { "RA" } else { "NRA" }.into(),
                d.to_string(),
                cell(&sl),
                cell(&sh),
                format!("{:.0} / {:.0}", total(&sl, &lo_runs), total(&sh, &hi_runs)),
                paired_cell(pair),
            ]);
        }
    }
    w.cells(&format!("{id}.csv"), &cells)?;
    w.plot(
        id,
        &[Panel {
            title: format!("{} against input scale, Tc = 50 ms", capitalise(what)),
            x_label: "input scale (fraction of S0)".into(),
            y_label: format!("{unit} (mean, 95 % CI)"),
            series,
            y_range: None,
            paper: Vec::new(),
        }],
        800,
        500,
    )?;
    let claim = if red {
        "the paper: at Tc = 50 ms, with and without 50 ms of delay, 0.75x gives clearly more red-light infractions than 1.0x"
    } else {
        "the paper: lane invasions barely change with the scale"
    };
    Ok(format!(
        "## {}: {} against scale ({claim})\n\n![{id}]({id}.png)\n\nThe paper's figure gives \
         no values in its text, so none are drawn beside ours.\n\n{}\nFiles: `{id}.png`, `{id}.svg`, `{id}.csv`.\n",
        if red { "Fig. 3" } else { "Fig. 4" },
        what,
        t.markdown()
    ))
}

fn capitalise(s: &str) -> String {
    let mut c = s.chars();
    c.next().map_or(String::new(), |f| {
        f.to_uppercase().collect::<String>() + c.as_str()
    })
}
