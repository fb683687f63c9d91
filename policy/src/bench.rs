//! Benchmarks that print figures: inference latency per scale and training throughput.
//! Called by `mrdrive bench policy`; never asserted in tests. [`report`] writes
//! their tables as the command line prints them.

use crate::model::{ParamCounts, PolicyConfig};
use crate::train::loader::{Loader, LoaderConfig, TrainSet};
use crate::train::presets::Preset;
use crate::train::synthetic::toy_batch;
use crate::train::{MultiResTrainer, TrainConfig};
use burn::prelude::*;
use sim::render::image::test_pattern;
use std::sync::Arc;
use std::time::Instant;

pub mod overlap;
pub mod report;

/// Latency statistics of repeated runs (milliseconds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Latency {
    /// Median.
    pub median_ms: f64,
    /// Fastest.
    pub min_ms: f64,
    /// Slowest.
    pub max_ms: f64,
}

impl Latency {
    /// Statistics of a set of timings (milliseconds).
    pub fn of(mut times_ms: Vec<f64>) -> Self {
        assert!(!times_ms.is_empty());
        times_ms.sort_by(f64::total_cmp);
        let n = times_ms.len();
        let median_ms = if n % 2 == 1 {
            times_ms[n / 2]
        } else {
            0.5 * (times_ms[n / 2 - 1] + times_ms[n / 2])
        };
        Latency {
            median_ms,
            min_ms: times_ms[0],
            max_ms: times_ms[n - 1],
        }
    }
}

/// Batch-1 inference latency of `config` at each scale of its R on `device`
/// (forward of the backbone and the action head, result read back).
pub fn inference_latency(
    config: &PolicyConfig,
    device: &Device,
    warmup: usize,
    repeats: usize,
) -> Vec<(f32, [usize; 2], Latency)> {
    device.seed(0);
    let net = config.init(device).valid();
    let inputs: Vec<Tensor<4>> = config
        .scales
        .iter()
        .map(|&r| {
            let [h, w] = config.input_size(r);
            Tensor::<4>::random(
                [1, 3, h, w],
                burn::tensor::Distribution::Normal(0.0, 1.0),
                device,
            )
        })
        .collect();
    per_scale(config, warmup, repeats, |branch| {
        let z = net
            .forward(inputs[branch].clone(), branch, false)
            .action_logits;
        let _ = z.into_data();
    })
}

/// Batch-1 latency of the fused CPU path ([`crate::fused::FusedPolicy`]) of `config` at each
/// scale, from an RGB8 image (normalisation included) to the action logits, on rayon's pool.
pub fn fused_latency(
    config: &PolicyConfig,
    warmup: usize,
    repeats: usize,
) -> Vec<(f32, [usize; 2], Latency)> {
    let device = Device::flex();
    device.seed(0);
    let fused = crate::fused::FusedPolicy::from_net(&config.init(&device));
    let images: Vec<Vec<u8>> = config
        .scales
        .iter()
        .map(|&r| {
            let [h, w] = config.input_size(r);
            test_pattern(w as u32, h as u32, 0).data
        })
        .collect();
    per_scale(config, warmup, repeats, |branch| {
        let [h, w] = config.input_size(config.scales[branch]);
        std::hint::black_box(fused.forward_rgb8(&images[branch], h, w, branch));
    })
}

