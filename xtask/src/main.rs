//! Developer tasks: `cargo xtask <task>`.
//!
//! | task | what it does |
//! | --- | --- |
//! | `setup` | installs what the tests and the camera need and are missing (Debian packages, a Python venv) |
//! | `run [ARGS]` | `setup`, then `cargo run --release -- run scenarios/default.toml --json out/run.json --record out/run.mcap` (the RA policy `models/ra` with the oracle selector; `--expert` for the expert): its result table, its picture `out/run.png` and its Foxglove log; flags alone (`--seed 3`, `--checkpoint models/nra-1.0.safetensors`) are added to that, other arguments replace it |
//! | `test [ARGS]` | `setup`, then the whole test suite in release mode; ends with the count of skipped tests and why |
//! | `ci` | what `.ci/run` runs: formatting, then `test` with every skip turned into a failure |
//! | `lint` | `cargo fmt --check` and `cargo clippy --all-targets -- -D warnings` (run before committing; kept out of CI because it needs a second, check-mode build of every dependency) |
//! | `data [--quick]` | `mrdrive data study`: collects and labels the study's two datasets into `<cache>/data/original` and `<cache>/data/retarget` (the cache: `$MRDRIVE_CACHE`, else `~/.cache/mrdrive`; resumable; bit for bit; `--quick`: 2 short episodes each) |
//! | `train [--quick] [--lanes 1\|2] [--into DIR]` | `mrdrive train --all`: the training pipeline (`experiments::pipeline::TrainPlan`), skipping what is done: the datasets a slice at a time with the Original trained after each slice (the learning curve, `--slices N` rounds), NRA 0.75, NRA 1.0 and RA (two lanes of one thread each with `--lanes 2`, the default on 2 or more cores), the closed-loop bar into `DIR/models/closed-loop.md`, then RA5; `--quick`: toy sizes into `out/train-quick`; `--into DIR` is required otherwise (`--into .` replaces the shipped `models/`) |
//! | `bench` | `mrdrive bench all`: every benchmark on this machine in one go (physics and traffic, the rig per scale, policy inference and training, closed-loop real-time factors, PyTorch's reference when found, peak memory) into `docs/bench.md` |
//! | `paper [--quick] [--only ID,...]` | `mrdrive paper`: the paper's tables and figures from the shipped checkpoints (resumable sweeps, then Tables I-III, Figs. 3-5, the frontier, jitter, the more-scales study and the page in `docs/paper/`); `--quick`: toy size into `out/paper-quick` |
//! | `bless` | rewrites the golden files after a deliberate change: the regression suite's counts and the cross-CPU fingerprints |
//! | `gpu-test [FEATURES]` | the policy crate's tests built with burn's GPU backends (default `wgpu`; `wgpu,cuda` for both), in `target/gpu` so the main build is kept; lavapipe is enough for `wgpu`, CUDA needs an NVIDIA GPU |
//!
//! The set-up never asks: it installs a missing Debian package when it runs as
//! root (or with password-less sudo), and otherwise prints the exact command to
//! run and carries on, so the tests that need the package skip with a message.
//!
//! A test that skips (no `../shared`, no Python, no renderer) says so through
//! `world::testdata::skip`, which appends a line to the skip log
//! (`target/skipped-tests.txt`, passed as `MRDRIVE_SKIP_LOG`). `test` empties
//! the log before the run and prints its lines, counted, after it: the
//! harness itself reports a skipped test as "ok".

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

/// Debian packages the project uses at run time, with why.
const DEBIAN_PACKAGES: &[(&str, &str)] = &[
    (
        "mesa-vulkan-drivers",
        "software Vulkan (lavapipe) for the offscreen camera on machines without a GPU",
    ),
    (
        "qemu-user",
        "an emulated x86-64 CPU for the test that frames and policy arithmetic are the same on every CPU",
    ),
    ("slurm-wlm", "a local Slurm for the scale-out test"),
    ("munge", "Slurm's authentication"),
];

/// Python packages the cross-checking tests use (readers written by others).
const PYTHON_PACKAGES: &[&str] = &[
    "mcap==1.6.0",
    "jsonschema==4.26.0",
    "safetensors==0.8.0",
    "numpy==2.4.6",
    "zstandard==0.25.0",
    "gymnasium==1.4.0",
];

