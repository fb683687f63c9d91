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