/// The machine's peak f32 arithmetic for `threads` threads (GFLOP/s), estimated
/// from a `/proc/cpuinfo` text, with how it was reckoned; `None` without a clock.
///
/// Peak = threads x clock x FLOPs per cycle per core, the clock being the one
/// `/proc/cpuinfo` reports (a virtual machine's nominal clock; boost may go
/// higher). FLOPs per cycle come from the vector unit the flags show and the
/// vendors' documents: an Intel core with AVX-512 has two 512-bit FMA units
/// (Xeon Scalable Gold and Platinum; 64 f32 FLOPs a cycle), an AMD core with
/// AVX-512 (Zen 4) runs it on two 256-bit FMA pipes (32), a core with AVX2 and
/// FMA has two 256-bit FMA units (32), anything older is counted at 8. It is an
/// upper bound: no real kernel issues two FMAs every cycle.
pub fn cpu_peak_gflops(cpuinfo: &str, threads: usize) -> Option<(f64, String)> {
    let field = |key: &str| {
        cpuinfo
            .lines()
            .find_map(|l| l.strip_prefix(key)?.trim_start().strip_prefix(':'))
            .map(str::trim)
    };
    let mhz: f64 = field("cpu MHz")?.parse().ok()?;
    let flags: Vec<&str> = field("flags").unwrap_or("").split_whitespace().collect();
    let has = |f: &str| flags.contains(&f);
    let intel = field("vendor_id") == Some("GenuineIntel");
    let (per_cycle, why) = if has("avx512f") && intel {
        (64.0, "Intel AVX-512: two 512-bit FMA units")
    } else if has("avx512f") {
        (32.0, "AMD AVX-512 (Zen 4): two 256-bit FMA pipes")
    } else if has("avx2") && has("fma") {
        (32.0, "AVX2 + FMA: two 256-bit FMA units")
    } else {
        (8.0, "no AVX2/FMA: counted at 8")
    };
    let peak = threads as f64 * mhz / 1e3 * per_cycle;
    Some((
        peak,
        format!(
            "{threads} threads x {:.2} GHz x {per_cycle:.0} f32 FLOP/cycle ({why})",
            mhz / 1e3
        ),
    ))
}

/// The multiply-accumulates of one fused forward pass of `config` at each scale
/// of its R ([`crate::fused::FusedPolicy::macs`]): (scale, [height, width], MACs).
pub fn frame_macs(config: &PolicyConfig) -> Vec<(f32, [usize; 2], u64)> {
    let device = Device::flex();
    device.seed(0);
    let fused = crate::fused::FusedPolicy::from_net(&config.init(&device));
    config
        .scales
        .iter()
        .map(|&r| {
            let [h, w] = config.input_size(r);
            (r, [h, w], fused.macs(h, w))
        })
        .collect()
}

/// Times `run(branch)` for every branch of `config`, `warmup` untimed then `repeats` timed
/// rounds; scales are interleaved (one run of each per round) so that load from other
/// processes falls on all of them alike.
fn per_scale(
    config: &PolicyConfig,
    warmup: usize,
    repeats: usize,
    mut run: impl FnMut(usize),
) -> Vec<(f32, [usize; 2], Latency)> {
    let n = config.scales.len();
    let mut times = vec![Vec::with_capacity(repeats); n];
    for round in 0..warmup + repeats {
        for (branch, t) in times.iter_mut().enumerate() {
            let t0 = Instant::now();
            run(branch);
            if round >= warmup {
                t.push(t0.elapsed().as_secs_f64() * 1e3);
            }
        }
    }
    config
        .scales
        .iter()
        .zip(times)
        .map(|(&r, t)| (r, config.input_size(r), Latency::of(t)))
        .collect()
}

/// Training throughput of the multi-resolution step (samples per second; each sample is
/// seen once at every scale of R) with settings `train`, batch `batch`, on `device` (autodiff).
pub fn train_throughput(
    config: &PolicyConfig,
    train: TrainConfig,
    device: &Device,
    batch: usize,
    warmup: usize,
    steps: usize,
) -> f64 {
    device.seed(0);
    let data = toy_batch(config, batch, 0, device);
    let mut trainer = MultiResTrainer::new(config.init(device), None, train, device);
    for _ in 0..warmup {
        trainer.step(&data);
    }
    let t0 = Instant::now();
    for _ in 0..steps {
        trainer.step(&data);
    }
    (batch * steps) as f64 / t0.elapsed().as_secs_f64()
}

/// The training loader's rate alone: `batches` batches drawn from a fresh
/// [`Loader`] over `set` (after one untimed batch), in batches per second.
pub fn loader_throughput(
    set: Arc<TrainSet>,
    config: &PolicyConfig,
    cfg: LoaderConfig,
    batches: usize,
) -> f64 {
    let mut loader = Loader::start(set, config, cfg);
    let _ = loader.next_host();
    let t0 = Instant::now();
    let mut got = 0;
    while got < batches && loader.next_host().is_some() {
        got += 1;
    }
    got as f64 / t0.elapsed().as_secs_f64()
}

/// The multi-resolution step fed by the loader (worker thread and step
/// running together, as in training).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FedTraining {
    /// Samples per second trained.
    pub samples_per_s: f64,
    /// Share of the time the step waited for the loader's next batch.
    pub waiting: f64,
}

