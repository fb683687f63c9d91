//! Driving outside the route's lanes (the leaderboard's `OutsideRouteLanesTest`):
//! the share of the route's progress made while the ego was outside the
//! driving lanes (its centre farther than half a lane's width plus 1.3 m from
//! every lane: a sidewalk, a verge) or in a lane running the other way. How the
//! ego stands to the lanes is the rule book's ([`world::rules::LaneGrid::standing`]).
//! The driving score takes this share off, as leaderboard 1.0 does
//! ([`super::score::driving_score`]).
//!
//! Like the leaderboard, it measures progress along the route (the distance
//! between the route points the ego passed), not the distance driven: standing
//! or driving beside the route adds nothing.

use std::sync::Arc;

use world::Town;
use world::rules::{LaneStanding, RuleBook};

use super::{EgoTick, Infraction, Monitor};

/// Accumulates the route progress made outside the lanes.
#[derive(Debug, Clone)]
pub struct OutsideLaneMonitor {
    town: Arc<Town>,
    rules: Arc<RuleBook>,
    progress_m: f64,
    outside_m: f64,
    last_progress_m: f32,
}

impl OutsideLaneMonitor {
    /// A monitor for `town` with its rule book.
    pub fn new(town: Arc<Town>, rules: Arc<RuleBook>) -> Self {
        OutsideLaneMonitor {
            town,
            rules,
            progress_m: 0.0,
            outside_m: 0.0,
            last_progress_m: 0.0,
        }
    }

    /// Route progress made outside the lanes (metres).
    pub fn outside_m(&self) -> f64 {
        self.outside_m
    }

    /// Share of the route progress made outside the lanes (percent).
    pub fn outside_pct(&self) -> f64 {
        if self.progress_m > 0.0 {
            100.0 * self.outside_m / self.progress_m
        } else {
            0.0
        }
    }
}

impl Monitor for OutsideLaneMonitor {
    /// Adds the route progress since the last tick (`tick.route_progress_m`) to
    /// the outside share when the ego stands outside the lanes or against them
    /// after the step. It reports no event: the share is read at the run's end.
    fn observe(&mut self, tick: &EgoTick<'_>, _out: &mut Vec<Infraction>) {
        let progress_m = tick.route_progress_m;
        let d = f64::from((progress_m - self.last_progress_m).max(0.0));
        self.last_progress_m = self.last_progress_m.max(progress_m);
        if d == 0.0 {
            return;
        }
        self.progress_m += d;
        let standing = self
            .rules
            .lanes
            .standing(&self.town, tick.now.ground(), tick.now.heading);
        if standing != LaneStanding::InLane {
            self.outside_m += d;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::scripted;
    use super::*;
    use world::map::testtown;

    fn monitor() -> OutsideLaneMonitor {
        let town = Arc::new(testtown::grid(3, 1, 100.0));
        let rules = Arc::new(RuleBook::new(&town));
        OutsideLaneMonitor::new(town, rules)
    }

    /// Drives `poses`, the route progress being the distance along +x from x = 20.
    fn drive(m: &mut OutsideLaneMonitor, poses: &[world::EgoPose]) {
        scripted::drive(poses, 4.0, &[], |t| {
            let tick = EgoTick {
                route_progress_m: (t.now.position.x - 20.0).max(0.0),
                ..*t
            };
            m.observe(&tick, &mut Vec::new())
        });
    }

    #[test]
    fn a_quarter_of_the_route_on_the_sidewalk_or_against_the_lane_is_twenty_five_percent() {
        // 10 m in the lane, 10 m on the southern sidewalk (y = -5), 20 m in the lane.
        let mut m = monitor();
        let mut poses = scripted::straight(20.0, -1.75, 4.0, 100);
        poses.extend(scripted::straight(30.0, -5.0, 4.0, 100));
        poses.extend(scripted::straight(40.0, -1.75, 4.0, 200));
        drive(&mut m, &poses);
        assert!((m.outside_pct() - 25.0).abs() < 0.5, "{}", m.outside_pct());
        assert!((m.outside_m() - 10.0).abs() < 0.2);
        // The same in the oncoming lane (y = +1.75, which runs -x).
        let mut m = monitor();
        let mut poses = scripted::straight(20.0, -1.75, 4.0, 100);
        poses.extend(scripted::straight(30.0, 1.75, 4.0, 100));
        poses.extend(scripted::straight(40.0, -1.75, 4.0, 200));
        drive(&mut m, &poses);
        assert!((m.outside_pct() - 25.0).abs() < 0.5, "{}", m.outside_pct());
    }

    #[test]
    fn no_route_progress_adds_nothing() {
        let mut m = monitor();
        let poses = scripted::straight(30.0, -5.0, 0.0, 100);
        scripted::drive(&poses, 0.0, &[], |t| m.observe(t, &mut Vec::new()));
        assert_eq!(m.outside_pct(), 0.0);
    }
}
