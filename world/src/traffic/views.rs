//! What the traffic world shows: every actor as the behaviours see it
//! ([`ActorView`], refreshed after each change), snapshots for the camera,
//! the monitors and the logs, and the query for what is ahead of the ego.

use glam::{Vec2, Vec3};

use super::Traffic;
use crate::agents::npc::Npc;
use crate::agents::{ActorKind, ActorSnapshot, VehicleParams};
use crate::physics::{PEDESTRIAN_HEIGHT_M, PEDESTRIAN_RADIUS_M};
use crate::rules::{ActorView, Ahead, nearest_ahead, walker_horizon_s};

impl Traffic {
    /// Every actor as the behaviours see it (start of the next tick).
    pub fn actor_views(&self) -> &[ActorView] {
        &self.views
    }

    /// The nearest actor other than the ego ahead along a path (points ~1 m apart from the ego's centre): see [`crate::rules::ahead`].
    pub fn nearest_ahead_of_ego(
        &self,
        path: &[Vec2],
        corridor_half_m: f32,
        max_m: f32,
    ) -> Option<Ahead> {
        let speed = self.ego.as_ref().map_or(0.0, |e| e.state.speed_mps);
        nearest_ahead(
            path,
            &self.views,
            Some(0),
            corridor_half_m,
            max_m,
            walker_horizon_s(speed),
        )
    }

    pub(super) fn refresh_views(&mut self) {
        self.views.clear();
        let (hl, hw) = (
            self.cfg.vehicle.length_m * 0.5,
            self.cfg.vehicle.width_m * 0.5,
        );
        if let Some(e) = &self.ego {
            self.views.push(ActorView {
                id: 0,
                kind: ActorKind::Ego,
                position: e.state.position,
                yaw: e.state.yaw,
                speed_mps: e.state.speed_mps,
                half_length_m: hl,
                half_width_m: hw,
            });
        }
        for n in &self.npcs {
            self.views.push(npc_view(n, &self.cfg.vehicle));
        }
        for p in &self.pedestrians {
            self.views.push(ActorView {
                id: p.id,
                kind: ActorKind::Pedestrian,
                position: p.position,
                yaw: p.yaw,
                speed_mps: p.current_speed_mps,
                half_length_m: PEDESTRIAN_RADIUS_M,
                half_width_m: PEDESTRIAN_RADIUS_M,
            });
        }
    }

    /// Snapshots of every actor for the camera, monitors and logs (ego first, then by id).
    pub fn snapshots(&self, out: &mut Vec<ActorSnapshot>) {
        out.clear();
        let size = self.vehicle_size();
        if let Some(e) = &self.ego {
            out.push(ActorSnapshot {
                id: 0,
                kind: ActorKind::Ego,
                position: e.state.position.extend(e.z),
                heading: e.state.yaw,
                extent: size,
                speed_mps: e.state.speed_mps,
                color: 0,
            });
        }
        for n in &self.npcs {
            out.push(ActorSnapshot {
                id: n.id,
                kind: ActorKind::Vehicle,
                position: n.state.position.extend(n.ground_z),
                heading: n.state.yaw,
                extent: size,
                speed_mps: n.state.speed_mps,
                color: n.color,
            });
        }
        for p in &self.pedestrians {
            out.push(ActorSnapshot {
                id: p.id,
                kind: ActorKind::Pedestrian,
                position: p.position.extend(p.z),
                heading: p.yaw,
                extent: Vec3::new(
                    2.0 * PEDESTRIAN_RADIUS_M,
                    2.0 * PEDESTRIAN_RADIUS_M,
                    PEDESTRIAN_HEIGHT_M,
                ),
                speed_mps: p.current_speed_mps,
                color: (p.id % 8) as u8,
            });
        }
    }
}

/// How the rules see NPC `n`, a car of `vp`: where it is, its heading and speed.
pub(super) fn npc_view(n: &Npc, vp: &VehicleParams) -> ActorView {
    ActorView {
        id: n.id,
        kind: ActorKind::Vehicle,
        position: n.state.position,
        yaw: n.state.yaw,
        speed_mps: n.state.speed_mps,
        half_length_m: vp.length_m * 0.5,
        half_width_m: vp.width_m * 0.5,
    }
}
