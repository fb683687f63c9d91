//! The training pipeline as a plan (`mrdrive train --all`, `cargo xtask train`):
//! the study's datasets, the Original trained as a learning curve over its data's
//! slices, the three retargeted models, the closed-loop bar and the five-scale RA,
//! each a command of this binary.
//!
//! [`TrainPlan`] is the configuration ([`TrainPlan::full`] is the study's,
//! [`TrainPlan::quick`] the same plumbing at toy size); [`TrainPlan::steps`]
//! turns it into [`Step`]s, the commands in order, grouped where two may run at
//! once; [`execute`] runs them as child processes. Every command it runs is
//! resumable on its own (collect skips finished episodes, a stage resumes from
//! its checkpoint, a sweep skips finished runs), so running the plan again
//! after an interruption goes on where it stopped. Why these phases and
//! options: `docs/training.md`.

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use crate::progress::{JobRates, Left, Rates, Work};

/// A dataset of the study: `mrdrive collect --preset PRESET --out DIR --episodes N
/// --max-s S`, then `mrdrive label DIR`.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The collection preset (`original`, `retarget`).
    pub preset: String,
    /// The folder (relative to the working directory).
    pub dir: PathBuf,
    /// Episodes to collect.
    pub episodes: u32,
    /// Collected and labelled this many episodes at a time, so that the first
    /// slices can be trained on (and a learning curve drawn) while the rest is
    /// collected.
    pub slice: u32,
    /// Each episode's length cap (simulated seconds).
    pub max_s: f64,
}

/// The Original's training as a learning curve over its dataset's slices: after
/// slice k is labelled, round k trains the Original `steps` more steps on the first
/// k slices (`mrdrive train --stage original --episodes E_k --init` round k - 1's
/// network), then drives it on the curve's units (`mrdrive sweep`). The last round
/// publishes the Original. Why: the data takes hours that a job does not have, so
/// training starts on the first slices, and the curve says when more data stops
/// paying (issue 48).
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    /// Rounds: one per slice of the Original's dataset, up to its last.
    pub rounds: u32,
    /// Training steps (batches of 32) per round.
    pub steps: u32,
    /// Further `mrdrive train` options of every round (the recipe).
    pub options: Vec<String>,
    /// The units each round is driven on: scenarios, densities, seeds.
    pub scenarios: Vec<PathBuf>,
    /// Their densities (`mrdrive sweep --densities`).
    pub densities: String,
    /// Their seeds (`mrdrive sweep --seeds`).
    pub seeds: String,
}

/// DAgger rounds after the learning curve (issue 48; Ross, Gordon and Bagnell 2011):
/// in round r the Original so far drives the first `episodes` episodes of its data's
/// plan while the expert watches (`mrdrive collect --learner`, `dataset::dagger`),
/// the states it visited are labelled by the expert's world-on-rails values, and it
/// trains `steps` more steps on its data and every round's so far, then drives the
/// curve's units. The last round publishes the Original. Why: the Original of the
/// curve stood at green lights and stopped past its stop lines, states the expert's
/// data never holds (docs/training.md).
#[derive(Debug, Clone, PartialEq)]
pub struct DaggerRounds {
    /// Rounds (0: none; the curve's last round publishes the Original then).
    pub rounds: u32,
    /// Episodes each round drives: the first of the Original's plan (Town01's
    /// training routes at every density first, then random routes).
    pub episodes: u32,
    /// The Original's data each round trains on with the rounds' frames: its first
    /// this many episodes (the rounds' frames are then a third of the samples, not
    /// a twentieth).
    pub original_episodes: u32,
    /// Training steps (batches of 32) per round.
    pub steps: u32,
    /// Options added to the curve's recipe in these rounds.
    pub options: Vec<String>,
}

/// One retargeting stage: `mrdrive train --stage STAGE` on the retargeting set.
#[derive(Debug, Clone, PartialEq)]
pub struct Retarget {
    /// Its name (its log is `runs/NAME.log` when it runs in a lane).
    pub name: String,
    /// The stage (`nra-0.75`, `nra-1.0`, `ra`).
    pub stage: String,
    /// Further `mrdrive train` options.
    pub options: Vec<String>,
}

/// One set of units the closed-loop bar drives every driver on, with its table.
#[derive(Debug, Clone, PartialEq)]
pub struct BarSet {
    /// The folder of its sweeps, one per driver (relative to the base:
    /// `models/closed-loop`, committed with the models so that a job on a fresh machine
    /// goes on from the runs done, as the learning curve's records are).
    pub folder: String,
    /// Its table, `policy table` of those sweeps (relative to the base:
    /// `models/closed-loop.md`).
    pub table: String,
    /// The scenarios.
    pub scenarios: Vec<PathBuf>,
    /// The densities (`mrdrive sweep --densities`).
    pub densities: String,
    /// The seeds (`mrdrive sweep --seeds`).
    pub seeds: String,
}

/// One driver of the closed-loop bar: a sweep folder, a model (or the expert), a scale.
#[derive(Debug, Clone, PartialEq)]
pub struct BarDriver {
    /// The sweep folder's name under each set's folder (`models/closed-loop/`).
    pub label: String,
    /// The model under `models/` (`None`: the expert).
    pub model: Option<String>,
    /// The fixed input scale.
    pub scale: String,
}

/// The training pipeline's configuration; paths under `base` are the outputs,
/// the datasets and the run folders live in the cache (`dataset::cache`).
#[derive(Debug, Clone, PartialEq)]
pub struct TrainPlan {
    /// The folder whose `models/` (the bar's records in `models/closed-loop/` among
    /// them) the pipeline writes.
    pub base: PathBuf,
    /// The folder of the training runs' state (`mrdrive train --runs`):
    /// `<cache>/runs` for the study, `<base>/runs` for the quick plan.
    pub runs: PathBuf,
    /// The datasets (the Original's first, then the retargeting set).
    pub datasets: Vec<Dataset>,
    /// The Original's training: rounds after each slice of its data.
    pub curve: Curve,
    /// Then rounds in which the Original drives and the expert labels.
    pub dagger: DaggerRounds,
    /// The paper's three retargeted models, in the lanes they run in when two run at
    /// once: each lane a list run in order (each stage needs only the Original).
    pub lanes: Vec<Vec<Retarget>>,
    /// Run the lanes at once (one thread each) rather than one stage after another.
    pub parallel_lanes: bool,
    /// The drivers of the closed-loop bar.
    pub bar: Vec<BarDriver>,
    /// The units the bar drives each driver on: the paper's routes, then the
    /// held-out ones (issue 48's "what it must show").
    pub bar_sets: Vec<BarSet>,
    /// Trained after the bar, which does not need it: RA with five scales for the
    /// more-scales study.
    pub after_bar: Retarget,
    /// Every how many frames of the retargeting set RA's learned trigger is fit on
    /// (`mrdrive policy trigger --every`).
    pub trigger_every: u32,
    /// Options added to every training command (the quick plan's toy sizes).
    pub toy_options: Vec<String>,
    /// Options added to every retargeting command (the quick plan's).
    pub toy_retarget_options: Vec<String>,
}

/// Training steps (batches of 32) per round of the learning curve: sized on a
/// 2-core machine so that a round (a slice's collection and labels, its training,
/// its 12 closed-loop runs) fits well inside a 3-hour job (docs/training.md).
pub const CURVE_STEPS: u32 = 1000;

fn strings(s: &[&str]) -> Vec<String> {
    s.iter().map(|s| s.to_string()).collect()
}

