//! A training run's loss curves (`runs/NAME/losses.csv`, written by
//! `policy::train::stage`) as a PNG: what `mrdrive train` redraws at each
//! checkpoint and `mrdrive policy losses` draws from a shipped CSV.

use std::path::{Path, PathBuf};

use plotters::prelude::*;

/// Why a loss plot could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum LossPlotError {
    /// The CSV could not be read.
    #[error("{}: {error}", path.display())]
    Read {
        /// The losses CSV.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// The CSV has a header and no step yet.
    #[error("{}: no rows to plot yet", path.display())]
    Empty {
        /// The losses CSV.
        path: PathBuf,
    },
    /// plotters could not draw the chart.
    #[error("{0}")]
    Draw(String),
    /// The PNG could not be written.
    #[error("{}: could not write: {problem}", path.display())]
    Write {
        /// The PNG.
        path: PathBuf,
        /// What plotters said.
        problem: String,
    },
}

/// The title of a training run's loss plot: the model's name, and the stage when the
/// name is another (`ra5 (stage ra)`).
pub fn loss_title(name: &str, stage: &str) -> String {
    if name == stage {
        name.to_string()
    } else {
        format!("{name} (stage {stage})")
    }
}

/// Plots the columns `loss`, `act`, `seg`, `kd` and `feat` of a stage's `losses.csv`
/// against the step (log scale, each smoothed over 50 steps) into `png`.
pub fn loss_curves(csv: &Path, png: &Path, title: &str) -> Result<(), LossPlotError> {
    let text = std::fs::read_to_string(csv).map_err(|error| LossPlotError::Read {
        path: csv.to_path_buf(),
        error,
    })?;
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
        return Err(LossPlotError::Empty {
            path: csv.to_path_buf(),
        });
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
    crate::figures::register_fonts();
    let root = BitMapBackend::new(png, (900, 500)).into_drawing_area();
    let draw = |e: DrawingAreaErrorKind<_>| LossPlotError::Draw(e.to_string());
    root.fill(&WHITE).map_err(draw)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("{title}: training losses (mean of 50 steps)"),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0f64..x_max, (lo * 0.8..hi * 1.25).log_scale())
        .map_err(draw)?;
    chart
        .configure_mesh()
        .x_desc("step")
        .y_desc("loss (log)")
        .x_label_formatter(&|x| format!("{x:.0}"))
        .y_label_formatter(&|y| format!("{y:.3}"))
        .light_line_style(WHITE)
        .draw()
        .map_err(draw)?;
    for (k, (name, pts)) in series.into_iter().enumerate() {
        let colour = Palette99::pick(k).to_rgba();
        chart
            .draw_series(LineSeries::new(
                pts.into_iter().filter(|p| p.1 > 0.0),
                colour.stroke_width(2),
            ))
            .map_err(draw)?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], colour));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(draw)?;
    root.present().map_err(|e| LossPlotError::Write {
        path: png.to_path_buf(),
        problem: e.to_string(),
    })?;
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

    #[test]
    fn the_loss_plot_names_the_model_then_its_stage() {
        assert_eq!(loss_title("ra5", "ra"), "ra5 (stage ra)");
        assert_eq!(loss_title("ra", "ra"), "ra");
    }
}
