//! Fast CPU inference: a frozen copy of a [`PolicyNet`]'s driving path.
//!
//! burn's CPU backend spends most of a batch-1 forward outside its matrix
//! products (layout changes, im2col, output scatter, BatchNorm as separate
//! passes; see `docs/policy-bench.md`). This module runs the same network the
//! way inference engines do:
//! - activations stay channels-last (`[H, W, C]`, batch 1), which is what an
//!   RGB8 camera image already is, so nothing is transposed;
//! - every BatchNorm is folded into a per-channel scale and shift applied in
//!   the epilogue of its convolution, together with the residual add and ReLU;
//!   the convolution weights stay shared, each branch of a bank keeps its own
//!   scale and shift (so switching scales costs nothing);
//! - a k x k convolution is one matrix product that reads the zero-padded
//!   input in place (`kernels::conv`, an implicit im2col) against weights
//!   packed once when the policy is frozen.
//!
//! Only the driving path is here: backbone, global average pool, action head.
//! Training and the segmentation decoder stay in burn. [`FusedPolicy::from_net`]
//! is checked against [`PolicyNet::forward`] in the tests (same logits to 1e-4).
//! Convolutions run in tiles of output pixels (and, in the late layers with few
//! pixels, shares of the output channels) on rayon's pool; every output is one
//! fixed chain of fused multiply-adds however the work is cut (the `kernels`
//! crate's promise), so the logits are bit-identical for any thread count and
//! CPU (tested).

use crate::backbone::BasicBlock;
use crate::bn_bank::BnBank;
use crate::model::{PolicyConfig, PolicyNet};
use burn::nn::conv::Conv2d;
use burn::nn::{Linear, PaddingConfig2d};
use burn::prelude::*;
use dataset::action::{NUM_ACTIONS, NUM_STEERS, NUM_THROTTLES};
use kernels::conv::{Conv2dNhwc, Padded, conv2d_nhwc};
use kernels::gemm::NR;
use kernels::{Mat, PackedRhs};
use rayon::prelude::*;

/// A feature map of one image, channels last: `data[(y * w + x) * c + ch]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Fmap {
    /// Rows.
    pub h: usize,
    /// Columns.
    pub w: usize,
    /// Channels.
    pub c: usize,
    /// `h * w * c` values.
    pub data: Vec<f32>,
}

/// A bias-free square convolution, weights packed for `col [HoWo, K] x w [K, Cout]`.
#[derive(Debug, Clone)]
struct Conv {
    cin: usize,
    cout: usize,
    k: usize,
    stride: usize,
    pad: usize,
    /// `w[((ky * k + kx) * cin + ci) * cout + co]`, packed in panels for the product.
    w: PackedRhs,
}

/// A folded BatchNorm: `y = x * scale + shift`, per channel.
#[derive(Debug, Clone)]
struct Affine {
    scale: Vec<f32>,
    shift: Vec<f32>,
}

/// A convolution followed by a BN bank (one folded affine per branch).
#[derive(Debug, Clone)]
struct ConvBn {
    conv: Conv,
    bn: Vec<Affine>,
}

#[derive(Debug, Clone)]
struct Block {
    conv1: ConvBn,
    conv2: ConvBn,
    downsample: Option<ConvBn>,
}

/// A dense layer `y = x w + b`, `w[i * n_out + o]`.
#[derive(Debug, Clone)]
struct Dense {
    n_in: usize,
    n_out: usize,
    w: Vec<f32>,
    b: Vec<f32>,
}

/// The frozen driving path of a policy network, for batch-1 CPU inference.
#[derive(Debug, Clone)]
pub struct FusedPolicy {
    config: PolicyConfig,
    stem: ConvBn,
    blocks: Vec<Block>,
    head: [Dense; 3],
    factorised: bool,
}

/// A tensor's values as f32, read back from the device.
pub(crate) fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_to_vec::<f32>()
        .expect("f32 weights")
}

impl Conv {
    fn from_burn(c: &Conv2d) -> Self {
        let [cout, cin, kh, kw] = c.weight.val().dims();
        assert_eq!(kh, kw, "square kernels only");
        assert!(c.bias.is_none(), "the backbone's convolutions have no bias");
        let (k, stride) = (kh, c.stride[0]);
        let pad = match c.padding {
            PaddingConfig2d::Valid => 0,
            PaddingConfig2d::Explicit(t, l, b, r) if t == l && t == b && t == r => t,
            ref other => panic!("the backbone pads symmetrically, not {other:?}"),
        };
        let src = values(c.weight.val());
        let mut w = vec![0.0; cout * cin * k * k];
        for co in 0..cout {
            for ci in 0..cin {
                for t in 0..k * k {
                    w[(t * cin + ci) * cout + co] = src[(co * cin + ci) * k * k + t];
                }
            }
        }
        let kdim = k * k * cin;
        Conv {
            cin,
            cout,
            k,
            stride,
            pad,
            w: PackedRhs::new(Mat::rows(&w, cout), kdim, cout),
        }
    }

