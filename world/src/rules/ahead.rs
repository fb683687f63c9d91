//! What is ahead along a path: the one definition the NPCs and the expert share.
//!
//! An actor is "ahead" when its footprint reaches into a corridor around the
//! path (a polyline starting at the asking vehicle's reference point, points
//! about 1 m apart) and lies in front of the path's start. Its distance is
//! measured along the path to the near edge of its footprint.
//!
//! A walking pedestrian counts where it will be, too: its footprint is also
//! tested every [`PEDESTRIAN_PREDICT_STEP_S`] seconds up to a horizon,
//! moved along its heading at its speed, and the nearest hit along the path
//! wins. A walker about to step off the kerb is then ahead before it is in
//! the lane. The horizon is the asking vehicle's stopping time
//! ([`walker_horizon_s`]: its speed over [`STOPPING_DECEL_MPS2`], at most
//! [`PEDESTRIAN_PREDICT_S`]): a moving car brakes for a walker it would
//! otherwise reach, and a standing car (horizon 0) is held only by a walker
//! already in its way. Without that a car waiting at a busy crosswalk would
//! never start, since walkers yield only to moving vehicles. Vehicles follow
//! lanes, so a straight-line guess would be wrong for them; they count where
//! they are.

use crate::agents::actor::ActorKind;
use glam::Vec2;

/// A moving actor as the behaviours see it at the start of a tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActorView {
    /// The actor's id (the ego is 0).
    pub id: u32,
    /// Ego, vehicle or pedestrian.
    pub kind: ActorKind,
    /// Centre of its footprint (metres, ground plane).
    pub position: Vec2,
    /// Heading (radians).
    pub yaw: f32,
    /// Speed along the heading (metres per second).
    pub speed_mps: f32,
    /// Half its length (metres).
    pub half_length_m: f32,
    /// Half its width (metres).
    pub half_width_m: f32,
}

/// The nearest actor ahead along a path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ahead {
    /// The actor's id.
    pub id: u32,
    /// Its kind.
    pub kind: ActorKind,
    /// Path distance from the path's start to the near edge of its footprint (metres, >= 0).
    pub distance_m: f32,
    /// Its speed along the path's direction there (metres per second; negative when oncoming).
    pub speed_along_mps: f32,
}

/// Chord length of the coarse pass (path points).
const COARSE: usize = 5;

/// The longest horizon of a walking pedestrian's predicted position (seconds):
/// about the time a car at 6 m/s needs to stop at [`STOPPING_DECEL_MPS2`].
pub const PEDESTRIAN_PREDICT_S: f32 = 2.0;

/// The deceleration that sets a vehicle's stopping time in [`walker_horizon_s`] (m/s^2).
pub const STOPPING_DECEL_MPS2: f32 = 3.0;

/// How far ahead (seconds) a vehicle moving at `speed_mps` predicts walking
/// pedestrians: its stopping time at [`STOPPING_DECEL_MPS2`], at most
/// [`PEDESTRIAN_PREDICT_S`]; 0 when it stands.
pub fn walker_horizon_s(speed_mps: f32) -> f32 {
    (speed_mps.max(0.0) / STOPPING_DECEL_MPS2).min(PEDESTRIAN_PREDICT_S)
}

/// Step of the predicted pedestrian positions (seconds).
pub const PEDESTRIAN_PREDICT_STEP_S: f32 = 0.25;

/// Below this speed a pedestrian counts as standing (metres per second).
const PEDESTRIAN_STANDING_MPS: f32 = 0.1;

/// How many prediction steps of an actor are tested beyond where it is now:
/// up to `horizon_s` for a walking pedestrian, none for anyone else.
fn predicted_steps(a: &ActorView, horizon_s: f32) -> usize {
    let walking = a.kind == ActorKind::Pedestrian && a.speed_mps > PEDESTRIAN_STANDING_MPS;
    if walking {
        (horizon_s.clamp(0.0, PEDESTRIAN_PREDICT_S) / PEDESTRIAN_PREDICT_STEP_S).round() as usize
    } else {
        0
    }
}

