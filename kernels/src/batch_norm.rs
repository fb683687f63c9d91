//! BatchNorm in training mode: the batch statistics, the normalisation and its backward
//! on burn's NCHW layout, two passes per channel each way.
//!
//! Sums run in 16 f32 lanes per plane (lane k takes elements k, k + 16, ...: the same
//! order whatever the CPU's vector width), the lanes and planes then added in f64, one
//! channel at a time in a fixed order, so the result does not depend on the thread count
//! or the CPU. `policy::batch_norm` registers them with burn.

use rayon::prelude::*;

/// The layout of a `[batch, channels, pixels...]` activation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Planes {
    pub batch: usize,
    pub channels: usize,
    /// Values per sample and channel.
    pub pixels: usize,
}

impl Planes {
    /// The layout of an activation of dimensions `dims` (`[batch, channels, ...]`).
    pub fn of(dims: &[usize]) -> Self {
        Planes {
            batch: dims[0],
            channels: dims[1],
            pixels: dims[2..].iter().product(),
        }
    }

    /// Values per channel over the batch.
    fn count(&self) -> f64 {
        (self.batch * self.pixels) as f64
    }

    /// Channel `c`'s plane of sample `b` in `values`.
    fn plane<'a>(&self, values: &'a [f32], b: usize, c: usize) -> &'a [f32] {
        &values[(b * self.channels + c) * self.pixels..][..self.pixels]
    }

    /// Sums `f(a, b)` over channel `c`'s values of `a` and `b` (same layout): each plane in
    /// 16 f32 lanes, the lanes and planes added in f64, always in the same order.
    fn sum(&self, c: usize, a: &[f32], b: &[f32], f: impl Fn(f32, f32) -> f32) -> f64 {
        (0..self.batch)
            .map(|s| lane_sum(self.plane(a, s, c), self.plane(b, s, c), &f))
            .sum()
    }
}

/// `sum f(a[i], b[i])` over two equal slices in 16 independent f32 lanes (which the
/// compiler vectorises), the lanes and the tail then added in f64 in a fixed order.
fn lane_sum(a: &[f32], b: &[f32], f: &impl Fn(f32, f32) -> f32) -> f64 {
    const LANES: usize = 16;
    let mut acc = [0.0f32; LANES];
    let (ca, cb) = (a.chunks_exact(LANES), b.chunks_exact(LANES));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(&x, &y)| f64::from(f(x, y)))
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..LANES {
            acc[k] += f(x[k], y[k]);
        }
    }
    acc.iter().map(|&v| f64::from(v)).sum::<f64>() + tail
}

/// Per-channel mean and biased (population) variance of `x`.
pub fn statistics(x: &[f32], p: Planes) -> (Vec<f32>, Vec<f32>) {
    let n = p.count().max(1.0);
    (0..p.channels)
        .into_par_iter()
        .map(|c| {
            let mean = (p.sum(c, x, x, |v, _| v) / n) as f32;
            let var = p.sum(c, x, x, |v, _| (v - mean) * (v - mean)) / n;
            (mean, var as f32)
        })
        .unzip()
}

/// `1 / sqrt(var + eps)` per channel.
fn inv_std(var: &[f32], eps: f64) -> Vec<f32> {
    var.iter()
        .map(|&v| (1.0 / (f64::from(v) + eps).sqrt()) as f32)
        .collect()
}

/// `y = (x - mean) / sqrt(var + eps) * gamma + beta`, per channel.
pub fn normalize(
    x: &[f32],
    p: Planes,
    [gamma, beta, mean, var]: [&[f32]; 4],
    eps: f64,
) -> Vec<f32> {
    let inv = inv_std(var, eps);
    let mut y = vec![0.0; x.len()];
    if p.pixels == 0 {
        return y;
    }
    y.par_chunks_mut(p.pixels)
        .zip(x.par_chunks(p.pixels))
        .enumerate()
        .for_each(|(plane, (y, x))| {
            let c = plane % p.channels;
            let scale = inv[c] * gamma[c];
            let shift = beta[c] - mean[c] * scale;
            y.iter_mut()
                .zip(x)
                .for_each(|(y, x)| *y = x * scale + shift);
        });
    y
}

/// The gradients of [`normalize`] with the batch's own statistics (training mode) given
/// the output's gradient `dy`: `(dx, dgamma, dbeta)`.
pub fn backward(
    x: &[f32],
    dy: &[f32],
    p: Planes,
    [gamma, mean, var]: [&[f32]; 3],
    eps: f64,
) -> (Vec<f32>, Vec<f32>, Vec<f32>) {
    let inv = inv_std(var, eps);
    // Per channel: sum(dy) and sum(dy * xhat).
    let (dbeta, dgamma): (Vec<f64>, Vec<f64>) = (0..p.channels)
        .into_par_iter()
        .map(|c| {
            let (m, s) = (mean[c], inv[c]);
            let db = p.sum(c, dy, dy, |g, _| g);
            let dg = p.sum(c, dy, x, |g, v| g * (v - m) * s);
            (db, dg)
        })
        .unzip();
    let n = p.count().max(1.0);
    let mut dx = vec![0.0; x.len()];
    if p.pixels > 0 {
        dx.par_chunks_mut(p.pixels)
            .enumerate()
            .for_each(|(plane, dx)| {
                let c = plane % p.channels;
                let (m, s) = (mean[c], inv[c]);
                let (mean_dy, mean_dy_xhat) = ((dbeta[c] / n) as f32, (dgamma[c] / n) as f32);
                let scale = gamma[c] * s;
                let start = plane * p.pixels;
                let (x, dy) = (&x[start..][..p.pixels], &dy[start..][..p.pixels]);
                for ((dx, &x), &dy) in dx.iter_mut().zip(x).zip(dy) {
                    let xhat = (x - m) * s;
                    *dx = scale * (dy - mean_dy - xhat * mean_dy_xhat);
                }
            });
    }
    let to32 = |v: Vec<f64>| v.into_iter().map(|v| v as f32).collect();
    (dx, to32(dgamma), to32(dbeta))
}
