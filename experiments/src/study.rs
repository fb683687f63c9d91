//! The study's rerun as a chain of time-limited jobs (issue 50;
//! `docs/paper/registration.md`, sections 1 and 5).
//!
//! One commit makes every record: `docs/paper/study` pins it (`mrdrive study
//! --pin`, at a clean `HEAD` that descends from the registered commit). Each job
//! (`mrdrive study --hours H`) runs that commit's binary, built once into the
//! cache from a worktree of the commit (`<cache>/study/<commit>`, see
//! [`crate::collector::build`]), *inside* that worktree, so the maps, scenarios
//! and checkpoints are the commit's too, whatever the checkout has moved on to.
//! The stages run in the registration's order, each `mrdrive paper` call
//! resuming where the last job stopped:
//!
//! | stage | command | folder |
//! | --- | --- | --- |
//! | 1 | `mrdrive paper --only table2,fig3,fig4,fig5,table3` | `docs/paper` |
//! | 2 | `mrdrive paper --held-out` | `docs/paper-heldout` |
//! | 3 | `mrdrive paper` | `docs/paper` |
//!
//! Stage 3 starts only if stage 2 finished within [`BUDGET_JOBS`] -
//! [`STAGE3_JOBS`] jobs (the registration's budget), and is otherwise never run.
//!
//! Every [`Job::sync_every`] (an hour) and when the job ends, the worktree's new
//! and changed records ([`RESUME`]: the runs under `sweeps/` and `wall.json`) of
//! the two folders are copied into the checkout and committed there (`git commit
//! -- docs/paper docs/paper-heldout`), so a lost machine loses at most its last
//! hour of runs; a job on a fresh machine copies the committed records into its
//! new worktree first, and the sweeps skip them. The pinned build's own page in
//! the worktree is never copied: the registration builds the page once, at the
//! end, and an hour's half-done page is neither a verdict nor worth the megabytes
//! of figures it would add to every clone.
//!
//! The pages are built when every stage is settled (done, or stage 3 ruled out
//! by the budget), in the checkout, by the checkout's own build from the
//! records alone ([`build_pages`]: `mrdrive paper --report-only`, each folder
//! with its last finished stage's arguments), at the end of the job that settles
//! the last stage or by `mrdrive study --page`. The records' build runs the
//! study; the page's build need only descend from the registration, as the page
//! checks: it is the one that judges collisions under both registered rules
//! (registration, section 4), which the pinned commit's page did not.
//! Each job is a row of `docs/paper/study-jobs.md`, written when it starts (so a
//! job killed with its machine still counts against the budget) and completed
//! when it ends.

use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::{Duration, Instant};

use crate::PaperError;
use crate::collector;
use crate::registration::{self, Registration};

/// The pin file, in `docs/paper`: the study's commit.
pub const PIN_FILE: &str = "study";
/// The job log, in `docs/paper`.
pub const LOG_FILE: &str = "study-jobs.md";
/// The registration's budget: jobs of about 3 hours.
pub const BUDGET_JOBS: u32 = 14;
/// Jobs stage 3 needs at most (the registration's estimate, 11.8 h).
pub const STAGE3_JOBS: u32 = 5;
/// The folders the study writes, relative to the checkout (and to the worktree).
pub const FOLDERS: [&str; 2] = ["docs/paper", "docs/paper-heldout"];
/// What a resume needs of a folder, relative to it: the run records and the
/// sweeps' wall time: all a sync copies (the page is built at the end).
pub const RESUME: [&str; 2] = ["sweeps", "wall.json"];

/// A stage of the registration's plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stage {
    /// 1, 2 or 3.
    pub number: u32,
    /// What it makes.
    pub what: &'static str,
    /// The arguments of the pinned binary.
    pub args: &'static [&'static str],
    /// The folder (one of [`FOLDERS`]) it writes its records in.
    pub folder: &'static str,
}

/// The registration's three stages, in order.
pub const STAGES: [Stage; 3] = [
    Stage {
        number: 1,
        what: "the paper's tables and figures on its four routes",
        args: &["paper", "--only", "table2,fig3,fig4,fig5,table3"],
        folder: FOLDERS[0],
    },
    Stage {
        number: 2,
        what: "Fig. 3 and Table III on the 12 held-out routes",
        args: &["paper", "--held-out"],
        folder: FOLDERS[1],
    },
    Stage {
        number: 3,
        what: "beyond the paper: the frontier, jitter, more scales",
        args: &["paper"],
        folder: FOLDERS[0],
    },
];

/// What a job does with a stage.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Step {
    /// An earlier job finished it.
    Done,
    /// Run it (or go on with it).
    Run,
    /// The budget rules it out: never run (why).
    NotRun(String),
}

/// One row of the job log.
#[derive(Debug, Clone, PartialEq)]
pub struct JobRow {
    /// 1, 2, ...
    pub job: u32,
    /// When it started, `YYYY-MM-DD HH:MM` UTC.
    pub started: String,
    /// The machine.
    pub machine: String,
    /// Its wall time in hours, `None` while it runs (or when it was killed).
    pub hours: Option<f64>,
    /// The stages it finished.
    pub finished: Vec<u32>,
    /// How it ended.
    pub note: String,
}

/// The job log, `docs/paper/study-jobs.md`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JobLog {
    /// Its rows, in order.
    pub rows: Vec<JobRow>,
}

const LOG_HEAD: &str = "# The study's jobs\n\n\
One row per job of `mrdrive study` (docs/paper/registration.md, section 5): when it \
started (UTC), the machine, its wall time (blank: it was killed before its end), the \
stages it finished and how it ended. A row is written when its job starts, so every job \
counts against the budget of 14.\n\n\
| job | started (UTC) | machine | hours | stages finished | ended |\n\
| --- | --- | --- | --- | --- | --- |\n";