impl TrainPlan {
    /// The study's pipeline into `base`, its datasets and run folders in `cache`
    /// (`<cache>/data/original`, `<cache>/data/retarget`, `<cache>/runs`): about
    /// 250k frames for the Original (the paper pre-trains on 270k), the
    /// retargeting set at TimeParam's 50k; the retargeting stages in two lanes
    /// when `parallel_lanes` (on 2 cores two single-threaded stages make
    /// 1.39-1.46x the samples/s of one stage on two threads, docs/training.md).
    pub fn full(base: &Path, cache: &Path, parallel_lanes: bool) -> Self {
        let retarget = |name: &str, stage: &str, options: &[&str]| Retarget {
            name: name.into(),
            stage: stage.into(),
            options: strings(options),
        };
        let bar = |label: &str, model: Option<&str>, scale: &str| BarDriver {
            label: label.into(),
            model: model.map(String::from),
            scale: scale.into(),
        };
        TrainPlan {
            base: base.to_path_buf(),
            runs: cache.join("runs"),
            datasets: vec![
                Dataset {
                    preset: "original".into(),
                    dir: cache.join("data/original"),
                    episodes: 760,
                    slice: 40,
                    max_s: 90.0,
                },
                Dataset {
                    preset: "retarget".into(),
                    dir: cache.join("data/retarget"),
                    episodes: 150,
                    slice: 50,
                    max_s: 90.0,
                },
            ],
            curve: Curve {
                rounds: 19,
                steps: CURVE_STEPS,
                // Commands drawn evenly, a quarter of the standing frames, frames with
                // a walker in the corridor ahead drawn 8 times an epoch (without it the
                // Original of 2026-12-05 hit a walker in 3 of the 6 Town01 runs of the
                // bar) and those behind a stopped vehicle 4 times (issue 33: 0.19 % of
                // the frames, and the shipped RA did not brake behind queues).
                options: strings(&[
                    "--standing-keep",
                    "0.25",
                    "--balanced",
                    "true",
                    "--pedestrian-repeat",
                    "8",
                    "--stopped-vehicle-repeat",
                    "4",
                ]),
                scenarios: ["town02_route0", "town02_route1"]
                    .iter()
                    .map(|r| PathBuf::from(format!("scenarios/paper/{r}.toml")))
                    .collect(),
                densities: "0:0,5:10,20:40".into(),
                seeds: "0,1".into(),
            },
            // One round, tried first as a pilot on 2026-12-07 (docs/training.md, "DAgger").
            dagger: DaggerRounds {
                rounds: 1,
                episodes: 40,
                original_episodes: 80,
                steps: 500,
                options: strings(&["--start-repeat", "8"]),
            },
            // RA (both scales per step) takes about as long as the two NRA stages together.
            lanes: vec![
                vec![retarget("ra", "ra", &[])],
                vec![
                    retarget("nra-1.0", "nra-1.0", &[]),
                    retarget("nra-0.75", "nra-0.75", &[]),
                ],
            ],
            parallel_lanes,
            bar: vec![
                bar("expert", None, "1.0"),
                bar("original@1.0", Some("original"), "1.0"),
                bar("nra-0.75@0.75", Some("nra-0.75"), "0.75"),
                bar("nra-1.0@1.0", Some("nra-1.0"), "1.0"),
                bar("ra@0.75", Some("ra"), "0.75"),
                bar("ra@1.0", Some("ra"), "1.0"),
            ],
            bar_sets: vec![
                // The paper's routes, three densities, seeds 0-2: 18 runs a town.
                BarSet {
                    folder: "models/closed-loop".into(),
                    table: "models/closed-loop.md".into(),
                    scenarios: [
                        "town01_route0",
                        "town01_route1",
                        "town02_route0",
                        "town02_route1",
                    ]
                    .iter()
                    .map(|r| PathBuf::from(format!("scenarios/paper/{r}.toml")))
                    .collect(),
                    densities: "0:0,5:10,20:40".into(),
                    seeds: "0,1,2".into(),
                },
                // Routes no dataset drove (held01, Town02's held-out routes) at 5 + 10.
                BarSet {
                    folder: "models/closed-loop-heldout".into(),
                    table: "models/closed-loop-heldout.md".into(),
                    scenarios: (0..4)
                        .map(|k| format!("held01_random{k}"))
                        .chain((0..8).map(|k| format!("town02_random{k}")))
                        .map(|r| PathBuf::from(format!("scenarios/heldout/{r}.toml")))
                        .collect(),
                    densities: "5:10".into(),
                    seeds: "0".into(),
                },
            ],
            after_bar: retarget(
                "ra5",
                "ra",
                &["--scales", "0.5,0.625,0.75,0.875,1.0", "--name", "ra5"],
            ),
            // About 10,800 of the set's 54,000 frames: as many as the trigger of
            // 2026-12-03 was fit on (every 2nd frame of the data of that day).
            trigger_every: 5,
            toy_options: Vec::new(),
            toy_retarget_options: Vec::new(),
        }
    }

    /// The same plumbing at toy size (minutes): datasets of 2 episodes of 20 s in
    /// `<cache>/data/*-quick`, run folders in `<base>/runs`, 4 steps a stage of
    /// batch 4, one route and one density for the bar.
    pub fn quick(base: &Path, cache: &Path, parallel_lanes: bool) -> Self {
        let mut plan = Self::full(base, cache, parallel_lanes);
        plan.runs = base.join("runs");
        for d in &mut plan.datasets {
            d.dir = PathBuf::from(format!("{}-quick", d.dir.display()));
            d.episodes = 2;
            d.slice = 1;
            d.max_s = 20.0;
        }
        for set in &mut plan.bar_sets {
            set.scenarios.truncate(1);
            set.densities = "0:0".into();
            set.seeds = "0".into();
        }
        plan.curve.rounds = 2;
        plan.curve.steps = 4;
        plan.dagger.episodes = 1;
        plan.dagger.original_episodes = 1;
        plan.dagger.steps = 4;
        plan.curve.scenarios.truncate(1);
        plan.curve.densities = "0:0".into();
        plan.curve.seeds = "0".into();
        plan.toy_options = strings(&["--batch", "4", "--recalibrate-batches", "2"]);
        plan.toy_retarget_options = strings(&["--steps", "4", "--unfreeze-every", "1"]);
        plan.trigger_every = 1;
        plan
    }

    /// A plan whose Original is trained in `rounds` rounds, on that many slices of
    /// its dataset (`mrdrive train --all --slices N`): where the learning curve says
    /// more data stops paying.
    pub fn with_rounds(mut self, rounds: u32) -> Self {
        let rounds = rounds.max(1);
        self.curve.rounds = rounds;
        if let Some(d) = self.datasets.first_mut() {
            d.episodes = rounds * d.slice.max(1);
        }
        self
    }

    /// Each slice of dataset `d`: its last episode, the command that collects it
    /// (`collect --episodes` counts the episodes in all, so each collect goes on
    /// from the slice before), and the one that labels it.
    fn slices(d: &Dataset) -> Vec<(u32, Step, Step)> {
        let dir = d.dir.display().to_string();
        let slice = d.slice.max(1);
        (1..=d.episodes.div_ceil(slice))
            .map(|k| ((k - 1) * slice, (k * slice).min(d.episodes)))
            .map(|(from, end)| {
                let collect = Step::new(
                    format!("collect {dir} (episodes to {end} of {})", d.episodes),
                    vec![
                        "collect".into(),
                        "--preset".into(),
                        d.preset.clone(),
                        "--out".into(),
                        dir.clone(),
                        "--episodes".into(),
                        end.to_string(),
                        "--max-s".into(),
                        d.max_s.to_string(),
                    ],
                )
                .doing(Work::Collect {
                    dir: d.dir.clone(),
                    from,
                    end,
                })
                .making_data();
                let label = Step::new(
                    format!("label {dir} (episodes to {end})"),
                    vec!["label".into(), dir.clone()],
                )
                .doing(Work::Label {
                    dir: d.dir.clone(),
                    from,
                    end,
                })
                .making_data();
                (end, collect, label)
            })
            .collect()
    }

    /// `data info` of dataset `d`: a summary, not a product, so it may fail.
    fn info(d: &Dataset) -> Step {
        let dir = d.dir.display().to_string();
        Step {
            may_fail: true,
            ..Step::new(
                format!("data info {dir}"),
                vec!["data".into(), "info".into(), dir],
            )
        }
    }

    /// The commands that make the datasets (`mrdrive data study`): each dataset
    /// collected and labelled a slice at a time, then summarised.
    pub fn data_steps(&self) -> Vec<Step> {
        let mut steps = Vec::new();
        for d in &self.datasets {
            for (_, collect, label) in Self::slices(d) {
                steps.extend([collect, label]);
            }
            steps.push(Self::info(d));
        }
        steps
    }

