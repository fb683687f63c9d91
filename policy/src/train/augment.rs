//! WoR's image augmentations, seeded: each op applies with probability 0.5,
//! in a random order (imgaug's `Sequential(random_order=True)` of
//! `Sometimes(0.5, op)`), on the 8-bit RGB image; every op rounds and clips
//! back to 0-255, as imgaug does on `uint8` images.
//!
//! | op | what | parameters ([`AugmentConfig::default`]) |
//! | --- | --- | --- |
//! | blur | Gaussian, separable, edges clamped | sigma ~ U(0, 1.3) px |
//! | noise | additive Gaussian | std ~ U(0, 0.05 x 255); per channel with p 0.5, else one value per pixel |
//! | dropout | pixels (or, per channel with p 0.5, channel values) set to 0 | rate ~ U(0.01, 0.1) |
//! | brightness | multiply | factor ~ U(1/1.2, 1.2); per channel with p 0.5 |
//! | contrast | `128 + a (v - 128)` | a ~ U(1/1.2, 1.2); per channel with p 0.5 |
//! | grayscale | blend towards the luma `0.299 R + 0.587 G + 0.114 B` | alpha ~ U(0, 0.5) |
//! | warp | smooth displacement: a random shift per node of a grid 16 px apart, interpolated bilinearly between nodes; RGB sampled bilinearly, the class image by nearest neighbour with the same field | amplitude ~ U(0.5, 2) px per axis |
//!
//! Only the warp moves pixels, so only the warp touches the class image:
//! the segmentation target stays aligned with the picture.
//!
//! All randomness comes from the generator passed in; the loader seeds it
//! per sample from (epoch seed, sample index), so the result does not
//! depend on threads or timing.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Probabilities and parameter ranges of the augmentations.
#[derive(Debug, Clone, PartialEq)]
pub struct AugmentConfig {
    /// Probability that each op applies.
    pub p: f64,
    /// Probability that an op with a per-channel form draws per channel.
    pub per_channel_p: f64,
    /// Blur sigma range (pixels).
    pub blur_sigma_px: (f32, f32),
    /// Noise standard deviation range (0-255 units).
    pub noise_std: (f32, f32),
    /// Dropout rate range.
    pub dropout: (f32, f32),
    /// Brightness factor range.
    pub brightness: (f32, f32),
    /// Contrast factor range.
    pub contrast: (f32, f32),
    /// Grayscale blend range.
    pub grayscale: (f32, f32),
    /// Warp amplitude range (pixels).
    pub warp_px: (f32, f32),
    /// Spacing of the warp's grid nodes (pixels).
    pub warp_grid_px: usize,
}

impl Default for AugmentConfig {
    fn default() -> Self {
        AugmentConfig {
            p: 0.5,
            per_channel_p: 0.5,
            blur_sigma_px: (0.0, 1.3),
            noise_std: (0.0, 0.05 * 255.0),
            dropout: (0.01, 0.1),
            brightness: (1.0 / 1.2, 1.2),
            contrast: (1.0 / 1.2, 1.2),
            grayscale: (0.0, 0.5),
            warp_px: (0.5, 2.0),
            warp_grid_px: 16,
        }
    }
}

/// One augmentation op.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Op {
    /// Gaussian blur.
    Blur,
    /// Additive Gaussian noise.
    Noise,
    /// Pixel dropout.
    Dropout,
    /// Brightness (multiply).
    Brightness,
    /// Linear contrast.
    Contrast,
    /// Partial grayscale.
    Grayscale,
    /// Small smooth warp.
    Warp,
}

impl Op {
    /// Every op.
    pub const ALL: [Op; 7] = [
        Op::Blur,
        Op::Noise,
        Op::Dropout,
        Op::Brightness,
        Op::Contrast,
        Op::Grayscale,
        Op::Warp,
    ];
}

/// An 8-bit RGB image and its class image, `width x height`, row-major.
pub struct Sample<'a> {
    /// `H x W x 3` bytes.
    pub rgb: &'a mut [u8],
    /// `H x W` class ids.
    pub classes: &'a mut [u8],
    /// Width (pixels).
    pub width: usize,
    /// Height (pixels).
    pub height: usize,
}