    fn out_len(&self, n: usize) -> usize {
        (n + 2 * self.pad - self.k) / self.stride + 1
    }

    /// The multiply-accumulates of one application to an `h x w` input, and
    /// the output's height and width.
    fn macs(&self, h: usize, w: usize) -> (u64, usize, usize) {
        let (ho, wo) = (self.out_len(h), self.out_len(w));
        (
            (ho * wo * self.k * self.k * self.cin * self.cout) as u64,
            ho,
            wo,
        )
    }

    /// `epilogue(conv(x))`: the output `[Ho * Wo, cout]` and its size.
    ///
    /// The output is cut into [`Share`]s: tiles of [`TILE_ROWS`] pixels, and where a
    /// layer has fewer than [`MIN_SHARES`] tiles (the late layers' few pixels) each
    /// tile's channels too, so both cores work on every layer. A share is one
    /// single-threaded product over the padded input and the epilogue (called with the
    /// share and its `pixels x channels` values); shares run in parallel on rayon's pool.
    fn apply(
        &self,
        x: &Fmap,
        epilogue: impl Fn(Share, &mut [f32]) + Sync,
    ) -> (usize, usize, Vec<f32>) {
        debug_assert_eq!(x.c, self.cin);
        let (ho, wo) = (self.out_len(x.h), self.out_len(x.w));
        let pixels = ho * wo;
        let mut out = vec![0.0; pixels * self.cout];
        let tiles = pixels.div_ceil(TILE_ROWS);
        let per_tile = MIN_SHARES.div_ceil(tiles.max(1));
        let channels = (self.cout.div_ceil(per_tile).div_ceil(NR) * NR).min(self.cout);
        let padded = Padded::new(
            &x.data,
            Conv2dNhwc {
                h: x.h,
                w: x.w,
                cin: x.c,
                k: self.k,
                stride: self.stride,
                pad: self.pad,
            },
        );
        let compute = |share: Share, values: &mut [f32]| {
            let (pixels, cols) = (share.pixels.clone(), share.channels.clone());
            conv2d_nhwc(values, &padded, &self.w, pixels, cols);
            epilogue(share, values);
        };
        if channels == self.cout {
            out.par_chunks_mut(TILE_ROWS * self.cout)
                .enumerate()
                .for_each(|(t, values)| {
                    let first = t * TILE_ROWS;
                    let share = Share {
                        pixels: first..first + values.len() / self.cout,
                        channels: 0..self.cout,
                    };
                    compute(share, values);
                });
        } else {
            let shares: Vec<Share> = (0..tiles)
                .flat_map(|t| {
                    let px = t * TILE_ROWS..((t + 1) * TILE_ROWS).min(pixels);
                    (0..self.cout).step_by(channels).map(move |c0| Share {
                        pixels: px.clone(),
                        channels: c0..(c0 + channels).min(self.cout),
                    })
                })
                .collect();
            let parts: Vec<(Share, Vec<f32>)> = shares
                .into_par_iter()
                .map(|share| {
                    let mut values = vec![0.0; share.pixels.len() * share.channels.len()];
                    compute(share.clone(), &mut values);
                    (share, values)
                })
                .collect();
            for (share, values) in parts {
                let n = share.channels.len();
                for (i, p) in share.pixels.enumerate() {
                    out[p * self.cout + share.channels.start..][..n]
                        .copy_from_slice(&values[i * n..][..n]);
                }
            }
        }
        (ho, wo, out)
    }
}

/// A part of a convolution's output one worker computes: its pixels (row-major over
/// `[Ho, Wo]`) and its output channels.
#[derive(Debug, Clone)]
struct Share {
    pixels: std::ops::Range<usize>,
    channels: std::ops::Range<usize>,
}

/// Shares a convolution is cut into at least, where its pixels allow fewer tiles.
const MIN_SHARES: usize = 4;

/// Output pixels per tile of a convolution (see [`Conv::apply`]).
const TILE_ROWS: usize = 64;

