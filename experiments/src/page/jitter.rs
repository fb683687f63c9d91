//! Beyond the paper: fixed scales and switchers as the execution latency
//! spreads.

use super::beyond::{outcome_cells, safety_panels};
use super::configs::{Config, x};
use super::writer::Writer;
use crate::PaperError;
use crate::config::PaperConfig;
use crate::report::{Cells, Stats, Table};
use crate::results::Results;
use crate::units::{Driver, Unit, selector_name};
use sim::scenario::SelectorKind;

/// Beyond the paper: fixed scales and switchers under the first envelope as
/// the execution latency spreads.
pub(super) fn jitter(
    cfg: &PaperConfig,
    results: &Results,
    w: &mut Writer,
) -> Result<String, PaperError> {
    let Some(e) = cfg.envelopes.first().copied() else {
        return Ok(String::new());
    };
    let sigmas: Vec<f64> = std::iter::once(0.0)
        .chain(cfg.jitters.iter().copied())
        .collect();
    let configs_at = |j: f64| -> Vec<Config> {
        let sw = |s: SelectorKind| Config {
            label: format!("RA {} switcher", selector_name(s)),
            unit: Unit::jittered(s, e, j),
            scale: None,
        };
        let fixed = |scale: f64, ms: f64| Config {
            label: format!("fixed {} @ {ms} ms", x(scale)),
            unit: if j == 0.0 {
                Unit::fixed(Driver::Ra, ms)
            } else {
                Unit::jittered(SelectorKind::Fixed, e, j)
            },
            scale: Some(scale),
        };
        vec![
            fixed(cfg.low, e.low_ms),
            sw(SelectorKind::Oracle),
            sw(SelectorKind::Lookahead),
            fixed(cfg.high, e.high_ms),
        ]
    };
    let mut t = Table::new(&[
        "sigma",
        "configuration",
        "runs",
        "success %",
        "collided %",
        "red lights per run",
        "lane crossings per run",
        "max latency (ms)",
    ]);
    let mut cells = Cells::new();
    let mut lines: Vec<(String, Vec<(f64, Stats)>)> = configs_at(0.0)
        .into_iter()
        .map(|c| (c.label, Vec::new()))
        .collect();
    for &j in &sigmas {
        for (k, c) in configs_at(j).into_iter().enumerate() {
            let s = c.stats(cfg, results, None);
            cells.push(
                &format!("{} [sigma {j}]", c.label),
                "all",
                None,
                c.scale,
                &s,
            );
            let max_latency = if s.n == 0 {
                "–".into()
            } else {
                format!("{:.0}", s.max_latency_ms)
            };
            t.push(
                [j.to_string(), c.label.clone(), s.n.to_string()]
                    .into_iter()
                    .chain(outcome_cells(&s))
                    .chain([max_latency])
                    .collect(),
            );
            if s.n > 0 {
                lines[k].1.push((j, s));
            }
        }
    }
    w.cells("jitter.csv", &cells)?;
    w.plot(
        "jitter",
        &safety_panels(&lines, "latency jitter sigma (log-normal)"),
        1500,
        480,
    )?;
    Ok(format!(
        "## Beyond the paper: latency jitter ({})\n\n\
         Each control boundary draws its latency as `Lexec(scale) x` a log-normal factor with mean 1 \
         and the given sigma (`timing.latency_jitter`, seeded by the run's seed, so runs stay \
         reproducible); the period stretches with it (Tloop = max(Tc, L)). Sigma 0 is Table III.\n\n\
         ![jitter](jitter.png)\n\n{}\nFiles: `jitter.png`, `jitter.svg`, `jitter.csv`.\n",
        e.label(),
        t.markdown()
    ))
}
