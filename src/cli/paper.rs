//! `mrdrive paper [--quick] [--only ID,...]`: the paper's tables and figures
//! from the shipped checkpoints (`experiments`), resumable.

use std::path::PathBuf;
use std::sync::Mutex;

use anyhow::Context;
use clap::Args;
use experiments::{Experiment, PaperConfig, Progress, RunOptions};
use sim::sweep::RunSpec;

/// `paper` arguments.
#[derive(Args)]
pub struct PaperArgs {
    /// A smoke test of every table and figure (one route, one seed, runs capped at 8 s): minutes.
    #[arg(long)]
    pub quick: bool,
    /// The study on 12 routes no training run drove (8 random Town02 routes, 4 on
    /// the held-out generated town held01): Fig. 3 and Table III unless --only
    /// says otherwise; default folder docs/paper-heldout.
    #[arg(long, conflicts_with = "quick")]
    pub held_out: bool,
    /// Only these experiments, comma-separated: table1, table2, fig3, fig4, fig5, table3, frontier, jitter, scales.
    #[arg(long, default_value = "")]
    pub only: String,
    /// The folder of everything: sweeps (`sweeps/`), derived scenarios, tables,
    /// figures and the page (default: docs/paper, or out/paper-quick with --quick).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Runs at a time.
    #[arg(long, default_value_t = 2)]
    pub jobs: usize,
    /// Write the tables and figures from the runs already finished; run nothing.
    #[arg(long)]
    pub report_only: bool,
    /// Add runs to a folder whose runs another build (commit) made; without it
    /// such a folder is refused (the study's rule: one build for every record).
    #[arg(long)]
    pub mixed_builds: bool,
    /// Run only the first N seeds this time (the rest stay planned; a later call goes on).
    #[arg(long)]
    pub seeds: Option<usize>,
    /// Register the folder's `registration.md` (final, committed as it is) at the
    /// checkout's HEAD: writes `registered.toml` to commit next; runs nothing.
    /// From then on the page takes only records of builds descending from it.
    #[arg(long, conflicts_with_all = ["quick", "report_only"])]
    pub register: bool,
}

/// A progress bar over the runs still to do.
struct Bar {
    bar: indicatif::ProgressBar,
    unit: Mutex<String>,
}

impl Progress for Bar {
    fn unit(&self, id: &str, done: usize, planned: usize) {
        *self.unit.lock().expect("not poisoned") = id.to_string();
        self.bar.set_length(planned as u64);
        self.bar.set_position(done as u64);
        self.bar.set_message(id.to_string());
    }

    fn run_done(&self, _spec: &RunSpec) {
        self.bar.inc(1);
    }
}

/// Runs `paper`.
pub fn run(a: PaperArgs) -> anyhow::Result<()> {
    let (cfg, label, default_out) = if a.quick {
        (PaperConfig::quick(), "quick", "out/paper-quick")
    } else if a.held_out {
        (PaperConfig::held_out(), "held-out", "docs/paper-heldout")
    } else {
        (PaperConfig::full(), "full", "docs/paper")
    };
    let out = a.out.unwrap_or_else(|| PathBuf::from(default_out));
    // The held-out routes are part of the one registered study: the paper's
    // folder holds its registration.
    let registered_in = if a.held_out {
        PathBuf::from("docs/paper")
    } else {
        out.clone()
    };
    let only = if a.held_out && a.only.is_empty() {
        "fig3,table3"
    } else {
        a.only.as_str()
    };
    if a.register {
        let r = experiments::registration::register(&registered_in)?;
        println!(
            "paper: registered {} at commit {} (SHA-256 {}); commit {} now",
            registered_in
                .join(experiments::registration::RULES_FILE)
                .display(),
            r.commit,
            r.sha256,
            registered_in
                .join(experiments::registration::RECORD_FILE)
                .display()
        );
        return Ok(());
    }
    let experiments = Experiment::parse_list(only)?;
    let opts = RunOptions {
        out: out.clone(),
        jobs: a.jobs,
        experiments,
        report_only: a.report_only,
        mixed_builds: a.mixed_builds,
        label: label.into(),
        seeds: a.seeds,
        registered_in,
    };
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:40}] {pos}/{len} runs of {msg} (eta {eta})",
        )
        .expect("a valid template")
        .progress_chars("=> "),
    );
    let progress = Bar {
        bar,
        unit: Mutex::new(String::new()),
    };
    let outcome = experiments::run_paper(&cfg, &opts, &super::drivers(), &progress)
        .with_context(|| format!("paper run into {}", out.display()))?;
    progress.bar.finish_and_clear();
    for (unit, key, why) in &outcome.failed {
        eprintln!("paper: {unit}: run {key} failed: {why}");
    }
    println!(
        "paper ({label}): {} runs finished now, {} failed; {} files written under {} (page: {}/README.md)",
        outcome.finished,
        outcome.failed.len(),
        outcome.written.len(),
        out.display(),
        out.display()
    );
    anyhow::ensure!(
        outcome.failed.is_empty(),
        "{} run(s) failed; rerun the same command to retry them",
        outcome.failed.len()
    );
    Ok(())
}