/// Trains `steps` steps (after one warm-up) of `config` with `train` on
/// `device` (autodiff), each on the loader's next batch.
pub fn fed_training(
    set: Arc<TrainSet>,
    config: &PolicyConfig,
    train: TrainConfig,
    cfg: LoaderConfig,
    device: &Device,
    steps: usize,
) -> FedTraining {
    device.seed(0);
    let batch = cfg.batch;
    let mut loader = Loader::start(set, config, cfg);
    let mut trainer = MultiResTrainer::new(config.init(device), None, train, device);
    let first = loader.next_batch(device).expect("the loader streams");
    trainer.step(&first);
    let (mut waited, mut done) = (0.0, 0);
    let t0 = Instant::now();
    for _ in 0..steps {
        let w0 = Instant::now();
        let Some(b) = loader.next_batch(device) else {
            break;
        };
        waited += w0.elapsed().as_secs_f64();
        trainer.step(&b);
        done += 1;
    }
    let total = t0.elapsed().as_secs_f64();
    FedTraining {
        samples_per_s: (done * batch) as f64 / total,
        waiting: waited / total,
    }
}

/// The loader benchmark's figures.
#[derive(Debug, Clone, PartialEq)]
pub struct LoaderBench {
    /// Samples in the dataset.
    pub samples: usize,
    /// Loader alone, WoR's augmentations on (batches per second).
    pub augmented_batches_per_s: f64,
    /// Loader alone, no augmentation (batches per second).
    pub plain_batches_per_s: f64,
    /// The training step alone on a toy batch (samples per second), if trained.
    pub train_samples_per_s: Option<f64>,
    /// The training step fed by the (augmenting) loader, if trained.
    pub fed: Option<FedTraining>,
}

/// The loader (with `workers` threads) against the training step of `config`
/// (multi-resolution, segmentation on) on the CPU: `batches` timed loader batches each way,
/// `train_steps` timed steps alone and fed by the loader (0 skips training).
pub fn loader_bench(
    set: Arc<TrainSet>,
    config: &PolicyConfig,
    batch: usize,
    workers: usize,
    batches: usize,
    train_steps: usize,
) -> LoaderBench {
    let loader = LoaderConfig {
        workers,
        ..LoaderConfig::new(batch, 0)
    };
    let rate = |augment| {
        let cfg = LoaderConfig {
            augment,
            ..loader.clone()
        };
        loader_throughput(set.clone(), config, cfg, batches)
    };
    let augmented_batches_per_s = rate(Some(Default::default()));
    let plain_batches_per_s = rate(None);
    let (mut train_samples_per_s, mut fed) = (None, None);
    if train_steps > 0 {
        let device = Device::flex().autodiff();
        train_samples_per_s = Some(train_throughput(
            config,
            TrainConfig::new(),
            &device,
            batch,
            1,
            train_steps,
        ));
        fed = Some(fed_training(
            set.clone(),
            config,
            TrainConfig::new(),
            loader.clone(),
            &device,
            train_steps,
        ));
    }
    LoaderBench {
        samples: set.samples.len(),
        augmented_batches_per_s,
        plain_batches_per_s,
        train_samples_per_s,
        fed,
    }
}

/// One row of the BN-bank overhead table.
#[derive(Debug, Clone, PartialEq)]
pub struct Overhead {
    /// Network name.
    pub name: String,
    /// Number of scales (branches).
    pub scales: usize,
    /// Learnable parameters with one branch (the NRA model).
    pub single: usize,
    /// Learnable parameters with the banks.
    pub multi: usize,
    /// BN running statistics added (buffers, not learned).
    pub extra_buffers: usize,
}

impl Overhead {
    /// Extra learnable parameters in percent of the single-branch model.
    pub fn percent(&self) -> f64 {
        100.0 * (self.multi - self.single) as f64 / self.single as f64
    }
}

/// The networks `policy overhead` compares: the paper's at two and five
/// scales, a full-width ResNet-18, and the CPU default.
pub fn overhead_networks() -> Vec<(&'static str, PolicyConfig)> {
    vec![
        (
            "resnet34 (paper, 64-512)",
            Preset::Paper.config(&[0.75, 1.0]),
        ),
        (
            "resnet34 (paper), 5 scales",
            Preset::Paper.config(&[0.5, 0.625, 0.75, 0.875, 1.0]),
        ),
        ("resnet18 (64-512)", Preset::Resnet18.config(&[0.75, 1.0])),
        (
            "default: resnet18 half (32-256)",
            Preset::Cpu.config(&[0.75, 1.0]),
        ),
    ]
}