/// Augments `s` with the ops drawn from `rng`; returns the ops applied, in order.
pub fn augment(s: &mut Sample<'_>, cfg: &AugmentConfig, rng: &mut ChaCha8Rng) -> Vec<Op> {
    let mut order = Op::ALL;
    for i in (1..order.len()).rev() {
        order.swap(i, rng.random_range(0..=i));
    }
    let mut applied = Vec::new();
    for op in order {
        if rng.random_bool(cfg.p) {
            apply(op, s, cfg, rng);
            applied.push(op);
        }
    }
    applied
}

/// Applies one op with parameters drawn from `rng`.
pub fn apply(op: Op, s: &mut Sample<'_>, cfg: &AugmentConfig, rng: &mut ChaCha8Rng) {
    let draw = |rng: &mut ChaCha8Rng, (lo, hi): (f32, f32)| {
        if hi > lo {
            rng.random_range(lo..hi)
        } else {
            lo
        }
    };
    let per_channel = |rng: &mut ChaCha8Rng, range: (f32, f32)| -> [f32; 3] {
        if rng.random_bool(cfg.per_channel_p) {
            std::array::from_fn(|_| draw(rng, range))
        } else {
            [draw(rng, range); 3]
        }
    };
    match op {
        Op::Blur => blur(s, draw(rng, cfg.blur_sigma_px)),
        Op::Noise => {
            let std = draw(rng, cfg.noise_std);
            let each = rng.random_bool(cfg.per_channel_p);
            for px in s.rgb.chunks_exact_mut(3) {
                let shared = gaussian(rng);
                for v in px.iter_mut() {
                    let n = if each { gaussian(rng) } else { shared };
                    *v = to_u8(f32::from(*v) + std * n);
                }
            }
        }
        Op::Dropout => {
            let rate = f64::from(draw(rng, cfg.dropout));
            let each = rng.random_bool(cfg.per_channel_p);
            for px in s.rgb.chunks_exact_mut(3) {
                if each {
                    for v in px.iter_mut() {
                        if rng.random_bool(rate) {
                            *v = 0;
                        }
                    }
                } else if rng.random_bool(rate) {
                    px.fill(0);
                }
            }
        }
        Op::Brightness => {
            let f = per_channel(rng, cfg.brightness);
            map_channels(s.rgb, |c, v| v * f[c]);
        }
        Op::Contrast => {
            let a = per_channel(rng, cfg.contrast);
            map_channels(s.rgb, |c, v| 128.0 + a[c] * (v - 128.0));
        }
        Op::Grayscale => {
            let alpha = draw(rng, cfg.grayscale);
            for px in s.rgb.chunks_exact_mut(3) {
                let [r, g, b] = [px[0], px[1], px[2]].map(f32::from);
                let luma = 0.299 * r + 0.587 * g + 0.114 * b;
                for v in px.iter_mut() {
                    *v = to_u8(f32::from(*v) * (1.0 - alpha) + luma * alpha);
                }
            }
        }
        Op::Warp => {
            let amp = draw(rng, cfg.warp_px);
            warp(s, amp, cfg.warp_grid_px.max(2), rng);
        }
    }
}

/// A seeded generator for one sample: ChaCha8 from a 64-bit mix of `seed` and `index`.
pub fn sample_rng(seed: u64, index: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(mix(seed, index))
}

/// SplitMix64 of `a` and `b`: well-spread seeds for neighbouring indices.
pub fn mix(a: u64, b: u64) -> u64 {
    let mut z = a ^ b.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A standard normal draw (Box-Muller).
fn gaussian(rng: &mut ChaCha8Rng) -> f32 {
    let u1: f32 = rng.random_range(f32::EPSILON..1.0);
    let u2: f32 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
}

fn to_u8(v: f32) -> u8 {
    v.round().clamp(0.0, 255.0) as u8
}

fn map_channels(rgb: &mut [u8], f: impl Fn(usize, f32) -> f32) {
    for px in rgb.chunks_exact_mut(3) {
        for (c, v) in px.iter_mut().enumerate() {
            *v = to_u8(f(c, f32::from(*v)));
        }
    }
}

fn blur(s: &mut Sample<'_>, sigma: f32) {
    if sigma < 0.1 {
        return;
    }
    let r = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / sum).collect();
    let (w, h) = (s.width as isize, s.height as isize);
    let src: Vec<f32> = s.rgb.iter().map(|&v| f32::from(v)).collect();
    let mut tmp = vec![0.0f32; src.len()];
    let at = |x: isize, y: isize| (y.clamp(0, h - 1) * w + x.clamp(0, w - 1)) as usize * 3;
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let v: f32 = (-r..=r)
                    .map(|i| kernel[(i + r) as usize] * src[at(x + i, y) + c])
                    .sum();
                tmp[at(x, y) + c] = v;
            }
        }
    }
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let v: f32 = (-r..=r)
                    .map(|i| kernel[(i + r) as usize] * tmp[at(x, y + i) + c])
                    .sum();
                s.rgb[at(x, y) + c] = to_u8(v);
            }
        }
    }
}

