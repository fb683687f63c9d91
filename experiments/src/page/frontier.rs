//! Beyond the paper: success, collisions and red lights against worst-case
//! latency, fixed scales and switchers alike.

use super::beyond::{ra_fixed_lines, safety_panels};
use super::configs::Config;
use super::reference;
use super::writer::Writer;
use crate::PaperError;
use crate::config::PaperConfig;
use crate::figures::Reference;
use crate::report::{Cells, Table};
use crate::results::Results;
use crate::units::{Unit, selector_name};

/// Beyond the paper: success, collisions and red lights against worst-case latency.
pub(super) fn frontier(
    cfg: &PaperConfig,
    results: &Results,
    w: &mut Writer,
) -> Result<String, PaperError> {
    let mut lines = ra_fixed_lines(cfg, results, "");
    for s in cfg.selectors() {
        let pts = cfg
            .envelopes
            .iter()
            .map(|e| {
                let c = Config {
                    label: String::new(),
                    unit: Unit::switch(s, *e),
                    scale: None,
                };
                (e.high_ms, c.stats(cfg, results, None))
            })
            .filter(|(_, s)| s.n > 0)
            .collect();
        lines.push((format!("RA {} switcher", selector_name(s)), pts));
    }
    let mut cells = Cells::new();
    let mut t = Table::new(&[
        "configuration",
        "worst-case latency (ms)",
        "runs",
        "success %",
        "collided %",
        "red lights per run",
    ]);
    for (label, pts) in &lines {
        for (l, s) in pts {
            cells.push(label, "all", Some(*l), None, s);
            t.push(vec![
                label.clone(),
                l.to_string(),
                s.n.to_string(),
                s.success_cell(),
                s.collided_cell(),
                s.red_cell(),
            ]);
        }
    }
    w.cells("frontier.csv", &cells)?;
    let mut panels = safety_panels(&lines, "worst-case latency (ms)");
    // The paper's Table III beside ours: fixed 0.75x at the low latency, the
    // switcher and fixed 1.0x at the high one.
    for ((high, low), rows) in reference::TABLE3 {
        for ((success, collided, _, _, red), x) in rows.into_iter().zip([low, high, high]) {
            let values = [success, collided, f64::from(red) / reference::TABLE3_RUNS];
            for (panel, y) in panels.iter_mut().zip(values) {
                panel.paper.push(Reference {
                    label: "the paper (Table III, 12 runs)".into(),
                    x: (x, x),
                    y: (y, y),
                });
            }
        }
    }
    w.plot("frontier", &panels, 1500, 480)?;
    Ok(format!(
        "## Beyond the paper: the latency/safety frontier\n\n\
         One point per fixed scale at each injected delay (its worst-case latency is D) and per \
         switcher at each envelope (its worst case is the high scale's latency). A switcher is worth \
         having where its point sits above (success) or below (collisions, red lights) both fixed \
         lines at the same latency. Black crosses are the paper's Table III (its fixed 0.75x at \
         the low latency, its switcher and fixed 1.0x at the high one).\n\n![frontier](frontier.png)\n\n{}\nFiles: `frontier.png`, `frontier.svg`, `frontier.csv`.\n",
        t.markdown()
    ))
}