/// The tasks that build the release binary and run one of its commands.
const THROUGH: &[(&str, &[&str])] = &[
    ("data", &["data", "study"]),
    ("train", &["train", "--all"]),
    ("bench", &["bench", "all"]),
    ("paper", &["paper"]),
];

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let root = workspace_root();
    let task = args.first().map_or("", String::as_str);
    let through = THROUGH.iter().find(|(t, _)| *t == task);
    let result = match (task, through) {
        (_, Some((_, sub))) => setup(&root).and_then(|env| mrdrive(&root, &env, sub, &args[1..])),
        ("setup", _) => setup(&root).map(|_| ()),
        ("run", _) => setup(&root).and_then(|env| run(&root, &env, &args[1..])),
        ("test", _) => setup(&root).and_then(|env| test(&root, &env, &args[1..], false)),
        ("ci", _) => ci(&root),
        ("lint", _) => lint(&root),
        ("bless", _) => bless(&root),
        ("gpu-test", _) => setup(&root).and_then(|env| gpu_test(&root, &env, &args[1..])),
        _ => {
            eprintln!(
                "usage: cargo xtask <setup|run|test|ci|lint|bless|data|train|bench|paper|gpu-test> [ARGS]\n\nSee xtask/src/main.rs for what each task does."
            );
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("xtask: {message}");
            ExitCode::FAILURE
        }
    }
}

/// Environment variables that the set-up hands to the commands it starts.
type Env = Vec<(String, String)>;

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("xtask lives one folder below the workspace root")
        .to_path_buf()
}

/// Installs what is missing and can be installed; says what to do otherwise.
fn setup(root: &Path) -> Result<Env, String> {
    let mut env = Env::new();
    for (package, why) in DEBIAN_PACKAGES {
        if debian_package_installed(package) {
            continue;
        }
        eprintln!("xtask: the Debian package `{package}` is missing ({why}).");
        if can_install_packages() {
            eprintln!("xtask: installing it with apt-get ...");
            let prefix: &[&str] = if is_root() { &[] } else { &["sudo", "-n"] };
            let update = [prefix, &["apt-get", "update", "-qq"]].concat();
            let install = [prefix, &["apt-get", "install", "-y", "-qq", package]].concat();
            let ok = status_in(Path::new("."), &update, &[]).is_ok()
                && status_in(
                    Path::new("."),
                    &install,
                    &[("DEBIAN_FRONTEND", "noninteractive")],
                )
                .is_ok();
            if !ok {
                eprintln!(
                    "xtask: could not install `{package}`; install it by hand: sudo apt-get install {package}"
                );
            }
        } else {
            eprintln!(
                "xtask: install it with: sudo apt-get install {package}  (tests that need it will skip)"
            );
        }
    }
    match python_venv(root) {
        Ok(python) => env.push(("MRDRIVE_PYTHON".into(), python.display().to_string())),
        Err(why) => eprintln!(
            "xtask: no Python environment for the cross-checking tests ({why}); they will skip"
        ),
    }
    Ok(env)
}

fn debian_package_installed(package: &str) -> bool {
    Command::new("dpkg-query")
        .args(["-W", "-f=${Status}", package])
        .output()
        .map(|out| String::from_utf8_lossy(&out.stdout).contains("install ok installed"))
        // Not a Debian system: nothing to check, nothing to install.
        .unwrap_or(true)
}

fn is_root() -> bool {
    Command::new("id")
        .arg("-u")
        .output()
        .map(|out| String::from_utf8_lossy(&out.stdout).trim() == "0")
        .unwrap_or(false)
}

fn can_install_packages() -> bool {
    let has_apt = Command::new("apt-get").arg("--version").output().is_ok();
    has_apt && (is_root() || status_in(Path::new("."), &["sudo", "-n", "true"], &[]).is_ok())
}

