//! Driving on the sidewalk (scenario_runner's `OnSidewalkTest`): an event per
//! stretch driven on a sidewalk, where it began and how far it went. It is
//! informative: no penalty of its own (the distance shows in the outside-lanes
//! share, [`super::outside_lane`], which the driving score takes off).
//!
//! The ego is on the sidewalk when its centre is ([`world::rules::SidewalkGrid`]),
//! or when its centre is off every lane's paved width and a corner of its
//! footprint is on a sidewalk (scenario_runner's cases 1 and 2.2).

use std::sync::Arc;

use world::Town;
use world::rules::RuleBook;

use super::{EgoTick, Infraction, InfractionKind, Monitor};

/// The stretch on the sidewalk in progress: where and when it began, how far so far.
#[derive(Debug, Clone, Copy)]
struct Stretch {
    tick: u64,
    time_s: f64,
    position: [f32; 2],
    distance_m: f64,
}

/// Reports each stretch driven on a sidewalk.
#[derive(Debug, Clone)]
pub struct OnSidewalkMonitor {
    town: Arc<Town>,
    rules: Arc<RuleBook>,
    stretch: Option<Stretch>,
}

impl OnSidewalkMonitor {
    /// A monitor for `town` with its rule book.
    pub fn new(town: Arc<Town>, rules: Arc<RuleBook>) -> Self {
        OnSidewalkMonitor {
            town,
            rules,
            stretch: None,
        }
    }

    /// Whether the ego of `tick` is on a sidewalk (see the module docs).
    pub fn on_sidewalk(&self, tick: &EgoTick<'_>) -> bool {
        let sidewalks = &self.rules.sidewalks;
        let centre = tick.now.ground();
        sidewalks.under(centre).is_some()
            || (!self.rules.lanes.on_any_lane(&self.town, centre)
                && tick
                    .footprint()
                    .corners()
                    .iter()
                    .any(|c| sidewalks.under(*c).is_some()))
    }
}

impl Monitor for OnSidewalkMonitor {
    /// Adds this tick's distance to the stretch on the sidewalk, or ends it (an
    /// event) when the ego left the sidewalk.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        let d = f64::from(tick.now.ground().distance(tick.prev.ground()));
        match (self.on_sidewalk(tick), &mut self.stretch) {
            (true, Some(s)) => s.distance_m += d,
            (true, None) => {
                self.stretch = Some(Stretch {
                    tick: tick.tick,
                    time_s: tick.time_s,
                    position: tick.now.ground().to_array(),
                    distance_m: 0.0,
                })
            }
            (false, _) => self.finish(out),
        }
    }

    /// Ends a stretch in progress (at the end of the run).
    fn finish(&mut self, out: &mut Vec<Infraction>) {
        if let Some(s) = self.stretch.take() {
            out.push(Infraction {
                tick: s.tick,
                time_s: s.time_s,
                kind: InfractionKind::OnSidewalk,
                position: s.position,
                detail: format!("on the sidewalk for {:.1} m", s.distance_m),
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::scripted;
    use super::*;
    use world::map::testtown;

    fn monitor() -> OnSidewalkMonitor {
        let town = Arc::new(testtown::grid(3, 1, 100.0));
        let rules = Arc::new(RuleBook::new(&town));
        OnSidewalkMonitor::new(town, rules)
    }

    #[test]
    fn a_stretch_on_the_sidewalk_is_one_event_with_its_start_and_length() {
        // The southern sidewalk of the test town is y in [-6, -3.5]; its lane is at -1.75.
        let mut m = monitor();
        let mut out = Vec::new();
        let mut poses = scripted::straight(20.0, -1.75, 4.0, 100); // 10 m in the lane
        poses.extend(scripted::straight(30.0, -5.0, 4.0, 200)); // 20 m on the sidewalk
        poses.extend(scripted::straight(50.0, -1.75, 4.0, 100)); // back in the lane
        scripted::drive(&poses, 4.0, &[], |t| m.observe(t, &mut out));
        m.finish(&mut out);
        assert_eq!(out.len(), 1, "{out:?}");
        let e = &out[0];
        assert_eq!(e.kind, InfractionKind::OnSidewalk);
        assert_eq!(e.position, [30.0, -5.0]);
        assert!(e.detail.contains("20.0 m"), "{}", e.detail);
        // A run that ends on the sidewalk reports its stretch too; a lane-only drive none.
        let mut m = monitor();
        let mut out = Vec::new();
        scripted::drive(&scripted::straight(30.0, -5.0, 4.0, 40), 4.0, &[], |t| {
            m.observe(t, &mut out)
        });
        assert!(out.is_empty());
        m.finish(&mut out);
        assert_eq!(out.len(), 1);
        let mut m = monitor();
        let mut out = Vec::new();
        scripted::drive(&scripted::straight(20.0, -1.75, 4.0, 200), 4.0, &[], |t| {
            m.observe(t, &mut out)
        });
        m.finish(&mut out);
        assert!(out.is_empty(), "{out:?}");
    }
}