    /// The whole pipeline (`mrdrive train --all`): the Original's data a slice at a
    /// time, each slice followed by its round of the learning curve; the
    /// retargeting set; the retargeting stages, the bar and RA5. Rounds before
    /// `from_round` are left out: a committed snapshot of that round (a job whose
    /// cache was lost goes on from it) says they are done, and their records are
    /// committed; their slices are still made, as the later rounds train on them.
    pub fn steps(&self, from_round: u32) -> Vec<Group> {
        let mut groups = Vec::new();
        let mut datasets = self.datasets.iter();
        // A snapshot after every round of the Original (a retargeting stage's): its
        // data and rounds are not needed again; after the curve's (a DAgger round's),
        // only the slices the DAgger rounds train on.
        let original_done = from_round > self.curve.rounds + self.dagger.rounds;
        if let Some(original) = datasets.next().filter(|_| !original_done) {
            // After the curve, only the slices the DAgger rounds train on.
            let needed = if from_round > self.curve.rounds {
                self.dagger.original_episodes
            } else {
                original.episodes
            };
            for (k, (end, collect, label)) in (1..).zip(Self::slices(original)) {
                if (k - 1) * original.slice.max(1) >= needed {
                    break;
                }
                groups.extend([Group::One(collect), Group::One(label)]);
                if k <= self.curve.rounds && k >= from_round {
                    groups.extend(self.round_steps(k, end).into_iter().map(Group::One));
                }
            }
            groups.push(Group::One(Self::info(original)));
            // Every DAgger round, also those before the snapshot's: each trains on
            // the data of the rounds before it, driven by their networks.
            for r in 1..=self.dagger.rounds {
                groups.extend(self.dagger_steps(r).into_iter().map(Group::One));
            }
        }
        for d in datasets {
            for (_, collect, label) in Self::slices(d) {
                groups.extend([Group::One(collect), Group::One(label)]);
            }
            groups.push(Group::One(Self::info(d)));
        }
        groups.extend(self.train_steps());
        groups
    }

    /// The round (1-based) a snapshot's run folder (`ResumeState::run`, relative to
    /// the runs folder) belongs to: `curve/slice-05/original` is round 5; a
    /// retargeting stage of the plan's comes after every round. `None`: not a run
    /// of this plan's.
    pub fn round_of(&self, run: &Path) -> Option<u32> {
        let parts: Vec<String> = run
            .iter()
            .map(|p| p.to_string_lossy().into_owned())
            .collect();
        match parts.as_slice() {
            [curve, slice, _] if curve == "curve" => slice.strip_prefix("slice-")?.parse().ok(),
            [dagger, round, _] if dagger == "dagger" => {
                let r: u32 = round.strip_prefix("round-")?.parse().ok()?;
                (1..=self.dagger.rounds)
                    .contains(&r)
                    .then_some(self.curve.rounds + r)
            }
            [name] => {
                let mut later = self.lanes.iter().flatten().chain([&self.after_bar]);
                later
                    .any(|r| &r.name == name)
                    .then_some(self.curve.rounds + self.dagger.rounds + 1)
            }
            _ => None,
        }
    }

    /// Round `k`'s run folders (`--runs`) and published network.
    fn round_dir(&self, k: u32) -> String {
        format!("{}/curve/slice-{k:02}", self.runs())
    }

    /// The folder of round `k`'s closed-loop records.
    fn round_records(&self, k: u32) -> String {
        format!("{}/slice-{k:02}", self.curve_records())
    }

    /// The learning curve's table (`policy table` of the rounds' records).
    pub fn curve_table(&self) -> PathBuf {
        PathBuf::from(format!("{}.md", self.curve_records()))
    }

    fn curve_records(&self) -> String {
        format!("{}/original.curve", self.models())
    }

    /// Round `k` of the learning curve, on the first `episodes` episodes: train,
    /// drive the units, redraw the curve's table; the last round also publishes
    /// the Original into `models/` (the same command with `--out`: the finished
    /// run is published, not trained again).
    fn round_steps(&self, k: u32, episodes: u32) -> Vec<Step> {
        let dir = self.round_dir(k);
        let mut train = strings(&["train", "--stage", "original", "--data"]);
        train.push(self.original_data().display().to_string());
        train.extend(["--episodes".into(), episodes.to_string()]);
        train.extend(["--runs".into(), dir.clone(), "--out".into(), dir.clone()]);
        train.extend(["--steps".into(), self.curve.steps.to_string()]);
        if k > 1 {
            let before = self.round_dir(k - 1);
            train.extend(["--init".into(), format!("{before}/original.safetensors")]);
        }
        train.extend(self.curve.options.iter().cloned());
        train.extend(self.toy_options.iter().cloned());
        let mut steps = vec![
            Step::new(
                format!("original, round {k} (episodes 1-{episodes})"),
                train.clone(),
            )
            .doing(Work::Train {
                run: PathBuf::from(format!("{dir}/original")),
                steps: u64::from(self.curve.steps),
                samples_per_step: batch_of(&train),
            }),
        ];
        steps.push(self.curve_drive(&format!("round {k}"), &dir, &self.round_records(k)));
        steps.push(self.curve_table_step());
        if k == self.curve.rounds {
            steps.push(self.publish(train));
        }
        steps
    }

    /// The Original's training command `train` with `--out` the models folder: the
    /// finished run published, not trained again.
    fn publish(&self, mut train: Vec<String>) -> Step {
        let at = train.iter().position(|a| a == "--out").expect("--out") + 1;
        train[at] = self.models();
        Step::new("publish the Original", train)
    }

    /// The Original's dataset folder.
    fn original_data(&self) -> PathBuf {
        self.datasets
            .first()
            .map(|d| d.dir.clone())
            .unwrap_or_default()
    }

    /// Episodes of the Original's dataset.
    fn curve_episodes(&self) -> u32 {
        self.datasets.first().map_or(0, |d| d.episodes)
    }

    /// Round `r`'s folder of DAgger frames (`<cache>/data/original-dagger-01`).
    fn dagger_data(&self, r: u32) -> String {
        let original = self.original_data();
        let name = original
            .file_name()
            .map_or_else(|| "original".into(), |n| n.to_string_lossy().into_owned());
        original
            .with_file_name(format!("{name}-dagger-{r:02}"))
            .display()
            .to_string()
    }

    /// Round `r`'s run folders (`--runs`, `--out`) and trained network.
    fn dagger_dir(&self, r: u32) -> String {
        format!("{}/dagger/round-{r:02}", self.runs())
    }

    /// DAgger round `r`: the network so far drives and the expert labels, train
    /// on the Original's data and every round's frames, drive the curve's units;
    /// the last round publishes the Original. Round 1's learner is the curve's
    /// published Original (`models/original`), which only the last round replaces,
    /// so a cache lost before then makes every round's frames again, the same bytes.
    fn dagger_steps(&self, r: u32) -> Vec<Step> {
        let d = &self.dagger;
        let learner = if r == 1 {
            format!("{}/original.safetensors", self.models())
        } else {
            format!("{}/original.safetensors", self.dagger_dir(r - 1))
        };
        let data = self.dagger_data(r);
        let max_s = self.datasets.first().map_or(90.0, |o| o.max_s);
        let collect = Step::new(
            format!("DAgger round {r}: the Original drives, the expert watches"),
            vec![
                "collect".into(),
                "--preset".into(),
                "original".into(),
                "--learner".into(),
                learner.clone(),
                "--out".into(),
                data.clone(),
                "--episodes".into(),
                d.episodes.to_string(),
                "--max-s".into(),
                max_s.to_string(),
            ],
        )
        .doing(Work::Collect {
            dir: PathBuf::from(&data),
            from: 0,
            end: d.episodes,
        });
        let label = Step::new(format!("label {data}"), vec!["label".into(), data.clone()]).doing(
            Work::Label {
                dir: PathBuf::from(&data),
                from: 0,
                end: d.episodes,
            },
        );
        let dir = self.dagger_dir(r);
        let mut train = strings(&["train", "--stage", "original", "--data"]);
        train.push(self.original_data().display().to_string());
        let first = d.original_episodes.min(self.curve_episodes());
        train.extend(["--episodes".into(), first.to_string()]);
        for j in 1..=r {
            train.extend(["--also".into(), self.dagger_data(j)]);
        }
        train.extend(["--runs".into(), dir.clone(), "--out".into(), dir.clone()]);
        train.extend([
            "--steps".into(),
            d.steps.to_string(),
            "--init".into(),
            learner,
        ]);
        train.extend(self.curve.options.iter().cloned());
        train.extend(d.options.iter().cloned());
        train.extend(self.toy_options.iter().cloned());
        let records = format!("{}/dagger-{r:02}", self.curve_records());
        let mut steps = vec![
            collect,
            label,
            Step::new(format!("the Original, DAgger round {r}"), train.clone()).doing(
                Work::Train {
                    run: PathBuf::from(format!("{dir}/original")),
                    steps: u64::from(d.steps),
                    samples_per_step: batch_of(&train),
                },
            ),
        ];
        // Published as soon as trained: a job that ends after this has the Original
        // it needs for what follows (see `TrainPlan::dagger_published`).
        if r == d.rounds {
            steps.push(self.publish(train));
        }
        steps.push(self.curve_drive(&format!("DAgger round {r}"), &dir, &records));
        steps.push(self.curve_table_step());
        steps
    }

