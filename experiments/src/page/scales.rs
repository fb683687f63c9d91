//! Beyond the paper: one RA network with a BN branch for more scales than
//! two.

use std::collections::BTreeMap;

use super::beyond::{outcome_cells, paired_cells, ra_fixed_lines, safety_panels};
use super::configs::{Config, model_at, x};
use super::writer::Writer;
use crate::PaperError;
use crate::config::PaperConfig;
use crate::report::{Cells, Comparison, Stats, Table};
use crate::results::Results;
use crate::units::{Driver, Unit, selector_name};
use sim::scenario::SelectorKind;

/// Beyond the paper: one RA network with a BN branch for every scale of the
/// ladder, each scale alone at the latency each envelope gives it, paired
/// with the two-scale RA where both have the scale.
pub(super) fn scales(
    cfg: &PaperConfig,
    results: &Results,
    w: &mut Writer,
) -> Result<String, PaperError> {
    let Some(file) = &cfg.models.ladder else {
        return Ok(String::new());
    };
    let name = Driver::Ladder.id(cfg).to_uppercase();
    let mut t = Table::new(&[
        "envelope",
        "configuration",
        "latency (ms)",
        "runs",
        "success %",
        "collided %",
        "red lights per run",
        "lane crossings per run",
        "paired vs two-scale RA: success",
        "collided",
        "red lights",
    ]);
    let mut cells = Cells::new();
    let mut lines: Vec<(String, Vec<(f64, Stats)>)> = Vec::new();
    let mut switch_lines: BTreeMap<String, Vec<(f64, Stats)>> = BTreeMap::new();
    for e in &cfg.envelopes {
        let mut pts = Vec::new();
        for &scale in &cfg.ladder {
            let latency = e.latency_ms_at(scale, cfg.low, cfg.high);
            let c = Config {
                label: format!("{name} {}", x(scale)),
                unit: Unit::ladder(*e),
                scale: Some(scale),
            };
            let runs = c.runs(cfg, results, None);
            let s = Stats::of(&runs, cfg.high);
            let two_scale = [cfg.low, cfg.high]
                .iter()
                .any(|&k| (k - scale).abs() < 1e-9)
                .then(|| {
                    let ra = model_at(cfg, true, scale, latency).runs(cfg, results, None);
                    Comparison::of(&ra, &runs)
                });
            cells.push(
                &format!("{} [{}]", c.label, e.label()),
                "all",
                Some(latency),
                Some(scale),
                &s,
            );
            t.push(
                [
                    e.label(),
                    c.label.clone(),
                    latency.to_string(),
                    s.n.to_string(),
                ]
                .into_iter()
                .chain(outcome_cells(&s))
                .chain(paired_cells(two_scale.as_ref()))
                .collect(),
            );
            if s.n > 0 {
                pts.push((latency, s));
            }
        }
        lines.push((
            format!("{name} at each scale's latency ({})", e.label()),
            pts,
        ));
        // The switchers between the ladder's ends, paired with RA's own under `e`.
        let Some(ends) = cfg.ladder_envelope(*e) else {
            continue;
        };
        let (lo, hi) = Driver::Ladder.switch_scales(cfg);
        for sel in [
            SelectorKind::Oracle,
            SelectorKind::Lookahead,
            SelectorKind::Braking,
        ] {
            let c = Config {
                label: format!(
                    "{name} {} switcher {}<->{}",
                    selector_name(sel),
                    x(lo),
                    x(hi)
                ),
                unit: Unit::ladder_switch(sel, ends),
                scale: None,
            };
            let runs = c.runs(cfg, results, None);
            let s = Stats::of(&runs, hi);
            let ra = Unit::switch(sel, *e);
            let cmp = Comparison::of(&results.select(cfg, &ra, None, None), &runs);
            cells.push(
                &format!("{} [{}]", c.label, ends.label()),
                "all",
                Some(ends.high_ms),
                None,
                &s,
            );
            t.push(
                [
                    e.label(),
                    format!("{} ({})", c.label, ends.label()),
                    ends.high_ms.to_string(),
                    s.n.to_string(),
                ]
                .into_iter()
                .chain(outcome_cells(&s))
                .chain(paired_cells(Some(&cmp)))
                .collect(),
            );
            if s.n > 0 {
                switch_lines
                    .entry(c.label)
                    .or_default()
                    .push((ends.high_ms, s));
            }
        }
    }
    lines.extend(switch_lines);
    lines.extend(ra_fixed_lines(cfg, results, " (two scales)"));
    w.cells("scales.csv", &cells)?;
    w.plot(
        "scales",
        &safety_panels(&lines, "worst-case latency (ms)"),
        1500,
        480,
    )?;
    Ok(format!(
        "## Beyond the paper: more scales in one network\n\n\
         `{}` is RA with a BN branch for more scales than two, retargeted like RA (its card in \
         `models/` says which scales and how it was trained); here it drives at {}. Each scale \
         drives alone, its latency the injected delay: the straight line through each \
         envelope's two points (its low latency at {}, its high one at {}){}. The paired \
         columns set it against the two-scale RA at the same scale and delay, run for run: one \
         network with more branches should cost nothing. Its oracle, map-lookahead and braking-lookahead switchers \
         move between its two ends, the low end costing what the line gives it; they are paired \
         with RA's own switcher under the envelope, the same worst case with a dearer low \
         scale. The plot adds the two-scale RA's fixed scales at every injected delay.\n\n\
         ![scales](scales.png)\n\n{}\nFiles: `scales.png`, `scales.svg`, `scales.csv`.\n",
        file.display(),
        cfg.ladder
            .iter()
            .map(|&s| x(s))
            .collect::<Vec<_>>()
            .join(", "),
        x(cfg.low),
        x(cfg.high),
        cfg.envelopes.last().map_or(String::new(), |e| format!(
            ", so under {}: {}",
            e.label(),
            cfg.ladder
                .iter()
                .map(|&s| format!("{} {} ms", x(s), e.latency_ms_at(s, cfg.low, cfg.high)))
                .collect::<Vec<_>>()
                .join(", ")
        )),
        t.markdown()
    ))
}