/// Makes `.venv` with the Python packages the cross-checks use, once.
fn python_venv(root: &Path) -> Result<PathBuf, String> {
    let venv = root.join(".venv");
    let python = venv.join("bin").join("python3");
    let stamp = venv.join("mrdrive-packages.txt");
    let wanted = PYTHON_PACKAGES.join("\n");
    if python.exists() && std::fs::read_to_string(&stamp).ok().as_deref() == Some(wanted.as_str()) {
        return Ok(python);
    }
    let venv_str = venv.display().to_string();
    status_in(Path::new("."), &["python3", "-m", "venv", &venv_str], &[])
        .map_err(|e| format!("python3 -m venv: {e}"))?;
    let python_str = python.display().to_string();
    let pip = [
        &[
            python_str.as_str(),
            "-m",
            "pip",
            "install",
            "-q",
            "--disable-pip-version-check",
        ][..],
        PYTHON_PACKAGES,
    ]
    .concat();
    status_in(Path::new("."), &pip, &[]).map_err(|e| format!("pip install: {e}"))?;
    std::fs::write(&stamp, wanted).map_err(|e| format!("writing {}: {e}", stamp.display()))?;
    Ok(python)
}

fn run(root: &Path, env: &Env, args: &[String]) -> Result<(), String> {
    let mut cmd: Vec<&str> = vec!["cargo", "run", "--release", "--"];
    // Flags alone (`cargo xtask run --expert`) go to `mrdrive run` on the default scenario,
    // which writes its record, its picture and its log under out/.
    if args.first().is_none_or(|a| a.starts_with("--")) {
        cmd.extend(["run", "scenarios/default.toml"]);
        for (flag, file) in [("--json", "out/run.json"), ("--record", "out/run.mcap")] {
            if !args.iter().any(|a| a == flag) {
                cmd.extend([flag, file]);
            }
        }
    }
    cmd.extend(args.iter().map(String::as_str));
    status_in(root, &cmd, &borrow(env))
}

/// What CI sets so that a test that would skip fails instead.
const REQUIRE_ALL: [&str; 5] = [
    "MRDRIVE_REQUIRE_SHARED",
    "MRDRIVE_REQUIRE_PYTHON",
    "MRDRIVE_REQUIRE_GPU_API",
    "MRDRIVE_REQUIRE_EMULATOR",
    "MRDRIVE_REQUIRE_SLURM",
];

fn test(root: &Path, env: &Env, args: &[String], strict: bool) -> Result<(), String> {
    let log = root.join("target").join("skipped-tests.txt");
    let log_str = log.to_str().ok_or("the target path is not UTF-8")?;
    match std::fs::remove_file(&log) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(format!("cannot empty the skip log {}: {e}", log.display())),
    }
    let mut vars = borrow(env);
    vars.push(("MRDRIVE_SKIP_LOG", log_str));
    if strict {
        vars.extend(REQUIRE_ALL.map(|v| (v, "1")));
    }
    let mut cmd: Vec<&str> = vec!["cargo", "test", "--workspace", "--release"];
    cmd.extend(args.iter().map(String::as_str));
    let outcome = status_in(root, &cmd, &vars);
    let skipped = read_skips(&log)?;
    eprintln!("{}", skip_report(&skipped));
    outcome?;
    if strict && !skipped.is_empty() {
        return Err(format!(
            "{} test(s) skipped; CI must run every test",
            skipped.len()
        ));
    }
    Ok(())
}