impl JobLog {
    /// Reads `path` (an empty log where it does not exist).
    pub fn read(path: &Path) -> Result<JobLog, PaperError> {
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(JobLog::default()),
            Err(e) => return Err(PaperError::io("read", path, e)),
        };
        let bad = |n: usize, why: &str| PaperError::Study {
            path: path.to_path_buf(),
            problem: format!(
                "line {n}: {why}; each row is `| job | started | machine | hours | stages | \
                 ended |`, as `mrdrive study` writes it (restore the file from git)"
            ),
        };
        let mut rows = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let cells: Vec<&str> = line.split('|').map(str::trim).collect();
            if cells.len() != 8 || cells[1].parse::<u32>().is_err() {
                continue; // the heading, the table's head, prose
            }
            let hours = match cells[4] {
                "" => None,
                h => Some(
                    h.parse()
                        .map_err(|_| bad(i + 1, "the hours are not a number"))?,
                ),
            };
            let finished = match cells[5] {
                "" | "-" => Vec::new(),
                s => s
                    .split(',')
                    .map(|n| n.trim().parse::<u32>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad(i + 1, "the stages are not numbers"))?,
            };
            rows.push(JobRow {
                job: cells[1].parse().expect("checked above"),
                started: cells[2].into(),
                machine: cells[3].into(),
                hours,
                finished,
                note: cells[6].into(),
            });
        }
        Ok(JobLog { rows })
    }

    /// Writes it whole to `path` (a temporary file, then a rename).
    pub fn write(&self, path: &Path) -> Result<(), PaperError> {
        let mut text = LOG_HEAD.to_string();
        for r in &self.rows {
            let hours = r.hours.map(|h| format!("{h:.2}")).unwrap_or_default();
            let finished: Vec<String> = r.finished.iter().map(u32::to_string).collect();
            let finished = if finished.is_empty() {
                "-".to_string()
            } else {
                finished.join(", ")
            };
            text += &format!(
                "| {} | {} | {} | {hours} | {finished} | {} |\n",
                r.job,
                r.started,
                r.machine,
                r.note.replace('|', "/")
            );
        }
        let tmp = path.with_extension("md.tmp");
        std::fs::write(&tmp, text).map_err(|e| PaperError::io("write", &tmp, e))?;
        std::fs::rename(&tmp, path).map_err(|e| PaperError::io("rename", path, e))
    }

    /// The job that finished `stage`, if one did.
    pub fn finished_by(&self, stage: u32) -> Option<u32> {
        self.rows
            .iter()
            .find(|r| r.finished.contains(&stage))
            .map(|r| r.job)
    }

    /// Whether every stage is settled: done, or ruled out by the budget.
    pub fn settled(&self) -> bool {
        STAGES.iter().all(|s| self.step(s.number) != Step::Run)
    }

    /// What the next job does with `stage`: the registration's order and budget.
    pub fn step(&self, stage: u32) -> Step {
        if self.finished_by(stage).is_some() {
            return Step::Done;
        }
        if stage == 3
            && let Some(job) = self.finished_by(2)
        {
            let left = BUDGET_JOBS.saturating_sub(job);
            if left < STAGE3_JOBS {
                return Step::NotRun(format!(
                    "stages 1 and 2 took {job} jobs of the budget's {BUDGET_JOBS}: {left} \
                     left, stage 3 needs {STAGE3_JOBS} (registration, \"How it was sized\")"
                ));
            }
        }
        Step::Run
    }
}

/// One job: the pinned binary run in its worktree until the stages are done or
/// the deadline comes.
pub struct Job<'a> {
    /// The checkout the records are committed to.
    pub repo: PathBuf,
    /// The worktree of the study's commit the binary runs in.
    pub tree: PathBuf,
    /// The study's binary.
    pub binary: PathBuf,
    /// When to stop (the run in flight is killed; finished records are kept).
    pub deadline: Instant,
    /// How often to copy and commit the records.
    pub sync_every: Duration,
    /// Commit to the checkout (off: only copy).
    pub commit: bool,
    /// Hears what the job does.
    pub note: &'a dyn Fn(&str),
}

/// How a stage's call ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StageEnd {
    /// Every run of the stage is done.
    Finished,
    /// The deadline came first.
    TimeUp,
}

