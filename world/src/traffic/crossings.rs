//! Walkers sent across the road in front of the ego: a collection aid, like
//! CARLA's pedestrian-crossing scenarios.
//!
//! At the paper's densities a walker in the ego's way is rare (about one frame
//! in 400 of the original set), so a policy sees few examples of braking for
//! one. With [`PedestrianParams::ego_crossings_per_min`] above 0, each tick
//! the ego drives faster than [`MIN_EGO_SPEED_MPS`] starts a crossing with
//! probability `rate * tick / 60 s`:
//!
//! - a crosswalk or jaywalk edge of the walk graph is drawn among those that
//!   cut the ego's heading line [`AHEAD_M`] ahead of its centre;
//! - a walker at least [`FAR_M`] from the ego (so the camera does not see it
//!   vanish) is moved to the edge's kerb end, if the spot is free, and given
//!   the edge as its next leg;
//! - on that leg it does not wait at the kerb for approaching vehicles
//!   ([`crate::agents::pedestrian::Pedestrian::sent`]); everything else about
//!   it is unchanged, so it still stops short of a moving vehicle's next 1.5 s
//!   on the road and never walks into a body.
//!
//! The ego's heading line is a straight guess at its path: crossings are
//! found on straight roads and straight through junctions, not in turns. The
//! draws come from the traffic seed's own stream, so a run stays
//! reproducible. The paper's scenarios leave it at 0.
//!
//! [`PedestrianParams::ego_crossings_per_min`]: crate::agents::pedestrian::PedestrianParams::ego_crossings_per_min

use glam::Vec2;
use rand::RngExt;

use super::Traffic;
use crate::agents::pedestrian::EdgeKind;
use crate::road::geometry::segments_intersect;

/// The ego must drive at least this fast for a crossing to start (m/s).
pub const MIN_EGO_SPEED_MPS: f32 = 2.0;

/// Where along the ego's heading line the crossing must cut it (metres from its centre).
pub const AHEAD_M: std::ops::Range<f32> = 15.0..35.0;

/// The walker sent is at least this far from the ego before it is moved (metres).
pub const FAR_M: f32 = 50.0;

/// The road-crossing edges of a walk graph: (from, to) node pairs.
pub(super) fn crossing_edges(edges: &[Vec<(u32, f32, EdgeKind)>]) -> Vec<(u32, u32)> {
    edges
        .iter()
        .enumerate()
        .flat_map(|(from, out)| {
            out.iter()
                .filter(|e| matches!(e.2, EdgeKind::Crosswalk | EdgeKind::Jaywalk))
                .map(move |e| (from as u32, e.0))
        })
        .collect()
}

impl Traffic {
    /// Maybe sends a walker across the road ahead of the ego (see the module docs); returns whether one was sent.
    pub(super) fn maybe_send_walker(&mut self) -> bool {
        let rate = self.cfg.pedestrian.ego_crossings_per_min;
        let Some(ego) = &self.ego else { return false };
        if rate <= 0.0 || self.pedestrians.is_empty() {
            return false;
        }
        let p_tick = rate * self.cfg.tick_s / 60.0;
        // One draw per tick while the ego drives, so the stream does not depend on the outcome.
        if ego.state.speed_mps < MIN_EGO_SPEED_MPS || self.crossing_rng.random::<f32>() >= p_tick {
            return false;
        }
        let origin = ego.state.position;
        let dir = Vec2::from_angle(ego.state.yaw);
        // The stretch of the heading line a crossing must cut.
        let (line_a, line_b) = (origin + dir * AHEAD_M.start, origin + dir * AHEAD_M.end);
        let nodes = &self.walk.nodes;
        let candidates: Vec<(u32, u32)> = self
            .crossing_edges
            .iter()
            .copied()
            .filter(|&(a, b)| {
                segments_intersect(
                    line_a,
                    line_b,
                    nodes[a as usize].position,
                    nodes[b as usize].position,
                )
            })
            .collect();
        let far: Vec<usize> = (0..self.pedestrians.len())
            .filter(|&i| (self.pedestrians[i].position - origin).length() >= FAR_M)
            .collect();
        if candidates.is_empty() || far.is_empty() {
            return false;
        }
        let (from, to) = candidates[self.crossing_rng.random_range(0..candidates.len())];
        let i = far[self.crossing_rng.random_range(0..far.len())];
        let kerb = nodes[from as usize];
        if !self
            .physics
            .pedestrian_fits(kerb.position, self.cfg.pedestrian.spawn_clearance_m)
        {
            return false;
        }
        let target = nodes[to as usize].position;
        let w = &mut self.pedestrians[i];
        w.position = kerb.position;
        w.z = kerb.z;
        w.yaw = (target - kerb.position).to_angle();
        w.current_speed_mps = 0.0;
        w.from = from;
        w.route = vec![to];
        w.wait_ticks = 0;
        w.blocked_ticks = 0;
        w.sent = true;
        self.physics.add_pedestrian(w.id, kerb.position, kerb.z);
        self.physics.teleport(w.id, kerb.position, w.yaw);
        self.stats.walkers_sent += 1;
        true
    }
}