/// The lines of the skip log (none if there is no log).
fn read_skips(log: &Path) -> Result<Vec<String>, String> {
    match std::fs::read_to_string(log) {
        Ok(text) => Ok(text
            .lines()
            .filter(|l| !l.trim().is_empty())
            .map(str::to_string)
            .collect()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(Vec::new()),
        Err(e) => Err(format!("cannot read the skip log {}: {e}", log.display())),
    }
}

/// The closing lines of a test run: how many tests skipped and why.
fn skip_report(skipped: &[String]) -> String {
    if skipped.is_empty() {
        return "xtask: no test skipped".into();
    }
    let mut text = format!(
        "xtask: {} test(s) SKIPPED (they passed without running; see why below):",
        skipped.len()
    );
    for line in skipped {
        text += "\n  ";
        text += line.strip_prefix("SKIPPED: ").unwrap_or(line);
    }
    text
}

fn ci(root: &Path) -> Result<(), String> {
    status_in(root, &["cargo", "fmt", "--all", "--", "--check"], &[])?;
    let env = setup(root)?;
    test(root, &env, &[], true)
}

fn lint(root: &Path) -> Result<(), String> {
    status_in(root, &["cargo", "fmt", "--all", "--", "--check"], &[])?;
    let clippy = "cargo clippy --release --workspace --all-targets -- -D warnings";
    status_in(root, &clippy.split(' ').collect::<Vec<_>>(), &[])
}

fn gpu_test(root: &Path, env: &Env, args: &[String]) -> Result<(), String> {
    let features = args.first().map_or("wgpu", String::as_str);
    let target = root.join("target").join("gpu");
    let target = target.to_str().ok_or("the target path is not UTF-8")?;
    let mut vars = borrow(env);
    vars.push(("CARGO_TARGET_DIR", target));
    // The root package's features switch the backends on for the policy crate too.
    status_in(
        root,
        &[
            "cargo",
            "test",
            "--release",
            "--workspace",
            "--features",
            features,
            "--lib",
            "--",
            "device",
        ],
        &vars,
    )
}

/// Builds the release binary and runs `mrdrive SUBCOMMAND... ARGS...`: `paper` is
/// `mrdrive paper`, `train` is `mrdrive train --all` (the pipeline,
/// `experiments::pipeline`), `data` is `mrdrive data study`, `bench` is
/// `mrdrive bench all`; see each command's `--help`.
fn mrdrive(root: &Path, env: &Env, subcommand: &[&str], args: &[String]) -> Result<(), String> {
    let vars = borrow(env);
    status_in(root, &["cargo", "build", "--release"], &vars)?;
    let bin = root.join("target/release/mrdrive");
    let bin = bin.to_str().ok_or("the target path is not UTF-8")?;
    let mut cmd = vec![bin];
    cmd.extend(subcommand);
    cmd.extend(args.iter().map(String::as_str));
    status_in(root, &cmd, &vars)
}

/// Rewrites the golden files: the regression suite's counts and the cross-CPU
/// fingerprints (`tests/golden/`).
fn bless(root: &Path) -> Result<(), String> {
    let bless = [("MRDRIVE_BLESS", "1")];
    status_in(
        root,
        &["cargo", "test", "--release", "--test", "regression"],
        &bless,
    )?;
    // Only the fingerprint tests that compare with a golden file.
    status_in(
        root,
        &[
            "cargo",
            "test",
            "--release",
            "--test",
            "cross_cpu",
            "golden",
        ],
        &bless,
    )
}

fn borrow(env: &Env) -> Vec<(&str, &str)> {
    env.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect()
}

fn status_in(dir: &Path, cmd: &[&str], vars: &[(&str, &str)]) -> Result<(), String> {
    let (program, args) = cmd.split_first().ok_or("empty command")?;
    let outcome = Command::new(program)
        .args(args)
        .current_dir(dir)
        .envs(vars.iter().copied())
        .status();
    match outcome {
        Ok(s) if s.success() => Ok(()),
        Ok(s) => Err(format!("`{}` failed ({s})", cmd.join(" "))),
        Err(e) => Err(format!("`{}` could not start: {e}", cmd.join(" "))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_skip_report_counts_each_skip_and_says_why() {
        let tmp = std::env::temp_dir().join(format!("xtask-skips-{}", std::process::id()));
        std::fs::write(
            &tmp,
            "SKIPPED: a: /x/carla/Town01.xodr not found\n\nSKIPPED: b: no Python\n",
        )
        .unwrap();
        let skips = read_skips(&tmp).unwrap();
        std::fs::remove_file(&tmp).unwrap();
        assert_eq!(skips.len(), 2);
        let report = skip_report(&skips);
        assert!(report.contains("2 test(s) SKIPPED"), "{report}");
        assert!(
            report.contains("\n  a: /x/carla/Town01.xodr not found"),
            "{report}"
        );
        assert!(report.contains("\n  b: no Python"), "{report}");
        assert_eq!(skip_report(&[]), "xtask: no test skipped");
        assert!(
            read_skips(Path::new("/nonexistent/skips.txt"))
                .unwrap()
                .is_empty()
        );
    }
}