impl ConvBn {
    fn from_burn(conv: &Conv2d, bank: &BnBank) -> Self {
        let bn = bank
            .branches
            .iter()
            .map(|b| {
                let mean = values(b.running_mean.value_sync());
                let var = values(b.running_var.value_sync());
                let gamma = values(b.gamma.val());
                let beta = values(b.beta.val());
                let scale: Vec<f32> = gamma
                    .iter()
                    .zip(&var)
                    .map(|(g, v)| g / (v + b.epsilon as f32).sqrt())
                    .collect();
                let shift = beta
                    .iter()
                    .zip(&mean)
                    .zip(&scale)
                    .map(|((be, m), s)| be - m * s)
                    .collect();
                Affine { scale, shift }
            })
            .collect();
        ConvBn {
            conv: Conv::from_burn(conv),
            bn,
        }
    }

    /// `relu?(bn(conv(x)) + residual?)` with BN branch `branch`.
    fn apply(&self, x: &Fmap, branch: usize, residual: Option<&Fmap>, relu: bool) -> Fmap {
        let Affine { scale, shift } = &self.bn[branch];
        let c = self.conv.cout;
        let (h, w, data) = self.conv.apply(x, |share, values| {
            let (c0, n) = (share.channels.start, share.channels.len());
            let (scale, shift) = (&scale[c0..][..n], &shift[c0..][..n]);
            for (px, p) in values.chunks_exact_mut(n).zip(share.pixels) {
                let res = residual.map(|r| &r.data[p * c + c0..][..n]);
                for ch in 0..n {
                    let mut v = px[ch] * scale[ch] + shift[ch];
                    if let Some(r) = res {
                        v += r[ch];
                    }
                    px[ch] = if relu { v.max(0.0) } else { v };
                }
            }
        });
        Fmap { h, w, c, data }
    }
}

impl Block {
    fn from_burn(b: &BasicBlock) -> Self {
        Block {
            conv1: ConvBn::from_burn(&b.conv1, &b.bn1),
            conv2: ConvBn::from_burn(&b.conv2, &b.bn2),
            downsample: b
                .downsample
                .as_ref()
                .map(|d| ConvBn::from_burn(&d.conv, &d.bn)),
        }
    }

    fn apply(&self, x: &Fmap, branch: usize) -> Fmap {
        let projected = self
            .downsample
            .as_ref()
            .map(|d| d.apply(x, branch, None, false));
        let shortcut = projected.as_ref().unwrap_or(x);
        let y = self.conv1.apply(x, branch, None, true);
        self.conv2.apply(&y, branch, Some(shortcut), true)
    }
}

impl Dense {
    fn from_burn(l: &Linear) -> Self {
        let [n_in, n_out] = l.weight.val().dims();
        Dense {
            n_in,
            n_out,
            w: values(l.weight.val()),
            b: l.bias
                .as_ref()
                .map(|b| values(b.val()))
                .unwrap_or_else(|| vec![0.0; n_out]),
        }
    }

    fn apply(&self, x: &[f32], relu: bool) -> Vec<f32> {
        let mut y = self.b.clone();
        for (i, &xi) in x.iter().enumerate().take(self.n_in) {
            for (yo, wo) in y
                .iter_mut()
                .zip(&self.w[i * self.n_out..(i + 1) * self.n_out])
            {
                *yo += xi * wo;
            }
        }
        if relu {
            y.iter_mut().for_each(|v| *v = v.max(0.0));
        }
        y
    }
}

/// 3x3 stride-2 max-pool with padding 1 (padding never wins).
/// The output length of the stem's 3x3, stride-2, pad-1 max pooling.
fn maxpool_len(n: usize) -> usize {
    (n + 2 - 3) / 2 + 1
}

fn maxpool3x3s2(x: &Fmap) -> Fmap {
    let (ho, wo) = (maxpool_len(x.h), maxpool_len(x.w));
    let c = x.c;
    let mut data = vec![f32::NEG_INFINITY; ho * wo * c];
    for oy in 0..ho {
        for ox in 0..wo {
            let out = &mut data[(oy * wo + ox) * c..][..c];
            for iy in (2 * oy).saturating_sub(1)..(2 * oy + 2).min(x.h) {
                for ix in (2 * ox).saturating_sub(1)..(2 * ox + 2).min(x.w) {
                    let src = &x.data[(iy * x.w + ix) * c..][..c];
                    for (o, v) in out.iter_mut().zip(src) {
                        *o = o.max(*v);
                    }
                }
            }
        }
    }
    Fmap {
        h: ho,
        w: wo,
        c,
        data,
    }
}