    /// Whether the published Original (its card's `training.data`, `published_data`)
    /// was trained by the last DAgger round: a snapshot of that round then means the
    /// Original is done, and a fresh machine must not collect the round's frames
    /// again (its learner, the curve's Original, was replaced by the publication).
    pub fn dagger_published(&self, published_data: &str) -> bool {
        let last = self.dagger_data(self.dagger.rounds);
        let name = Path::new(&last)
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        self.dagger.rounds > 0
            && published_data.split(" + ").any(|d| {
                Path::new(d.trim())
                    .file_name()
                    .is_some_and(|n| n.to_string_lossy() == name)
            })
    }

    /// Drives the network in `dir` on the curve's units into `records`.
    fn curve_drive(&self, what: &str, dir: &str, records: &str) -> Step {
        let mut sweep = vec!["sweep".to_string()];
        sweep.extend(self.curve.scenarios.iter().map(|p| p.display().to_string()));
        sweep.extend(strings(&[
            "--delays",
            "0",
            "--scales",
            "1.0",
            "--densities",
        ]));
        sweep.extend([self.curve.densities.clone(), "--seeds".into()]);
        sweep.extend([self.curve.seeds.clone(), "--out".into(), records.into()]);
        sweep.extend(["--checkpoint".into(), format!("{dir}/original.safetensors")]);
        let runs = self.curve.scenarios.len()
            * list_len(&self.curve.densities)
            * list_len(&self.curve.seeds);
        Step::new(format!("drive {what}"), sweep).doing(Work::Drive {
            out: PathBuf::from(records),
            runs: runs as u32,
        })
    }

    /// Redraws the learning curve's table (a summary: it may fail).
    fn curve_table_step(&self) -> Step {
        Step {
            may_fail: true,
            ..Step::new(
                "the learning curve's table",
                vec![
                    "policy".into(),
                    "table".into(),
                    self.curve_records(),
                    "--out".into(),
                    format!("{}.md", self.curve_records()),
                ],
            )
        }
    }

    fn models(&self) -> String {
        self.base.join("models").display().to_string()
    }

    fn runs(&self) -> String {
        self.runs.display().to_string()
    }

    /// Fits RA's learned trigger (`models/ra.trigger.json`, which the `learned`
    /// selector reads) on the retargeting set, by regret, the top 10 % positive, as
    /// the trigger of 2026-12-03 was; the retargeting set rather than the Original's
    /// data because a fresh machine makes it again after the Original is done, where
    /// the Original's (8 hours of collection) it does not. A trigger of the same RA,
    /// data and target is left as it is (`policy trigger` says so).
    fn trigger_step(&self) -> Step {
        let data = self
            .datasets
            .get(1)
            .map(|d| d.dir.display().to_string())
            .unwrap_or_default();
        let models = self.models();
        let mut args = strings(&["policy", "trigger", "--checkpoint"]);
        args.extend([format!("{models}/ra.safetensors"), "--data".into(), data]);
        args.extend(["--every".into(), self.trigger_every.to_string()]);
        args.extend(strings(&["--target", "regret", "--share", "0.1", "--out"]));
        args.push(format!("{models}/ra.trigger.json"));
        Step::new("fit RA's learned trigger", args)
    }

    fn retarget_step(&self, r: &Retarget) -> Step {
        let data = self
            .datasets
            .get(1)
            .map(|d| d.dir.display().to_string())
            .unwrap_or_default();
        let mut args = strings(&["train", "--stage"]);
        args.extend([r.stage.clone(), "--data".into(), data]);
        args.extend(["--runs".into(), self.runs(), "--out".into(), self.models()]);
        args.extend(r.options.iter().cloned());
        args.extend(self.toy_options.iter().cloned());
        args.extend(self.toy_retarget_options.iter().cloned());
        // A step trains the batch at each of the stage's scales (RA: 0.75 and 1.0).
        let scales =
            flag_value(&args, "--scales").map_or(if r.stage == "ra" { 2 } else { 1 }, list_len);
        let steps = flag_value(&args, "--steps")
            .and_then(|s| s.parse().ok())
            .unwrap_or(RETARGET_STEPS);
        let work = Work::Train {
            run: self.runs.join(&r.name),
            steps,
            samples_per_step: batch_of(&args) * scales as u64,
        };
        Step::new(format!("train {}", r.name), args).doing(work)
    }

    /// The commands that train and judge the models after the Original: the
    /// retargeting lanes, the bar and its table, RA5.
    pub fn train_steps(&self) -> Vec<Group> {
        let mut groups = Vec::new();
        let (models, runs) = (self.models(), self.runs());
        if self.parallel_lanes {
            groups.push(Group::Lanes(
                self.lanes
                    .iter()
                    .map(|lane| {
                        lane.iter()
                            .map(|r| Step {
                                log: Some(PathBuf::from(format!("{runs}/{}.log", r.name))),
                                one_thread: true,
                                ..self.retarget_step(r)
                            })
                            .collect()
                    })
                    .collect(),
            ));
        } else {
            // One after another: NRA 0.75, NRA 1.0, RA (the order of the paper's table).
            let mut all: Vec<&Retarget> = self.lanes.iter().flatten().collect();
            all.sort_by_key(|r| match r.stage.as_str() {
                "nra-0.75" => 0,
                "nra-1.0" => 1,
                _ => 2,
            });
            groups.extend(all.into_iter().map(|r| Group::One(self.retarget_step(r))));
        }
        groups.push(Group::One(self.trigger_step()));
        for set in &self.bar_sets {
            let sweeps = self.base.join(&set.folder).display().to_string();
            for b in &self.bar {
                let mut args = vec!["sweep".to_string()];
                args.extend(set.scenarios.iter().map(|p| p.display().to_string()));
                args.extend(strings(&["--delays", "0", "--scales"]));
                args.extend([b.scale.clone(), "--densities".into(), set.densities.clone()]);
                args.extend(["--seeds".into(), set.seeds.clone(), "--out".into()]);
                args.push(format!("{sweeps}/{}", b.label));
                match &b.model {
                    Some(m) => {
                        args.extend(["--checkpoint".into(), format!("{models}/{m}.safetensors")])
                    }
                    None => args.push("--expert".into()),
                }
                let runs = set.scenarios.len() * list_len(&set.densities) * list_len(&set.seeds);
                let work = Work::Drive {
                    out: PathBuf::from(format!("{sweeps}/{}", b.label)),
                    runs: runs as u32,
                };
                groups.push(Group::One(
                    Step::new(format!("bar {} ({})", b.label, set.folder), args).doing(work),
                ));
            }
            groups.push(Group::One(Step::new(
                format!("closed-loop table of {}", set.folder),
                vec![
                    "policy".into(),
                    "table".into(),
                    sweeps,
                    "--out".into(),
                    self.base.join(&set.table).display().to_string(),
                ],
            )));
        }
        groups.push(Group::One(self.retarget_step(&self.after_bar)));
        groups
    }
}

/// What is left of `groups` (the current step's group first), read under `dir`,
/// at `rates` ([`crate::progress`]): lanes that run at once count by the longest.
pub fn left(groups: &[Group], dir: &Path, rates: &JobRates) -> Left {
    let mut out = Left::default();
    for g in groups {
        out.secs += match g {
            Group::One(s) => out.add(&s.work, dir, rates),
            Group::Lanes(lanes) => lanes
                .iter()
                .map(|lane| {
                    lane.iter()
                        .map(|s| out.add(&s.work, dir, rates))
                        .sum::<f64>()
                })
                .fold(0.0, f64::max),
        };
    }
    out
}

