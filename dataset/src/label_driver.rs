//! A privileged driver that drives by the action values: at each control
//! boundary it labels the moment it is in (the other actors held where they
//! are, the lights as they are) and decodes the values of its command the
//! way the policy decodes its logits (`softmax(Q / 0.01)`, WoR's decoding).
//!
//! It answers "do the labels say how to drive?" before any network is
//! trained on them: if this driver cannot follow a route and stop at its
//! lights, no policy that imitates the labels can.

use sim::driver::{Driver, DriverNeeds, Observation, VehicleControl};

use crate::action::{NUM_ACTIONS, NUM_COMMANDS, NUM_SPEED_BINS};
use crate::decode::{decode, interpolate_speed};
use crate::format::{ActorRow, EgoRow};
use crate::labels::{FrameInput, Hazards, Labeller};

/// WoR's temperature of the soft targets.
pub const TEMPERATURE: f32 = 0.01;

/// Drives by the labels of the moment.
pub struct LabelDriver {
    labeller: Labeller,
}

impl LabelDriver {
    /// A driver for this town.
    pub fn new(town: &world::Town, vehicle: &world::agents::VehicleParams) -> LabelDriver {
        LabelDriver {
            labeller: Labeller::wor(town, vehicle),
        }
    }
}

impl Driver for LabelDriver {
    fn name(&self) -> String {
        "labels (privileged)".into()
    }

    fn needs(&self) -> DriverNeeds {
        DriverNeeds {
            camera: false,
            privileged: true,
            labels: false,
        }
    }

    fn act(&mut self, obs: &Observation<'_>) -> VehicleControl {
        let Some(p) = obs.privileged else {
            return VehicleControl::default();
        };
        let prm = &self.labeller.params;
        let ego = EgoRow {
            x: p.ego.position.x,
            y: p.ego.position.y,
            yaw: p.ego.heading,
            speed: p.ego.speed_mps,
        };
        let point = p.route.points.get(p.route_index);
        let ego_s = world::rules::route_s_at(p.route, p.route_index, p.ego.position.truncate());
        let light = |l: world::LightIdx| world::rules::light_state(p.lights, l);
        let hazards = Hazards::measure(prm, p.stops, ego_s, light, p.ahead);
        let lights: Vec<u8> = p
            .lights
            .iter()
            .map(|&s| crate::format::light_code(s))
            .collect();
        let steps = self.labeller.steps + 1;
        let actors: Vec<&[ActorRow]> = vec![&[]; steps];
        let light_rows: Vec<&[u8]> = vec![&lights; steps];
        let input = FrameInput {
            ego,
            actors: &actors,
            lights: &light_rows,
            hazards,
            lane: point.map(|q| (q.lane, q.s)),
        };
        let cmd = obs.command as usize;
        let mut wanted = [false; NUM_COMMANDS];
        wanted[cmd] = true;
        let q = &self
            .labeller
            .label_commands(p.town, &input, &[0.0], &wanted)[0][cmd];
        let logits: [[f32; NUM_ACTIONS]; NUM_SPEED_BINS] =
            std::array::from_fn(|b| std::array::from_fn(|a| q[b][a] / TEMPERATURE));
        decode(
            &interpolate_speed(&logits, obs.speed_mps),
            obs.speed_mps,
            obs.command,
        )
        .control
    }
}
