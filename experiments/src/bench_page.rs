//! The benchmark page (`mrdrive bench all`, `cargo xtask bench`): every
//! benchmark of this binary run in one go on this machine, their printed
//! figures and peak memory gathered into `docs/bench.md`.
//!
//! Each benchmark is a command of this binary ([`benchmarks`]); [`write_page`]
//! runs them under `/usr/bin/time` (for the peak resident memory) when it
//! exists, then adds the closed-loop real-time factors from the runs' result
//! records and PyTorch's reference when a Python with torch is found.

use std::path::{Path, PathBuf};
use std::process::Command;

/// One benchmark: a title and the arguments to this binary.
#[derive(Debug, Clone, PartialEq)]
pub struct Benchmark {
    /// The section title.
    pub title: String,
    /// The arguments (the subcommand first).
    pub args: Vec<String>,
}

/// The closed-loop runs whose real-time factor the page lists: (what, record file name).
pub const LOOP_RECORDS: [(&str, &str); 3] = [
    ("expert, no camera", "expert.json"),
    ("expert, rig every frame", "rig.json"),
    ("RA + oracle (rig at the selector's scale)", "ra.json"),
];

/// The benchmarks, in the page's order; the runs write their records into `records`;
/// `carla`: the CARLA towns are there (`../shared/carla/`), so Town01's rig is timed too.
pub fn benchmarks(records: &Path, carla: bool) -> Vec<Benchmark> {
    let bench = |title: &str, args: &[&str]| Benchmark {
        title: title.into(),
        args: args.iter().map(|s| s.to_string()).collect(),
    };
    let record = |name: &str| records.join(name).display().to_string();
    let render_along = |title: &str, scenario: &str| {
        bench(
            title,
            &[
                "bench",
                "render",
                "--frames",
                "60",
                "--repeats",
                "3",
                "--scenario",
                scenario,
            ],
        )
    };
    let mut list = vec![
        bench(
            "Physics and traffic: 20 vehicles, 40 pedestrians, 2 simulated minutes on gen01",
            &[
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
        render_along(
            "Camera rig frames/s per scale along the default scenario (gen01)",
            "scenarios/default.toml",
        ),
    ];
    if carla {
        list.push(render_along(
            "Camera rig frames/s per scale along Town01 route 0",
            "scenarios/paper/town01_route0.toml",
        ));
    }
    let run = |title: &str, scenario: &str, extra: &[&str], json: &str| {
        let mut args = vec!["run", scenario];
        args.extend(extra);
        args.extend(["--quiet", "--json", json]);
        bench(title, &args)
    };
    list.extend([
        bench(
            "Policy inference per scale (fused and burn) and training samples/s",
            &[
                "bench",
                "policy",
                "--quick",
                "--repeats",
                "10",
                "--train-steps",
                "5",
            ],
        ),
        bench(
            "Render and policy overlapped: what pipelining a run's loop would win",
            &["bench", "overlap", "--frames", "60", "--repeats", "5"],
        ),
        run(
            "Closed loop: the expert, no camera (scenarios/default.toml)",
            "scenarios/default.toml",
            &["--expert"],
            &record(LOOP_RECORDS[0].1),
        ),
        run(
            "Closed loop: the expert with the rig rendered every frame",
            "scenarios/default.toml",
            &["--expert", "--camera"],
            &record(LOOP_RECORDS[1].1),
        ),
        run(
            "Closed loop: the RA policy with the oracle selector (scenarios/policy_oracle.toml)",
            "scenarios/policy_oracle.toml",
            &[],
            &record(LOOP_RECORDS[2].1),
        ),
    ]);
    list
}

/// A command's output (stdout then stderr, minus the renderer's XDG noise) and its
/// peak resident memory (MiB) when `/usr/bin/time` measured it.
pub struct Measured {
    /// What it printed.
    pub output: String,
    /// Peak resident memory (MiB).
    pub peak_mib: Option<f64>,
}

/// Runs `program args` in `dir` under `/usr/bin/time` when it exists.
pub fn measure(dir: &Path, program: &Path, args: &[String]) -> Result<Measured, String> {
    let line = format!("{} {}", program.display(), args.join(" "));
    let timed = Path::new("/usr/bin/time").exists();
    let mut cmd = if timed {
        let mut c = Command::new("/usr/bin/time");
        c.args(["-f", "PEAK_RSS_KB %M"]).arg(program);
        c
    } else {
        Command::new(program)
    };
    let out = cmd
        .args(args)
        .current_dir(dir)
        .output()
        .map_err(|e| format!("`{line}` could not start: {e}"))?;
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        return Err(format!("`{line}` failed ({}):\n{text}", out.status));
    }
    let mut peak_mib = None;
    let mut output = String::new();
    for line in text.lines() {
        if let Some(kb) = line.strip_prefix("PEAK_RSS_KB ") {
            peak_mib = kb.trim().parse::<f64>().ok().map(|kb| kb / 1024.0);
        } else if !line.contains("XDG_RUNTIME_DIR") {
            output += line;
            output.push('\n');
        }
    }
    Ok(Measured { output, peak_mib })
}

/// The real-time factor in a result record written by `mrdrive run --json`.
pub fn rtf_of(json: &str) -> Option<f64> {
    let v: serde_json::Value = serde_json::from_str(json).ok()?;
    find_number(&v, "real_time_factor")
}

fn find_number(v: &serde_json::Value, key: &str) -> Option<f64> {
    match v {
        serde_json::Value::Object(m) => m
            .get(key)
            .and_then(serde_json::Value::as_f64)
            .or_else(|| m.values().find_map(|x| find_number(x, key))),
        serde_json::Value::Array(a) => a.iter().find_map(|x| find_number(x, key)),
        _ => None,
    }
}

/// The first line of `sh -c script`'s output, trimmed (empty when it fails).
fn shell(script: &str) -> String {
    Command::new("sh")
        .args(["-c", script])
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default()
}

/// A Python with torch: `MRDRIVE_TORCH_PYTHON`, else the checkout's `.venv`.
fn torch_python(root: &Path) -> Option<PathBuf> {
    std::env::var("MRDRIVE_TORCH_PYTHON")
        .ok()
        .map(PathBuf::from)
        .or_else(|| Some(root.join(".venv/bin/python")))
        .filter(|p| {
            Command::new(p)
                .args(["-c", "import torch"])
                .output()
                .is_ok_and(|o| o.status.success())
        })
}

/// Runs every benchmark with the binary `exe` in `root` and returns the page
/// (Markdown); `note` hears each benchmark's title as it starts.
pub fn write_page(exe: &Path, root: &Path, note: &dyn Fn(&str)) -> Result<String, String> {
    let version = Command::new(exe)
        .arg("--version")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    let mut md = format!(
        "# Benchmarks\n\nMade by `cargo xtask bench` on {} UTC: {}, {} cores, {} GiB; `{version}`.\n\
         Figures vary by 10-30 % run to run on a shared machine: read ratios.\n\n",
        shell("date -u '+%Y-%m-%d %H:%M'"),
        shell("grep -m1 'model name' /proc/cpuinfo | cut -d: -f2"),
        shell("nproc"),
        shell("free -g | awk '/Mem:/{print $2}'"),
    );
    let carla = root.join("../shared/carla/Town01.xodr").exists();
    let tmp = tempfile_dir()?;
    let shown = |s: &str| s.replace(&tmp.display().to_string(), "out");
    let mut outputs = Vec::new();
    for b in benchmarks(&tmp, carla) {
        note(&b.title);
        let m = measure(root, exe, &b.args)?;
        outputs.push(m.output.clone());
        md += &format!("## {}\n\n`mrdrive {}`", b.title, shown(&b.args.join(" ")));
        if let Some(p) = m.peak_mib {
            md += &format!(", peak memory {p:.0} MiB");
        }
        md += &format!("\n\n```text\n{}```\n\n", shown(&m.output));
    }
    md += &budget(&outputs.join("\n"));
    md += "## Real-time factors\n\n| run | simulated s per wall s |\n| --- | --- |\n";
    for (what, file) in LOOP_RECORDS {
        let rtf = std::fs::read_to_string(tmp.join(file))
            .ok()
            .as_deref()
            .and_then(rtf_of);
        md += &format!(
            "| {what} | {} |\n",
            rtf.map_or("?".into(), |r| format!("{r:.1}"))
        );
    }
    md += "\n## PyTorch's reference\n\n";
    match torch_python(root) {
        Some(py) => {
            let args: Vec<String> = [
                "bench/torch_reference.py",
                "--quick",
                "--repeats",
                "10",
                "--train-steps",
                "5",
            ]
            .iter()
            .map(|s| s.to_string())
            .collect();
            let m = measure(root, &py, &args)?;
            md += &format!(
                "`python bench/torch_reference.py --quick --repeats 10 --train-steps 5`\n\n```text\n{}```\n",
                m.output
            );
        }
        None => md += "Not run: no Python with torch (set MRDRIVE_TORCH_PYTHON to one).\n",
    }
    md += &comparisons(root);
    let _ = std::fs::remove_dir_all(&tmp);
    Ok(md)
}

/// `docs/bench-compare.md`, the measured comparisons of two builds side by side
/// (`bench/compare.sh`), which no single build can make: kept on the page whenever it
/// is remade, under its own heading. Empty when the file is missing.
pub fn comparisons(root: &Path) -> String {
    match std::fs::read_to_string(root.join("docs/bench-compare.md")) {
        Ok(text) => format!("\n{}", text.trim_end()) + "\n",
        Err(_) => String::new(),
    }
}

/// The first number after `prefix` on the last line of `text` that starts
/// with it (after the prefix, whitespace-separated fields; `field` picks one).
fn number_after(text: &str, prefix: &str, field: usize) -> Option<f64> {
    text.lines()
        .rev()
        .find(|l| l.starts_with(prefix))
        .and_then(|l| l[prefix.len()..].split_whitespace().nth(field))
        .and_then(|v| v.parse().ok())
}

/// The per-frame budget of a policy run at 1.0x, from the benchmarks' printed
/// figures (`outputs`, all of them): each part's cost per 20 Hz camera frame
/// beside its floor, what the same work would cost with nothing wasted.
/// Parts whose figures are missing are left out.
pub fn budget(outputs: &str) -> String {
    // The rig along Town01 route 0 when it was timed, else along gen01 (the last
    // render benchmark printed wins, and Town01's comes after gen01's).
    let render = number_after(outputs, "scenario  scale 1.00", 2);
    let empty = number_after(outputs, "empty     scale 1.00", 2);
    let ticks = number_after(outputs, "ticks/s", 0);
    // The fused row at 1.0x: scale, input, GFLOP/frame, median ms, GFLOP/s, % peak, ms at peak.
    let arithmetic = outputs
        .find("network (fused)")
        .map_or("", |i| &outputs[i..]);
    let fused = arithmetic
        .lines()
        .find(|l| l.split_whitespace().take(2).collect::<Vec<_>>() == ["1", "240x96"])
        .map(|l| l.split_whitespace().map(str::to_string).collect::<Vec<_>>());
    let field = |i: usize| fused.as_ref().and_then(|f| f.get(i)?.parse::<f64>().ok());
    let mut t = String::from(
        "| part of one frame (1.0x, 20 Hz camera, 40 Hz physics) | ms | its floor | floor ms | measured / floor |\n\
         | --- | --- | --- | --- | --- |\n",
    );
    let mut total = (0.0, 0.0);
    let mut row = |part: &str, ms: f64, what: &str, floor: f64| {
        total.0 += ms;
        total.1 += floor;
        t += &format!(
            "| {part} | {ms:.2} | {what} | {floor:.2} | {:.1} |\n",
            ms / floor
        );
    };
    if let (Some(fps), Some(efps)) = (render, empty) {
        row(
            "render: the rig, 2x2 supersampled, read back",
            1e3 / fps,
            "the same frames of an empty town (sky, clear, resolve, sRGB, readback)",
            1e3 / efps,
        );
    }
    if let (Some(ms), Some(floor)) = (field(3), field(6)) {
        row(
            &format!(
                "policy: the fused pass, {} GFLOP",
                field(2).map_or("?".into(), |g| format!("{g:.3}"))
            ),
            ms,
            "the same arithmetic at the CPU's estimated peak",
            floor,
        );
    }
    if let Some(tps) = ticks {
        // Traffic's floor is not known: counted at its measured cost.
        row(
            "physics and traffic: 2 ticks (20 vehicles, 40 pedestrians)",
            2e3 / tps,
            "(none estimated: counted as measured)",
            2e3 / tps,
        );
    }
    if total.0 == 0.0 {
        return String::new();
    }
    format!(
        "## Per-frame budget\n\n\
         Each part of a policy run's 20 Hz frame at 1.0x, from the figures above, beside its \
         floor: what the same work costs with nothing wasted. The render's floor is measured \
         (the pipeline with nothing to draw); the policy's is arithmetic (its multiply-adds at \
         the estimated peak, which no kernel reaches: an upper bound on what tuning can win).\n\n\
         {t}| total | {:.2} | | {:.2} | {:.1} |\n\n\
         Without changing what is drawn or computed, a frame can get at most {:.1}x faster on \
         this machine: the records stay identical only while the arithmetic and the pictures do.\n\n",
        total.0,
        total.1,
        total.0 / total.1,
        total.0 / total.1,
    )
}

/// A fresh folder for the runs' records.
fn tempfile_dir() -> Result<PathBuf, String> {
    let tmp = std::env::temp_dir().join(format!("mrdrive-bench-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).map_err(|e| format!("{}: {e}", tmp.display()))?;
    Ok(tmp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_real_time_factor_is_read_from_a_record_wherever_it_sits() {
        let json = r#"{"result": {"completion_pct": 100.0}, "timing": {"real_time_factor": 12.5}}"#;
        assert_eq!(rtf_of(json), Some(12.5));
        assert_eq!(rtf_of(r#"{"result": {}}"#), None);
        assert_eq!(rtf_of("not json"), None);
    }

    #[test]
    fn the_page_times_the_rig_along_town01_only_with_the_carla_towns() {
        let with = benchmarks(Path::new("/tmp/r"), true);
        let without = benchmarks(Path::new("/tmp/r"), false);
        assert_eq!(with.len(), without.len() + 1);
        let ra = without.last().unwrap().args.join(" ");
        assert_eq!(
            ra,
            "run scenarios/policy_oracle.toml --quiet --json /tmp/r/ra.json"
        );
        assert_eq!(
            without[4].args.join(" "),
            "run scenarios/default.toml --expert --quiet --json /tmp/r/expert.json"
        );
        assert_eq!(without[3].args[..2], ["bench", "overlap"]);
    }

    #[test]
    fn the_budget_sets_each_part_beside_its_floor() {
        let outputs = "\
ticks/s                 10000 per wall second of stepping (physics + behaviours, one thread)
network                              engine  scale  input WxH  median ms    min ms    max ms  t(.75)/t(1)
default: resnet18 half 32-256        burn     0.75     180x72       6.30      5.54      7.26
                                                 1     240x96       9.44      8.31     10.57        0.667
scenario  scale 1.00  240x96   median   200.0 rig fps  (repeats: 200 200 200)
scenario  scale 0.75  180x72   median   250.0 rig fps  (repeats: 250 250 250)
empty     scale 1.00  240x96   median   400.0 rig fps  (repeats: 400 400 400)
network (fused)                       scale  input WxH  GFLOP/frame  median ms    GFLOP/s   % peak   ms at peak
default: resnet18 half 32-256          0.75     180x72        0.283       5.19       54.6     32.9         1.71
                                          1     240x96        0.450       8.00       56.3     33.9         2.50
";
        let page = budget(outputs);
        assert!(
            page.contains("| render: the rig, 2x2 supersampled, read back | 5.00 |"),
            "{page}"
        );
        assert!(page.contains("the same frames of an empty town (sky, clear, resolve, sRGB, readback) | 2.50 | 2.0 |"), "{page}");
        assert!(
            page.contains("| policy: the fused pass, 0.450 GFLOP | 8.00 |"),
            "{page}"
        );
        assert!(page.contains("| 2.50 | 3.2 |"), "{page}");
        // 5 + 8 + 0.2 ms against 2.5 + 2.5 + 0.2: at most 2.5x.
        assert!(page.contains("| total | 13.20 | | 5.20 | 2.5 |"), "{page}");
        assert!(page.contains("at most 2.5x faster"), "{page}");
        assert_eq!(budget("nothing measured"), "");
    }

    #[test]
    fn a_measured_command_keeps_its_output_and_a_failure_names_it() {
        let dir = std::env::temp_dir();
        let m = measure(&dir, Path::new("/bin/sh"), &["-c".into(), "echo hi".into()]).unwrap();
        assert!(m.output.contains("hi"));
        let e = measure(&dir, Path::new("/bin/sh"), &["-c".into(), "exit 4".into()]);
        assert!(e.err().unwrap().contains("exit 4"));
    }

    #[test]
    fn the_comparisons_file_is_carried_onto_the_page() {
        let root = tempfile::tempdir().unwrap();
        assert_eq!(comparisons(root.path()), "");
        std::fs::create_dir_all(root.path().join("docs")).unwrap();
        std::fs::write(
            root.path().join("docs/bench-compare.md"),
            "## Before and after\n\n| a |\n\n",
        )
        .unwrap();
        assert_eq!(comparisons(root.path()), "\n## Before and after\n\n| a |\n");
    }
}
