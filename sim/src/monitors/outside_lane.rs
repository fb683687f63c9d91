//! Driving outside the lanes (scenario_runner's `OutsideRouteLanesTest`):
//! the share of the distance driven with the ego's centre off every driving
//! lane, or on one that runs the other way. The lane under the ego is the
//! rule book's ([`world::rules::lanes`]: within half a lane width plus 0.5 m,
//! heading within 60 degrees), so the NPCs and this monitor agree on it.

use super::{EgoTick, Infraction, Monitor};

/// Accumulates the distance driven outside the lanes.
#[derive(Debug, Clone, Default)]
pub struct OutsideLaneMonitor {
    driven_m: f64,
    outside_m: f64,
}

impl OutsideLaneMonitor {
    /// Distance driven outside the lanes (metres).
    pub fn outside_m(&self) -> f64 {
        self.outside_m
    }

    /// Share of the distance driven outside the lanes (percent).
    pub fn outside_pct(&self) -> f64 {
        if self.driven_m > 0.0 {
            100.0 * self.outside_m / self.driven_m
        } else {
            0.0
        }
    }
}

impl Monitor for OutsideLaneMonitor {
    /// Adds this tick's distance, to the outside share when the ego is not
    /// on a driving lane in its direction after the step. Reports nothing.
    fn observe(&mut self, tick: &EgoTick<'_>, _out: &mut Vec<Infraction>) {
        let d = f64::from(tick.now.ground().distance(tick.prev.ground()));
        self.driven_m += d;
        if !tick.on_lane {
            self.outside_m += d;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::scripted;
    use super::*;

    #[test]
    fn a_quarter_of_the_drive_off_the_lane_is_twenty_five_percent() {
        let mut m = OutsideLaneMonitor::default();
        let poses = scripted::straight(0.0, 0.0, 4.0, 400); // 40 m
        scripted::drive(&poses, 4.0, &[], |t| {
            let on_lane = !(100..200).contains(&t.tick);
            m.observe(&EgoTick { on_lane, ..*t }, &mut Vec::new())
        });
        assert!((m.outside_pct() - 25.0).abs() < 0.5, "{}", m.outside_pct());
        assert!((m.outside_m() - 10.0).abs() < 0.2);
    }

    #[test]
    fn standing_still_off_the_lane_adds_nothing() {
        let mut m = OutsideLaneMonitor::default();
        let poses = scripted::straight(0.0, 0.0, 0.0, 100);
        scripted::drive(&poses, 0.0, &[], |t| {
            m.observe(
                &EgoTick {
                    on_lane: false,
                    ..*t
                },
                &mut Vec::new(),
            )
        });
        assert_eq!(m.outside_pct(), 0.0);
    }
}
