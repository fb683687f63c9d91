//! The benchmark tables as `mrdrive` prints them: `policy overhead`, `bench
//! policy` and `bench loader`. Each measures and writes its lines as it goes
//! (a benchmark of many networks takes minutes), so a caller passes its
//! standard output or a buffer.

use std::io::{self, Write};
use std::path::Path;
use std::sync::Arc;

use burn::prelude::*;

use crate::device::DeviceKind;
use crate::model::PolicyConfig;
use crate::train::loader::TrainSet;
use crate::train::{Preset, TrainConfig};

/// The BN banks' parameter overhead of every network of [`super::overhead_networks`],
/// one line each under a header (`mrdrive policy overhead`).
pub fn overhead_table() -> String {
    use std::fmt::Write;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "BN-bank parameter overhead (learnable gamma/beta of the extra branches; whole network: backbone + action head + decoder)"
    );
    let _ = writeln!(
        out,
        "{:<34} {:>6} {:>12} {:>12} {:>10} {:>9} {:>14}",
        "network", "scales", "single", "banked", "extra", "extra %", "extra buffers"
    );
    for (name, cfg) in super::overhead_networks() {
        let o = super::overhead(name, &cfg);
        let _ = writeln!(
            out,
            "{:<34} {:>6} {:>12} {:>12} {:>10} {:>8.3}% {:>14}",
            o.name,
            o.scales,
            o.single,
            o.multi,
            o.multi - o.single,
            o.percent(),
            o.extra_buffers
        );
    }
    out
}

/// What `bench policy` times.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PolicyBench {
    /// Timed repeats per scale (after 3 warm-up runs).
    pub repeats: usize,
    /// Timed training steps (after 1 warm-up step); 0 skips training.
    pub train_steps: usize,
    /// Training batch size.
    pub batch: usize,
    /// Only the default model (no ResNet-34/18 at the paper's S0).
    pub quick: bool,
}

/// One network's fused timings per scale, as [`super::fused_latency`] gives them.
type FusedRows<'a> = (
    &'a str,
    &'a PolicyConfig,
    Vec<(f32, [usize; 2], super::Latency)>,
);

/// The arithmetic of each network's fused pass per scale against the machine's
/// estimated peak ([`super::cpu_peak_gflops`]), at the medians the latency
/// table measured: what each frame costs at best.
fn arithmetic(fused: &[FusedRows<'_>], threads: usize, out: &mut dyn Write) -> io::Result<()> {
    let cpuinfo = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let peak = super::cpu_peak_gflops(&cpuinfo, threads);
    match &peak {
        Some((p, why)) => writeln!(out, "estimated peak: {p:.0} GFLOP/s f32 ({why})")?,
        None => writeln!(out, "estimated peak: unknown (no clock in /proc/cpuinfo)")?,
    }
    writeln!(
        out,
        "{:<36} {:>6} {:>10} {:>12} {:>10} {:>10} {:>8} {:>12}",
        "network (fused)",
        "scale",
        "input WxH",
        "GFLOP/frame",
        "median ms",
        "GFLOP/s",
        "% peak",
        "ms at peak"
    )?;
    for (name, cfg, times) in fused {
        let macs = super::frame_macs(cfg);
        for (i, ((r, [h, w], m), (_, _, l))) in macs.iter().zip(times).enumerate() {
            let gflop = 2.0 * *m as f64 / 1e9;
            let rate = gflop / (l.median_ms / 1e3);
            let (pct, floor) = peak.as_ref().map_or(("-".into(), "-".into()), |(p, _)| {
                (
                    format!("{:.1}", 100.0 * rate / p),
                    format!("{:.2}", 1e3 * gflop / p),
                )
            });
            writeln!(
                out,
                "{:<36} {:>6} {:>10} {:>12.3} {:>10.2} {:>10.1} {:>8} {:>12}",
                if i == 0 { *name } else { "" },
                r,
                format!("{w}x{h}"),
                gflop,
                l.median_ms,
                rate,
                pct,
                floor
            )?;
        }
        if let [(_, _, lo), .., (_, _, hi)] = macs.as_slice() {
            writeln!(
                out,
                "{:<36} arithmetic ratio low/high scale {:.3} (the ideal t(low)/t(high); strided layers round up)",
                "",
                *lo as f64 / *hi as f64
            )?;
        }
    }
    Ok(())
}

/// The system's load average as `/proc/loadavg` has it (empty where there is none).
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .unwrap_or_default()
        .trim()
        .to_string()
}