impl FusedPolicy {
    /// Freezes `net` (its BN running statistics, read after a sync) for CPU inference.
    pub fn from_net(net: &PolicyNet) -> Self {
        net.sync_running_stats();
        let bb = &net.backbone;
        let blocks = bb
            .layer1
            .iter()
            .chain(&bb.layer2)
            .chain(&bb.layer3)
            .chain(&bb.layer4)
            .map(Block::from_burn)
            .collect();
        let h = &net.action_head;
        FusedPolicy {
            config: net.config.clone(),
            stem: ConvBn::from_burn(&bb.conv1, &bb.bn1),
            blocks,
            head: [
                Dense::from_burn(&h.fc1),
                Dense::from_burn(&h.fc2),
                Dense::from_burn(&h.fc3),
            ],
            factorised: h.factorised,
        }
    }

    /// The network's config.
    pub fn config(&self) -> &PolicyConfig {
        &self.config
    }

    /// Entries of the pooled feature ([`FusedPolicy::features`]).
    pub fn feature_dim(&self) -> usize {
        self.head[0].n_in
    }

    /// Normalises an RGB8 image (row-major, 3 bytes a pixel: already channels-last).
    pub fn normalize(&self, rgb: &[u8], height: usize, width: usize) -> Fmap {
        let (m, s) = (self.config.mean, self.config.std);
        // One table entry per channel and byte value, by the same expression
        // as the per-pixel arithmetic it replaces: the same bits, fewer divisions.
        let lut: [[f32; 256]; 3] =
            std::array::from_fn(|c| std::array::from_fn(|v| (v as f32 / 255.0 - m[c]) / s[c]));
        let n = height * width;
        let mut data = Vec::with_capacity(3 * n);
        for px in rgb.chunks_exact(3).take(n) {
            data.extend([
                lut[0][usize::from(px[0])],
                lut[1][usize::from(px[1])],
                lut[2][usize::from(px[2])],
            ]);
        }
        Fmap {
            h: height,
            w: width,
            c: 3,
            data,
        }
    }

    /// The globally pooled backbone feature `[D]` of a normalised image, BN branch `branch`.
    pub fn features(&self, x: &Fmap, branch: usize) -> Vec<f32> {
        let y = self.stem.apply(x, branch, None, true);
        let mut y = maxpool3x3s2(&y);
        for block in &self.blocks {
            y = block.apply(&y, branch);
        }
        let n = (y.h * y.w) as f32;
        let mut f = vec![0.0f32; y.c];
        for px in y.data.chunks_exact(y.c) {
            for (a, v) in f.iter_mut().zip(px) {
                *a += v;
            }
        }
        f.iter_mut().for_each(|v| *v /= n);
        f
    }

    /// Action logits `[commands][speed bins][28]` (flattened) from a pooled feature.
    pub fn action_logits(&self, features: &[f32]) -> Vec<f32> {
        let h = self.head[0].apply(features, true);
        let h = self.head[1].apply(&h, true);
        let raw = self.head[2].apply(&h, false);
        if !self.factorised {
            return raw;
        }
        let per = NUM_STEERS + NUM_THROTTLES + 1;
        raw.chunks_exact(per)
            .flat_map(|cell| {
                let (steer, rest) = cell.split_at(NUM_STEERS);
                let (throttle, brake) = rest.split_at(NUM_THROTTLES);
                let mut z = [0.0f32; NUM_ACTIONS];
                for (t, th) in throttle.iter().enumerate() {
                    for (s, st) in steer.iter().enumerate() {
                        z[t * NUM_STEERS + s] = st + th;
                    }
                }
                z[NUM_ACTIONS - 1] = brake[0];
                z
            })
            .collect()
    }

    /// The multiply-accumulates of one forward pass on a `height x width`
    /// image: every convolution of the backbone and the three dense layers of
    /// the action head. A frame's arithmetic is twice this in FLOPs; BN (folded
    /// into each convolution's epilogue), ReLU, pooling and the normalisation
    /// are a few operations per activation and not counted.
    pub fn macs(&self, height: usize, width: usize) -> u64 {
        let (mut total, h, w) = self.stem.conv.macs(height, width);
        let (mut h, mut w) = (maxpool_len(h), maxpool_len(w));
        for b in &self.blocks {
            if let Some(d) = &b.downsample {
                total += d.conv.macs(h, w).0;
            }
            let (m1, h1, w1) = b.conv1.conv.macs(h, w);
            let (m2, h2, w2) = b.conv2.conv.macs(h1, w1);
            total += m1 + m2;
            (h, w) = (h2, w2);
        }
        total
            + self
                .head
                .iter()
                .map(|d| (d.n_in * d.n_out) as u64)
                .sum::<u64>()
    }