/// Steps of a retargeting stage (`policy::train::StageSpec`'s default for the
/// retargeting stages).
pub const RETARGET_STEPS: u64 = 600;

/// The batch a training command asks for (`--batch`; 32 without).
fn batch_of(args: &[String]) -> u64 {
    flag_value(args, "--batch")
        .and_then(|b| b.parse().ok())
        .unwrap_or(32)
}

/// The value after `flag` in `args`, if any.
fn flag_value<'a>(args: &'a [String], flag: &str) -> Option<&'a str> {
    let at = args.iter().position(|a| a == flag)?;
    args.get(at + 1).map(String::as_str)
}

/// Items of a comma-separated list ("0:0,5:10,20:40": 3).
fn list_len(list: &str) -> usize {
    list.split(',').filter(|s| !s.trim().is_empty()).count()
}

/// One command of the plan: arguments to this binary.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// What it does, for progress lines.
    pub name: String,
    /// The arguments (the binary's subcommand first).
    pub args: Vec<String>,
    /// Where its output goes (appended) when it runs beside another; `None`: the terminal.
    pub log: Option<PathBuf>,
    /// Run it on one thread (`RAYON_NUM_THREADS=1`).
    pub one_thread: bool,
    /// A failure is reported and the plan goes on (a summary, not a product).
    pub may_fail: bool,
    /// What it does, for how long the rest of the plan will take.
    pub work: Work,
    /// The binary that runs it; `None`: the plan's own (see [`data_by`]).
    pub exe: Option<PathBuf>,
    /// It makes one of the study's datasets (their `collect` and `label`): the
    /// data's own build runs it ([`data_by`]). A DAgger round's frames depend on
    /// its learner and are made by the plan's build.
    pub makes_data: bool,
}

impl Step {
    fn new(name: impl Into<String>, args: Vec<String>) -> Self {
        Step {
            name: name.into(),
            args,
            log: None,
            one_thread: false,
            may_fail: false,
            work: Work::Small,
            exe: None,
            makes_data: false,
        }
    }

    fn doing(self, work: Work) -> Self {
        Step { work, ..self }
    }

    fn making_data(self) -> Self {
        Step {
            makes_data: true,
            ..self
        }
    }
}

/// Steps that run alone, or lanes that run at once (each lane's steps in order).
#[derive(Debug, Clone, PartialEq)]
pub enum Group {
    /// One step.
    One(Step),
    /// Lanes side by side.
    Lanes(Vec<Vec<Step>>),
}

/// A step that failed.
#[derive(Debug, thiserror::Error)]
#[error("{step}: `{command}` {what}")]
pub struct StepError {
    /// The step's name.
    pub step: String,
    /// The command line.
    pub command: String,
    /// What went wrong (its exit status and where its output is, or why it did not start).
    pub what: String,
    /// It stopped at the job's time limit (exit status [`STOPPED_AT_TIME_LIMIT`]) or
    /// was not started because the limit had passed: not a failure, the plan goes on
    /// when run again.
    pub time_limit: bool,
}

impl StepError {
    /// Whether the plan stopped at its time limit rather than failed.
    pub fn stopped_at_time_limit(&self) -> bool {
        self.time_limit
    }
}

/// The exit status of a step stopped at the job's time limit (`mrdrive train
/// --hours`; BSD's `EX_TEMPFAIL`).
pub const STOPPED_AT_TIME_LIMIT: i32 = 75;

/// Every step of `groups`, lanes included.
fn every_step(groups: &mut [Group]) -> impl Iterator<Item = &mut Step> {
    groups.iter_mut().flat_map(|g| match g {
        Group::One(s) => std::slice::from_mut(s).iter_mut().collect::<Vec<_>>(),
        Group::Lanes(lanes) => lanes.iter_mut().flatten().collect(),
    })
}

/// Adds `extra` arguments to every training step of `groups` (`mrdrive train`), lanes
/// included: the job's time limit (`--until-unix S`), a snapshot to go on from
/// (`--resume-state FILE`).
pub fn add_to_training(groups: &mut [Group], extra: &[String]) {
    for step in every_step(groups) {
        if step.args.first().map(String::as_str) == Some("train") {
            step.args.extend(extra.iter().cloned());
        }
    }
}

/// Makes `exe` run every step of `groups` that writes the study's datasets
/// ([`Step::makes_data`]: their `collect` and `label`): the data's own build
/// (`crate::collector`), so that they stay the bytes their hashes list when the
/// simulator changes after them.
pub fn data_by(groups: &mut [Group], exe: &Path) {
    for step in every_step(groups) {
        if step.makes_data {
            step.exe = Some(exe.to_path_buf());
        }
    }
}

/// The command lines of `groups`, one a line, each with the binary that runs it
/// (its own, or `exe`); a step in a lane is prefixed `lane N: ` (`mrdrive train --all
/// --print-plan`).
pub fn commands(groups: &[Group], exe: &Path) -> String {
    let line = |s: &Step| {
        let bin = s.exe.as_deref().unwrap_or(exe).display().to_string();
        format!("{bin} {}\n", s.args.join(" "))
    };
    let mut out = String::new();
    for g in groups {
        match g {
            Group::One(s) => out.push_str(&line(s)),
            Group::Lanes(lanes) => {
                for (i, lane) in lanes.iter().enumerate() {
                    for s in lane {
                        out.push_str(&format!("lane {}: {}", i + 1, line(s)));
                    }
                }
            }
        }
    }
    out
}

/// Runs one step with its own binary, or `exe`, in `dir`.
fn run_step(exe: &Path, dir: &Path, step: &Step) -> Result<(), StepError> {
    let exe = step.exe.as_deref().unwrap_or(exe);
    let fail = |what: String| StepError {
        step: step.name.clone(),
        command: format!("{} {}", exe.display(), step.args.join(" ")),
        what,
        time_limit: false,
    };
    let mut cmd = Command::new(exe);
    cmd.args(&step.args).current_dir(dir);
    if step.one_thread {
        cmd.env("RAYON_NUM_THREADS", "1");
    }
    if let Some(log) = &step.log {
        let path = dir.join(log);
        let open = || -> std::io::Result<(File, File)> {
            if let Some(parent) = path.parent() {
                std::fs::create_dir_all(parent)?;
            }
            let f = OpenOptions::new().create(true).append(true).open(&path)?;
            let g = f.try_clone()?;
            Ok((f, g))
        };
        let (out, err) =
            open().map_err(|e| fail(format!("cannot open its log {}: {e}", path.display())))?;
        cmd.stdout(out).stderr(err);
    }
    match cmd.status() {
        Ok(s) if s.success() => Ok(()),
        Ok(s) if s.code() == Some(STOPPED_AT_TIME_LIMIT) => Err(StepError {
            time_limit: true,
            ..fail("stopped at the time limit".into())
        }),
        Ok(s) => Err(fail(match &step.log {
            Some(log) => format!("failed ({s}); its output is in {}", log.display()),
            None => format!("failed ({s})"),
        })),
        Err(e) => Err(fail(format!("could not start: {e}"))),
    }
}

/// Runs `groups` in order with the binary `exe` in `dir`; `note` hears each step's
/// start and end. Stops at the first failed step (the lanes of a group finish
/// first), except for steps marked `may_fail`, which are noted and passed.
pub fn execute(
    exe: &Path,
    dir: &Path,
    groups: &[Group],
    note: &(dyn Fn(&str) + Sync),
) -> Result<(), StepError> {
    execute_until(exe, dir, groups, None, note)
}

