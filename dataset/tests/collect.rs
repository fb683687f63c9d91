//! A dataset is deterministic for its plan and resumes after a kill; its
//! labels are deterministic too.

use std::path::Path;

use dataset::collect::{self, CollectConfig, Preset};
use dataset::format::{Index, Shard};
use dataset::labels::episode::label_dataset;
use world::testdata::{self, Needs};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

/// Two short episodes of the retargeting plan (our generated towns: no
/// ../shared needed), collected into `dir`; `None` without a renderer.
/// The first `episodes` episodes of the retargeting plan on our generated towns.
fn plan(episodes: usize) -> Vec<collect::EpisodeSpec> {
    collect::plan(Preset::Retarget, 3, Path::new("/no/carla"), root())
        .into_iter()
        .filter(|s| matches!(s.route, collect::RouteChoice::File { .. }))
        .take(episodes)
        .collect()
}

/// The collection's configuration: 4 s episodes.
fn config() -> CollectConfig {
    let mut cfg = CollectConfig::cpu_default("retarget");
    cfg.max_s = 4.0;
    cfg
}

fn collect_into(dir: &Path, episodes: usize) -> Option<Index> {
    let plan = plan(episodes);
    let cfg = config();
    match collect::collect(&plan, &cfg, dir, &mut |_, _| {}) {
        Ok(index) => Some(index),
        Err(e) if e.to_string().contains("adapter") || e.to_string().contains("camera") => {
            testdata::skip("collect", Needs::Renderer, &e.to_string());
            None
        }
        Err(e) => panic!("{e}"),
    }
}

fn bytes(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap()
}

#[test]
fn collection_and_labels_are_deterministic_and_resume() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let Some(full) = collect_into(a.path(), 2) else {
        return;
    };
    assert_eq!(full.episodes.len(), 2);
    assert!(
        full.episodes.iter().all(|e| e.frames == 16),
        "{:?}",
        full.episodes
    );
    // A collection killed after its first episode resumes where it stopped.
    let first = collect_into(b.path(), 1).unwrap();
    assert_eq!(first.episodes.len(), 1);
    let resumed = collect_into(b.path(), 2).unwrap();
    assert_eq!(resumed, full);
    for e in &full.episodes {
        let (sa, sb) = (
            Shard::read(&a.path().join(&e.shard), full.s0, 3).unwrap(),
            Shard::read(&b.path().join(&e.shard), full.s0, 3).unwrap(),
        );
        assert!(
            sa.ego == sb.ego && sa.actors == sb.actors && sa.lights == sb.lights,
            "{}: state differs",
            e.shard
        );
        assert!(sa.classes == sb.classes, "{}: class images differ", e.shard);
        let diff = sa.rgb.iter().zip(&sb.rgb).filter(|(x, y)| x != y).count();
        assert_eq!(diff, 0, "{}: {diff} rgb bytes differ", e.shard);
        assert!(
            bytes(a.path(), &e.shard) == bytes(b.path(), &e.shard),
            "{}: the files differ",
            e.shard
        );
    }
    // Labels: the same bytes from both copies; a second run labels nothing.
    for dir in [a.path(), b.path()] {
        let report = label_dataset(dir, &mut |_, _| {}).unwrap();
        assert_eq!((report.episodes, report.frames), (2, 2 * (16 - 5)));
        assert_eq!(label_dataset(dir, &mut |_, _| {}).unwrap().skipped, 2);
    }
    let index = Index::load(a.path()).unwrap();
    for e in &index.episodes {
        let name = e.labels.as_deref().unwrap();
        assert!(
            bytes(a.path(), name) == bytes(b.path(), name),
            "{name} differs"
        );
    }
    // Resuming with other traffic would mix two datasets: refused, naming the flag.
    let mut other = plan(2);
    for spec in &mut other {
        spec.crossings_per_min = 0.0;
    }
    let err = collect::collect(&other, &config(), a.path(), &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("episode 0") && err.contains("--crossings-per-min"),
        "{err}"
    );
}

#[test]
fn a_truncated_shard_is_skipped_by_name_and_the_rest_labelled() {
    let dir = tempfile::tempdir().unwrap();
    let Some(index) = collect_into(dir.path(), 2) else {
        return;
    };
    let bad = dir.path().join(&index.episodes[0].shard);
    let len = std::fs::metadata(&bad).unwrap().len();
    let f = std::fs::OpenOptions::new().write(true).open(&bad).unwrap();
    f.set_len(len / 2).unwrap();
    let report = label_dataset(dir.path(), &mut |_, _| {}).unwrap();
    assert_eq!(report.episodes, 1);
    assert_eq!(report.failed.len(), 1);
    assert_eq!(report.failed[0].0, bad);
    assert!(
        report.failed[0].1.contains("truncated"),
        "{}",
        report.failed[0].1
    );
}

/// A learner that never moves: the expert must take over.
struct Parked;

impl sim::driver::Driver for Parked {
    fn name(&self) -> String {
        "parked".into()
    }
    fn needs(&self) -> sim::driver::DriverNeeds {
        sim::driver::DriverNeeds::default()
    }
    fn act(&mut self, _: &sim::driver::Observation<'_>) -> sim::driver::VehicleControl {
        sim::driver::VehicleControl::BRAKE
    }
}

#[test]
fn a_dagger_round_records_the_learners_states_and_the_expert_takes_over_where_it_stands() {
    let dir = tempfile::tempdir().unwrap();
    let mut cfg = config();
    cfg.max_s = 8.0;
    let learner = || -> Result<Box<dyn sim::driver::Driver>, String> { Ok(Box::new(Parked)) };
    let mut reports = Vec::new();
    let got = collect::collect_with(&plan(1), &cfg, dir.path(), Some(&learner), &mut |r, _| {
        reports.push(r.clone())
    });
    let index = match got {
        Ok(index) => index,
        Err(e) if e.to_string().contains("adapter") || e.to_string().contains("camera") => {
            testdata::skip("collect", Needs::Renderer, &e.to_string());
            return;
        }
        Err(e) => panic!("{e}"),
    };
    // The learner stands 3 s where the expert would go, the expert drives 5 s.
    let share = reports[0]
        .dagger
        .expect("a DAgger episode reports who drove");
    assert_eq!(share.takeovers, 1, "{share:?}");
    let learner_part = share.learner as f64 / (share.learner + share.expert) as f64;
    assert!((0.3..0.45).contains(&learner_part), "{share:?}");
    assert!(reports[0].line(1).contains("takeovers)"));
    // The frames hold both: standing first, then moving under the expert.
    let e = &index.episodes[0];
    let shard = Shard::read(&dir.path().join(&e.shard), index.s0, 3).unwrap();
    let speeds: Vec<f32> = shard.ego.iter().map(|r| r.speed).collect();
    assert!(speeds[..8].iter().all(|&v| v < 0.5), "{speeds:?}");
    assert!(speeds.last().is_some_and(|&v| v > 1.0), "{speeds:?}");
}
