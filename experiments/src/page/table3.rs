//! Table III: the scale switchers against the fixed scales under the same
//! worst-case latency.

use super::configs::{Config, x};
use super::reference;
use super::writer::Writer;
use crate::PaperError;
use crate::config::PaperConfig;
use crate::report::{Cells, Comparison, Table, mean_sd_cell, paired_cell};
use crate::results::Results;
use crate::units::{Driver, Unit, selector_name};
use sim::scenario::SelectorKind;

/// Table III: the switchers against the fixed scales under each envelope.
pub(super) fn table3(
    cfg: &PaperConfig,
    results: &Results,
    w: &mut Writer,
) -> Result<String, PaperError> {
    let mut t = Table::new(&[
        "envelope",
        "configuration",
        "runs",
        "success % [95 % CI]",
        "collided % [95 % CI]",
        "lane crossings per run",
        "red lights (total)",
        "time at the high scale %",
        "max latency (ms)",
        "paper: success / collided % / lane / red",
    ]);
    let mut cells = Cells::new();
    let mut paired_t = Table::new(&[
        "envelope",
        "comparison (b - a)",
        "red lights per run",
        "collided (0/1)",
        "success (0/1)",
        "lane crossings per run",
    ]);
    for e in &cfg.envelopes {
        let fixed_low = Config {
            label: format!("fixed {} @ {} ms", x(cfg.low), e.low_ms),
            unit: Unit::fixed(Driver::Ra, e.low_ms),
            scale: Some(cfg.low),
        };
        let fixed_high = Config {
            label: format!("fixed {} @ {} ms", x(cfg.high), e.high_ms),
            unit: Unit::fixed(Driver::Ra, e.high_ms),
            scale: Some(cfg.high),
        };
        let switch = |s: SelectorKind| Config {
            label: format!(
                "RA {} switcher ({}/{} ms)",
                selector_name(s),
                e.low_ms,
                e.high_ms
            ),
            unit: Unit::switch(s, *e),
            scale: None,
        };
        let oracle = switch(SelectorKind::Oracle);
        let lookahead = switch(SelectorKind::Lookahead);
        let learned = cfg
            .selectors()
            .contains(&SelectorKind::Learned)
            .then(|| switch(SelectorKind::Learned));
        let braking = switch(SelectorKind::Braking);
        let theirs = reference::TABLE3
            .iter()
            .find(|(env, _)| *env == (e.high_ms, e.low_ms))
            .map(|(_, v)| v);
        let mut rows = vec![
            (&fixed_low, theirs.map(|v| v[0])),
            (&oracle, theirs.map(|v| v[1])),
            (&lookahead, None),
        ];
        if let Some(l) = &learned {
            rows.push((l, None));
        }
        rows.push((&braking, None));
        rows.push((&fixed_high, theirs.map(|v| v[2])));
        for (c, paper_row) in rows {
            let s = c.stats(cfg, results, None);
            cells.push(
                &format!("{} [{}]", c.label, e.label()),
                "all",
                None,
                c.scale,
                &s,
            );
            t.push(vec![
                e.label(),
                c.label.clone(),
                s.n.to_string(),
                s.success_cell(),
                s.collided_cell(),
                mean_sd_cell(s.lane, s.n),
                if s.n == 0 {
                    "–".into()
                } else {
                    s.red_total.to_string()
                },
                if c.scale.is_none() && s.n > 0 {
                    format!("{:.1}", s.high_share_pct)
                } else {
                    "–".into()
                },
                if s.n == 0 {
                    "–".into()
                } else {
                    format!("{}", s.max_latency_ms)
                },
                paper_row.map_or("–".into(), |(su, co, l, lsd, r)| {
                    format!("{su} / {co} / {l:.2} ± {lsd:.2} / {r}")
                }),
            ]);
        }
        let runs = |c: &Config| c.runs(cfg, results, None);
        let mut pairs = vec![
            (&fixed_low, &oracle),
            (&fixed_high, &oracle),
            (&oracle, &lookahead),
        ];
        if let Some(l) = &learned {
            pairs.push((&oracle, l));
        }
        pairs.extend([(&oracle, &braking), (&lookahead, &braking)]);
        for (a, b) in pairs {
            let c = Comparison::of(&runs(a), &runs(b));
            paired_t.push(vec![
                e.label(),
                format!("{} - {}", b.label, a.label),
                paired_cell(&c.red),
                paired_cell(&c.collided),
                paired_cell(&c.success),
                paired_cell(&c.lane),
            ]);
        }
    }
    w.cells("table3.csv", &cells)?;
    Ok(format!(
        "## Table III: scale switching against fixed scales under the same worst-case latency\n\n\
         The paper's oracle (0.75x by default, 1.0x within 5 m of a light's stop line, back beyond 15 m) \
         and, past the paper, the map-lookahead selector (switches up at a distance derived from speed \
         and latency, before the light), the braking lookahead (up before the braking point as well: \
         the stopping distance at 3 m/s^2 is added, so the high scale decides the stop) and the learned trigger (a logistic head on the RA network's \
         pooled feature, fit to the frames where acting on the low-scale branch loses the most value by the labels, or where the two branches disagree most, as its card says; no map; `mrdrive policy trigger`). Fixed rows are the RA model at one scale with D = its latency.\n\n{}\n\
         Paired over the same route, density and seed:\n\n{}\nWhether the switcher beats both fixed \
         scales is judged in the shapes section, by the registered rule.\n\nFiles: `table3.csv`.\n",
        t.markdown(),
        paired_t.markdown(),
    ))
}
