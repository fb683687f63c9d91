//! Route completion, success and deviation (docs/protocol.md §3, scenario_runner's
//! `RouteCompletionTest` and `InRouteTest`).
//!
//! Progress is the arc length of the dense route point the ego has reached:
//! the monitor looks a short window ahead of its last point for the nearest
//! one, so a route that passes the same place twice is followed in order.
//! Completion is that arc length over the route's length; the run succeeds
//! with >= 99 % completion within 10 m of the final point. Farther than the
//! deviation limit from the route near the ego ends the run.

use world::Vec2;
use world::route::DenseRoute;
use world::rules::nearest_route_point;

use super::{EgoTick, Infraction, InfractionKind, Monitor};

/// How far ahead along the route the ego is looked for (route points, ~1 m each).
const WINDOW_POINTS: usize = 40;

/// Tracks progress along a dense route.
#[derive(Debug, Clone)]
pub struct RouteMonitor {
    route: DenseRoute,
    /// The route point reached.
    index: usize,
    /// Distance from the route that ends the run (metres).
    pub deviation_m: f32,
    deviated: bool,
}

impl RouteMonitor {
    /// Follows a dense route (its points' `route_s` measure the progress).
    pub fn new(route: &DenseRoute, deviation_m: f32) -> Self {
        Self {
            route: route.clone(),
            index: 0,
            deviation_m,
            deviated: false,
        }
    }

    /// The route's length (metres).
    pub fn length_m(&self) -> f32 {
        self.route.length_m
    }

    /// The index of the route point reached.
    pub fn index(&self) -> usize {
        self.index
    }

    /// Distance driven along the route so far (metres).
    pub fn progress_m(&self) -> f32 {
        self.route.points.get(self.index).map_or(0.0, |p| p.route_s)
    }

    /// Route completion in percent.
    pub fn completion_pct(&self) -> f64 {
        if self.length_m() <= 0.0 {
            100.0
        } else {
            f64::from(self.progress_m() / self.length_m()) * 100.0
        }
    }

    /// Whether the route counts as driven: >= 99 % and within 10 m of its end.
    pub fn succeeded(&self, position: Vec2) -> bool {
        let end = self
            .route
            .points
            .last()
            .map_or(position, |p| p.position.truncate());
        self.completion_pct() >= 99.0 && position.distance(end) <= 10.0
    }
}

impl Monitor for RouteMonitor {
    /// Advances the progress; pushes a deviation (once) when the ego is too far
    /// from the route.
    fn observe(&mut self, tick: &EgoTick<'_>, out: &mut Vec<Infraction>) {
        let nearest =
            nearest_route_point(&self.route, tick.now.ground(), self.index, WINDOW_POINTS);
        let distance = match nearest {
            Some((i, d)) => {
                self.index = i;
                d
            }
            None => f32::INFINITY,
        };
        if distance > self.deviation_m && !self.deviated {
            self.deviated = true;
            out.push(Infraction::at(
                tick,
                InfractionKind::RouteDeviation,
                format!("{distance:.1} m from the route"),
            ));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{EgoPose, scripted};
    use super::*;
    use world::map::testtown::route_through;

    fn line(length: usize) -> Vec<Vec2> {
        (0..=length).map(|i| Vec2::new(i as f32, 0.0)).collect()
    }

    #[test]
    fn driving_the_whole_route_completes_and_succeeds() {
        let mut monitor = RouteMonitor::new(&route_through(&line(100)), 10.0);
        let mut out = Vec::new();
        let poses = scripted::straight(0.0, -1.5, 6.0, 700); // to x = 105
        scripted::drive(&poses, 6.0, &[], |t| monitor.observe(t, &mut out));
        assert!(out.is_empty());
        assert_eq!(monitor.completion_pct(), 100.0);
        assert!(monitor.succeeded(poses.last().unwrap().ground()));
    }

    #[test]
    fn stopping_halfway_completes_half() {
        let mut monitor = RouteMonitor::new(&route_through(&line(100)), 10.0);
        let mut out = Vec::new();
        let poses = scripted::straight(0.0, 0.0, 5.0, 400); // to x = 50
        scripted::drive(&poses, 5.0, &[], |t| monitor.observe(t, &mut out));
        assert!((monitor.completion_pct() - 50.0).abs() < 1e-3);
        assert!(!monitor.succeeded(poses.last().unwrap().ground()));
    }

    #[test]
    fn leaving_the_route_is_one_deviation() {
        let mut monitor = RouteMonitor::new(&route_through(&line(100)), 10.0);
        let mut out = Vec::new();
        let poses: Vec<EgoPose> = (0..200)
            .map(|i| scripted::pose(i as f32 * 0.1, i as f32 * 0.1, 0.8))
            .collect();
        scripted::drive(&poses, 5.0, &[], |t| monitor.observe(t, &mut out));
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].kind, InfractionKind::RouteDeviation);
    }

    #[test]
    fn a_route_through_the_same_place_twice_is_followed_in_order() {
        // Out along +x and back along the same line: at the start the ego is
        // at both the first and the last point, but has driven nothing.
        let mut points = line(50);
        points.extend((0..50).rev().map(|i| Vec2::new(i as f32, 0.0)));
        let mut monitor = RouteMonitor::new(&route_through(&points), 10.0);
        let mut out = Vec::new();
        let poses = scripted::straight(0.0, 0.0, 0.0, 10);
        scripted::drive(&poses, 0.0, &[], |t| monitor.observe(t, &mut out));
        assert_eq!(monitor.index(), 0);
    }
}
