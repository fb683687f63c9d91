//! The plots (plotters): lines with 95 % error bars, written as PNG and SVG
//! with an embedded font, so they look the same on every machine.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::PaperError;

/// Registers the embedded DejaVu Sans as plotters' "sans-serif" (no system fonts needed).
pub fn register_fonts() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        for style in [FontStyle::Normal, FontStyle::Bold] {
            let bytes = match style {
                FontStyle::Bold => dejavu::sans::bold(),
                _ => dejavu::sans::regular(),
            };
            // Only fails on bytes that are not a font; these are.
            let _ = plotters::style::register_font("sans-serif", style, bytes);
        }
    });
}

/// One point: x, y and the 95 % interval of y.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// The interval's low end.
    pub lo: f64,
    /// The interval's high end.
    pub hi: f64,
}

/// A labelled line of points.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Its legend.
    pub label: String,
    /// Its points, in x order.
    pub points: Vec<Point>,
    /// Dashed (a reference line such as the expert's).
    pub dashed: bool,
}

/// What the paper reports, drawn behind our points: a shaded box over an x
/// range and a y range (the paper's Fig. 5 ranges), or, when both ranges are
/// a single value, a black cross at that point (a Table III row).
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// Its legend ("the paper's range"); references sharing a label share one entry.
    pub label: String,
    /// Low and high x.
    pub x: (f64, f64),
    /// Low and high y.
    pub y: (f64, f64),
}

/// One panel: axes and series.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// The panel's title.
    pub title: String,
    /// The x axis's label (with its unit).
    pub x_label: String,
    /// The y axis's label (with its unit).
    pub y_label: String,
    /// The lines.
    pub series: Vec<Series>,
    /// Fixed y range, or `None` to fit the data.
    pub y_range: Option<(f64, f64)>,
    /// The paper's values, drawn behind the lines.
    pub paper: Vec<Reference>,
}

/// Draws `panels` side by side into `stem.png` (`width` x `height` pixels)
/// and `stem.svg`. Series sharing an x are offset sideways by 1.5 % of the
/// x range each, so overlapping points stay visible.
pub fn plot(stem: &Path, panels: &[Panel], width: u32, height: u32) -> Result<(), PaperError> {
    register_fonts();
    let png = stem.with_extension("png");
    let svg = stem.with_extension("svg");
    let err = |path: &Path| {
        let path = path.to_path_buf();
        move |e: String| PaperError::Plot {
            path: path.clone(),
            problem: e,
        }
    };
    {
        let root = BitMapBackend::new(&png, (width, height)).into_drawing_area();
        draw(&root, panels).map_err(err(&png))?;
        root.present().map_err(|e| err(&png)(e.to_string()))?;
    }
    {
        let root = SVGBackend::new(&svg, (width, height)).into_drawing_area();
        draw(&root, panels).map_err(err(&svg))?;
        root.present().map_err(|e| err(&svg)(e.to_string()))?;
    }
    Ok(())
}

/// Colours that stay apart in print and for most colour-blind readers
/// (Okabe-Ito), ordered so that the first five differ in hue and lightness:
/// blue, vermillion, bluish green, reddish purple, black, then orange and sky
/// blue (the one close to the first, used only by a seventh line).
const COLOURS: [RGBColor; 7] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(0, 0, 0),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
];

fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, panels: &[Panel]) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let areas = root.split_evenly((1, panels.len().max(1)));
    for (area, panel) in areas.iter().zip(panels) {
        draw_panel(area, panel)?;
    }
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<(), String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let pts = p.series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for q in pts {
        x0 = x0.min(q.x);
        x1 = x1.max(q.x);
        y0 = y0.min(q.lo.min(q.y));
        y1 = y1.max(q.hi.max(q.y));
    }
    for r in &p.paper {
        y0 = y0.min(r.y.0);
        y1 = y1.max(r.y.1);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let xpad = ((x1 - x0) * 0.08).max(0.05);
    let (y0, y1) = p
        .y_range
        .unwrap_or((y0.min(0.0), (y1 * 1.15).max(y0 + 1.0)));
    let mut chart = ChartBuilder::on(area)
        .caption(&p.title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d((x0 - xpad)..(x1 + xpad), y0..y1)
        .map_err(e)?;
    let trim = |v: &f64| {
        let t = format!("{v:.3}");
        t.trim_end_matches('0').trim_end_matches('.').to_string()
    };
    chart
        .configure_mesh()
        .x_label_formatter(&trim)
        .y_label_formatter(&trim)
        .x_desc(&p.x_label)
        .y_desc(&p.y_label)
        .light_line_style(RGBColor(235, 235, 235))
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(e)?;
    // The paper's values go first, behind ours: grey boxes and black crosses.
    let mut labelled = std::collections::BTreeSet::new();
    for r in &p.paper {
        let grey = RGBColor(150, 150, 150);
        let drawn = if r.x.0 == r.x.1 && r.y.0 == r.y.1 {
            chart
                .draw_series(std::iter::once(Cross::new(
                    (r.x.0, r.y.0),
                    6,
                    BLACK.stroke_width(2),
                )))
                .map_err(e)?
        } else {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(r.x.0, r.y.0), (r.x.1, r.y.1)],
                    grey.mix(0.25).filled(),
                )))
                .map_err(e)?
        };
        if labelled.insert(r.label.clone()) {
            let point = r.x.0 == r.x.1 && r.y.0 == r.y.1;
            drawn
                .label(&r.label)
                .legend(move |(x, y)| -> DynElement<'static, DB, (i32, i32)> {
                    if point {
                        Cross::new((x + 9, y), 5, BLACK.stroke_width(2)).into_dyn()
                    } else {
                        Rectangle::new([(x, y - 5), (x + 18, y + 5)], grey.mix(0.25).filled())
                            .into_dyn()
                    }
                });
        }
    }
    // Series that share x values are drawn side by side ("dodged") by a
    // small offset, so equal values stay visible; the data is not changed.
    let n = p.series.len() as f64;
    let dodge = (x1 - x0).max(1e-9) * 0.015;
    for (k, s) in p.series.iter().enumerate() {
        let c = COLOURS[k % COLOURS.len()];
        let style = c.stroke_width(2);
        let off = (k as f64 - (n - 1.0) / 2.0) * dodge;
        let s = &Series {
            points: s
                .points
                .iter()
                .map(|q| Point { x: q.x + off, ..*q })
                .collect(),
            ..s.clone()
        };
        let line: Vec<(f64, f64)> = s.points.iter().map(|q| (q.x, q.y)).collect();
        if s.dashed {
            chart
                .draw_series(DashedLineSeries::new(line, 6, 4, style))
                .map_err(e)?
                .label(&s.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c));
        } else {
            chart
                .draw_series(LineSeries::new(line, style))
                .map_err(e)?
                .label(&s.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c));
        }
        chart
            .draw_series(
                s.points
                    .iter()
                    .map(|q| ErrorBar::new_vertical(q.x, q.lo, q.y, q.hi, c.filled(), 8)),
            )
            .map_err(e)?;
        chart
            .draw_series(
                s.points
                    .iter()
                    .map(|q| Circle::new((q.x, q.y), 4, c.filled())),
            )
            .map_err(e)?;
    }
    chart
        .configure_series_labels()
        .position(legend_corner(p, (x0, x1), (y0, y1)))
        .label_font(("sans-serif", 13))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;
    Ok(())
}

/// The corner of the plot with the fewest points (error-bar ends and the
/// paper's values included) near it, for the legend; upper left on a tie.
fn legend_corner(p: &Panel, (x0, x1): (f64, f64), (y0, y1): (f64, f64)) -> SeriesLabelPosition {
    let near = |left: bool, top: bool| -> usize {
        let (w, h) = ((x1 - x0).max(1e-9), (y1 - y0).max(1e-9));
        p.series
            .iter()
            .flat_map(|s| s.points.iter())
            .flat_map(|q| [(q.x, q.y), (q.x, q.lo), (q.x, q.hi)])
            .chain(
                p.paper
                    .iter()
                    .flat_map(|r| [(r.x.0, r.y.0), (r.x.1, r.y.1)]),
            )
            .filter(|&(x, y)| {
                let fx = (x - x0) / w;
                let fy = (y - y0) / h;
                (if left { fx < 0.45 } else { fx > 0.55 })
                    && (if top { fy > 0.6 } else { fy < 0.4 })
            })
            .count()
    };
    [
        (SeriesLabelPosition::UpperLeft, near(true, true)),
        (SeriesLabelPosition::UpperRight, near(false, true)),
        (SeriesLabelPosition::LowerLeft, near(true, false)),
        (SeriesLabelPosition::LowerRight, near(false, false)),
    ]
    .into_iter()
    .min_by_key(|(_, n)| *n)
    .map_or(SeriesLabelPosition::UpperLeft, |(c, _)| c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_figure_is_written_as_png_and_svg() {
        let dir = tempfile::tempdir().unwrap();
        let stem = dir.path().join("fig");
        let s = |label: &str, dashed| Series {
            label: label.into(),
            points: (0..3)
                .map(|i| Point {
                    x: f64::from(i) * 50.0,
                    y: f64::from(i),
                    lo: f64::from(i) - 0.5,
                    hi: f64::from(i) + 0.5,
                })
                .collect(),
            dashed,
        };
        let panel = Panel {
            title: "t".into(),
            x_label: "D (ms)".into(),
            y_label: "y".into(),
            series: vec![s("a", false), s("b", true)],
            y_range: None,
            paper: vec![
                Reference {
                    label: "the paper's range".into(),
                    x: (0.0, 50.0),
                    y: (0.5, 1.5),
                },
                Reference {
                    label: "the paper".into(),
                    x: (100.0, 100.0),
                    y: (3.0, 3.0),
                },
            ],
        };
        plot(&stem, &[panel.clone(), panel], 1000, 400).unwrap();
        let img = image::open(dir.path().join("fig.png")).unwrap();
        assert_eq!((img.width(), img.height()), (1000, 400));
        let svg = std::fs::read_to_string(dir.path().join("fig.svg")).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.contains("D (ms)"),
            "{}",
            &svg[..80]
        );
        // The paper's values have their legend entries, once each.
        assert_eq!(
            svg.matches("the paper&apos;s range").count()
                + svg.matches("the paper's range").count(),
            2,
            "one per panel"
        );
    }
}
