//! The same run on every CPU: the fixed frames of `mrdrive render fingerprint` and
//! the policy arithmetic of `mrdrive policy fingerprint` give the same bytes
//!
//! - as the golden files in `tests/golden/` (made on an Intel Xeon; the same bytes
//!   must come out on an AMD EPYC or any other x86-64 CPU with AVX2 and FMA);
//! - under llvmpipe settings that change its code paths (`GALLIUM_OVERRIDE_CPU_CAPS=avx`
//!   compiles the shaders without AVX-512; one rasteriser thread instead of several);
//! - on an emulated CPU: `qemu-x86_64 -cpu max` is an "AuthenticAMD" CPU without
//!   AVX-512 whose `rsqrtps` is exact, where Intel's and AMD's are approximations
//!   with different low bits. Before the renderer stopped using sRGB texture
//!   formats, about 0.3 % of a frame's pixels came out one level apart there; before
//!   burn's SIMD reductions were turned off, a training step's losses differed.
//!
//! The emulator comes from Debian's `qemu-user` (`cargo xtask setup` installs it); without
//! it that test skips visibly, and CI (`MRDRIVE_REQUIRE_EMULATOR=1`) fails instead.
//! `MRDRIVE_BLESS=1` (`cargo xtask bless`) rewrites the golden files.

mod common;

use std::process::Command;

use common::root;
use world::testdata::{Needs, skip};

/// The emulator and the CPU model it emulates.
const QEMU: &str = "qemu-x86_64";
const QEMU_CPU: &str = "max";

/// `mrdrive ARGS` with extra environment, run natively or under the emulator; its
/// standard output.
fn fingerprint(args: &[&str], env: &[(&str, &str)], emulated: bool) -> String {
    let exe = env!("CARGO_BIN_EXE_mrdrive");
    let mut cmd = if emulated {
        let mut c = Command::new(QEMU);
        c.args(["-cpu", QEMU_CPU, exe]);
        c
    } else {
        Command::new(exe)
    };
    cmd.current_dir(root()).args(args).envs(env.iter().copied());
    let out = cmd.output().expect("mrdrive starts");
    let mode = if emulated { "emulated" } else { "native" };
    common::succeeded(&[format!("{} ({mode}, {env:?})", args.join(" "))], &out)
}

/// The digest line of a fingerprint report.
fn digest(report: &str) -> &str {
    report
        .lines()
        .find(|l| l.starts_with("digest"))
        .expect("a digest line")
}

/// Compares a report with its golden file (or writes it when blessing).
fn check_golden(name: &str, got: &str) {
    let path = root().join("tests/golden").join(name);
    if std::env::var("MRDRIVE_BLESS").as_deref() == Ok("1") {
        std::fs::write(&path, got).unwrap();
        eprintln!("blessed {}", path.display());
        return;
    }
    let want = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (`cargo xtask bless` writes it)", path.display()));
    assert!(
        want == got,
        "{} differs from this machine's fingerprint.\n--- golden\n{want}--- here\n{got}\
         The same build must draw and compute the same bytes on every x86-64 CPU with AVX2 \
         and FMA (README, \"Determinism\"). If the backend line differs, this machine has \
         another Mesa or GPU and its frames are not comparable; otherwise the CPU changed a \
         result: find which frame or output and why before blessing.",
        path.display()
    );
}

#[test]
fn the_fixed_frames_are_the_golden_bytes() {
    let report = fingerprint(&["render", "fingerprint"], &[], false);
    check_golden("render_fingerprint.txt", &report);
}

#[test]
fn the_policy_arithmetic_is_the_golden_bits() {
    let full = fingerprint(&["policy", "fingerprint"], &[], false);
    let quick = fingerprint(&["policy", "fingerprint", "--quick"], &[], false);
    check_golden("policy_fingerprint.txt", &format!("{full}--quick\n{quick}"));
}

#[test]
fn llvmpipe_settings_that_change_its_code_paths_draw_the_same_frames() {
    let base = fingerprint(&["render", "fingerprint"], &[], false);
    for env in [
        [
            ("GALLIUM_OVERRIDE_CPU_CAPS", "avx"),
            ("LP_NUM_THREADS", "1"),
        ],
        [
            ("GALLIUM_OVERRIDE_CPU_CAPS", "avx"),
            ("LP_NUM_THREADS", "0"),
        ],
    ] {
        let other = fingerprint(&["render", "fingerprint"], &env, false);
        assert_eq!(
            digest(&other),
            digest(&base),
            "with {env:?}:\n{other}\nwithout:\n{base}"
        );
    }
}

#[test]
fn an_emulated_amd_cpu_without_avx512_draws_and_computes_the_same_bits() {
    let test = "an_emulated_amd_cpu_without_avx512_draws_and_computes_the_same_bits";
    if Command::new(QEMU).arg("--version").output().is_err() {
        skip(
            test,
            Needs::Emulator,
            &format!("`{QEMU}` not found (Debian: apt-get install qemu-user)"),
        );
        return;
    }
    for args in [
        &["render", "fingerprint"][..],
        &["policy", "fingerprint", "--quick"][..],
    ] {
        let native = fingerprint(args, &[], false);
        let emulated = fingerprint(args, &[], true);
        assert_eq!(
            native,
            emulated,
            "mrdrive {}: the emulated CPU ({QEMU} -cpu {QEMU_CPU}) computed other bytes",
            args.join(" ")
        );
    }
}
