//! Whether a run's frame could overlap its render with its policy pass: the
//! rig frame `k + 1` rendered while the policy acts on frame `k`, against the
//! two one after the other as the closed loop does them now.
//!
//! A run keeps about one core busy (`docs/scale-out.md`): the render and the
//! policy take turns. Where the latency in force is at least the control
//! period, the next frame's picture does not depend on the action being
//! computed (that action lands at the next boundary, after its picture is
//! taken), so the two could run at once. This measures what that would win
//! on this machine with the real renderer and the fused policy (random
//! weights: the arithmetic is the trained network's) before the loop is
//! changed for it.

use std::time::Instant;

use burn::prelude::*;
use sim::render::{RenderError, Renderer, RigConfig, demo};

use crate::fused::FusedPolicy;
use crate::model::PolicyConfig;

/// Frames per second of the two layouts, median over repeats.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Overlap {
    /// The rig's frame (width, height) at the scale timed.
    pub size: (u32, u32),
    /// Render, then policy, one frame after the other (frames per second).
    pub sequential_fps: f64,
    /// The policy on frame `k` on a second thread while frame `k + 1` renders.
    pub overlapped_fps: f64,
}

/// Times `frames` frames `repeats` times in each layout (interleaved), at
/// `scale` of the CPU rig in the 4 x 4 demo town.
pub fn overlap(scale: f32, frames: usize, repeats: usize) -> Result<Overlap, RenderError> {
    let town = demo::grid_town(4, 4, 100.0, 7);
    let (ego, actors, states) = demo::demo_state(&town);
    let mut renderer = Renderer::new(&town, RigConfig::cpu_default(), 7)?;
    let device = Device::flex();
    device.seed(0);
    let policy = FusedPolicy::from_net(&PolicyConfig::cpu_default().init(&device));
    let branch = usize::from(scale >= 1.0);
    let mut render = |k: usize| -> Result<(Vec<u8>, u32, u32), RenderError> {
        // The ego creeps forward, so frames differ as a drive's do.
        let mut pose = ego;
        pose.position.x += 0.25 * k as f32;
        let (rgb, _) = renderer.render_rig(&pose, &actors, &states, scale)?;
        Ok((rgb.data.clone(), rgb.width, rgb.height))
    };
    let act = |(rgb, w, h): &(Vec<u8>, u32, u32)| {
        std::hint::black_box(policy.forward_rgb8(rgb, *h as usize, *w as usize, branch));
    };
    let (_, w, h) = render(0)?;
    let mut seq = Vec::new();
    let mut ovl = Vec::new();
    for round in 0..repeats + 1 {
        let t0 = Instant::now();
        for k in 0..frames {
            let frame = render(k)?;
            act(&frame);
        }
        let sequential = frames as f64 / t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let mut previous = render(0)?;
        for k in 1..=frames {
            let next = std::thread::scope(|s| {
                let acting = s.spawn(|| act(&previous));
                let next = render(k);
                acting.join().expect("the policy pass does not panic");
                next
            })?;
            previous = next;
        }
        let overlapped = frames as f64 / t0.elapsed().as_secs_f64();
        // The first round warms both up.
        if round > 0 {
            seq.push(sequential);
            ovl.push(overlapped);
        }
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    Ok(Overlap {
        size: (w, h),
        sequential_fps: median(seq),
        overlapped_fps: median(ovl),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use world::testdata::{self, Needs};

    #[test]
    fn both_layouts_are_timed_on_the_rigs_frame() {
        let o = match overlap(0.75, 2, 1) {
            Ok(o) => o,
            Err(e) => {
                testdata::skip(
                    "both_layouts_are_timed_on_the_rigs_frame",
                    Needs::Renderer,
                    &e.to_string(),
                );
                return;
            }
        };
        assert_eq!(o.size, (180, 72));
        assert!(o.sequential_fps > 0.0 && o.overlapped_fps > 0.0, "{o:?}");
    }
}