    /// Action logits of an RGB8 image through BN branch `branch` (on rayon's current pool).
    pub fn forward_rgb8(&self, rgb: &[u8], height: usize, width: usize, branch: usize) -> Vec<f32> {
        let x = self.normalize(rgb, height, width);
        self.action_logits(&self.features(&x, branch))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backbone::Depth;
    use burn::module::{Module, RunningState};
    use burn::tensor::Distribution;

    #[test]
    fn the_arithmetic_of_a_frame_is_counted_layer_by_layer() {
        let device = Device::flex();
        let fused = FusedPolicy::from_net(&PolicyConfig::cpu_default().init(&device));
        // The CPU default (ResNet-18, widths 32-64-128-256) on a 32 x 32 image, by hand:
        // stem 7x7/2 to 16x16, pool to 8x8, then 8x8, 4x4, 2x2 and 1x1 per stage.
        let stem = 16 * 16 * 49 * 3 * 32;
        let stage1 = 4 * (8 * 8 * 9 * 32 * 32);
        // A later stage at side n, widths c -> 2c: strided conv, conv, 1x1 projection,
        // then a second block of two convs.
        let stage = |n: u64, c: u64| {
            let px = n * n;
            px * 9 * c * 2 * c + px * 9 * 4 * c * c + px * c * 2 * c + 2 * px * 9 * 4 * c * c
        };
        let backbone = stem + stage1 + stage(4, 32) + stage(2, 64) + stage(1, 128);
        assert_eq!(backbone, 9_854_976);
        let head: u64 = fused.head.iter().map(|d| (d.n_in * d.n_out) as u64).sum();
        assert_eq!(fused.macs(32, 32), backbone + head);
        // The rig's two scales: 0.75x costs 0.629 of 1.0x, not its area ratio 0.5625,
        // because strided layers round up (72 rows go 36, 18, 9, 5, 3; 96 go 48, 24,
        // 12, 6, 3: the last stage has as many rows at both scales).
        let (full, low) = (fused.macs(96, 240), fused.macs(72, 180));
        let ratio = low as f64 / full as f64;
        assert!((ratio - 0.6293).abs() < 1e-4, "{ratio}");
    }

    /// RGB8 bytes of an image `h` x `w` (the shared test pattern).
    fn image(h: usize, w: usize, seed: u8) -> Vec<u8> {
        sim::render::image::test_pattern(w as u32, h as u32, u64::from(seed)).data
    }

    /// A net whose BN statistics and affine parameters are far from the identity, so that a
    /// wrong fold or a wrong branch shows.
    fn perturbed(cfg: &PolicyConfig, device: &Device) -> PolicyNet {
        let mut net = cfg.init(device);
        for (i, bank) in net.banks_mut().into_iter().enumerate() {
            for (b, bn) in bank.branches.iter_mut().enumerate() {
                let n = bn.gamma.val().dims()[0];
                let r = |lo: f64, hi: f64| {
                    Tensor::<1>::random([n], Distribution::Uniform(lo, hi), device)
                };
                bn.running_mean = RunningState::new(r(-0.3, 0.3));
                bn.running_var = RunningState::new(r(0.5, 2.0));
                bn.gamma = burn::module::Param::from_tensor(r(0.5, 1.5).add_scalar(0.1 * b as f64));
                bn.beta =
                    burn::module::Param::from_tensor(r(-0.2, 0.2).add_scalar(0.01 * i as f64));
            }
        }
        net.valid()
    }

    fn burn_logits(net: &PolicyNet, rgb: &[u8], h: usize, w: usize, branch: usize) -> Vec<f32> {
        let x = net.config.normalize_rgb8(rgb, h, w);
        let x = Tensor::<4>::from_data(TensorData::new(x, [1, 3, h, w]), &Device::flex());
        values(net.forward(x, branch, false).action_logits)
    }

    fn assert_close(a: &[f32], b: &[f32], what: &str) {
        assert_eq!(a.len(), b.len());
        let scale = a.iter().fold(1.0f32, |m, v| m.max(v.abs()));
        let worst = a
            .iter()
            .zip(b)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f32::max);
        assert!(
            worst <= 1e-4 * scale,
            "{what}: max diff {worst} (scale {scale})"
        );
    }

