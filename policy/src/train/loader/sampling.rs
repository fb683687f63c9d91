//! Which samples an epoch draws and how often: [`Sampling`], one struct for a
//! stage's spec, the loader and the checkpoint's card.

use serde::{Deserialize, Serialize};

/// Below this speed a frame counts as standing (metres per second).
pub const STANDING_MPS: f32 = 0.5;

/// Which samples an epoch draws and how often: one struct for a stage's spec, the
/// loader and the checkpoint's card (flattened into their JSON). The default is WoR's:
/// every sample once per epoch. A frame that is of several repeated kinds appears the
/// largest of their numbers of times.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Sampling {
    /// Draw commands evenly instead of visiting every sample once per epoch.
    pub balanced: bool,
    /// The share of standing frames (ego below [`STANDING_MPS`]) kept, in [0, 1]: a
    /// fixed subset chosen by the seed (1 keeps all). Waiting at red lights fills a third
    /// of our data; fewer of those frames weaken the "junction ahead: brake" prior.
    pub standing_keep: f64,
    /// How many times each kept starting frame ([`TrainSet::starts`](super::set::TrainSet::starts): standing, and
    /// the target goes, as when the light has just turned green) appears per epoch (1:
    /// once). They are about one standing frame in 25.
    pub start_repeat: usize,
    /// How many times each kept frame with a pedestrian ahead
    /// ([`TrainSet::pedestrian_ahead`](super::set::TrainSet::pedestrian_ahead)) appears per epoch (1: once).
    pub pedestrian_repeat: usize,
    /// How many times each kept frame with a stopped vehicle ahead
    /// ([`TrainSet::stopped_vehicle_ahead`](super::set::TrainSet::stopped_vehicle_ahead): a queue at a light, a car waiting) appears
    /// per epoch (1: once). At the paper's densities they are under 1 % of the frames.
    pub stopped_vehicle_repeat: usize,
}

impl Default for Sampling {
    fn default() -> Self {
        Sampling {
            balanced: false,
            standing_keep: 1.0,
            start_repeat: 1,
            pedestrian_repeat: 1,
            stopped_vehicle_repeat: 1,
        }
    }
}

impl Sampling {
    /// A phrase for a model card: how the samples were drawn (", commands drawn
    /// evenly, starting frames 8 times").
    pub fn describe(&self) -> String {
        let mut s = String::from(if self.balanced {
            ", commands drawn evenly"
        } else {
            ", every sample once per epoch"
        });
        if self.standing_keep < 1.0 {
            s += &format!(", {} of the standing frames", self.standing_keep);
        }
        for (n, what) in [
            (self.start_repeat, "starting frames"),
            (self.pedestrian_repeat, "frames with a pedestrian ahead"),
            (
                self.stopped_vehicle_repeat,
                "frames with a stopped vehicle ahead",
            ),
        ] {
            if n > 1 {
                s += &format!(", {what} {n} times");
            }
        }
        s
    }
}