/// Where an actor's footprint is tested: where it is now, and for a walking
/// pedestrian where it will be at each of `steps` prediction steps
/// ([`predicted_steps`]) along its unit `heading`.
fn test_positions(a: &ActorView, heading: Vec2, steps: usize) -> impl Iterator<Item = Vec2> + '_ {
    let step = heading * (a.speed_mps * PEDESTRIAN_PREDICT_STEP_S);
    (0..=steps).map(move |k| a.position + step * k as f32)
}

/// Nearest actor (other than `exclude`) ahead along `path` within `max_m`, whose footprint comes within `corridor_half_m` of the path (metres); a walking pedestrian's footprint is also tested where it will be up to `walker_horizon_s` seconds ahead (give [`walker_horizon_s`] of the asking vehicle's speed; see the module's doc).
pub fn nearest_ahead(
    path: &[Vec2],
    actors: &[ActorView],
    exclude: Option<u32>,
    corridor_half_m: f32,
    max_m: f32,
    walker_horizon_s: f32,
) -> Option<Ahead> {
    if path.len() < 2 {
        return None;
    }
    let mut lo = Vec2::splat(f32::INFINITY);
    let mut hi = Vec2::splat(f32::NEG_INFINITY);
    for p in path {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let pad = corridor_half_m + 3.5;
    lo -= Vec2::splat(pad);
    hi += Vec2::splat(pad);
    let mut best: Option<Ahead> = None;
    for a in actors {
        if Some(a.id) == exclude {
            continue;
        }
        // Every tested position lies within its travel of where it is now
        // (1 m more for rounding): most actors are refused here, before
        // their heading is computed.
        let steps = predicted_steps(a, walker_horizon_s);
        let travel = Vec2::splat(a.speed_mps * PEDESTRIAN_PREDICT_STEP_S * steps as f32 + 1.0);
        if a.position.cmplt(lo - travel).any() || a.position.cmpgt(hi + travel).any() {
            continue;
        }
        let heading = Vec2::from_angle(a.yaw);
        for position in test_positions(a, heading, steps) {
            if position.cmplt(lo).any() || position.cmpgt(hi).any() {
                continue;
            }
            if let Some(dist) = footprint_ahead(path, a, heading, position, corridor_half_m, max_m)
                && best.is_none_or(|b| dist.0 < b.distance_m)
            {
                best = Some(Ahead {
                    id: a.id,
                    kind: a.kind,
                    distance_m: dist.0,
                    speed_along_mps: dist.1,
                });
            }
        }
    }
    best
}

/// Whether the footprint of `a` (unit `heading`), placed at `position`,
/// reaches into the corridor ahead along `path`: its path distance (metres,
/// the nearest crossing) and its speed along the path there (m/s).
fn footprint_ahead(
    path: &[Vec2],
    a: &ActorView,
    heading: Vec2,
    position: Vec2,
    corridor_half_m: f32,
    max_m: f32,
) -> Option<(f32, f32)> {
    let n = path.len();
    let mut best: Option<(f32, f32)> = None;
    let reach = corridor_half_m + a.half_length_m.max(a.half_width_m);
    // Coarse pass over chords of COARSE segments (their sagitta is below 1 m on
    // our lanes), then a fine pass around the first chord that comes near.
    let mut k = 0;
    while k + 1 < n {
        let k2 = (k + COARSE).min(n - 1);
        if seg_dist(position, path[k], path[k2]).0 > reach + 1.0 {
            k = k2;
            continue;
        }
        let lo = k.saturating_sub(COARSE);
        let hi = (k2 + COARSE).min(n - 1);
        let mut near: Option<(f32, usize, f32)> = None;
        for i in lo..hi {
            let (d, t) = seg_dist(position, path[i], path[i + 1]);
            if near.is_none_or(|b| d < b.0) {
                near = Some((d, i, t));
            }
        }
        k = hi;
        let Some((d, i, t)) = near else { continue };
        if d > reach {
            continue;
        }
        let seg = path[i + 1] - path[i];
        let seg_len = seg.length().max(1e-6);
        let dir = seg / seg_len;
        let (c, s) = (heading.dot(dir).abs(), heading.perp_dot(dir).abs());
        let lat_ext = s * a.half_length_m + c * a.half_width_m;
        let long_ext = c * a.half_length_m + s * a.half_width_m;
        let lateral = dir.perp_dot(position - path[i]).abs();
        if lateral > corridor_half_m + lat_ext {
            continue;
        }
        if i == 0 && t <= 0.0 && (position - path[0]).dot(dir) < 0.0 {
            continue; // behind the start
        }
        let along = path_len_to(path, i) + t * seg_len;
        let dist = (along - long_ext).max(0.0);
        if dist > max_m {
            continue;
        }
        if best.is_none_or(|b| dist < b.0) {
            best = Some((dist, a.speed_mps * heading.dot(dir)));
        }
    }
    best
}

fn path_len_to(path: &[Vec2], i: usize) -> f32 {
    path[..=i].windows(2).map(|w| (w[1] - w[0]).length()).sum()
}

/// Distance from `p` to segment `a`-`b` and the parameter of the nearest point.
fn seg_dist(p: Vec2, a: Vec2, b: Vec2) -> (f32, f32) {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
    ((a + ab * t - p).length(), t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn car(id: u32, x: f32, y: f32, yaw: f32) -> ActorView {
        ActorView {
            id,
            kind: ActorKind::Vehicle,
            position: Vec2::new(x, y),
            yaw,
            speed_mps: 2.0,
            half_length_m: 2.4,
            half_width_m: 1.1,
        }
    }

    #[test]
    fn finds_the_nearest_actor_in_the_corridor() {
        let path: Vec<Vec2> = (0..40).map(|i| Vec2::new(i as f32, 0.0)).collect();
        let actors = [
            car(1, 20.0, 0.3, 0.0),
            car(2, 12.0, 3.6, 0.0), // next lane: outside the corridor
            car(3, 30.0, 0.0, 0.0), // farther
            car(4, -6.0, 0.0, 0.0), // behind
            car(5, 15.0, 2.5, std::f32::consts::FRAC_PI_2), // crossing, nose in the corridor
        ];
        let a = nearest_ahead(&path, &actors, None, 1.2, 50.0, PEDESTRIAN_PREDICT_S).unwrap();
        assert_eq!(a.id, 5);
        assert!(
            (a.distance_m - (15.0 - 1.1)).abs() < 0.05,
            "{}",
            a.distance_m
        );
        assert!(a.speed_along_mps.abs() < 1e-3);
        let a = nearest_ahead(&path, &actors[..4], None, 1.2, 50.0, PEDESTRIAN_PREDICT_S).unwrap();
        assert_eq!(a.id, 1);
        assert!((a.distance_m - 17.6).abs() < 0.05);
        assert!((a.speed_along_mps - 2.0).abs() < 1e-4);
        assert!(
            nearest_ahead(
                &path,
                &actors[..4],
                Some(1),
                1.2,
                10.0,
                PEDESTRIAN_PREDICT_S
            )
            .is_none()
        );
    }

    #[test]
    fn follows_a_curved_path() {
        // Quarter circle of radius 10 m, points ~1 m apart.
        let path: Vec<Vec2> = (0..=16)
            .map(|i| Vec2::from_angle(i as f32 / 10.0) * 10.0)
            .collect();
        let on = Vec2::from_angle(1.2) * 10.0;
        // A standing walker: only where it is counts.
        let actors = [ActorView {
            id: 7,
            kind: ActorKind::Pedestrian,
            position: on,
            yaw: 0.0,
            speed_mps: 0.0,
            half_length_m: 0.3,
            half_width_m: 0.3,
        }];
        let a = nearest_ahead(&path, &actors, None, 1.0, 30.0, PEDESTRIAN_PREDICT_S).unwrap();
        assert!(
            (a.distance_m - (12.0 - 0.3)).abs() < 0.2,
            "{}",
            a.distance_m
        );
        let off = [ActorView {
            position: on * 1.3,
            ..actors[0]
        }];
        assert!(nearest_ahead(&path, &off, None, 1.0, 30.0, PEDESTRIAN_PREDICT_S).is_none());
    }

    fn walker(x: f32, y: f32, yaw: f32, speed_mps: f32) -> ActorView {
        ActorView {
            id: 9,
            kind: ActorKind::Pedestrian,
            position: Vec2::new(x, y),
            yaw,
            speed_mps,
            half_length_m: 0.3,
            half_width_m: 0.3,
        }
    }

    #[test]
    fn a_walker_heading_for_the_path_is_ahead_before_it_steps_in() {
        use std::f32::consts::FRAC_PI_2;
        let path: Vec<Vec2> = (0..40).map(|i| Vec2::new(i as f32, 0.0)).collect();
        // 3.1 m to the left of the path, 9 m ahead: outside the 1.4 m corridor.
        let toward = walker(9.0, 3.1, -FRAC_PI_2, 1.3);
        let a = nearest_ahead(&path, &[toward], None, 1.4, 40.0, PEDESTRIAN_PREDICT_S).unwrap();
        assert_eq!(a.id, 9);
        assert!((a.distance_m - 8.7).abs() < 0.05, "{}", a.distance_m);
        assert!(a.speed_along_mps.abs() < 1e-3);
        // The same walker standing, walking away, or walking too slowly to
        // reach the corridor within the prediction, is not ahead.
        for w in [
            walker(9.0, 3.1, -FRAC_PI_2, 0.0),
            walker(9.0, 3.1, FRAC_PI_2, 1.3),
            walker(9.0, 3.1, -FRAC_PI_2, 0.5),
        ] {
            assert!(
                nearest_ahead(&path, &[w], None, 1.4, 40.0, PEDESTRIAN_PREDICT_S).is_none(),
                "{w:?}"
            );
        }
        // The horizon is the asker's stopping time: a car at 6 m/s looks 2 s
        // ahead and sees the walker; a standing car (0 s) does not until it is
        // in the corridor, and a car at 1.5 m/s (0.5 s: 0.65 m) does not either.
        assert_eq!(walker_horizon_s(6.0), PEDESTRIAN_PREDICT_S);
        assert_eq!(walker_horizon_s(0.0), 0.0);
        assert!(nearest_ahead(&path, &[toward], None, 1.4, 40.0, walker_horizon_s(6.0)).is_some());
        for speed in [0.0, 1.5] {
            let h = walker_horizon_s(speed);
            assert!(
                nearest_ahead(&path, &[toward], None, 1.4, 40.0, h).is_none(),
                "{speed}"
            );
        }
        let stepped_in = walker(9.0, 1.5, -FRAC_PI_2, 1.3);
        assert!(nearest_ahead(&path, &[stepped_in], None, 1.4, 40.0, 0.0).is_some());
        // A vehicle with the same motion counts only where it is.
        let crossing_car = car(3, 9.0, 5.0, -FRAC_PI_2);
        assert!(
            nearest_ahead(
                &path,
                &[crossing_car],
                None,
                1.4,
                40.0,
                PEDESTRIAN_PREDICT_S
            )
            .is_none()
        );
        // A quick walker that starts beyond the box the path is searched in
        // (corridor + 3.5 m to either side) and reaches the corridor within
        // the horizon is ahead too: the box is grown by its travel.
        let from_afar = walker(9.0, 6.5, -FRAC_PI_2, 3.0);
        let a = nearest_ahead(&path, &[from_afar], None, 1.4, 40.0, PEDESTRIAN_PREDICT_S).unwrap();
        assert_eq!(a.id, 9);
        assert!(nearest_ahead(&path, &[from_afar], None, 1.4, 40.0, 0.0).is_none());
        // Walking along the path, the walker is where it is, not where it goes.
        let along = walker(20.0, 0.0, 0.0, 1.3);
        let a = nearest_ahead(&path, &[along], None, 1.4, 40.0, PEDESTRIAN_PREDICT_S).unwrap();
        assert!((a.distance_m - 19.7).abs() < 0.05, "{}", a.distance_m);
        assert!((a.speed_along_mps - 1.3).abs() < 1e-4);
    }
}
