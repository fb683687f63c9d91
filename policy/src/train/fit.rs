//! How well a network fits a labelled dataset, sample by sample, in the terms the
//! driver acts on: at the frame's own command and speed (the logits interpolated
//! between speed bins as the decoder does), the KL to the Boltzmann target, whether
//! the most likely action agrees, and how often target and network brake
//! (P(brake) > 0.5). Split into standing (< 0.5 m/s) and moving frames, and
//! follow and turn commands: a policy that brakes on a free road shows here before
//! it stalls on a route.

use super::loader::{Loader, LoaderConfig, TrainSet};
use super::losses::TEMPERATURE;
use crate::model::PolicyNet;
use burn::prelude::*;
use dataset::action::{BRAKE, NUM_ACTIONS, NUM_COMMANDS, NUM_SPEED_BINS};
use dataset::decode::{BRAKE_THRESHOLD, interpolate_speed, softmax};
use std::sync::Arc;

/// The statistics of one group of samples.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FitGroup {
    /// What the group holds ("standing, follow", ...).
    pub name: String,
    /// Samples.
    pub n: usize,
    /// Mean KL(target || network) over the 28 actions (nats).
    pub kl: f64,
    /// Share of samples whose most likely action is the target's.
    pub argmax_agree: f64,
    /// Share where the target brakes (P > 0.5).
    pub target_brakes: f64,
    /// Share where the network brakes (P > 0.5).
    pub net_brakes: f64,
    /// Share where exactly one of the two brakes.
    pub brake_disagree: f64,
}

/// Fits `net` (branch `branch`, at its scale) on `batches` unaugmented batches of
/// `batch` samples drawn in a seeded order from `set`.
pub fn fit(
    net: &PolicyNet,
    branch: usize,
    set: &Arc<TrainSet>,
    batches: usize,
    batch: usize,
    device: &Device,
) -> Vec<FitGroup> {
    let cfg = LoaderConfig {
        augment: None,
        epochs: Some(1),
        ..LoaderConfig::new(batch, 0x0f17)
    };
    let scale = net.config.scales[branch];
    let mut loader = Loader::start(set.clone(), &net.config, cfg);
    // Groups: standing/moving x follow/turn (turns: commands 0-2; the rest "follow").
    let names = [
        "standing, follow",
        "standing, turn",
        "moving, follow",
        "moving, turn",
    ];
    let mut acc: Vec<[f64; 6]> = vec![[0.0; 6]; 4];
    for _ in 0..batches {
        let Some(hb) = loader.next_host() else { break };
        let b = hb.to_batch(device);
        let x = super::resize::resize_to_scale(b.images, scale);
        let z = net.forward(x, branch, false).action_logits;
        let z: Vec<f32> = z.into_data().try_to_vec().expect("f32 logits");
        let per = NUM_COMMANDS * NUM_SPEED_BINS * NUM_ACTIONS;
        for (i, s) in hb.samples.iter().enumerate() {
            let c = usize::from(s.command);
            let speed = set.speed_mps(s);
            let bins = |v: &[f32]| -> [[f32; NUM_ACTIONS]; NUM_SPEED_BINS] {
                std::array::from_fn(|k| {
                    std::array::from_fn(|j| v[i * per + (c * NUM_SPEED_BINS + k) * NUM_ACTIONS + j])
                })
            };
            let q = interpolate_speed(&bins(&hb.q), speed);
            let target = softmax(&std::array::from_fn(|j| q[j] / TEMPERATURE));
            let pred = softmax(&interpolate_speed(&bins(&z), speed));
            let kl: f64 = (0..NUM_ACTIONS)
                .filter(|&j| target[j] > 0.0)
                .map(|j| {
                    f64::from(target[j])
                        * (f64::from(target[j]) / f64::from(pred[j]).max(1e-12)).ln()
                })
                .sum();
            let argmax = |p: &[f32; NUM_ACTIONS]| {
                (0..NUM_ACTIONS)
                    .max_by(|&a, &b| p[a].total_cmp(&p[b]))
                    .unwrap_or(0)
            };
            let (tb, nb) = (
                target[BRAKE] > BRAKE_THRESHOLD,
                pred[BRAKE] > BRAKE_THRESHOLD,
            );
            let g = usize::from(speed >= 0.5) * 2 + usize::from(c < 3);
            let a = &mut acc[g];
            a[0] += 1.0;
            a[1] += kl;
            a[2] += f64::from(u8::from(argmax(&target) == argmax(&pred)));
            a[3] += f64::from(u8::from(tb));
            a[4] += f64::from(u8::from(nb));
            a[5] += f64::from(u8::from(tb != nb));
        }
    }
    acc.iter()
        .zip(names)
        .map(|(a, name)| {
            let n = a[0].max(1.0);
            FitGroup {
                name: name.into(),
                n: a[0] as usize,
                kl: a[1] / n,
                argmax_agree: a[2] / n,
                target_brakes: a[3] / n,
                net_brakes: a[4] / n,
                brake_disagree: a[5] / n,
            }
        })
        .collect()
}

/// The groups as a Markdown table, shares in percent (`mrdrive policy fit`).
pub fn markdown(groups: &[FitGroup]) -> String {
    use std::fmt::Write;
    let mut out = String::from(
        "| frames | n | KL (nats) | argmax agrees | target brakes | net brakes | brake disagrees |\n\
         | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for g in groups {
        let _ = writeln!(
            out,
            "| {} | {} | {:.3} | {:.1} % | {:.1} % | {:.1} % | {:.1} % |",
            g.name,
            g.n,
            g.kl,
            100.0 * g.argmax_agree,
            100.0 * g.target_brakes,
            100.0 * g.net_brakes,
            100.0 * g.brake_disagree
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_has_a_row_per_group_in_percent() {
        let g = FitGroup {
            name: "moving, turn".into(),
            n: 12,
            kl: 0.25,
            argmax_agree: 0.5,
            target_brakes: 0.125,
            net_brakes: 0.0,
            brake_disagree: 0.125,
        };
        assert_eq!(
            markdown(&[g]),
            "| frames | n | KL (nats) | argmax agrees | target brakes | net brakes | brake disagrees |\n\
             | --- | --- | --- | --- | --- | --- | --- |\n\
             | moving, turn | 12 | 0.250 | 50.0 % | 12.5 % | 0.0 % | 12.5 % |\n"
        );
    }
}
