//! The configurations the page compares (a sweep unit, a fixed scale or none,
//! and its label) and the small helpers every table and figure shares.

use crate::config::PaperConfig;
use crate::figures::Point;
use crate::report::Stats;
use crate::results::{Results, Run};
use crate::units::{Driver, Unit, scale_label};

/// A configuration of the comparisons: a unit, a fixed scale (or none) and its label.
pub(super) struct Config {
    pub(super) label: String,
    pub(super) unit: Unit,
    pub(super) scale: Option<f64>,
}

impl Config {
    pub(super) fn runs<'a>(
        &self,
        cfg: &PaperConfig,
        results: &'a Results,
        town: Option<&str>,
    ) -> Vec<&'a Run> {
        results.select(cfg, &self.unit, self.scale, town)
    }

    pub(super) fn stats(&self, cfg: &PaperConfig, results: &Results, town: Option<&str>) -> Stats {
        Stats::of(&self.runs(cfg, results, town), cfg.high)
    }
}

/// A scale as the page writes it, e.g. `0.75x`.
pub(super) fn x(scale: f64) -> String {
    format!("{}x", scale_label(scale))
}

/// NRA or RA at one scale and delay.
pub(super) fn model_at(cfg: &PaperConfig, ra: bool, scale: f64, delay_ms: f64) -> Config {
    let driver = match (ra, scale == cfg.low) {
        (true, _) => Driver::Ra,
        (false, true) => Driver::NraLow,
        (false, false) => Driver::NraHigh,
    };
    Config {
        label: format!("{} {}", if ra { "RA" } else { "NRA" }, x(scale)),
        unit: Unit::fixed(driver, delay_ms),
        scale: Some(scale),
    }
}

/// A plot point at `xv` with value `y` and interval `ci` (none: no error bar).
pub(super) fn point(xv: f64, y: f64, ci: crate::report::Interval) -> Point {
    let (lo, hi) = ci.unwrap_or((y, y));
    Point { x: xv, y, lo, hi }
}
