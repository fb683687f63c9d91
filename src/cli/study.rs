//! `mrdrive study`: the study's rerun as a chain of time-limited jobs
//! ([`experiments::study`]): `--pin` names its one build, `--hours H` runs a job,
//! and with neither it says where the study stands.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use anyhow::Result;
use clap::Args;
use experiments::study::{self, JobLog, STAGES, Step};

/// `study` arguments.
#[derive(Debug, Args)]
pub struct StudyArgs {
    /// Pin the study's commit: this clean checkout's HEAD, which must descend from
    /// the registered commit; writes docs/paper/study (commit it next). Once.
    #[arg(long, conflicts_with = "hours")]
    pub pin: bool,
    /// Run one job for at most this many hours (a run in flight at the limit is
    /// stopped; every finished run is kept and committed): the registration's stages
    /// in order, each resuming where the last job stopped.
    #[arg(long)]
    pub hours: Option<f64>,
    /// Build the pages now (every stage settled, a job that failed to build them
    /// before): in the checkout, by this build, from the records alone. A job
    /// that settles the last stage does it itself.
    #[arg(long, conflicts_with_all = ["hours", "pin"])]
    pub page: bool,
    /// Minutes between the job's commits of its records to the checkout.
    #[arg(long, default_value_t = 60.0)]
    pub sync_minutes: f64,
    /// The checkout (its docs/paper holds the registration, the pin and the log).
    #[arg(long, default_value = ".")]
    pub repo: PathBuf,
}

/// Runs `study`.
pub fn run(a: StudyArgs) -> Result<()> {
    let paper = a.repo.join(study::FOLDERS[0]);
    if a.pin {
        let commit = study::pin(&paper)?;
        println!(
            "study: pinned commit {commit} in {}; commit that file, then run `mrdrive study \
             --hours H` job after job",
            paper.join(study::PIN_FILE).display()
        );
        return Ok(());
    }
    if !a.page && a.hours.is_none() {
        return status(&a.repo);
    }
    // This build writes the pages (at the end of the job that settles the last
    // stage, or with --page).
    let exe = std::env::current_exe()?;
    study::check_page_build(&exe, &sim::output::provenance::build_id())?;
    let Some(hours) = a.hours else {
        let log = JobLog::read(&paper.join(study::LOG_FILE))?;
        let built = study::build_pages(&a.repo, &exe, &log, &|line| eprintln!("{line}"))?;
        println!(
            "study: the pages of {} are built and committed",
            built.join(" and ")
        );
        return Ok(());
    };
    anyhow::ensure!(
        hours > 0.0 && a.sync_minutes > 0.0,
        "--hours and --sync-minutes must be above 0 (got {hours} and {})",
        a.sync_minutes
    );
    let cache = dataset::cache::root();
    let place = study::Place {
        repo: &a.repo,
        cache: &cache,
        page_binary: &exe,
    };
    let row = study::run_job(
        place,
        hours,
        Duration::from_secs_f64(a.sync_minutes * 60.0),
        &|| super::time_utc(SystemTime::now()),
        &policy::train::stage::machine(),
        &|line| eprintln!("{line}"),
    )?;
    println!(
        "study: job {} ended after {:.2} h: {}; stages finished in it: {:?}",
        row.job,
        row.hours.unwrap_or(0.0),
        row.note,
        row.finished
    );
    Ok(())
}

/// Prints the pinned commit, the jobs so far, the runs recorded and what the next
/// job does, from the checkout `repo`.
fn status(repo: &Path) -> Result<()> {
    let paper = &repo.join(study::FOLDERS[0]);
    match study::pinned_commit(paper) {
        Ok(c) => println!("study: commit {c} makes every record"),
        Err(e) => println!("{e}"),
    }
    let log = JobLog::read(&paper.join(study::LOG_FILE))?;
    println!(
        "study: {} of the budget's {} jobs used",
        log.rows.len(),
        study::BUDGET_JOBS
    );
    for f in study::FOLDERS {
        let n = study::recorded(&repo.join(f))?;
        println!("study: {n} runs recorded in {f}/sweeps");
    }
    for s in &STAGES {
        let step = match log.step(s.number) {
            Step::Done => format!("done (job {})", log.finished_by(s.number).unwrap_or(0)),
            Step::Run => "to run".into(),
            Step::NotRun(why) => format!("not run: {why}"),
        };
        println!(
            "stage {} ({}): `mrdrive {}`: {step}",
            s.number,
            s.what,
            s.args.join(" ")
        );
    }
    Ok(())
}