/// The networks `bench policy` times (R = {0.75, 1.0}): the CPU default,
/// and unless `quick` the full-width ResNet-18 and ResNet-34 at the CPU and
/// the paper's S0 and the default at the paper's S0.
pub fn latency_networks(quick: bool) -> Vec<(&'static str, PolicyConfig)> {
    let r = [0.75, 1.0];
    let mut nets = vec![("default: resnet18 half 32-256", Preset::Cpu.config(&r))];
    if !quick {
        let cpu_s0 = |c: PolicyConfig| c.with_input_height(96).with_input_width(240);
        nets.extend([
            (
                "resnet18 64-512 @ 240x96",
                cpu_s0(Preset::Resnet18.config(&r)),
            ),
            ("resnet18 64-512 @ 480x192", Preset::Resnet18.config(&r)),
            ("resnet34 64-512 @ 240x96", cpu_s0(Preset::Paper.config(&r))),
            (
                "resnet34 64-512 @ 480x192 (paper)",
                Preset::Paper.config(&r),
            ),
            (
                "resnet18 half 32-256 @ 480x192",
                Preset::Cpu
                    .config(&r)
                    .with_input_height(192)
                    .with_input_width(480),
            ),
        ]);
    }
    nets
}

/// Parameter overhead of the BN banks of `config` against the same network with one branch.
pub fn overhead(name: &str, config: &PolicyConfig) -> Overhead {
    let device = Device::flex();
    let single = ParamCounts::of(&config.clone().with_scales(vec![1.0]).init(&device));
    let multi = ParamCounts::of(&config.init(&device));
    Overhead {
        name: name.into(),
        scales: config.scales.len(),
        single: single.learnable,
        multi: multi.learnable,
        extra_buffers: multi.bn_buffers - single.bn_buffers,
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn the_peak_is_reckoned_from_the_vendor_the_flags_and_the_clock() {
        let amd =
            "vendor_id\t: AuthenticAMD\ncpu MHz\t\t: 2596.126\nflags\t\t: fpu avx2 fma avx512f\n";
        let (p, why) = cpu_peak_gflops(amd, 2).unwrap();
        assert!((p - 2.0 * 2.596_126 * 32.0).abs() < 1e-9, "{p}");
        assert!(
            why.contains("2 threads x 2.60 GHz x 32") && why.contains("Zen 4"),
            "{why}"
        );
        let intel = amd.replace("AuthenticAMD", "GenuineIntel");
        let peak = |text: &str, threads| cpu_peak_gflops(text, threads).unwrap().0;
        assert!((peak(&intel, 1) - 2.596_126 * 64.0).abs() < 1e-9);
        let avx2 = amd.replace(" avx512f", "");
        assert!((peak(&avx2, 1) - 2.596_126 * 32.0).abs() < 1e-9);
        let old = "vendor_id\t: GenuineIntel\ncpu MHz\t: 1000\nflags\t: fpu sse2\n";
        assert_eq!(cpu_peak_gflops(old, 4).unwrap().0, 32.0);
        assert_eq!(cpu_peak_gflops("vendor_id : x\n", 2), None);
    }

    use super::*;

    #[test]
    fn median_of_odd_and_even_sets() {
        assert_eq!(Latency::of(vec![3.0, 1.0, 2.0]).median_ms, 2.0);
        let l = Latency::of(vec![4.0, 1.0, 2.0, 3.0]);
        assert_eq!((l.median_ms, l.min_ms, l.max_ms), (2.5, 1.0, 4.0));
    }

    #[test]
    fn resnet34_two_scale_overhead_is_about_a_tenth_of_a_percent() {
        // The paper calls the banks negligible; measured here on the full network
        // (backbone + action head + decoder).
        let o = overhead("resnet34", &PolicyConfig::paper());
        assert_eq!(o.multi - o.single, o.extra_buffers);
        assert!(
            o.percent() > 0.0 && o.percent() < 0.2,
            "{o:?} {}",
            o.percent()
        );
    }
}