fn warp(s: &mut Sample<'_>, amp: f32, grid: usize, rng: &mut ChaCha8Rng) {
    let (w, h) = (s.width, s.height);
    let (gx, gy) = (w.div_ceil(grid) + 1, h.div_ceil(grid) + 1);
    let nodes: Vec<[f32; 2]> = (0..gx * gy)
        .map(|_| [rng.random_range(-amp..=amp), rng.random_range(-amp..=amp)])
        .collect();
    let src = s.rgb.to_vec();
    let classes = s.classes.to_vec();
    let px = |x: usize, y: usize, c: usize| f32::from(src[(y * w + x) * 3 + c]);
    for y in 0..h {
        for x in 0..w {
            // The displacement at (x, y): bilinear between the four nodes around it.
            let (fx, fy) = (x as f32 / grid as f32, y as f32 / grid as f32);
            let (i, j) = ((fx as usize).min(gx - 2), (fy as usize).min(gy - 2));
            let (tx, ty) = (fx - i as f32, fy - j as f32);
            let n = |a: usize, b: usize, k: usize| nodes[(j + b) * gx + i + a][k];
            let d: [f32; 2] = std::array::from_fn(|k| {
                (1.0 - ty) * ((1.0 - tx) * n(0, 0, k) + tx * n(1, 0, k))
                    + ty * ((1.0 - tx) * n(0, 1, k) + tx * n(1, 1, k))
            });
            let sx = (x as f32 + d[0]).clamp(0.0, (w - 1) as f32);
            let sy = (y as f32 + d[1]).clamp(0.0, (h - 1) as f32);
            let (x0, y0) = (sx.floor() as usize, sy.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
            let (ax, ay) = (sx - x0 as f32, sy - y0 as f32);
            for c in 0..3 {
                let v = (1.0 - ay) * ((1.0 - ax) * px(x0, y0, c) + ax * px(x1, y0, c))
                    + ay * ((1.0 - ax) * px(x0, y1, c) + ax * px(x1, y1, c));
                s.rgb[(y * w + x) * 3 + c] = to_u8(v);
            }
            let (nx, ny) = (sx.round() as usize, sy.round() as usize);
            s.classes[y * w + x] = classes[ny * w + nx];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const W: usize = 40;
    const H: usize = 24;

    fn image() -> (Vec<u8>, Vec<u8>) {
        let rgb = (0..W * H * 3)
            .map(|i| {
                let (p, c) = (i / 3, i % 3);
                let (x, y) = (p % W, p / W);
                (40 + ((x / 4 + y / 4) % 2) * 120 + c * 30) as u8
            })
            .collect();
        let classes = (0..W * H).map(|p| ((p % W) * 6 / W) as u8).collect();
        (rgb, classes)
    }

    fn with(op: Op, cfg: &AugmentConfig, seed: u64) -> (Vec<u8>, Vec<u8>) {
        let (mut rgb, mut classes) = image();
        let mut s = Sample {
            rgb: &mut rgb,
            classes: &mut classes,
            width: W,
            height: H,
        };
        apply(op, &mut s, cfg, &mut sample_rng(seed, 0));
        (rgb, classes)
    }

    fn mean(v: &[u8]) -> f32 {
        v.iter().map(|&x| f32::from(x)).sum::<f32>() / v.len() as f32
    }

    fn channel_spread(rgb: &[u8]) -> f32 {
        rgb.chunks_exact(3)
            .map(|p| f32::from(p.iter().max().unwrap() - p.iter().min().unwrap()))
            .sum::<f32>()
            / (rgb.len() / 3) as f32
    }

    fn roughness(rgb: &[u8]) -> f32 {
        rgb.windows(4)
            .step_by(3)
            .map(|p| (f32::from(p[0]) - f32::from(p[3])).abs())
            .sum()
    }

    #[test]
    fn each_op_changes_the_image_the_way_it_says() {
        let cfg = AugmentConfig::default();
        let (rgb, classes) = image();
        let fixed = |range: (f32, f32)| AugmentConfig {
            blur_sigma_px: range,
            noise_std: range,
            dropout: range,
            brightness: range,
            contrast: range,
            grayscale: range,
            warp_px: range,
            ..cfg.clone()
        };
        // Blur smooths the checkerboard.
        let (b, c) = with(Op::Blur, &fixed((1.3, 1.3)), 1);
        assert!(roughness(&b) < 0.7 * roughness(&rgb));
        assert_eq!(c, classes, "only the warp moves classes");
        // Brightness 1.2 brightens; 1/1.2 darkens.
        assert!(mean(&with(Op::Brightness, &fixed((1.2, 1.2)), 1).0) > 1.15 * mean(&rgb));
        assert!(mean(&with(Op::Brightness, &fixed((0.8, 0.8)), 1).0) < 0.85 * mean(&rgb));
        // Contrast 1.2 spreads values around 128.
        let spread = |v: &[u8]| v.iter().map(|&x| (f32::from(x) - 128.0).abs()).sum::<f32>();
        assert!(spread(&with(Op::Contrast, &fixed((1.2, 1.2)), 1).0) > 1.1 * spread(&rgb));
        // Grayscale halves the difference between channels.
        let g = with(Op::Grayscale, &fixed((0.5, 0.5)), 1).0;
        assert!((channel_spread(&g) - 0.5 * channel_spread(&rgb)).abs() < 1.0);
        // Dropout zeroes about the rate's share of pixels.
        let d = with(Op::Dropout, &fixed((0.1, 0.1)), 1).0;
        let zeros = d.iter().filter(|&&v| v == 0).count() as f32 / d.len() as f32;
        assert!((0.03..0.2).contains(&zeros), "{zeros}");
        // Noise keeps the mean and moves most values.
        let n = with(Op::Noise, &fixed((10.0, 10.0)), 1).0;
        assert!((mean(&n) - mean(&rgb)).abs() < 2.0);
        let moved = n.iter().zip(&rgb).filter(|(a, b)| a != b).count();
        assert!(moved > rgb.len() / 2, "{moved}");
        // The warp moves pixels by at most its amplitude, classes with them.
        let (wr, wc) = with(Op::Warp, &fixed((2.0, 2.0)), 1);
        assert_ne!(wr, rgb);
        assert_ne!(wc, classes);
        for y in 0..H {
            for x in 0..W {
                let c = wc[y * W + x];
                let near = (x.saturating_sub(3)..(x + 4).min(W)).any(|sx| classes[y * W + sx] == c);
                assert!(near, "class at ({x}, {y}) came from more than 3 px away");
            }
        }
    }

    #[test]
    fn augmentation_is_a_function_of_the_seed_and_each_op_applies_half_the_time() {
        let cfg = AugmentConfig::default();
        let run = |seed: u64| {
            let (mut rgb, mut classes) = image();
            let mut s = Sample {
                rgb: &mut rgb,
                classes: &mut classes,
                width: W,
                height: H,
            };
            let ops = augment(&mut s, &cfg, &mut sample_rng(seed, 7));
            (rgb, classes, ops)
        };
        assert_eq!(run(3), run(3));
        assert_ne!(run(3).0, run(4).0);
        let mut counts = [0usize; 7];
        let trials = 400;
        for seed in 0..trials {
            for op in run(seed).2 {
                counts[Op::ALL.iter().position(|&o| o == op).unwrap()] += 1;
            }
        }
        for (op, n) in Op::ALL.iter().zip(counts) {
            assert!(
                (150..250).contains(&n),
                "{op:?} applied {n} of {trials} times"
            );
        }
    }
}