impl Job<'_> {
    /// Runs `stage` until it finishes or the deadline comes, copying and
    /// committing the records every [`Job::sync_every`] and at the end.
    pub fn run_stage(&self, stage: &Stage) -> Result<StageEnd, PaperError> {
        (self.note)(&format!(
            "study: stage {} ({}): {} {}",
            stage.number,
            stage.what,
            self.binary.display(),
            stage.args.join(" ")
        ));
        let mut child = Command::new(&self.binary)
            .args(stage.args)
            .current_dir(&self.tree)
            .spawn()
            .map_err(|e| PaperError::io("run", &self.binary, e))?;
        let mut next_sync = Instant::now() + self.sync_every;
        loop {
            if let Some(status) = child
                .try_wait()
                .map_err(|e| PaperError::io("wait for", &self.binary, e))?
            {
                self.sync(&format!("stage {}", stage.number))?;
                return if status.success() {
                    Ok(StageEnd::Finished)
                } else {
                    Err(PaperError::Study {
                        path: self.tree.clone(),
                        problem: format!(
                            "stage {}'s `mrdrive {}` ended with {status}; its finished runs are \
                             kept and committed: read its message above, mend, and run the job \
                             again",
                            stage.number,
                            stage.args.join(" ")
                        ),
                    })
                };
            }
            let now = Instant::now();
            if now >= self.deadline {
                stop(&mut child);
                self.sync(&format!("stage {} (time limit)", stage.number))?;
                return Ok(StageEnd::TimeUp);
            }
            if now >= next_sync {
                self.sync(&format!("stage {}", stage.number))?;
                next_sync = now + self.sync_every;
            }
            std::thread::sleep(Duration::from_millis(200).min(self.deadline - now));
        }
    }

    /// Copies the worktree's new and changed records ([`RESUME`] of each of
    /// [`FOLDERS`]) into the checkout and commits them there (with `what` in the
    /// message).
    pub fn sync(&self, what: &str) -> Result<usize, PaperError> {
        let mut copied = 0;
        for f in FOLDERS {
            for r in RESUME {
                let (from, to) = (self.tree.join(f).join(r), self.repo.join(f).join(r));
                copied += mirror(&from, &to, Overwrite::Changed)?;
            }
        }
        // Also when nothing was copied now: a commit that failed before is tried again
        // (`commit` does nothing where nothing is new).
        if self.commit {
            commit(
                &self.repo,
                &format!("Add the study's records: {what}, {copied} files copied now"),
            )
            .unwrap_or_else(|e| {
                (self.note)(&format!(
                    "study: not committed ({e}); the next sync tries again"
                ))
            });
        }
        Ok(copied)
    }
}

/// Where a job works.
#[derive(Debug, Clone, Copy)]
pub struct Place<'a> {
    /// The checkout: its docs/paper holds the registration, the pin and the log.
    pub repo: &'a Path,
    /// The cache the pinned binary and its worktree live in.
    pub cache: &'a Path,
    /// The checkout's own build, which builds the pages ([`build_pages`]).
    pub page_binary: &'a Path,
}

/// Runs one job of the study from the checkout `place.repo`: the pinned
/// commit's binary (built into `place.cache` where missing), the committed
/// records copied into its worktree, then the stages the log and the budget
/// leave, until they are done or `hours` have passed; the job that settles the
/// last stage builds the pages ([`build_pages`]). `now_utc` gives `YYYY-MM-DD
/// HH:MM`; `machine` names this machine in the log. Returns the job's row.
pub fn run_job(
    place: Place<'_>,
    hours: f64,
    sync_every: Duration,
    now_utc: &dyn Fn() -> String,
    machine: &str,
    note: &dyn Fn(&str),
) -> Result<JobRow, PaperError> {
    let Place {
        repo,
        cache,
        page_binary,
    } = place;
    let start = Instant::now();
    let paper = repo.join(FOLDERS[0]);
    let pinned = pinned_commit(&paper)?;
    let base = cache.join("study");
    let tree = base.join(&pinned);
    let binary = cache
        .join("bin")
        .join(format!("mrdrive-{}", pinned.get(..7).unwrap_or(&pinned)));
    if !tree.join("Cargo.toml").exists() || !binary.exists() {
        // The collector's target folder: the same dependencies, already built.
        let target = cache.join("collector").join("target");
        collector::build(
            repo,
            &pinned,
            &base,
            &target,
            &binary,
            "the study's build",
            note,
        )
        .map_err(|e| PaperError::Study {
            path: e.path,
            problem: e.problem,
        })?;
    }
    link_shared(repo, &base)?;
    // What earlier jobs committed (a fresh machine's worktree has none of it).
    for f in FOLDERS {
        for r in RESUME {
            let (from, to) = (repo.join(f).join(r), tree.join(f).join(r));
            mirror(&from, &to, Overwrite::Never)?;
        }
    }
    let log_path = paper.join(LOG_FILE);
    let mut log = JobLog::read(&log_path)?;
    let number = log.rows.last().map_or(1, |r| r.job + 1);
    log.rows.push(JobRow {
        job: number,
        started: now_utc(),
        machine: machine.to_string(),
        hours: None,
        finished: Vec::new(),
        note: "running, or killed before its end".into(),
    });
    log.write(&log_path)?;
    let keep = |e: String| {
        note(&format!(
            "study: not committed ({e}); the next sync tries again"
        ))
    };
    commit(repo, &format!("Start the study's job {number}")).unwrap_or_else(keep);
    let job = Job {
        repo: repo.to_path_buf(),
        tree,
        binary,
        deadline: start + Duration::from_secs_f64(hours.max(0.0) * 3600.0),
        sync_every,
        commit: true,
        note,
    };
    let mut ended = "every registered stage is done: the page is built".to_string();
    for stage in &STAGES {
        match log.step(stage.number) {
            Step::Done => continue,
            Step::NotRun(why) => {
                ended = format!("stage 3 not run: {why}");
                break;
            }
            Step::Run => {}
        }
        let outcome = job.run_stage(stage);
        let row = log.rows.last_mut().expect("this job's row");
        match outcome {
            Ok(StageEnd::Finished) => row.finished.push(stage.number),
            Ok(StageEnd::TimeUp) => {
                ended = format!("stopped at the time limit in stage {}", stage.number);
                break;
            }
            Err(e) => {
                row.note = format!("failed: {e}");
                row.hours = Some(start.elapsed().as_secs_f64() / 3600.0);
                log.write(&log_path)?;
                commit(repo, &format!("End the study's job {number}: it failed"))
                    .unwrap_or_else(keep);
                return Err(e);
            }
        }
        log.write(&log_path)?;
    }
    let row = log.rows.last_mut().expect("this job's row");
    row.hours = Some(start.elapsed().as_secs_f64() / 3600.0);
    row.note = ended;
    let row = row.clone();
    log.write(&log_path)?;
    job.sync(&format!("job {number}'s end"))?;
    commit(repo, &format!("End the study's job {number}: {}", row.note)).unwrap_or_else(keep);
    if log.settled() {
        build_pages(repo, page_binary, &log, note)?;
    }
    Ok(row)
}

