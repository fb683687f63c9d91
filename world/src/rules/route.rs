//! Distances along a dense route.
//!
//! A pose's distance along the route is measured from a route point it has
//! reached (the route monitor's, see [`nearest_route_point`]): that point's
//! `route_s` plus the pose's offset along the route's heading there. The
//! expert plans its stops and its pursuit point with it; the resolution
//! selectors measure the distance to the next stop line with it.

use glam::Vec2;

use crate::route::dense::DenseRoute;

/// Distance along `route` of a position (metres, ground plane), measured
/// from route point `index`: its `route_s` plus the position's offset along
/// the route's heading there. An index past the route's end gives the
/// route's length.
pub fn route_s_at(route: &DenseRoute, index: usize, position: Vec2) -> f32 {
    let Some(pt) = route.points.get(index) else {
        return route.length_m;
    };
    let forward = Vec2::from_angle(pt.heading);
    pt.route_s + (position - pt.position.truncate()).dot(forward)
}

/// The point of `route` at distance `route_s` along it (metres, ground
/// plane), interpolated between its points, searching forward from point
/// `from`; clamped to the route's last point. `None` for a route without
/// points.
pub fn route_point_at(route: &DenseRoute, from: usize, route_s: f32) -> Option<Vec2> {
    let pts = &route.points;
    let last = pts.last()?;
    let mut i = from.min(pts.len() - 1);
    while i + 1 < pts.len() && pts[i + 1].route_s < route_s {
        i += 1;
    }
    if i + 1 >= pts.len() {
        return Some(last.position.truncate());
    }
    let (a, b) = (pts[i], pts[i + 1]);
    let t = ((route_s - a.route_s) / (b.route_s - a.route_s).max(1e-3)).clamp(0.0, 1.0);
    Some(a.position.truncate().lerp(b.position.truncate(), t))
}

/// The route points a car's front at route arc length `front_s` stands on
/// and drives towards: the index of the last point at or behind it (`None`
/// before the first point) and of the first point at or ahead of it (the
/// route's length when past the last). What a car has entered (a junction, a
/// lane change) is what the point behind its front belongs to.
pub fn points_around(route: &DenseRoute, front_s: f32) -> (Option<usize>, usize) {
    let ahead = route.points.partition_point(|p| p.route_s < front_s);
    let behind = route.points.partition_point(|p| p.route_s <= front_s);
    (behind.checked_sub(1), ahead)
}

/// The path ahead of a vehicle along its route, for the "ahead" query
/// ([`crate::rules::ahead::nearest_ahead`]): its position first, then the route's
/// points from point `from` on, up to `range_m` metres along the route from
/// that point (metres, ground plane). Clears `out` first.
pub fn route_ahead(
    route: &DenseRoute,
    from: usize,
    position: Vec2,
    range_m: f32,
    out: &mut Vec<Vec2>,
) {
    out.clear();
    out.push(position);
    let start_s = route.points.get(from).map_or(0.0, |p| p.route_s);
    out.extend(
        route.points[from.min(route.points.len())..]
            .iter()
            .take_while(|p| p.route_s - start_s <= range_m)
            .map(|p| p.position.truncate()),
    );
}

/// The route point nearest to `position` among the `window` points from
/// `from` on: (its index, its distance in metres). `None` when there are no
/// points there. Searching a window forward from the point last reached
/// follows a route that passes the same place twice in order.
pub fn nearest_route_point(
    route: &DenseRoute,
    position: Vec2,
    from: usize,
    window: usize,
) -> Option<(usize, f32)> {
    let end = from.saturating_add(window).min(route.points.len());
    let mut best: Option<(usize, f32)> = None;
    for (i, p) in route.points.iter().enumerate().take(end).skip(from) {
        let d2 = p.position.truncate().distance_squared(position);
        if best.is_none_or(|(_, b)| d2 < b) {
            best = Some((i, d2));
        }
    }
    best.map(|(i, d2)| (i, d2.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::testtown::route_through;

    fn l_shape() -> DenseRoute {
        // 10 m east, then 10 m north, 1 m apart.
        let mut p: Vec<Vec2> = (0..=10).map(|i| Vec2::new(i as f32, 0.0)).collect();
        p.extend((1..=10).map(|i| Vec2::new(10.0, i as f32)));
        route_through(&p)
    }

    #[test]
    fn the_distance_of_a_pose_adds_its_offset_along_the_route() {
        let r = l_shape();
        // Reached point 3 (x = 3), standing at x = 3.4, 0.5 m to the side.
        assert!((route_s_at(&r, 3, Vec2::new(3.4, 0.5)) - 3.4).abs() < 1e-5);
        // On the northbound leg, point 15 is (10, 5) at 15 m.
        assert!((route_s_at(&r, 15, Vec2::new(10.2, 5.3)) - 15.3).abs() < 1e-5);
        assert_eq!(route_s_at(&r, 99, Vec2::ZERO), 20.0);
    }

    #[test]
    fn the_point_at_a_distance_interpolates_and_clamps() {
        let r = l_shape();
        assert!(
            route_point_at(&r, 0, 4.25)
                .unwrap()
                .distance(Vec2::new(4.25, 0.0))
                < 1e-5
        );
        assert!(
            route_point_at(&r, 2, 12.5)
                .unwrap()
                .distance(Vec2::new(10.0, 2.5))
                < 1e-5
        );
        assert_eq!(route_point_at(&r, 0, 50.0), Some(Vec2::new(10.0, 10.0)));
        let empty = DenseRoute {
            points: vec![],
            ..r
        };
        assert_eq!(route_point_at(&empty, 0, 1.0), None);
    }

    #[test]
    fn the_path_ahead_starts_at_the_vehicle_and_ends_at_the_range() {
        let r = l_shape();
        let mut out = vec![Vec2::splat(9.0)];
        route_ahead(&r, 8, Vec2::new(8.3, 0.2), 5.0, &mut out);
        // The vehicle, then points 8 ..= 13 (8 m to 13 m along the route).
        assert_eq!(out.len(), 7);
        assert_eq!(out[0], Vec2::new(8.3, 0.2));
        assert_eq!(out[1], Vec2::new(8.0, 0.0));
        assert_eq!(out[6], Vec2::new(10.0, 3.0));
        route_ahead(&r, 99, Vec2::ZERO, 5.0, &mut out);
        assert_eq!(out, vec![Vec2::ZERO]);
    }

    #[test]
    fn the_nearest_point_is_searched_in_its_window_only() {
        // Out 10 m and back along the same line.
        let mut p: Vec<Vec2> = (0..=10).map(|i| Vec2::new(i as f32, 0.0)).collect();
        p.extend((0..10).rev().map(|i| Vec2::new(i as f32, 0.0)));
        let r = route_through(&p);
        // At x = 2 the first pass is found from the start ...
        assert_eq!(
            nearest_route_point(&r, Vec2::new(2.0, 0.3), 0, 5).map(|b| b.0),
            Some(2)
        );
        // ... and the way back from point 12 on.
        let (i, d) = nearest_route_point(&r, Vec2::new(2.0, 0.3), 12, 40).unwrap();
        assert_eq!(i, 18);
        assert!((d - 0.3).abs() < 1e-5);
        assert!(nearest_route_point(&r, Vec2::ZERO, 21, 5).is_none());
    }
}
