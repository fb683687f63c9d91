//! Fig. 5: success and collisions against the injected delay.

use super::configs::{Config, model_at, point};
use super::reference;
use super::writer::Writer;
use crate::PaperError;
use crate::config::PaperConfig;
use crate::figures::{Panel, Reference, Series};
use crate::report::{Cells, Stats, Table};
use crate::results::Results;
use crate::units::{Driver, Unit};

/// Fig. 5: success and collisions against D, each model and scale, the expert dashed.
pub(super) fn fig5(
    cfg: &PaperConfig,
    results: &Results,
    w: &mut Writer,
) -> Result<String, PaperError> {
    let mut configs: Vec<Config> = Vec::new();
    for ra in [false, true] {
        for scale in [cfg.low, cfg.high] {
            configs.push(model_at(cfg, ra, scale, 0.0));
        }
    }
    configs.push(Config {
        label: "Expert".into(),
        unit: Unit::fixed(Driver::Expert, 0.0),
        scale: None,
    });
    let at = |c: &Config, d: f64| Config {
        label: c.label.clone(),
        unit: Unit {
            driver: c.unit.driver,
            selection: crate::units::Selection::Fixed { delay_ms: d },
        },
        scale: c.scale,
    };
    let mut cells = Cells::new();
    let mut success = Vec::new();
    let mut collision = Vec::new();
    let mut header = vec!["D (ms)".to_string()];
    header.extend(
        configs
            .iter()
            .map(|c| format!("{}: success / collided %", c.label)),
    );
    let refs: Vec<&str> = header.iter().map(String::as_str).collect();
    let mut t = Table::new(&refs);
    let mut rows: Vec<Vec<String>> = cfg.delays_ms.iter().map(|d| vec![d.to_string()]).collect();
    for c in &configs {
        let mut sp = Vec::new();
        let mut cp = Vec::new();
        for (i, &d) in cfg.delays_ms.iter().enumerate() {
            let s = at(c, d).stats(cfg, results, None);
            cells.push(&c.label, "all", Some(d), c.scale, &s);
            if s.n > 0 {
                sp.push(point(d, s.success_pct(), s.success_ci));
                cp.push(point(d, s.collision_pct(), s.collision_ci));
                rows[i].push(format!(
                    "{:.0} / {:.0} (n = {})",
                    s.success_pct(),
                    s.collision_pct(),
                    s.n
                ));
            } else {
                rows[i].push("–".into());
            }
        }
        let dashed = c.unit.driver == Driver::Expert;
        success.push(Series {
            label: c.label.clone(),
            points: sp,
            dashed,
        });
        collision.push(Series {
            label: c.label.clone(),
            points: cp,
            dashed,
        });
    }
    for r in rows {
        t.push(r);
    }
    w.cells("fig5.csv", &cells)?;
    // The paper's ranges, shaded: up to 100 ms and at 200 ms.
    let ranges = |pick: fn(reference::Ranges) -> (f64, f64)| {
        [
            ((0.0, 100.0), pick(reference::FIG5_UP_TO_100)),
            ((190.0, 210.0), pick(reference::FIG5_AT_200)),
        ]
        .map(|(x, y)| Reference {
            label: "the paper's range (its text, §IV-D)".into(),
            x,
            y,
        })
        .to_vec()
    };
    let panel = |title: &str, y: &str, series, paper| Panel {
        title: title.into(),
        x_label: "injected delay D (ms); Tc = max(50, D)".into(),
        y_label: y.into(),
        series,
        y_range: Some((0.0, 105.0)),
        paper,
    };
    w.plot(
        "fig5",
        &[
            panel(
                "Success against delay",
                "success % (95 % CI over routes)",
                success,
                ranges(|r| r.0),
            ),
            panel(
                "Runs with a collision against delay",
                "collided % (95 % CI over routes)",
                collision,
                ranges(|r| r.1),
            ),
        ],
        1400,
        520,
    )?;
    // Where does each policy fall off? The first D with success below half.
    let mut cliff = Vec::new();
    for c in configs.iter().filter(|c| c.unit.driver != Driver::Expert) {
        let run: Vec<(f64, Stats)> = cfg
            .delays_ms
            .iter()
            .map(|&d| (d, at(c, d).stats(cfg, results, None)))
            .filter(|(_, s)| s.n > 0)
            .collect();
        let first = run.iter().find(|(_, s)| s.success_pct() < 50.0);
        let ran: Vec<String> = run.iter().map(|(d, _)| d.to_string()).collect();
        cliff.push(format!(
            "{}: {}",
            c.label,
            match first {
                Some((d, _)) => format!("success first below 50 % at D = {d} ms"),
                None if run.is_empty() => "no runs yet".to_string(),
                None => format!(
                    "not below 50 % at the delays run so far ({} ms)",
                    ran.join(", ")
                ),
            }
        ));
    }
    Ok(format!(
        "## Fig. 5: success and collisions against injected delay\n\n![fig5](fig5.png)\n\n{}\n\
         The paper: {}. Ours: {}.\n\nFiles: `fig5.png`, `fig5.svg`, `fig5.csv`.\n",
        t.markdown(),
        reference::FIG5,
        cliff.join("; ")
    ))
}