/// Checks that the binary `exe`, whose build is `build` (`mrdrive VERSION
/// (COMMIT)`), may write the study's pages: a clean checkout's commit, as
/// every record's build must be ([`Registration::check_builds`]).
pub fn check_page_build(exe: &Path, build: &str) -> Result<(), PaperError> {
    match registration::build_commit(build) {
        Some(c) if !c.ends_with("-dirty") => Ok(()),
        _ => Err(PaperError::Study {
            path: exe.to_path_buf(),
            problem: format!(
                "its build `{build}` names no clean commit (uncommitted changes, or built \
                 outside git), and a study job or `--page` writes the study's pages with it: \
                 commit, build again (`cargo build --release`), then run it"
            ),
        }),
    }
}

/// Builds the study's pages in the checkout `repo` with `page_binary` (the
/// checkout's own build), from the records alone (`--report-only`), each folder
/// of [`FOLDERS`] with the arguments of the last stage that finished in it (a
/// folder none finished in is left alone), and commits them. Refused while a
/// stage is still to run. Returns the folders built.
pub fn build_pages(
    repo: &Path,
    page_binary: &Path,
    log: &JobLog,
    note: &dyn Fn(&str),
) -> Result<Vec<&'static str>, PaperError> {
    if let Some(s) = STAGES.iter().find(|s| log.step(s.number) == Step::Run) {
        return Err(PaperError::Study {
            path: repo.join(FOLDERS[0]).join(LOG_FILE),
            problem: format!(
                "stage {} is still to run: the page is built once, when every stage is done \
                 (`mrdrive study --hours H` goes on with it)",
                s.number
            ),
        });
    }
    let mut built = Vec::new();
    for f in FOLDERS {
        let Some(stage) = STAGES
            .iter()
            .rev()
            .find(|s| s.folder == f && log.finished_by(s.number).is_some())
        else {
            continue;
        };
        let mut args = stage.args.to_vec();
        args.push("--report-only");
        note(&format!(
            "study: the page of {f}: {} {}",
            page_binary.display(),
            args.join(" ")
        ));
        let status = Command::new(page_binary)
            .args(&args)
            .current_dir(repo)
            .status()
            .map_err(|e| PaperError::io("run", page_binary, e))?;
        if !status.success() {
            return Err(PaperError::Study {
                path: repo.join(f),
                problem: format!(
                    "building its page, `mrdrive {}` ended with {status}; every record is \
                     committed: read its message above, mend, and build it again with `mrdrive \
                     study --page`",
                    args.join(" ")
                ),
            });
        }
        built.push(f);
    }
    commit(repo, "Build the study's pages from its records").map_err(|e| PaperError::Study {
        path: repo.to_path_buf(),
        problem: format!("the pages are built but not committed ({e}): commit them by hand"),
    })?;
    Ok(built)
}

/// The scenarios name CARLA's maps by paths relative to the checkout
/// (`scenarios/paper/../../../shared/carla/Town01.xodr`, the `../shared/` beside it):
/// the worktrees under `base` find them through a link `base/shared` to the
/// checkout's `../shared`, made (or pointed there again, on a machine where the
/// checkout moved) before the stages run. Without a `../shared` nothing is linked, and
/// a stage that needs a CARLA map names the missing file.
fn link_shared(repo: &Path, base: &Path) -> Result<(), PaperError> {
    let Ok(shared) = repo.join("../shared").canonicalize() else {
        return Ok(());
    };
    let link = base.join("shared");
    if let Ok(meta) = std::fs::symlink_metadata(&link) {
        if !meta.file_type().is_symlink() || std::fs::read_link(&link).is_ok_and(|l| l == shared) {
            return Ok(());
        }
        std::fs::remove_file(&link).map_err(|e| PaperError::io("remove", &link, e))?;
    }
    std::fs::create_dir_all(base).map_err(|e| PaperError::io("create", base, e))?;
    std::os::unix::fs::symlink(&shared, &link).map_err(|e| PaperError::io("link", &link, e))
}

/// How many runs `folder` (one of [`FOLDERS`]) records: the files of its
/// sweeps' `runs/` folders (0 where it has none).
pub fn recorded(folder: &Path) -> Result<usize, PaperError> {
    let sweeps = folder.join(RESUME[0]);
    let entries = match std::fs::read_dir(&sweeps) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(PaperError::io("read", &sweeps, e)),
    };
    let mut n = 0;
    for entry in entries {
        let root = entry
            .map_err(|e| PaperError::io("read", &sweeps, e))?
            .path();
        if let Ok(files) = std::fs::read_dir(sim::sweep::folder::SweepDir { root }.runs_dir()) {
            n += files.filter(|f| f.is_ok()).count();
        }
    }
    Ok(n)
}

/// Stops a stage's call: a kill (every record is written whole or not at all).
fn stop(child: &mut Child) {
    let _ = child.kill();
    let _ = child.wait();
}

/// Which files [`mirror`] copies over ones already there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overwrite {
    /// Only files missing in the destination.
    Never,
    /// Missing files and files whose bytes differ.
    Changed,
}