/// [`execute`] within a time limit: no step starts once `stop_at` has passed (the
/// error then says so, [`StepError::stopped_at_time_limit`]), and a step that stops
/// at the limit ends the plan the same way. Before each group `note` also hears
/// how far the plan is and how long the rest will take ([`progress`]; each kind
/// of work at this job's rate once a step of that kind has done some).
pub fn execute_until(
    exe: &Path,
    dir: &Path,
    groups: &[Group],
    stop_at: Option<std::time::SystemTime>,
    note: &(dyn Fn(&str) + Sync),
) -> Result<(), StepError> {
    let rates = Mutex::new(JobRates::new(Rates::default()));
    let rates_now = || rates.lock().unwrap_or_else(|e| e.into_inner()).clone();
    let one = |step: &Step| -> Result<(), StepError> {
        if stop_at.is_some_and(|t| std::time::SystemTime::now() >= t) {
            return Err(StepError {
                step: step.name.clone(),
                command: format!(
                    "{} {}",
                    step.exe.as_deref().unwrap_or(exe).display(),
                    step.args.join(" ")
                ),
                what: "not started: the time limit has passed".into(),
                time_limit: true,
            });
        }
        note(&match &step.log {
            Some(log) => format!("{} (log {})", step.name, log.display()),
            None => step.name.clone(),
        });
        let (kind, before) = step.work.left(dir);
        let started = std::time::Instant::now();
        let ran = run_step(exe, dir, step);
        // What it did counts toward this job's rate, a step stopped at the limit too.
        let (_, after) = step.work.left(dir);
        rates.lock().unwrap_or_else(|e| e.into_inner()).observe(
            kind,
            before - after,
            started.elapsed().as_secs_f64(),
        );
        match ran {
            Err(e) if step.may_fail && !e.time_limit => {
                note(&format!("{e} (going on)"));
                Ok(())
            }
            Err(e) => Err(e),
            Ok(()) => {
                note(&format!("{} done", step.name));
                Ok(())
            }
        }
    };
    for (i, g) in groups.iter().enumerate() {
        let rates = rates_now();
        let rest = left(&groups[i..], dir, &rates);
        note(&format!(
            "step {} of {}: {}",
            i + 1,
            groups.len(),
            rest.line(&rates)
        ));
        match g {
            Group::One(step) => one(step)?,
            Group::Lanes(lanes) => {
                let results: Vec<Result<(), StepError>> = std::thread::scope(|scope| {
                    let handles: Vec<_> = lanes
                        .iter()
                        .map(|lane| scope.spawn(|| lane.iter().try_for_each(one)))
                        .collect();
                    handles
                        .into_iter()
                        .map(|h| {
                            h.join().unwrap_or_else(|_| {
                                Err(StepError {
                                    step: "a training lane".into(),
                                    command: String::new(),
                                    what: "panicked".into(),
                                    time_limit: false,
                                })
                            })
                        })
                        .collect()
                });
                results.into_iter().collect::<Result<Vec<()>, _>>()?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn joined(g: &Group) -> Vec<String> {
        match g {
            Group::One(s) => vec![s.args.join(" ")],
            Group::Lanes(l) => l.iter().flatten().map(|s| s.args.join(" ")).collect(),
        }
    }

    #[test]
    fn the_data_comes_a_slice_at_a_time_and_the_retargeting_set_last() {
        let plan = TrainPlan::full(Path::new("out/scratch"), Path::new("/c"), true);
        let data: Vec<String> = plan.data_steps().iter().map(|s| s.args.join(" ")).collect();
        // Slices of 40 episodes, each collected then labelled: 19 slices, then `data info`.
        assert_eq!(
            data[0],
            "collect --preset original --out /c/data/original --episodes 40 --max-s 90"
        );
        assert_eq!(data[1], "label /c/data/original");
        assert_eq!(
            data[36],
            "collect --preset original --out /c/data/original --episodes 760 --max-s 90"
        );
        assert_eq!(data[38], "data info /c/data/original");
        // The retargeting set's last slice is the remainder: 50, 100, 150.
        assert_eq!(
            data[43],
            "collect --preset retarget --out /c/data/retarget --episodes 150 --max-s 90"
        );
    }

    #[test]
    fn each_slice_is_followed_by_its_round_of_the_learning_curve() {
        let plan = TrainPlan::full(Path::new("out/scratch"), Path::new("/c"), true);
        let groups = plan.steps(1);
        let all: Vec<String> = groups.iter().flat_map(joined).collect();
        assert!(all[0].ends_with("--episodes 40 --max-s 90"));
        assert_eq!(all[1], "label /c/data/original");
        assert_eq!(
            all[2],
            format!(
                "train --stage original --data /c/data/original --episodes 40 \
                 --runs /c/runs/curve/slice-01 --out /c/runs/curve/slice-01 --steps {CURVE_STEPS} \
                 --standing-keep 0.25 --balanced true --pedestrian-repeat 8 \
                 --stopped-vehicle-repeat 4"
            )
        );
        assert_eq!(
            all[3],
            "sweep scenarios/paper/town02_route0.toml scenarios/paper/town02_route1.toml \
             --delays 0 --scales 1.0 --densities 0:0,5:10,20:40 --seeds 0,1 \
             --out out/scratch/models/original.curve/slice-01 \
             --checkpoint /c/runs/curve/slice-01/original.safetensors"
        );
        assert_eq!(
            all[4],
            "policy table out/scratch/models/original.curve \
             --out out/scratch/models/original.curve.md"
        );
        // Round 2 trains on the first two slices, from round 1's network.
        assert!(all[5].ends_with("--episodes 80 --max-s 90"));
        assert!(
            all[7].contains(
                "--episodes 80 --runs /c/runs/curve/slice-02 --out /c/runs/curve/slice-02 \
             --steps 1000 --init /c/runs/curve/slice-01/original.safetensors"
                    .replace("1000", &CURVE_STEPS.to_string())
                    .as_str()
            )
        );
        // 19 rounds of collect, label, train, drive, table; round 19 publishes the
        // Original; `data info`; the DAgger round (collect, label, train, drive, table,
        // publish); the retargeting set; then the lanes, RA's trigger, the bar on the
        // paper's routes and on the held-out ones (six drivers and a table each), RA5.
        let publish = 19 * 5;
        assert!(all[publish].contains("--runs /c/runs/curve/slice-19 --out out/scratch/models"));
        assert_eq!(all[publish + 1], "data info /c/data/original");
        assert_eq!(
            groups.len(),
            publish + 1 + 1 + 6 + 7 + 1 + 1 + 2 * (6 + 1) + 1
        );
        let trigger = joined(&groups[publish + 16])[0].clone();
        assert_eq!(
            trigger,
            "policy trigger --checkpoint out/scratch/models/ra.safetensors --data \
             /c/data/retarget --every 5 --target regret --share 0.1 --out \
             out/scratch/models/ra.trigger.json"
        );
        // The bar: 18 runs a town and driver (seeds 0-2), then 12 held-out routes at 5 + 10.
        let bar = joined(&groups[publish + 17])[0].clone();
        assert!(
            bar.starts_with("sweep scenarios/paper/town01_route0.toml")
                && bar.contains("--densities 0:0,5:10,20:40 --seeds 0,1,2 --out out/scratch/models/closed-loop/expert --expert"),
            "{bar}"
        );
        let heldout = joined(&groups[publish + 24])[0].clone();
        assert!(
            heldout.starts_with("sweep scenarios/heldout/held01_random0.toml")
                && heldout.contains("town02_random7.toml --delays 0 --scales 1.0 --densities 5:10 --seeds 0 --out out/scratch/models/closed-loop-heldout/expert"),
            "{heldout}"
        );
        assert_eq!(
            joined(&groups[publish + 30])[0],
            "policy table out/scratch/models/closed-loop-heldout --out out/scratch/models/closed-loop-heldout.md"
        );
        let Group::Lanes(lanes) = &groups[publish + 15] else {
            panic!("the retargeting stages run in lanes")
        };
        assert_eq!(lanes.len(), 2);
        assert!(
            lanes
                .iter()
                .flatten()
                .all(|s| s.one_thread && s.log.is_some())
        );
        assert_eq!(
            lanes[0][0].args.join(" "),
            "train --stage ra --data /c/data/retarget --runs /c/runs --out out/scratch/models"
        );
        assert!(all.last().unwrap().contains("--name ra5"));
    }

    #[test]
    fn fewer_slices_shorten_the_data_and_a_snapshot_skips_the_rounds_before_it() {
        let plan = TrainPlan::full(Path::new("b"), Path::new("/c"), false).with_rounds(3);
        assert_eq!(plan.datasets[0].episodes, 120);
        let all: Vec<String> = plan.steps(1).iter().flat_map(joined).collect();
        assert!(all[15].contains("--runs /c/runs/curve/slice-03 --out b/models"));
        assert_eq!(all[16], "data info /c/data/original");
        // A snapshot of round 3: slices 1-3 made again, rounds 1-2 not trained or driven.
        assert_eq!(plan.round_of(Path::new("curve/slice-03/original")), Some(3));
        let from3: Vec<String> = plan.steps(3).iter().flat_map(joined).collect();
        let rounds: Vec<&String> = from3
            .iter()
            .filter(|a| a.contains("/curve/slice-") || a.contains("original.curve/slice-"))
            .collect();
        assert_eq!(rounds.len(), 3, "{rounds:?}");
        assert!(rounds.iter().all(|a| a.contains("slice-03")));
        assert_eq!(
            from3
                .iter()
                .filter(|a| a.starts_with("collect --preset original --out"))
                .count(),
            3
        );
        // A retargeting stage comes after every round, the DAgger round's too; a
        // folder of another plan is none.
        assert_eq!(
            plan.round_of(Path::new("dagger/round-01/original")),
            Some(4)
        );
        assert_eq!(plan.round_of(Path::new("dagger/round-02/original")), None);
        assert_eq!(plan.round_of(Path::new("ra")), Some(5));
        assert_eq!(plan.round_of(Path::new("wor/original")), None);
        assert_eq!(plan.round_of(Path::new("curve/slice-x/original")), None);
    }

    #[test]
    fn a_dagger_round_follows_the_curve_drives_its_network_and_publishes_the_original() {
        let plan = TrainPlan::full(Path::new("b"), Path::new("/c"), false).with_rounds(2);
        let all: Vec<String> = plan.steps(1).iter().flat_map(joined).collect();
        let info = all
            .iter()
            .position(|a| a == "data info /c/data/original")
            .unwrap();
        let round = &all[info + 1..info + 7];
        assert_eq!(
            round[0],
            "collect --preset original --learner b/models/original.safetensors \
             --out /c/data/original-dagger-01 --episodes 40 --max-s 90"
        );
        assert_eq!(round[1], "label /c/data/original-dagger-01");
        assert_eq!(
            round[2],
            "train --stage original --data /c/data/original --episodes 80 \
             --also /c/data/original-dagger-01 \
             --runs /c/runs/dagger/round-01 --out /c/runs/dagger/round-01 --steps 500 \
             --init b/models/original.safetensors --standing-keep 0.25 --balanced true \
             --pedestrian-repeat 8 --stopped-vehicle-repeat 4 --start-repeat 8"
        );
        assert!(round[4].starts_with("sweep scenarios/paper/town02_route0.toml"));
        assert!(round[4].ends_with(
            "--out b/models/original.curve/dagger-01 \
             --checkpoint /c/runs/dagger/round-01/original.safetensors"
        ));
        assert!(round[5].starts_with("policy table b/models/original.curve "));
        // The last round publishes as soon as it is trained: its training command into
        // models/. Its card's data then says so.
        assert_eq!(
            round[3],
            round[2].replace("--out /c/runs/dagger/round-01", "--out b/models")
        );
        assert!(plan.dagger_published("/x/data/original + /y/original-dagger-01"));
        assert!(!plan.dagger_published("/c/data/original"));
        assert!(!plan.dagger_published("/c/data/original + /c/data/original-dagger-010"));
        // The curve's last round publishes too: round 1's learner.
        let publishes = all
            .iter()
            .filter(|a| a.starts_with("train ") && a.contains("--out b/models"))
            .count();
        assert_eq!(publishes, 2 + 4, "the curve, DAgger, NRA x 2, RA, RA5");
        // A second round learns from the first's network, on both rounds' frames.
        let two = DaggerRounds {
            rounds: 2,
            ..plan.dagger.clone()
        };
        let plan2 = TrainPlan {
            dagger: two,
            ..plan.clone()
        };
        let all2: Vec<String> = plan2.steps(1).iter().flat_map(joined).collect();
        let second = all2
            .iter()
            .find(|a| a.contains("--out /c/data/original-dagger-02"))
            .unwrap();
        assert!(second.contains("--learner /c/runs/dagger/round-01/original.safetensors"));
        assert!(all2.iter().any(|a| {
            a.contains("--also /c/data/original-dagger-01 --also /c/data/original-dagger-02")
        }));
        // A snapshot of the DAgger round: the curve's rounds skipped, the data and the
        // round made again. One of a retargeting stage: neither.
        let from3: Vec<String> = plan.steps(3).iter().flat_map(joined).collect();
        assert!(!from3.iter().any(|a| a.contains("/curve/slice-")));
        assert!(
            from3
                .iter()
                .any(|a| a.starts_with("collect --preset original --out"))
        );
        assert!(from3.iter().any(|a| a.contains("--learner")));
        // The study's plan at its DAgger round: the slices that round trains on only.
        let full = TrainPlan::full(Path::new("b"), Path::new("/c"), false);
        let at_dagger: Vec<String> = full.steps(20).iter().flat_map(joined).collect();
        let collects: Vec<&String> = at_dagger
            .iter()
            .filter(|a| a.starts_with("collect --preset original --out"))
            .collect();
        assert_eq!(collects.len(), 2, "{collects:?}");
        assert!(collects[1].ends_with("--episodes 80 --max-s 90"));
        let from4: Vec<String> = plan.steps(4).iter().flat_map(joined).collect();
        assert!(!from4.iter().any(|a| a.contains("--preset original")));
        assert!(from4[0].starts_with("collect --preset retarget"));
    }

    #[test]
    fn one_lane_runs_the_stages_in_the_tables_order_and_quick_is_toy_sized() {
        let plan = TrainPlan::quick(Path::new("out/train-quick"), Path::new("c"), false);
        let groups = plan.train_steps();
        let stages: Vec<String> = groups[..3].iter().map(|g| joined(g)[0].clone()).collect();
        assert!(stages[0].starts_with(
            "train --stage nra-0.75 --data c/data/retarget-quick --runs out/train-quick/runs"
        ));
        assert!(stages[1].starts_with("train --stage nra-1.0"));
        assert!(stages[2].starts_with("train --stage ra "));
        assert!(
            stages[2].ends_with("--batch 4 --recalibrate-batches 2 --steps 4 --unfreeze-every 1")
        );
        assert!(joined(&groups[3])[0].ends_with(
            "--every 1 --target regret --share 0.1 --out out/train-quick/models/ra.trigger.json"
        ));
        let bar = joined(&groups[4])[0].clone();
        assert!(bar.starts_with("sweep scenarios/paper/town01_route0.toml --delays 0"));
        assert!(bar.contains("--densities 0:0 "));
        let all: Vec<String> = plan.steps(1).iter().flat_map(joined).collect();
        // Two rounds of one episode each, 4 steps of 4, one route, one density, one seed.
        assert!(all[2].contains("--episodes 1 --runs out/train-quick/runs/curve/slice-01"));
        assert!(
            all[2].contains("--steps 4 ") && all[2].ends_with("--batch 4 --recalibrate-batches 2")
        );
        assert!(all[3].starts_with("sweep scenarios/paper/town02_route0.toml --delays 0"));
        assert!(all[3].contains("--densities 0:0 --seeds 0 "));
        let data: Vec<String> = plan.data_steps().iter().map(|s| s.args.join(" ")).collect();
        // Slices of one episode: collect 1, label, collect 2, label, info; then the retargeting set.
        assert_eq!(
            data[5],
            "collect --preset retarget --out c/data/retarget-quick --episodes 1 --max-s 20"
        );
        assert_eq!(
            data[7],
            "collect --preset retarget --out c/data/retarget-quick --episodes 2 --max-s 20"
        );
    }

    #[test]
    fn a_failed_step_names_itself_and_stops_the_plan_unless_it_may_fail() {
        let dir = tempfile::tempdir().unwrap();
        let step = |name: &str, args: &[&str], may_fail: bool| Step {
            may_fail,
            ..Step::new(name, strings(args))
        };
        let notes = std::sync::Mutex::new(Vec::new());
        let note = |s: &str| notes.lock().unwrap().push(s.to_string());
        let groups = vec![
            Group::One(step("a summary", &["-c", "exit 3"], true)),
            Group::Lanes(vec![
                vec![step("lane one", &["-c", "true"], false)],
                vec![step("lane two", &["-c", "exit 2"], false)],
            ]),
            Group::One(step("never", &["-c", "true"], false)),
        ];
        let e = execute(Path::new("/bin/sh"), dir.path(), &groups, &note).unwrap_err();
        assert_eq!(e.step, "lane two");
        assert!(e.what.contains("failed"), "{e}");
        let notes = notes.into_inner().unwrap();
        assert!(notes.iter().any(|n| n.contains("(going on)")));
        assert!(notes.iter().any(|n| n == "lane one done"));
        assert!(!notes.iter().any(|n| n == "never"));
    }

    #[test]
    fn the_rest_of_a_fresh_plan_adds_up_its_slices_rounds_and_lanes() {
        let tmp = tempfile::tempdir().unwrap();
        let cache = tmp.path().join("cache");
        let plan = TrainPlan::full(tmp.path(), &cache, true);
        let rates = JobRates::default();
        let left = left(&plan.steps(1), tmp.path(), &rates);
        // 760 + 40 (DAgger) + 150 episodes; 19 rounds of 1000 x 32, a DAgger round of
        // 500 x 32, NRA 0.75 and 1.0 at 600 x 32, RA at 600 x 32 x 2 scales, RA5 at
        // 600 x 32 x 5; 20 x 12 curve runs, and 6 drivers x (36 runs on the paper's
        // routes + 12 on the held-out ones).
        assert_eq!(left.collect, 950.0);
        assert_eq!(left.label, 950.0);
        assert_eq!(
            left.train,
            19.0 * 32_000.0 + 500.0 * 32.0 + 600.0 * 32.0 * (1.0 + 1.0 + 2.0 + 5.0)
        );
        assert_eq!(left.drive, 20.0 * 12.0 + 6.0 * (36.0 + 12.0));
        // The two retargeting lanes run at once: the longer lane counts (RA, 2 scales,
        // against NRA 1.0 + NRA 0.75: the same), not both.
        let d = Rates::default();
        let serial =
            950.0 * (d.collect_s + d.label_s) + left.train * d.train_s + left.drive * d.drive_s;
        let lanes = 600.0 * 32.0 * 2.0 * d.train_s;
        assert!(
            (left.secs - (serial - lanes)).abs() < 1e-6,
            "{} {}",
            left.secs,
            serial
        );
        assert!(
            left.line(&rates).starts_with("about "),
            "{}",
            left.line(&rates)
        );
        assert!(
            left.line(&rates).contains(
                "collect 950 episodes, label 950 episodes, train 797k samples, drive 528 runs"
            ),
            "{}",
            left.line(&rates)
        );
    }

    #[test]
    fn before_each_group_the_plan_says_how_far_it_is_and_how_long_the_rest_takes() {
        // Two "collect" steps of 5 episodes each that make their episode files: the
        // first is sized at the measured rate, the second at this job's.
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("d")).unwrap();
        let collect = |from: u32, end: u32| {
            let touch: Vec<String> = (from..end)
                .map(|i| format!("d/episode-{i:05}.safetensors"))
                .collect();
            Step::new(
                format!("collect to {end}"),
                strings(&["-c", &format!("touch {}", touch.join(" "))]),
            )
            .doing(Work::Collect {
                dir: "d".into(),
                from,
                end,
            })
        };
        let groups = vec![Group::One(collect(0, 5)), Group::One(collect(5, 10))];
        let notes = std::sync::Mutex::new(Vec::new());
        let note = |s: &str| notes.lock().unwrap().push(s.to_string());
        execute(Path::new("/bin/sh"), dir.path(), &groups, &note).unwrap();
        let notes = notes.into_inner().unwrap();
        assert!(
            notes[0].starts_with("step 1 of 2: about ") && notes[0].contains("collect 10 episodes"),
            "{notes:?}"
        );
        let second = notes.iter().find(|n| n.starts_with("step 2 of 2")).unwrap();
        assert!(
            second.contains("collect 5 episodes (at this job's rate)"),
            "{notes:?}"
        );
    }

    #[test]
    fn the_data_steps_run_the_datas_own_build() {
        // Every collect and label step of the datasets, and no other, gets the data's
        // binary; the DAgger round's frames are the plan's build's.
        let mut plan = TrainPlan::quick(Path::new("q"), Path::new("c"), true).steps(1);
        data_by(&mut plan, Path::new("/c/bin/mrdrive-540f94d"));
        let mut data = 0;
        for step in every_step(&mut plan) {
            let first = step.args[0].as_str();
            let dagger = step.args.iter().any(|a| a.contains("-dagger-"));
            let is_data = (first == "collect" || first == "label") && !dagger;
            data += usize::from(is_data);
            assert_eq!(
                step.exe.as_deref() == Some(Path::new("/c/bin/mrdrive-540f94d")),
                is_data,
                "{}",
                step.args.join(" ")
            );
        }
        assert!(data >= 4, "{data} data steps");
        // A step with its own binary runs it, not the plan's.
        let dir = tempfile::tempdir().unwrap();
        let marker = dir.path().join("ran");
        let touch = format!("touch {}", marker.display());
        let groups = vec![Group::One(Step {
            exe: Some(PathBuf::from("/bin/sh")),
            ..Step::new("touch", strings(&["-c", &touch]))
        })];
        execute(Path::new("/bin/false"), dir.path(), &groups, &|_: &str| {}).unwrap();
        assert!(marker.exists());
    }

    #[test]
    fn the_plan_prints_as_the_commands_it_runs() {
        let mut groups = TrainPlan::quick(Path::new("q"), Path::new("c"), true).steps(1);
        data_by(&mut groups, Path::new("/c/bin/mrdrive-540f94d"));
        let text = commands(&groups, Path::new("/bin/mrdrive"));
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), every_step(&mut groups).count());
        assert_eq!(
            lines[0],
            "/c/bin/mrdrive-540f94d collect --preset original --out c/data/original-quick \
             --episodes 1 --max-s 20"
        );
        assert!(lines[2].starts_with("/bin/mrdrive train --stage original "));
        assert!(
            lines
                .iter()
                .any(|l| l.starts_with("lane 2: /bin/mrdrive train --stage nra-1.0"))
        );
    }

    #[test]
    fn a_time_limit_stops_the_plan_without_calling_it_a_failure() {
        let dir = tempfile::tempdir().unwrap();
        let note = |_: &str| {};
        let groups = vec![
            Group::One(Step::new("stops at its limit", strings(&["-c", "exit 75"]))),
            Group::One(Step::new("never", strings(&["-c", "true"]))),
        ];
        let e = execute(Path::new("/bin/sh"), dir.path(), &groups, &note).unwrap_err();
        assert!(
            e.stopped_at_time_limit() && e.step == "stops at its limit",
            "{e}"
        );
        // A limit already passed: nothing starts.
        let marker = dir.path().join("ran");
        let touch = format!("touch {}", marker.display());
        let groups = vec![Group::One(Step::new("touch", strings(&["-c", &touch])))];
        let past = Some(std::time::SystemTime::UNIX_EPOCH);
        let e = execute_until(Path::new("/bin/sh"), dir.path(), &groups, past, &note).unwrap_err();
        assert!(e.stopped_at_time_limit() && !marker.exists(), "{e}");
        // A real failure is not a time limit.
        let groups = vec![Group::One(Step::new("fails", strings(&["-c", "exit 2"])))];
        let e = execute(Path::new("/bin/sh"), dir.path(), &groups, &note).unwrap_err();
        assert!(!e.stopped_at_time_limit());
        // Every training step, in lanes too, gets the limit; the others do not.
        let mut plan = TrainPlan::quick(Path::new("q"), Path::new("c"), true).steps(1);
        add_to_training(&mut plan, &strings(&["--until-unix", "1800000000"]));
        let all: Vec<String> = plan.iter().flat_map(joined).collect();
        for a in &all {
            assert_eq!(
                a.starts_with("train "),
                a.ends_with("--until-unix 1800000000"),
                "{a}"
            );
        }
        assert!(all.iter().any(|a| a.starts_with("sweep ")));
    }
}