/// Times batch-1 inference of every network of [`super::latency_networks`] per
/// scale on `device` (of kind `kind`; on the CPU also the fused engine), then
/// the multi-resolution training step, and writes the table to `out`
/// (`mrdrive bench policy`).
pub fn policy_bench(
    b: &PolicyBench,
    kind: DeviceKind,
    device: &Device,
    out: &mut dyn Write,
) -> io::Result<()> {
    let PolicyBench {
        repeats,
        train_steps,
        batch,
        quick,
    } = *b;
    let threads = crate::cpu_threads();
    writeln!(
        out,
        "policy benchmark: device {kind} (burn; cpu = flex with {threads} rayon threads, RAYON_NUM_THREADS), batch 1 inference, median of {repeats} (scales interleaved)"
    )?;
    writeln!(out, "load average before: {}", load_average())?;
    let nets = super::latency_networks(quick);
    writeln!(
        out,
        "{:<36} {:<6} {:>6} {:>10} {:>10} {:>9} {:>9} {:>12}",
        "network", "engine", "scale", "input WxH", "median ms", "min ms", "max ms", "t(.75)/t(1)"
    )?;
    let mut fused: Vec<FusedRows<'_>> = Vec::new();
    for (name, cfg) in &nets {
        let mut engines = vec![("burn", super::inference_latency(cfg, device, 3, repeats))];
        if kind == DeviceKind::Cpu {
            let rows = super::fused_latency(cfg, 3, repeats);
            fused.push((name, cfg, rows.clone()));
            engines.push(("fused", rows));
        }
        for (e, (engine, rows)) in engines.iter().enumerate() {
            let t = |s: f32| rows.iter().find(|r| r.0 == s).map(|r| r.2.median_ms);
            let ratio = match (t(0.75), t(1.0)) {
                (Some(a), Some(b)) => format!("{:.3}", a / b),
                _ => "-".into(),
            };
            for (i, (r, [h, w], l)) in rows.iter().enumerate() {
                writeln!(
                    out,
                    "{:<36} {:<6} {:>6} {:>10} {:>10.2} {:>9.2} {:>9.2} {:>12}",
                    if i == 0 && e == 0 { *name } else { "" },
                    if i == 0 { *engine } else { "" },
                    r,
                    format!("{w}x{h}"),
                    l.median_ms,
                    l.min_ms,
                    l.max_ms,
                    if i + 1 == rows.len() {
                        ratio.as_str()
                    } else {
                        ""
                    }
                )?;
            }
        }
    }
    writeln!(
        out,
        "(area ratio 0.5625; burn: tensor in, logits read back; fused: the driver's CPU path, RGB8 in, normalisation included)"
    )?;
    if kind == DeviceKind::Cpu {
        arithmetic(&fused, threads, out)?;
    }
    writeln!(out, "load average after inference: {}", load_average())?;
    if train_steps > 0 {
        let cfg = Preset::Cpu.config(&[0.75, 1.0]);
        let ad = device.clone().autodiff();
        for (what, tc) in [
            ("segmentation on (weight 0.05)", TrainConfig::new()),
            ("segmentation off", TrainConfig::new().with_seg_weight(0.0)),
        ] {
            let sps = super::train_throughput(&cfg, tc, &ad, batch, 1, train_steps);
            writeln!(
                out,
                "training, multi-resolution step (0.75x + 1.0x, {what}, Adam, head frozen), default model, batch {batch}: {sps:.1} samples/s (each sample at both scales; {train_steps} steps after 1 warm-up)"
            )?;
        }
    }
    Ok(())
}

/// What `bench loader` times.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoaderRun {
    /// Batch size.
    pub batch: usize,
    /// Loader worker threads.
    pub workers: usize,
    /// Timed loader batches (after 1 untimed).
    pub batches: usize,
    /// Timed training steps, alone and fed by the loader (after 1 warm-up); 0 skips training.
    pub train_steps: usize,
}

/// Runs [`super::loader_bench`] on `set` (read from `dir`) for the network
/// `config` and writes its figures to `out` (`mrdrive bench loader`).
pub fn loader_bench(
    dir: &Path,
    set: Arc<TrainSet>,
    config: &PolicyConfig,
    run: &LoaderRun,
    out: &mut dyn Write,
) -> io::Result<()> {
    let LoaderRun {
        batch,
        workers,
        batches,
        train_steps,
    } = *run;
    writeln!(
        out,
        "loader benchmark: {} ({} samples), batch {batch}, S0 {} x {}, {workers} loader thread(s) + {} rayon threads; load average {}",
        dir.display(),
        set.samples.len(),
        config.input_width,
        config.input_height,
        crate::cpu_threads(),
        load_average()
    )?;
    let r = super::loader_bench(set, config, batch, workers, batches, train_steps);
    let per_s = |bps: f64| format!("{bps:.2} batches/s = {:.0} samples/s", bps * batch as f64);
    writeln!(
        out,
        "loader alone, augmented:     {} ({batches} batches)",
        per_s(r.augmented_batches_per_s)
    )?;
    writeln!(
        out,
        "loader alone, not augmented: {} ({batches} batches)",
        per_s(r.plain_batches_per_s)
    )?;
    if let (Some(sps), Some(fed)) = (r.train_samples_per_s, r.fed) {
        writeln!(
            out,
            "training step alone (default model, 0.75x + 1.0x, segmentation on), toy batch: {sps:.1} samples/s = {:.3} batches/s ({train_steps} steps)",
            sps / batch as f64
        )?;
        writeln!(
            out,
            "training step fed by the augmenting loader: {:.1} samples/s, waiting for a batch {:.1} % of the time",
            fed.samples_per_s,
            100.0 * fed.waiting
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_overhead_table_has_a_line_per_network() {
        let table = overhead_table();
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 2 + super::super::overhead_networks().len());
        assert!(lines[1].starts_with("network"), "{table}");
        assert!(lines[2].starts_with("resnet34 (paper, 64-512)"), "{table}");
        assert!(lines[2].ends_with(|c: char| c.is_ascii_digit()), "{table}");
    }
}