/// Copies the files under `from` into `to` (same relative paths), missing ones
/// and, with [`Overwrite::Changed`], differing ones; returns how many it copied.
/// A file `from` is copied to the file `to`; a missing `from` copies nothing.
pub fn mirror(from: &Path, to: &Path, overwrite: Overwrite) -> Result<usize, PaperError> {
    let meta = match std::fs::metadata(from) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(PaperError::io("read", from, e)),
    };
    if !meta.is_dir() {
        return copy_file(from, to, overwrite);
    }
    let entries = std::fs::read_dir(from).map_err(|e| PaperError::io("read", from, e))?;
    let mut copied = 0;
    for entry in entries {
        let entry = entry.map_err(|e| PaperError::io("read", from, e))?;
        copied += mirror(&entry.path(), &to.join(entry.file_name()), overwrite)?;
    }
    Ok(copied)
}

/// [`mirror`] of one file: 1 if it copied `src` to `dst`, else 0.
fn copy_file(src: &Path, dst: &Path, overwrite: Overwrite) -> Result<usize, PaperError> {
    let same = match std::fs::read(dst) {
        Ok(old) => {
            overwrite == Overwrite::Never || {
                let new = std::fs::read(src).map_err(|e| PaperError::io("read", src, e))?;
                old == new
            }
        }
        Err(_) => false,
    };
    if same {
        return Ok(0);
    }
    if let Some(dir) = dst.parent() {
        std::fs::create_dir_all(dir).map_err(|e| PaperError::io("create", dir, e))?;
    }
    let tmp = dst.with_extension("study-tmp");
    std::fs::copy(src, &tmp).map_err(|e| PaperError::io("copy", src, e))?;
    std::fs::rename(&tmp, dst).map_err(|e| PaperError::io("rename", dst, e))?;
    Ok(1)
}

/// Commits [`FOLDERS`] (what is in them now, nothing else) in `repo`.
fn commit(repo: &Path, message: &str) -> Result<(), String> {
    let present: Vec<&str> = FOLDERS
        .into_iter()
        .filter(|f| repo.join(f).exists())
        .collect();
    // Git's own message is the error: the caller notes it and the next sync tries again.
    let git = |args: &[&str]| registration::git(repo, args).map_err(|e| e.to_string());
    let mut add = vec!["add", "--"];
    add.extend(&present);
    git(&add)?;
    let mut staged = vec!["diff", "--cached", "--quiet", "--"];
    staged.extend(&present);
    if git(&staged).is_ok() {
        return Ok(()); // nothing new
    }
    let mut commit = vec!["commit", "-q", "-m", message, "--"];
    commit.extend(&present);
    git(&commit).map(drop)
}

/// `dir/study`'s commit, checked: it descends from the registered commit.
pub fn pinned_commit(paper: &Path) -> Result<String, PaperError> {
    let file = paper.join(PIN_FILE);
    let bad = |problem: String| PaperError::Study {
        path: file.clone(),
        problem,
    };
    let commit = collector::pinned_in(&file, "the study's commit", "whose build runs the study")
        .map_err(|e| bad(e.problem))?
        .ok_or_else(|| {
            bad(
                "missing: pin the study's commit with `mrdrive study --pin` at a clean checkout \
                 of the commit that is to make every record, then commit the file"
                    .into(),
            )
        })?;
    let reg = registered(paper)?;
    if !registration::descends(paper, &reg.commit, &commit)? {
        return Err(bad(format!(
            "commit {commit} does not descend from the registered commit {}: pin a later one",
            reg.commit
        )));
    }
    Ok(commit)
}

/// Pins the study's commit: `HEAD` of the checkout around `paper`, which must
/// have no uncommitted changes to tracked files and descend from the registered
/// commit. Writes `paper/study` (to be committed) and returns the commit.
pub fn pin(paper: &Path) -> Result<String, PaperError> {
    let file = paper.join(PIN_FILE);
    if file.exists() {
        return Err(PaperError::Study {
            path: file,
            problem: "the study's commit is pinned already; one build makes every record, so \
                      it never changes"
                .into(),
        });
    }
    let git = |args: &[&str]| registration::git(paper, args).map(|s| s.trim().to_string());
    if !git(&["status", "--porcelain", "--untracked-files=no"])?.is_empty() {
        return Err(PaperError::Study {
            path: paper.to_path_buf(),
            problem: "the checkout has uncommitted changes: the study's build must be a clean \
                      build of a commit; commit or stash them, then pin"
                .into(),
        });
    }
    let head = git(&["rev-parse", "HEAD"])?;
    let reg = registered(paper)?;
    if !registration::descends(paper, &reg.commit, &head)? {
        return Err(PaperError::Study {
            path: paper.to_path_buf(),
            problem: format!(
                "HEAD {head} does not descend from the registered commit {}",
                reg.commit
            ),
        });
    }
    let text = format!(
        "# The study's commit (`mrdrive study --pin`): its build, from a worktree of it, makes\n\
         # every record of docs/paper and docs/paper-heldout. Never edit it.\n{head}\n"
    );
    std::fs::write(&file, text).map_err(|e| PaperError::io("write", &file, e))?;
    Ok(head)
}