    #[test]
    fn normalising_by_table_gives_the_bits_of_the_arithmetic() {
        let device = Device::flex();
        device.seed(3);
        let cfg = PolicyConfig::new(Depth::Resnet18, [8, 16, 24, 32]);
        let fused = FusedPolicy::from_net(&cfg.init(&device).valid());
        // Every byte value in every channel: 256 pixels of (v, 255 - v, v * 7).
        let rgb: Vec<u8> = (0..=255u8)
            .flat_map(|v| [v, 255 - v, v.wrapping_mul(7)])
            .collect();
        let x = fused.normalize(&rgb, 16, 16);
        assert_eq!((x.h, x.w, x.c, x.data.len()), (16, 16, 3, 768));
        let (m, s) = (cfg.mean, cfg.std);
        for (i, (&byte, &got)) in rgb.iter().zip(&x.data).enumerate() {
            let c = i % 3;
            let want = (byte as f32 / 255.0 - m[c]) / s[c];
            assert_eq!(got.to_bits(), want.to_bits(), "byte {byte} channel {c}");
        }
    }

    #[test]
    fn matches_burn_at_every_branch_for_resnet18_and_34() {
        let device = Device::flex();
        device.seed(41);
        for depth in [Depth::Resnet18, Depth::Resnet34] {
            let cfg = PolicyConfig::new(depth, [8, 16, 24, 32])
                .with_input_height(64)
                .with_input_width(112)
                .with_scales(vec![0.5, 0.75, 1.0]);
            let net = perturbed(&cfg, &device);
            let fused = FusedPolicy::from_net(&net);
            for (branch, &r) in cfg.scales.iter().enumerate() {
                let [h, w] = cfg.input_size(r);
                let rgb = image(h, w, branch as u8);
                let want = burn_logits(&net, &rgb, h, w, branch);
                let got = fused.forward_rgb8(&rgb, h, w, branch);
                assert_close(&got, &want, &format!("{depth:?} branch {branch}"));
            }
            // Branches really differ: the same image through two branches.
            let [h, w] = cfg.input_size(1.0);
            let rgb = image(h, w, 7);
            assert_ne!(
                fused.forward_rgb8(&rgb, h, w, 0),
                fused.forward_rgb8(&rgb, h, w, 2)
            );
        }
    }

    #[test]
    fn unfactorised_head_and_odd_sizes_match_burn() {
        let device = Device::flex();
        device.seed(42);
        let mut cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(37)
            .with_input_width(53)
            .with_scales(vec![1.0]);
        cfg.factorised_actions = false;
        let net = perturbed(&cfg, &device);
        let rgb = image(37, 53, 3);
        let fused = FusedPolicy::from_net(&net);
        assert_close(
            &fused.forward_rgb8(&rgb, 37, 53, 0),
            &burn_logits(&net, &rgb, 37, 53, 0),
            "unfactorised",
        );
    }

    #[test]
    fn thread_count_does_not_change_a_bit() {
        // Wide enough that the products take the multi-threaded path.
        let device = Device::flex();
        device.seed(43);
        let cfg = PolicyConfig::new(Depth::Resnet18, [32, 64, 128, 256])
            .with_input_height(96)
            .with_input_width(240);
        let fused = FusedPolicy::from_net(&perturbed(&cfg, &device));
        let rgb = image(96, 240, 1);
        let pool = |n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
        };
        let one = pool(1).install(|| fused.forward_rgb8(&rgb, 96, 240, 1));
        let two = pool(2).install(|| fused.forward_rgb8(&rgb, 96, 240, 1));
        let again = pool(2).install(|| fused.forward_rgb8(&rgb, 96, 240, 1));
        assert_eq!(two, again);
        assert_eq!(one, two);
    }

    #[test]
    fn maxpool_ignores_padding_and_picks_the_window_maximum() {
        // A 3x4 single-channel map of negatives: padding must not turn into zeros.
        let x = Fmap {
            h: 3,
            w: 4,
            c: 1,
            data: (0..12).map(|v| -(v as f32) - 1.0).collect(),
        };
        let y = maxpool3x3s2(&x);
        assert_eq!((y.h, y.w), (2, 2));
        // Windows: rows {0,1} x cols {0,1} -> -1; rows {0,1} x cols {1,2,3} -> -2;
        // rows {1,2} x cols {0,1} -> -5; rows {1,2} x cols {1,2,3} -> -6.
        assert_eq!(y.data, vec![-1.0, -2.0, -5.0, -6.0]);
    }
}
