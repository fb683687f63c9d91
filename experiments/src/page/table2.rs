//! Table II: success and collisions per town at the first delay, with the
//! expert, and RA paired against NRA at each scale.

use super::configs::{Config, model_at, x};
use super::reference;
use super::writer::Writer;
use crate::PaperError;
use crate::config::PaperConfig;
use crate::report::{Cells, Comparison, Stats, Table, mean_sd_cell, paired_cell};
use crate::results::Results;
use crate::units::{Driver, Unit};

/// The configurations of Table II, in its column order.
fn table2_configs(cfg: &PaperConfig) -> Vec<Config> {
    let d0 = cfg.delays_ms.first().copied().unwrap_or(0.0);
    let c = |label: String, driver, scale| Config {
        label,
        unit: Unit::fixed(driver, d0),
        scale,
    };
    vec![
        c("Expert".into(), Driver::Expert, None),
        c("Original".into(), Driver::Original, Some(cfg.high)),
        c(format!("NRA {}", x(cfg.low)), Driver::NraLow, Some(cfg.low)),
        c(
            format!("NRA {}", x(cfg.high)),
            Driver::NraHigh,
            Some(cfg.high),
        ),
        c(format!("RA {}", x(cfg.low)), Driver::Ra, Some(cfg.low)),
        c(format!("RA {}", x(cfg.high)), Driver::Ra, Some(cfg.high)),
    ]
}

/// Table II: success and collisions per town at D = 0, with the expert.
pub(super) fn table2(
    cfg: &PaperConfig,
    results: &Results,
    w: &mut Writer,
) -> Result<String, PaperError> {
    let configs = table2_configs(cfg);
    let mut header = vec!["town", "row"];
    header.extend(configs.iter().map(|c| c.label.as_str()));
    let mut t = Table::new(&header);
    let mut cells = Cells::new();
    let d0 = cfg.delays_ms.first().copied();
    for town in cfg.towns() {
        let stats: Vec<Stats> = configs
            .iter()
            .map(|c| c.stats(cfg, results, Some(&town)))
            .collect();
        for (c, s) in configs.iter().zip(&stats) {
            cells.push(&c.label, &town, d0, c.scale, s);
        }
        let paper_success = reference::TABLE2_SUCCESS.iter().find(|(t, _)| *t == town);
        let paper_coll = reference::TABLE2_COLLISIONS
            .iter()
            .find(|(t, _)| *t == town);
        let row = |name: &str, f: &dyn Fn(&Stats) -> String| -> Vec<String> {
            let mut r = vec![town.clone(), name.to_string()];
            r.extend(stats.iter().map(f));
            r
        };
        t.push(row("success % [95 % CI]", &|s| s.success_cell()));
        if let Some((_, v)) = paper_success {
            let mut r = vec![town.clone(), "success %, paper (6 runs)".into(), "–".into()];
            r.extend(v.iter().map(|x| format!("{x:.0}")));
            t.push(r);
        }
        t.push(row("runs with a collision", &|s| {
            if s.n == 0 {
                "–".into()
            } else {
                format!("{}/{} ({})", s.collided, s.n, s.collided_cell())
            }
        }));
        if let Some((_, v)) = paper_coll {
            let mut r = vec![
                town.clone(),
                "collision incidence, paper (of 6)".into(),
                "–".into(),
            ];
            r.extend(v.iter().map(|x| x.to_string()));
            t.push(r);
        }
        t.push(row("red lights (total)", &|s| {
            if s.n == 0 {
                "–".into()
            } else {
                s.red_total.to_string()
            }
        }));
        t.push(row("lane crossings per run", &|s| {
            mean_sd_cell(s.lane, s.n)
        }));
        t.push(row("route completion %", &|s| {
            mean_sd_cell(s.completion, s.n)
        }));
    }
    w.cells("table2.csv", &cells)?;
    let mut s = format!(
        "## Table II: driving performance at Tc = 50 ms, D = {} ms\n\n{}\n",
        d0.unwrap_or(0.0),
        t.markdown()
    );
    // RA vs NRA at each scale, over both towns, pair by pair.
    s += "**RA against NRA** (the paper: \"the two RA configurations with a single shared model perform \
          similarly with the NRA baselines\"). Paired over every route, density and seed, RA - NRA:\n\n";
    let mut p = Table::new(&[
        "scale",
        "success (0/1)",
        "collided (0/1)",
        "red lights per run",
        "lane crossings per run",
    ]);
    for scale in [cfg.low, cfg.high] {
        let d = d0.unwrap_or(0.0);
        let nra = model_at(cfg, false, scale, d).runs(cfg, results, None);
        let ra = model_at(cfg, true, scale, d).runs(cfg, results, None);
        let c = Comparison::of(&nra, &ra);
        p.push(vec![
            x(scale),
            paired_cell(&c.success),
            paired_cell(&c.collided),
            paired_cell(&c.red),
            paired_cell(&c.lane),
        ]);
    }
    s += &p.markdown();
    s += "\nFiles: `table2.csv`.\n";
    Ok(s)
}