fn registered(paper: &Path) -> Result<Registration, PaperError> {
    Registration::load(paper)?.ok_or_else(|| PaperError::Registration {
        path: paper.join(registration::RECORD_FILE),
        problem: "missing: the study runs only under a registration (`mrdrive paper \
                  --register`, docs/paper/registration.md)"
            .into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(job: u32, finished: &[u32]) -> JobRow {
        JobRow {
            job,
            started: "2026-12-08 09:00".into(),
            machine: "AMD EPYC, 2 cores".into(),
            hours: Some(2.5),
            finished: finished.to_vec(),
            note: "stopped at the time limit".into(),
        }
    }

    #[test]
    fn the_job_log_reads_back_what_it_wrote() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(LOG_FILE);
        assert_eq!(JobLog::read(&path).unwrap(), JobLog::default());
        let mut running = row(2, &[1, 2]);
        running.hours = None;
        let log = JobLog {
            rows: vec![row(1, &[]), running],
        };
        log.write(&path).unwrap();
        assert_eq!(JobLog::read(&path).unwrap(), log);
        std::fs::write(&path, "| 3 | x | y | many | - | z |\n").unwrap();
        let e = JobLog::read(&path).unwrap_err().to_string();
        assert!(e.contains(LOG_FILE) && e.contains("line 1"), "{e}");
    }

    #[test]
    fn stages_run_in_order_and_stage_3_only_within_the_budget() {
        let log = |rows: Vec<JobRow>| JobLog { rows };
        let none = log(vec![row(1, &[])]);
        assert_eq!(none.step(1), Step::Run);
        let after = log(vec![row(1, &[1]), row(2, &[])]);
        assert_eq!(after.step(1), Step::Done);
        assert_eq!(after.step(2), Step::Run);
        // Stage 2 done at job 9: 5 jobs left, stage 3 runs.
        let mut rows: Vec<JobRow> = (1..9).map(|j| row(j, &[])).collect();
        rows.push(row(9, &[1, 2]));
        assert_eq!(log(rows.clone()).step(3), Step::Run);
        // At job 10: 4 left, never run.
        rows.push(row(10, &[]));
        rows[8].finished = vec![1];
        rows[9].finished = vec![2];
        assert!(matches!(log(rows.clone()).step(3), Step::NotRun(why) if why.contains("10 jobs")));
        rows[9].finished = vec![2, 3];
        assert_eq!(log(rows).step(3), Step::Done);
    }

    #[test]
    fn mirror_copies_new_files_and_overwrites_only_when_asked() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        std::fs::create_dir_all(a.join("sweeps/u/runs")).unwrap();
        std::fs::write(a.join("sweeps/u/runs/r.json"), "1").unwrap();
        std::fs::write(a.join("README.md"), "new").unwrap();
        std::fs::create_dir_all(&b).unwrap();
        std::fs::write(b.join("README.md"), "old").unwrap();
        assert_eq!(mirror(&a, &b, Overwrite::Never).unwrap(), 1);
        assert_eq!(text(b.join("README.md")), "old");
        assert_eq!(mirror(&a, &b, Overwrite::Changed).unwrap(), 1);
        assert_eq!(text(b.join("README.md")), "new");
        assert_eq!(mirror(&a, &b, Overwrite::Changed).unwrap(), 0);
        assert_eq!(text(b.join("sweeps/u/runs/r.json")), "1");
        assert_eq!(
            mirror(&dir.path().join("none"), &b, Overwrite::Changed).unwrap(),
            0
        );
        // A file to a file, into a folder that is not there yet.
        let one = dir.path().join("c/wall.json");
        assert_eq!(
            mirror(&a.join("README.md"), &one, Overwrite::Never).unwrap(),
            1
        );
        assert_eq!(text(&one), "new");
    }

    /// A file's text (the test fails where it cannot be read).
    fn text(path: impl AsRef<Path>) -> String {
        std::fs::read_to_string(path).unwrap()
    }

    /// The checkout's build at toy size: it writes its arguments as the page of
    /// the folder they name (`--held-out`: docs/paper-heldout), where it runs.
    const FAKE_PAGE: &str = "case \"$*\" in *--held-out*) d=docs/paper-heldout;; *) d=docs/paper;; esac\n\
                             mkdir -p $d && echo \"$@\" > $d/README.md";

    /// A checkout with one commit, and a fake study binary (a shell script) in a
    /// worktree folder: the job's mechanics at toy size.
    fn toy(script: &str) -> (tempfile::TempDir, PathBuf, PathBuf, PathBuf) {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let (repo, tree) = (dir.path().join("repo"), dir.path().join("tree"));
        std::fs::create_dir_all(repo.join("docs/paper")).unwrap();
        std::fs::create_dir_all(tree.join("docs/paper")).unwrap();
        std::fs::write(repo.join("docs/paper/README.md"), "placeholder\n").unwrap();
        let git = |args: &[&str]| {
            let ok = Command::new("git")
                .arg("-C")
                .arg(&repo)
                .args(["-c", "user.name=t", "-c", "user.email=t@t"])
                .args(args)
                .status()
                .unwrap()
                .success();
            assert!(ok, "git {args:?}");
        };
        git(&["init", "-q"]);
        // The job's own commits need an identity; CI's machine may have none.
        git(&["config", "user.name", "toy"]);
        git(&["config", "user.email", "toy@example.org"]);
        git(&["add", "."]);
        git(&["commit", "-q", "-m", "start"]);
        let bin = dir.path().join("fake-mrdrive");
        std::fs::write(&bin, format!("#!/bin/sh\n{script}\n")).unwrap();
        std::fs::set_permissions(&bin, std::fs::Permissions::from_mode(0o755)).unwrap();
        (dir, repo, tree, bin)
    }

    /// A job over the toy's folders that stops after `limit`.
    fn toy_job(repo: &Path, tree: &Path, bin: &Path, limit: Duration) -> Job<'static> {
        Job {
            repo: repo.to_path_buf(),
            tree: tree.to_path_buf(),
            binary: bin.to_path_buf(),
            deadline: Instant::now() + limit,
            sync_every: Duration::from_secs(3600),
            commit: true,
            note: &|_| {},
        }
    }

    fn commits(repo: &Path) -> String {
        let out = Command::new("git")
            .arg("-C")
            .arg(repo)
            .args(["log", "--format=%s"])
            .output()
            .unwrap();
        String::from_utf8_lossy(&out.stdout).into_owned()
    }

    #[test]
    fn a_finished_stage_lands_its_records_in_the_checkout_as_a_commit() {
        // The fake binary writes a record and the page in its working folder (the
        // worktree), with the arguments it was given: the record lands, the pinned
        // build's page does not (the checkout's build writes the page at the end).
        let (_dir, repo, tree, bin) = toy(
            "mkdir -p docs/paper/sweeps/u/runs && echo \"$@\" > docs/paper/sweeps/u/runs/r.json \
             && echo page > docs/paper/README.md",
        );
        let job = toy_job(&repo, &tree, &bin, Duration::from_secs(60));
        assert_eq!(job.run_stage(&STAGES[0]).unwrap(), StageEnd::Finished);
        let record = repo.join("docs/paper/sweeps/u/runs/r.json");
        assert_eq!(text(record), "paper --only table2,fig3,fig4,fig5,table3\n");
        assert_eq!(text(repo.join("docs/paper/README.md")), "placeholder\n");
        let log = commits(&repo);
        assert!(
            log.starts_with("Add the study's records: stage 1, 1 files copied now"),
            "{log}"
        );
    }

    #[test]
    fn the_deadline_stops_a_stage_and_keeps_what_it_finished() {
        // A record, the sweeps' wall time and a half-done page, then a long run
        // that the deadline cuts short.
        let (_dir, repo, tree, bin) = toy(
            "mkdir -p docs/paper/sweeps/u/runs && echo 1 > docs/paper/sweeps/u/runs/a.json \
             && echo 2 > docs/paper/wall.json && echo half > docs/paper/README.md \
             && echo fig > docs/paper/fig3.svg && sleep 60",
        );
        let job = toy_job(&repo, &tree, &bin, Duration::from_millis(1500));
        let start = Instant::now();
        assert_eq!(job.run_stage(&STAGES[0]).unwrap(), StageEnd::TimeUp);
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "the stage was not stopped"
        );
        assert!(repo.join("docs/paper/sweeps/u/runs/a.json").exists());
        assert_eq!(text(repo.join("docs/paper/wall.json")), "2\n");
        // The pinned build's page never comes: the checkout keeps its own.
        assert_eq!(text(repo.join("docs/paper/README.md")), "placeholder\n");
        assert!(!repo.join("docs/paper/fig3.svg").exists());
        assert!(commits(&repo).contains("stage 1 (time limit), 2 files copied now"));
        assert_eq!(recorded(&repo.join("docs/paper")).unwrap(), 1);
        assert_eq!(recorded(&repo.join("docs/paper-heldout")).unwrap(), 0);
    }

    #[test]
    fn the_pages_are_built_in_the_checkout_once_every_stage_is_settled() {
        // The checkout's build, faked: it writes its arguments as the page of the
        // folder they name, in the folder it runs in.
        let (_dir, repo, _, page) = toy(FAKE_PAGE);
        let read = |f: &str| text(repo.join(f).join("README.md"));
        // Stage 2 still to run: refused, nothing written.
        let log = JobLog {
            rows: vec![row(1, &[1])],
        };
        let e = build_pages(&repo, &page, &log, &|_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("stage 2 is still to run"), "{e}");
        assert_eq!(read("docs/paper"), "placeholder\n");
        // Stages 1 and 2 done at job 10: stage 3 is ruled out, the page is stage 1's.
        let mut rows: Vec<JobRow> = (1..10).map(|j| row(j, &[])).collect();
        rows.push(row(10, &[1, 2]));
        let log = JobLog { rows };
        assert!(log.settled());
        let built = build_pages(&repo, &page, &log, &|_| {}).unwrap();
        assert_eq!(built, FOLDERS.to_vec());
        assert_eq!(
            read("docs/paper"),
            "paper --only table2,fig3,fig4,fig5,table3 --report-only\n"
        );
        assert_eq!(
            read("docs/paper-heldout"),
            "paper --held-out --report-only\n"
        );
        assert!(commits(&repo).starts_with("Build the study's pages from its records"));
        // A page that fails to build names its command and how to try again.
        std::fs::write(&page, "#!/bin/sh\nexit 5\n").unwrap();
        let e = build_pages(&repo, &page, &log, &|_| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("mrdrive study --page"), "{e}");
    }

    #[test]
    fn only_a_clean_commits_build_may_write_the_pages() {
        let exe = Path::new("target/release/mrdrive");
        assert!(check_page_build(exe, "mrdrive 0.1.0 (c36f3af7814e)").is_ok());
        for unfit in [
            "mrdrive 0.1.0 (c36f3af7814e-dirty)",
            "mrdrive 0.1.0 (unknown commit)",
        ] {
            let e = check_page_build(exe, unfit).unwrap_err().to_string();
            assert!(e.contains("no clean commit"), "{e}");
        }
    }

    #[test]
    fn a_failing_stage_is_an_error_that_names_its_command() {
        let (_dir, repo, tree, bin) = toy("exit 3");
        let job = toy_job(&repo, &tree, &bin, Duration::from_secs(60));
        let e = job.run_stage(&STAGES[2]).unwrap_err().to_string();
        assert!(
            e.contains("stage 3") && e.contains("`mrdrive paper`"),
            "{e}"
        );
    }

    #[test]
    fn jobs_pin_resume_and_finish_the_stages_in_a_worktree_of_the_pinned_commit() {
        // A registered checkout, its commit pinned and a worktree of it in the
        // cache with a fake study binary: two stages finish, then the third.
        let (_dir, repo, _, _) = toy("");
        let git = |args: &[&str]| -> String {
            let out = Command::new("git")
                .arg("-C")
                .arg(&repo)
                .args(["-c", "user.name=t", "-c", "user.email=t@t"])
                .args(args)
                .output()
                .unwrap();
            assert!(out.status.success(), "git {args:?}");
            String::from_utf8_lossy(&out.stdout).trim().to_string()
        };
        let paper = repo.join("docs/paper");
        let first = git(&["rev-parse", "HEAD"]);
        std::fs::write(
            paper.join(registration::RECORD_FILE),
            format!("commit = \"{first}\"\nsha256 = \"{}\"\n", "0".repeat(64)),
        )
        .unwrap();
        git(&["add", "."]);
        git(&["commit", "-q", "-m", "register"]);
        std::fs::write(paper.join("README.md"), "edited\n").unwrap();
        let e = pin(&paper).unwrap_err().to_string();
        assert!(e.contains("uncommitted"), "{e}");
        git(&["checkout", "--", "."]);
        let commit = pin(&paper).unwrap();
        assert!(
            pin(&paper)
                .unwrap_err()
                .to_string()
                .contains("pinned already")
        );
        git(&["add", "."]);
        git(&["commit", "-q", "-m", "pin"]);
        assert_eq!(pinned_commit(&paper).unwrap(), commit);

        let cache = repo.parent().unwrap().join("cache");
        let tree = cache.join("study").join(&commit);
        git(&[
            "worktree",
            "add",
            "-q",
            "--detach",
            tree.to_str().unwrap(),
            &commit,
        ]);
        std::fs::write(tree.join("Cargo.toml"), "").unwrap();
        // An earlier job's committed record reaches the worktree before any stage.
        std::fs::create_dir_all(paper.join("sweeps/old/runs")).unwrap();
        std::fs::write(paper.join("sweeps/old/runs/o.json"), "old").unwrap();
        git(&["add", "."]);
        git(&["commit", "-q", "-m", "an earlier job's record"]);
        // The fake binary: stage 3 (`paper` alone) fails until told otherwise;
        // the others write one record each.
        let bin = cache.join("bin").join(format!("mrdrive-{}", &commit[..7]));
        std::fs::create_dir_all(bin.parent().unwrap()).unwrap();
        // A CARLA map beside the checkout, which the stages reach from the worktree.
        let carla = repo.parent().unwrap().join("shared/carla");
        std::fs::create_dir_all(&carla).unwrap();
        std::fs::write(carla.join("Town01.xodr"), "map").unwrap();
        let script = format!(
            "#!/bin/sh\ntest -f docs/paper/sweeps/old/runs/o.json || exit 9\n\
             test -f ../shared/carla/Town01.xodr || exit 8\n\
             if [ \"$#\" = 1 ] && [ ! -f {ok} ]; then exit 4; fi\n\
             mkdir -p docs/paper/sweeps/new/runs && echo \"$@\" > \"docs/paper/sweeps/new/runs/$#.json\"\n",
            ok = cache.join("ok").display()
        );
        std::fs::write(&bin, script).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&bin, std::fs::Permissions::from_mode(0o755)).unwrap();
        // The checkout's build, which writes the pages: its arguments as the page.
        let page = cache.join("bin").join("mrdrive-checkout");
        std::fs::write(&page, format!("#!/bin/sh\n{FAKE_PAGE}\n")).unwrap();
        std::fs::set_permissions(&page, std::fs::Permissions::from_mode(0o755)).unwrap();

        let job = |n: &str| {
            run_job(
                Place {
                    repo: &repo,
                    cache: &cache,
                    page_binary: &page,
                },
                1.0,
                Duration::from_secs(3600),
                &|| n.to_string(),
                "toy",
                &|_| {},
            )
        };
        let e = job("2026-12-08 09:00").unwrap_err().to_string();
        assert!(e.contains("stage 3"), "{e}");
        let log = JobLog::read(&paper.join(LOG_FILE)).unwrap();
        assert_eq!(log.rows.len(), 1);
        assert_eq!(log.rows[0].finished, vec![1, 2]);
        assert!(log.rows[0].note.starts_with("failed"), "{:?}", log.rows[0]);
        assert!(paper.join("sweeps/new/runs/3.json").exists());
        // Stage 3 still to run: no page yet.
        assert_eq!(text(paper.join("README.md")), "placeholder\n");
        std::fs::write(cache.join("ok"), "").unwrap();
        let row = job("2026-12-08 12:00").unwrap();
        assert_eq!((row.job, row.finished.clone()), (2, vec![3]));
        // The job that settles the last stage builds the pages, in the checkout.
        assert_eq!(text(paper.join("README.md")), "paper --report-only\n");
        assert_eq!(
            text(repo.join("docs/paper-heldout/README.md")),
            "paper --held-out --report-only\n"
        );
        assert!(paper.join("sweeps/new/runs/1.json").exists());
        assert_eq!(git(&["status", "--porcelain", "--", "docs/paper"]), "");
        let row = job("2026-12-08 15:00").unwrap();
        assert_eq!(row.finished, Vec::<u32>::new());
        assert!(
            row.note.starts_with("every registered stage is done"),
            "{row:?}"
        );
        assert_eq!(JobLog::read(&paper.join(LOG_FILE)).unwrap().rows.len(), 3);
    }
}
