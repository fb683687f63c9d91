//! Figures written by the command line (plotters): a training stage's loss curves.

use anyhow::{Context, Result, bail};
use plotters::prelude::*;
use std::path::Path;

/// Plots the columns `loss`, `act`, `seg`, `kd` and `feat` of a stage's `losses.csv`
/// against the step (log scale, each smoothed over 50 steps) into `png`.
pub fn loss_curves(csv: &Path, png: &Path, title: &str) -> Result<()> {
    let text = std::fs::read_to_string(csv).with_context(|| format!("{}", csv.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let wanted = ["loss", "act", "seg", "kd", "feat"];
    let cols: Vec<(usize, &str)> = header
        .iter()
        .enumerate()
        .filter(|(_, h)| wanted.contains(h))
        .map(|(i, h)| (i, *h))
        .collect();
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    if rows.is_empty() {
        bail!("{}: no rows to plot yet", csv.display());
    }
    let series: Vec<(&str, Vec<(f64, f64)>)> = cols
        .iter()
        .map(|&(i, name)| (name, smooth(&rows, i, 50)))
        .filter(|(_, pts)| pts.iter().any(|p| p.1 > 0.0))
        .collect();
    let x_max = rows.last().map_or(1.0, |r| r[0] + 1.0);
    let (lo, hi) = series
        .iter()
        .flat_map(|(_, p)| p.iter().map(|q| q.1))
        .filter(|v| *v > 0.0 && v.is_finite())
        .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
    experiments::figures::register_fonts();
    let root = BitMapBackend::new(png, (900, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{title}: training losses (mean of 50 steps)"),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..x_max, (lo * 0.8..hi * 1.25).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("step")
        .y_desc("loss (log)")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.3}"))
        .light_line_style(WHITE)
        .draw()?;
    for (k, (name, pts)) in series.into_iter().enumerate() {
        let colour = Palette99::pick(k).to_rgba();
        chart
            .draw_series(LineSeries::new(
                pts.into_iter().filter(|p| p.1 > 0.0),
                colour.stroke_width(2),
            ))?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()
        .with_context(|| format!("{}: could not write", png.display()))?;
    Ok(())
}

/// Column `col` against column 0, as means over windows of `w` rows.
fn smooth(rows: &[Vec<f64>], col: usize, w: usize) -> Vec<(f64, f64)> {
    rows.chunks(w)
        .map(|c| {
            let n = c.len() as f64;
            let x = c.iter().map(|r| r[0]).sum::<f64>() / n;
            let y = c
                .iter()
                .map(|r| r.get(col).copied().unwrap_or(f64::NAN))
                .sum::<f64>()
                / n;
            (x, y)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plots_a_loss_log_and_refuses_an_empty_one() {
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("losses.csv");
        let mut text = String::from(
            "step,epoch,loss,act,seg,kd,feat,loss_1x,unfrozen_stages,samples_per_s,wall_s\n",
        );
        for s in 0..120 {
            let l = 1.0 / (1.0 + s as f64 * 0.05);
            text += &format!("{s},0,{l},{},{},0,0,{l},4,20.0,{s}\n", l * 0.5, l * 8.0);
        }
        std::fs::write(&csv, text).unwrap();
        let png = dir.path().join("losses.png");
        loss_curves(&csv, &png, "test").unwrap();
        let img = image::open(&png).unwrap();
        assert_eq!((img.width(), img.height()), (900, 500));
        std::fs::write(&csv, "step,loss\n").unwrap();
        assert!(
            loss_curves(&csv, &png, "test")
                .unwrap_err()
                .to_string()
                .contains("no rows")
        );
    }
}
