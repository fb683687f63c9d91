//! Developer tasks: `cargo xtask <task>`.
//!
//! | task | what it does |
//! | --- | --- |
//! | `setup` | installs what the tests and the camera need and are missing (Debian packages, a Python venv) |
//! | `run [ARGS]` | `setup`, then `cargo run --release -- run scenarios/default.toml --json out/run.json --record out/run.mcap` (the RA policy `models/ra-towns` with the oracle selector; `--expert` for the expert): its result table, its picture `out/run.png` and its Foxglove log; flags alone (`--seed 3`, `--checkpoint models/ra.safetensors`) are added to that, other arguments replace it |
//! | `test [ARGS]` | `setup`, then the whole test suite in release mode; ends with the count of skipped tests and why |
//! | `ci` | what `.ci/run` runs: formatting, then `test` with every skip turned into a failure |
//! | `lint` | `cargo fmt --check` and `cargo clippy --all-targets -- -D warnings` (run before committing; kept out of CI because it needs a second, check-mode build of every dependency) |
//! | `data [--quick]` | collects and labels the two datasets of the study into `data/original` and `data/retarget` (resumable; regenerates them bit for bit; `--quick`: 2 short episodes each, for a smoke run) |
//! | `train [--quick] [--lanes 1\|2] [--into DIR]` | the paper's pipeline, skipping what is done: `data`, then `mrdrive train` for the Original (three phases, `ORIGINAL_PHASES`), then NRA 0.75, NRA 1.0 and RA (resumable; two at a time on one thread each with `--lanes 2`, the default on 2 or more cores, their output in `runs/<name>.log`), then the closed-loop bar (`mrdrive sweep` of `scenarios/paper/` at Tc = 50 ms, D = 0, three densities, per model and for the expert) into `models/closed-loop.md`, then the five-scale RA5 for the more-scales study; `--quick`: tiny datasets, 4 steps per stage, one density, into `out/train-quick`; `--into DIR`: models, runs and sweeps under DIR instead of the checkout (the shipped `models/` stay as they are) |
//! | `bench` | every benchmark on this machine, in one go: physics + traffic ticks/s (20 vehicles, 40 pedestrians), rig frames/s per scale (gen01, Town01), policy inference per scale (fused and burn) and training samples/s, closed-loop real-time factors (expert without and with the rig, RA with the oracle), PyTorch's reference when a Python with torch is found (`MRDRIVE_TORCH_PYTHON`, else `.venv`), peak memory per command; writes `docs/bench.md` |
//! | `paper [--quick] [--only ID,...]` | the paper's tables and figures from the shipped checkpoints: `mrdrive paper` (resumable sweeps into `out/paper/sweeps/`, then Tables I-III, Figs. 3-5, the latency frontier, latency jitter, the more-scales study and the comparison page into `docs/paper/`); `--quick`: every table and figure at toy size into `out/paper-quick` (minutes) |
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

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let root = workspace_root();
    let result = match args.first().map(String::as_str) {
        Some("setup") => setup(&root).map(|_| ()),
        Some("run") => setup(&root).and_then(|env| run(&root, &env, &args[1..])),
        Some("test") => setup(&root).and_then(|env| test(&root, &env, &args[1..], false)),
        Some("ci") => ci(&root),
        Some("lint") => lint(&root),
        Some("bless") => bless(&root),
        Some("data") => setup(&root).and_then(|env| data(&root, &env, &args[1..])),
        Some("train") => setup(&root).and_then(|env| train(&root, &env, &args[1..])),
        Some("bench") => setup(&root).and_then(|env| bench(&root, &env)),
        Some("paper") => setup(&root).and_then(|env| paper(&root, &env, &args[1..])),
        Some("gpu-test") => setup(&root).and_then(|env| gpu_test(&root, &env, &args[1..])),
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
            let ok = status(&update, &[]).is_ok()
                && status(&install, &[("DEBIAN_FRONTEND", "noninteractive")]).is_ok();
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
    has_apt && (is_root() || status(&["sudo", "-n", "true"], &[]).is_ok())
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
    status(&["python3", "-m", "venv", &venv_str], &[])
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
    status(&pip, &[]).map_err(|e| format!("pip install: {e}"))?;
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
        vars.push(("MRDRIVE_REQUIRE_SHARED", "1"));
        vars.push(("MRDRIVE_REQUIRE_PYTHON", "1"));
        vars.push(("MRDRIVE_REQUIRE_GPU_API", "1"));
        vars.push(("MRDRIVE_REQUIRE_EMULATOR", "1"));
        vars.push(("MRDRIVE_REQUIRE_SLURM", "1"));
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

/// `head`, then each line without its `prefix`, one per indented line.
fn listed(head: String, lines: &[String], prefix: &str) -> String {
    let mut text = head;
    for line in lines {
        text += "\n  ";
        text += line.strip_prefix(prefix).unwrap_or(line);
    }
    text
}

/// The closing lines of a test run: how many tests skipped and why.
fn skip_report(skipped: &[String]) -> String {
    if skipped.is_empty() {
        return "xtask: no test skipped".into();
    }
    let head = format!(
        "xtask: {} test(s) SKIPPED (they passed without running; see why below):",
        skipped.len()
    );
    listed(head, skipped, "SKIPPED: ")
}

fn ci(root: &Path) -> Result<(), String> {
    status_in(root, &["cargo", "fmt", "--all", "--", "--check"], &[])?;
    let env = setup(root)?;
    test(root, &env, &[], true)
}

fn lint(root: &Path) -> Result<(), String> {
    status_in(root, &["cargo", "fmt", "--all", "--", "--check"], &[])?;
    status_in(
        root,
        &[
            "cargo",
            "clippy",
            "--release",
            "--workspace",
            "--all-targets",
            "--",
            "-D",
            "warnings",
        ],
        &[],
    )
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

/// The study's datasets: (preset, folder, episodes). About 330 frames an episode (90 s
/// at 4 Hz, some end earlier): the Original's at the paper's scale (it pre-trains on
/// 270k frames; ours about 250k), the retargeting set at TimeParam's 50k.
const DATASETS: &[(&str, &str, &str)] = &[
    ("original", "data/original", "760"),
    ("retarget", "data/retarget", "150"),
];

fn data(root: &Path, env: &Env, args: &[String]) -> Result<(), String> {
    let quick = args.iter().any(|a| a == "--quick");
    let vars = borrow(env);
    status_in(root, &["cargo", "build", "--release"], &vars)?;
    let bin = root.join("target/release/mrdrive");
    let bin = bin.to_str().ok_or("the target path is not UTF-8")?;
    for &(preset, dir, episodes) in DATASETS {
        let dir = if quick {
            format!("{dir}-quick")
        } else {
            dir.to_string()
        };
        let (episodes, max_s) = if quick { ("2", "20") } else { (episodes, "90") };
        status_in(
            root,
            &[
                bin,
                "collect",
                "--preset",
                preset,
                "--out",
                &dir,
                "--episodes",
                episodes,
                "--max-s",
                max_s,
            ],
            &vars,
        )?;
        status_in(root, &[bin, "label", &dir], &vars)?;
        status_in(root, &[bin, "data", "info", &dir], &vars).unwrap_or_else(|e| {
            eprintln!("xtask: {e}");
        });
    }
    Ok(())
}

/// The drivers of the closed-loop bar: (sweep folder, checkpoint or expert, fixed scale).
const BAR: &[(&str, Option<&str>, &str)] = &[
    ("expert", None, "1.0"),
    ("original@1.0", Some("original"), "1.0"),
    ("nra-0.75@0.75", Some("nra-0.75"), "0.75"),
    ("nra-1.0@1.0", Some("nra-1.0"), "1.0"),
    ("ra@0.75", Some("ra"), "0.75"),
    ("ra@1.0", Some("ra"), "1.0"),
];

/// The Original's phases: (name, steps of 32, options). Each starts from the one before.
/// Phase NAME trains in `runs/NAME/original/` and publishes `runs/NAME/original.*`; the
/// last trains in `runs/original/` and publishes `models/original.*`. Why these:
/// docs/training.md, "The Original from scratch".
const ORIGINAL_PHASES: &[(&str, &str, &[&str])] = &[
    // WoR's recipe: every sample once per epoch.
    ("wor", "2300", &[]),
    // Commands drawn evenly, a quarter of the standing frames.
    (
        "balanced",
        "2000",
        &["--standing-keep", "0.25", "--balanced", "true"],
    ),
    // Frames with a walker in the corridor ahead drawn 8 times an epoch: without this
    // phase the Original hit a walker in 3 of the 6 Town01 runs of the bar, with it in none.
    (
        "original",
        "800",
        &[
            "--standing-keep",
            "0.25",
            "--balanced",
            "true",
            "--pedestrian-repeat",
            "8",
        ],
    ),
];

/// Where `cargo xtask train` writes its models and runs: `--into DIR`, or
/// `out/train-quick` with `--quick`. Without either it refuses: the checkout's own
/// `models/` hold the shipped checkpoints, which `--into .` replaces on purpose.
fn train_base(args: &[String], quick: bool) -> Result<String, String> {
    match (into_arg(args)?, quick) {
        (Some(dir), _) => Ok(dir),
        (None, true) => Ok("out/train-quick".into()),
        (None, false) => Err(
            "cargo xtask train needs --into DIR: --into out/scratch trains beside the shipped \
             checkpoints, --into . replaces the shipped models/ (their records on the paper \
             page name their SHA-256)"
                .into(),
        ),
    }
}

fn train(root: &Path, env: &Env, args: &[String]) -> Result<(), String> {
    let quick = args.iter().any(|a| a == "--quick");
    let base = train_base(args, quick)?;
    data(root, env, if quick { args } else { &[] })?;
    let vars = borrow(env);
    let bin = root.join("target/release/mrdrive");
    let bin = bin.to_str().ok_or("the target path is not UTF-8")?;
    let suffix = if quick { "-quick" } else { "" };
    let models = format!("{base}/models");
    let runs = format!("{base}/runs");
    // The Original in phases (docs/training.md), each continuing the one before it;
    // the last is published to `models/`, the others stay in their run folders.
    let original_data = format!("data/original{suffix}");
    let toy = ["--batch", "4", "--recalibrate-batches", "2"];
    let mut init: Option<String> = None;
    for (i, &(phase, steps, options)) in ORIGINAL_PHASES.iter().enumerate() {
        let last = i + 1 == ORIGINAL_PHASES.len();
        let (run_root, out) = if last {
            (runs.clone(), models.clone())
        } else {
            let own = format!("{runs}/{phase}");
            (own.clone(), own)
        };
        let steps = if quick { "4" } else { steps };
        let mut cmd = vec![
            bin,
            "train",
            "--stage",
            "original",
            "--data",
            &original_data,
        ];
        cmd.extend(["--runs", &run_root, "--out", &out, "--steps", steps]);
        if let Some(init) = &init {
            cmd.extend(["--init", init.as_str()]);
        }
        cmd.extend(options);
        if quick {
            cmd.extend(toy);
        }
        status_in(root, &cmd, &vars)?;
        init = Some(format!("{out}/original.safetensors"));
    }
    let retarget_data = format!("data/retarget{suffix}");
    // The three retargeted models of the paper (run name, stage, options); RA with five
    // scales for the more-scales study (`cargo xtask paper --only scales`) trains after
    // the bar, which does not need it.
    let retarget = |name: &'static str, stage: &'static str, extra: &[&'static str]| {
        let mut cmd = vec![
            bin,
            "train",
            "--stage",
            stage,
            "--data",
            retarget_data.as_str(),
        ];
        cmd.extend(["--runs", runs.as_str(), "--out", models.as_str()]);
        cmd.extend(extra);
        if quick {
            cmd.extend(toy);
            cmd.extend(["--steps", "4", "--unfreeze-every", "1"]);
        }
        (name, cmd)
    };
    let [nra_low, nra_high, ra] = [
        retarget("nra-0.75", "nra-0.75", &[]),
        retarget("nra-1.0", "nra-1.0", &[]),
        retarget("ra", "ra", &[]),
    ];
    let ra5 = retarget(
        "ra5",
        "ra",
        &["--scales", "0.5,0.625,0.75,0.875,1.0", "--name", "ra5"],
    );
    let lanes = lanes_arg(args)?;
    if lanes == 1 {
        for (_, cmd) in [&nra_low, &nra_high, &ra] {
            status_in(root, cmd, &vars)?;
        }
    } else {
        // Each stage needs only the Original (its teacher), so they run side by side in
        // two lanes of one thread each: on 2 cores two single-threaded stages make
        // 1.39-1.46x the samples/s of one stage on two threads (docs/training.md). RA
        // (both scales per step) takes about as long as the two NRA stages together.
        let lane_plan = [vec![&ra], vec![&nra_high, &nra_low]];
        let mut one_thread = vars.clone();
        one_thread.push(("RAYON_NUM_THREADS", "1"));
        let runs_dir = root.join(&runs);
        let results: Vec<Result<(), String>> = std::thread::scope(|scope| {
            let handles: Vec<_> = lane_plan
                .iter()
                .map(|lane| {
                    let (vars, runs_dir) = (&one_thread, &runs_dir);
                    scope.spawn(move || {
                        for (name, cmd) in lane {
                            let log = runs_dir.join(format!("{name}.log"));
                            eprintln!("xtask: training {name} (one thread; log {})", log.display());
                            logged_status_in(root, cmd, vars, &log)?;
                            eprintln!("xtask: {name} done");
                        }
                        Ok(())
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join()
                        .unwrap_or_else(|_| Err("a training lane panicked".into()))
                })
                .collect()
        });
        results.into_iter().collect::<Result<Vec<()>, String>>()?;
    }
    let scenarios = [
        "scenarios/paper/town01_route0.toml",
        "scenarios/paper/town01_route1.toml",
        "scenarios/paper/town02_route0.toml",
        "scenarios/paper/town02_route1.toml",
    ];
    let densities = if quick { "0:0" } else { "0:0,5:10,20:40" };
    let sweeps = format!("{base}/out/bar");
    for &(label, model, scale) in BAR {
        let out = format!("{sweeps}/{label}");
        let checkpoint = model.map(|m| format!("{models}/{m}.safetensors"));
        let mut cmd = vec![bin, "sweep"];
        cmd.extend(scenarios);
        cmd.extend(["--delays", "0", "--scales", scale, "--densities", densities]);
        cmd.extend(["--seeds", "0", "--out", &out]);
        match &checkpoint {
            Some(c) => cmd.extend(["--checkpoint", c.as_str()]),
            None => cmd.push("--expert"),
        }
        if quick {
            // The quick pipeline checks the plumbing: one short scenario suffices.
            cmd.retain(|a| !a.contains("town0") || a.ends_with("town01_route0.toml"));
        }
        status_in(root, &cmd, &vars)?;
    }
    let table = format!("{models}/closed-loop.md");
    status_in(
        root,
        &[bin, "policy", "table", &sweeps, "--out", &table],
        &vars,
    )?;
    eprintln!("xtask: the closed-loop table is in {table}");
    eprintln!("xtask: training ra5 (both threads)");
    status_in(root, &ra5.1, &vars)
}

/// Runs `cmd` in `dir` under `/usr/bin/time` when it exists; returns its output (stdout
/// then stderr, minus the renderer's XDG noise) and its peak resident memory (MiB).
fn measured(
    dir: &Path,
    cmd: &[&str],
    vars: &[(&str, &str)],
) -> Result<(String, Option<f64>), String> {
    let timed = Path::new("/usr/bin/time").exists();
    let mut full: Vec<&str> = Vec::new();
    if timed {
        full.extend(["/usr/bin/time", "-f", "PEAK_RSS_KB %M"]);
    }
    full.extend(cmd);
    let (program, args) = full.split_first().ok_or("empty command")?;
    let out = Command::new(program)
        .args(args)
        .current_dir(dir)
        .envs(vars.iter().copied())
        .output()
        .map_err(|e| format!("`{}` could not start: {e}", cmd.join(" ")))?;
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        return Err(format!(
            "`{}` failed ({}):\n{text}",
            cmd.join(" "),
            out.status
        ));
    }
    let mut peak = None;
    let mut kept = String::new();
    for line in text.lines() {
        if let Some(kb) = line.strip_prefix("PEAK_RSS_KB ") {
            peak = kb.trim().parse::<f64>().ok().map(|kb| kb / 1024.0);
        } else if !line.contains("XDG_RUNTIME_DIR") {
            kept += line;
            kept.push('\n');
        }
    }
    Ok((kept, peak))
}

/// The real-time factor in a result record written by `mrdrive run --json`.
fn rtf_of(json: &str) -> Option<f64> {
    let at = json.find("\"real_time_factor\"")?;
    let rest = json[at..].split_once(':')?.1;
    let end = rest.find([',', '}'])?;
    rest[..end].trim().parse().ok()
}

/// `cargo xtask paper [--quick] [--only ID,...] [...]`: builds the release
/// binary and runs `mrdrive paper` with the same arguments (the paper's
/// tables and figures into `docs/paper/`, resumable; see `mrdrive paper --help`).
fn paper(root: &Path, env: &Env, args: &[String]) -> Result<(), String> {
    let vars = borrow(env);
    status_in(root, &["cargo", "build", "--release"], &vars)?;
    let bin = root.join("target/release/mrdrive");
    let bin = bin.to_str().ok_or("the target path is not UTF-8")?;
    let mut cmd = vec![bin, "paper"];
    cmd.extend(args.iter().map(String::as_str));
    status_in(root, &cmd, &vars)
}

fn bench(root: &Path, env: &Env) -> Result<(), String> {
    let vars = borrow(env);
    status_in(root, &["cargo", "build", "--release"], &vars)?;
    let bin = root.join("target/release/mrdrive");
    let bin = bin.to_str().ok_or("the target path is not UTF-8")?;
    let shell = |c: &[&str]| -> String {
        Command::new(c[0])
            .args(&c[1..])
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
            .unwrap_or_default()
    };
    let cpu = shell(&[
        "sh",
        "-c",
        "grep -m1 'model name' /proc/cpuinfo | cut -d: -f2",
    ]);
    let mut md = format!(
        "# Benchmarks\n\nMade by `cargo xtask bench` on {} UTC: {}, {} cores, {} GiB; `{}`.\n\
         Figures vary by 10-30 % run to run on a shared machine: read ratios.\n\n",
        shell(&["date", "-u", "+%Y-%m-%d %H:%M"]),
        cpu,
        shell(&["nproc"]),
        shell(&["sh", "-c", "free -g | awk '/Mem:/{print $2}'"]),
        shell(&[bin, "--version"]),
    );
    let carla = root.join("../shared/carla/Town01.xodr").exists();
    let tmp = std::env::temp_dir().join(format!("mrdrive-bench-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).map_err(|e| e.to_string())?;
    let json = |name: &str| tmp.join(name).display().to_string();
    let (j1, j2, j3) = (json("expert.json"), json("rig.json"), json("ra.json"));
    let render_along = |scenario: &'static str| -> Vec<&str> {
        let mut c = vec![bin, "bench", "render", "--frames", "60", "--repeats", "3"];
        c.extend(["--scenario", scenario]);
        c
    };
    let mut steps: Vec<(&str, Vec<&str>)> = vec![
        (
            "Physics and traffic: 20 vehicles, 40 pedestrians, 2 simulated minutes on gen01",
            vec![
                bin,
                "traffic",
                "soak",
                "--map",
                "maps/gen01.xodr",
                "--minutes",
                "2",
                "--seed",
                "1",
            ],
        ),
        (
            "Camera rig frames/s per scale along the default scenario (gen01)",
            render_along("scenarios/default.toml"),
        ),
    ];
    if carla {
        steps.push((
            "Camera rig frames/s per scale along Town01 route 0",
            render_along("scenarios/paper/town01_route0.toml"),
        ));
    }
    steps.extend([
        (
            "Policy inference per scale (fused and burn) and training samples/s",
            vec![
                bin,
                "bench",
                "policy",
                "--quick",
                "--repeats",
                "10",
                "--train-steps",
                "5",
            ],
        ),
        (
            "Closed loop: the expert, no camera (scenarios/default.toml)",
            vec![
                bin,
                "run",
                "scenarios/default.toml",
                "--expert",
                "--quiet",
                "--json",
                &j1,
            ],
        ),
        (
            "Closed loop: the expert with the rig rendered every frame",
            vec![
                bin,
                "run",
                "scenarios/default.toml",
                "--expert",
                "--quiet",
                "--camera",
                "--json",
                &j2,
            ],
        ),
        (
            "Closed loop: the RA policy with the oracle selector (scenarios/policy_oracle.toml)",
            vec![
                bin,
                "run",
                "scenarios/policy_oracle.toml",
                "--quiet",
                "--json",
                &j3,
            ],
        ),
    ]);
    for (what, cmd) in &steps {
        eprintln!("xtask bench: {what}");
        let (out, peak) = measured(root, cmd, &vars)?;
        md += &format!(
            "## {what}\n\n`mrdrive {}`",
            cmd[1..]
                .join(" ")
                .replace(&tmp.display().to_string(), "out")
        );
        if let Some(p) = peak {
            md += &format!(", peak memory {p:.0} MiB");
        }
        let out = out.replace(&tmp.display().to_string(), "out");
        md += &format!("\n\n```text\n{out}```\n\n");
    }
    let rtf = |p: &str| std::fs::read_to_string(p).ok().as_deref().and_then(rtf_of);
    md += "## Real-time factors\n\n| run | simulated s per wall s |\n| --- | --- |\n";
    for (what, p) in [
        ("expert, no camera", &j1),
        ("expert, rig every frame", &j2),
        ("RA + oracle (rig at the selector's scale)", &j3),
    ] {
        md += &format!(
            "| {what} | {} |\n",
            rtf(p).map_or("?".into(), |r| format!("{r:.1}"))
        );
    }
    let torch_python = std::env::var("MRDRIVE_TORCH_PYTHON")
        .ok()
        .or_else(|| Some(root.join(".venv/bin/python").display().to_string()))
        .filter(|p| {
            Command::new(p)
                .args(["-c", "import torch"])
                .output()
                .is_ok_and(|o| o.status.success())
        });
    md += "\n## PyTorch's reference\n\n";
    match torch_python {
        Some(py) => {
            let (out, _) = measured(
                root,
                &[
                    &py,
                    "bench/torch_reference.py",
                    "--quick",
                    "--repeats",
                    "10",
                    "--train-steps",
                    "5",
                ],
                &vars,
            )?;
            md += &format!(
                "`python bench/torch_reference.py --quick --repeats 10 --train-steps 5`\n\n```text\n{out}```\n"
            );
        }
        None => md += "Not run: no Python with torch (set MRDRIVE_TORCH_PYTHON to one).\n",
    }
    let _ = std::fs::remove_dir_all(&tmp);
    let path = root.join("docs/bench.md");
    std::fs::write(&path, md).map_err(|e| format!("{}: {e}", path.display()))?;
    eprintln!("xtask bench: wrote {}", path.display());
    Ok(())
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

fn status(cmd: &[&str], vars: &[(&str, &str)]) -> Result<(), String> {
    status_in(Path::new("."), cmd, vars)
}

/// `--into DIR` of `train`: the folder whose `models/`, `runs/` and `out/bar/` the
/// pipeline writes (by default the checkout itself, so the shipped checkpoints; a run
/// from scratch beside them takes e.g. `--into out/scratch`).
fn into_arg(args: &[String]) -> Result<Option<String>, String> {
    let Some(i) = args.iter().position(|a| a == "--into") else {
        return Ok(None);
    };
    match args.get(i + 1) {
        Some(dir) if !dir.starts_with("--") => Ok(Some(dir.clone())),
        _ => Err("--into takes a folder, e.g. `cargo xtask train --into out/scratch`".into()),
    }
}

/// `--lanes N` of `train`: how many retargeting stages run at once (1 or 2); by default
/// 2 where the machine has at least two cores, else 1.
fn lanes_arg(args: &[String]) -> Result<usize, String> {
    let Some(i) = args.iter().position(|a| a == "--lanes") else {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        return Ok(if cores >= 2 { 2 } else { 1 });
    };
    match args.get(i + 1).map(String::as_str) {
        Some("1") => Ok(1),
        Some("2") => Ok(2),
        other => Err(format!(
            "--lanes takes 1 (the stages one after another, on every thread) or 2 (two at \
             once, one thread each), not {other:?}"
        )),
    }
}

/// Like [`status_in`], with the command's stdout and stderr appended to `log` (created
/// with its folder), so that two stages running at once do not mix their progress bars.
fn logged_status_in(
    dir: &Path,
    cmd: &[&str],
    vars: &[(&str, &str)],
    log: &Path,
) -> Result<(), String> {
    let (program, args) = cmd.split_first().ok_or("empty command")?;
    let open = || -> std::io::Result<std::fs::File> {
        if let Some(parent) = log.parent() {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(log)
    };
    let file = open().map_err(|e| format!("cannot open the log {}: {e}", log.display()))?;
    let err = file
        .try_clone()
        .map_err(|e| format!("cannot open the log {}: {e}", log.display()))?;
    let outcome = Command::new(program)
        .args(args)
        .current_dir(dir)
        .envs(vars.iter().copied())
        .stdout(file)
        .stderr(err)
        .status();
    match outcome {
        Ok(s) if s.success() => Ok(()),
        Ok(s) => Err(format!(
            "`{}` failed ({s}); its output is in {}",
            cmd.join(" "),
            log.display()
        )),
        Err(e) => Err(format!("`{}` could not start: {e}", cmd.join(" "))),
    }
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
    fn a_logged_command_appends_both_streams_and_a_failure_names_the_log() {
        let dir = std::env::temp_dir().join(format!("xtask-lanes-{}", std::process::id()));
        let log = dir.join("runs/stage.log");
        let ok = ["sh", "-c", "echo out; echo err >&2"];
        logged_status_in(Path::new("."), &ok, &[], &log).unwrap();
        let bad = ["sh", "-c", "echo again; exit 3"];
        let e = logged_status_in(Path::new("."), &bad, &[], &log).unwrap_err();
        assert!(
            e.contains("failed") && e.contains(&log.display().to_string()),
            "{e}"
        );
        let text = std::fs::read_to_string(&log).unwrap();
        assert_eq!(text.lines().collect::<Vec<_>>(), ["out", "err", "again"]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn lanes_are_one_or_two_and_a_wrong_count_is_refused_by_name() {
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(lanes_arg(&args(&["--quick", "--lanes", "1"])), Ok(1));
        assert_eq!(lanes_arg(&args(&["--lanes", "2", "--quick"])), Ok(2));
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        assert_eq!(lanes_arg(&args(&["--quick"])), Ok(cores.min(2)));
        assert_eq!(
            into_arg(&args(&["--quick", "--into", "out/x"])),
            Ok(Some("out/x".into()))
        );
        assert_eq!(into_arg(&args(&["--quick"])), Ok(None));
        assert!(into_arg(&args(&["--into"])).is_err());
        assert!(into_arg(&args(&["--into", "--quick"])).is_err());
        for bad in [&["--lanes", "3"][..], &["--lanes"]] {
            let e = lanes_arg(&args(bad)).unwrap_err();
            assert!(e.starts_with("--lanes takes 1"), "{e}");
        }
    }

    #[test]
    fn training_without_into_is_refused_and_names_both_ways() {
        let args = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let e = train_base(&args(&[]), false).unwrap_err();
        assert!(
            e.contains("--into out/scratch") && e.contains("--into ."),
            "{e}"
        );
        assert_eq!(
            train_base(&args(&[]), true).as_deref(),
            Ok("out/train-quick")
        );
        assert_eq!(
            train_base(&args(&["--into", "."]), false).as_deref(),
            Ok(".")
        );
    }

    #[test]
    fn the_real_time_factor_is_read_from_a_record() {
        let json = r#"{"result": {}, "perf": {"wall_s": 2.0, "real_time_factor": 312.5, "traffic_s": 0.1}}"#;
        assert_eq!(rtf_of(json), Some(312.5));
        assert_eq!(rtf_of("{}"), None);
    }

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
