//! A training stage on a tiny synthetic dataset: kill and resume, skip when done,
//! refuse other settings, retarget from a teacher.
//!
//! burn seeds its initialisers from one global RNG, so the two tests take a lock:
//! a parallel test drawing from it would change the other's initial weights.

use burn::prelude::*;
use dataset::synthetic::{self, SyntheticSpec};
use policy::checkpoint;
use policy::train::stage::{
    FINAL_FILE, Job, LOSSES_FILE, StageSpec, read_resume, resume_path, run_stage, run_stage_until,
    snapshot,
};
use policy::train::{Preset, TrainConfig};
use std::path::Path;
use std::sync::Mutex;

static SEEDED: Mutex<()> = Mutex::new(());

fn tiny_data() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let mut spec = SyntheticSpec::tiny(2, 14);
    spec.s0 = [96, 48];
    synthetic::write(dir.path(), &spec).unwrap();
    dir
}

fn tiny_original(data: &Path) -> StageSpec {
    StageSpec {
        batch: 4,
        steps: 6,
        checkpoint_every: 2,
        ..StageSpec::original(data, Preset::Tiny)
    }
}

fn rows(dir: &Path) -> Vec<String> {
    std::fs::read_to_string(dir.join(LOSSES_FILE))
        .unwrap()
        .lines()
        .map(String::from)
        .collect()
}

/// The final checkpoints of two run folders hold the same tensors, bit for bit.
fn same_tensors(a: &Path, b: &Path) {
    let a = std::fs::read(a.join(FINAL_FILE)).unwrap();
    let b = std::fs::read(b.join(FINAL_FILE)).unwrap();
    let (a, b) = (
        safetensors::SafeTensors::deserialize(&a).unwrap(),
        safetensors::SafeTensors::deserialize(&b).unwrap(),
    );
    let mut names = a.names();
    names.sort();
    assert!(names.len() > 20);
    for name in names {
        assert!(
            a.tensor(name).unwrap().data() == b.tensor(name).unwrap().data(),
            "{name} differs"
        );
    }
}

#[test]
fn a_killed_stage_resumes_bit_for_bit_and_a_done_stage_is_skipped() {
    let _seeded = SEEDED.lock().unwrap_or_else(|e| e.into_inner());
    let data = tiny_data();
    let device = Device::flex().autodiff();
    let spec = tiny_original(data.path());
    let straight = tempfile::tempdir().unwrap();
    let out = run_stage(&spec, straight.path(), &device, |_| {}).unwrap();
    assert_eq!(out.steps_now, 6);
    // "Killed" during step index 2: the checkpoint after 2 steps stands, row 2 was
    // written.
    let killed = tempfile::tempdir().unwrap();
    let mut seen = 0;
    let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        run_stage(&spec, killed.path(), &device, |u| {
            seen += 1;
            if u.report.step == 2 {
                panic!("killed");
            }
        })
    }));
    assert_eq!(seen, 3);
    let resumed = run_stage(&spec, killed.path(), &device, |_| {}).unwrap();
    assert_eq!(
        resumed.steps_now, 4,
        "resumes from the checkpoint at step 2"
    );
    let strip = |rows: Vec<String>| -> Vec<String> {
        // Drop the timing columns (samples/s, wall time).
        rows.iter()
            .map(|r| r.rsplitn(3, ',').nth(2).unwrap().to_string())
            .collect()
    };
    assert_eq!(strip(rows(killed.path())), strip(rows(straight.path())));
    same_tensors(straight.path(), killed.path());
    // A time limit already passed: one step, a checkpoint, nothing published; run
    // again (twice more), it finishes with the uninterrupted run's rows and bits.
    let runs = tempfile::tempdir().unwrap();
    let limited = runs.path().join("original");
    let past = Job {
        stop_at: Some(std::time::SystemTime::UNIX_EPOCH),
        ..Job::default()
    };
    let first = run_stage_until(&spec, &limited, &device, &past, |_| {}).unwrap();
    assert_eq!((first.stopped_at, first.steps_now), (Some(1), 1));
    assert!(!limited.join(FINAL_FILE).exists());
    let second = run_stage_until(&spec, &limited, &device, &past, |_| {}).unwrap();
    assert_eq!(second.stopped_at, Some(2));
    // The job's end: the run's network at step 2 in half precision, to commit.
    let out = runs.path().join("state/train-state.safetensors");
    let snap = snapshot(runs.path(), &out)
        .unwrap()
        .expect("a run with a state");
    assert_eq!((snap.run.clone(), snap.progress.step), (limited.clone(), 2));
    assert!(snap.last_losses.unwrap().starts_with("1,"));
    let (_, card) = checkpoint::load(&out, &Device::flex()).unwrap();
    assert!(
        card.source.ends_with("after 2 of 6 steps"),
        "{}",
        card.source
    );
    // The cache lost: a run folder without state goes on from the snapshot at step 2
    // (fresh Adam moments: close to, not the bits of, the uninterrupted run).
    let lost = tempfile::tempdir().unwrap();
    let again = lost.path().join("original");
    let from = Job {
        resume_state: Some(out.clone()),
        ..Job::default()
    };
    let resumed = run_stage_until(&spec, &again, &device, &from, |_| {}).unwrap();
    assert_eq!((resumed.stopped_at, resumed.steps_now), (None, 4));
    let first_row = rows(&again)[1].clone();
    assert!(first_row.starts_with("2,"), "{first_row}");
    // A snapshot of another run is ignored: this one starts from step 0.
    let other = lost.path().join("nra-1.0");
    let fresh = run_stage_until(&spec, &other, &device, &from, |_| {}).unwrap();
    assert_eq!(fresh.steps_now, 6);
    // One of this run at step 0 (where a chain goes on, nothing trained; no weights
    // beside it) is ignored too: the run is the straight one, bit for bit.
    let at_zero = lost.path().join("zero/train-state.safetensors");
    std::fs::create_dir_all(at_zero.parent().unwrap()).unwrap();
    std::fs::write(
        resume_path(&at_zero),
        r#"{"run": "first/original", "step": 0, "wall_s": 0.0}"#,
    )
    .unwrap();
    let first_run = lost.path().join("first/original");
    let zero = Job {
        resume_state: Some(at_zero),
        ..Job::default()
    };
    let started = run_stage_until(&spec, &first_run, &device, &zero, |_| {}).unwrap();
    assert_eq!((started.stopped_at, started.steps_now), (None, 6));
    same_tensors(straight.path(), &first_run);
    // A round of the learning curve whose --init (the round before) lived in the
    // lost cache: not needed with a snapshot of the round, refused without one.
    let gone = StageSpec {
        init: Some(lost.path().join("slice-01/original.safetensors")),
        ..spec.clone()
    };
    let round = lost.path().join("slice-02/original");
    let resumed = run_stage_until(&gone, &round, &device, &from, |_| {}).unwrap();
    assert_eq!((resumed.stopped_at, resumed.steps_now), (None, 4));
    let err = run_stage(
        &gone,
        &lost.path().join("slice-03/original"),
        &device,
        |_| {},
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        err.contains("slice-01") && err.contains("init checkpoint exists"),
        "{err}"
    );
    let rest = run_stage(&spec, &limited, &device, |_| {}).unwrap();
    assert_eq!((rest.stopped_at, rest.steps_now), (None, 4));
    assert_eq!(strip(rows(&limited)), strip(rows(straight.path())));
    same_tensors(straight.path(), &limited);
    // Done: nothing to do.
    let again = run_stage(&spec, killed.path(), &device, |_| {}).unwrap();
    assert_eq!(again.steps_now, 0);
    // Extended: it continues as if it had been asked for more steps from the start.
    let longer = StageSpec {
        steps: 8,
        ..spec.clone()
    };
    let more = run_stage(&longer, killed.path(), &device, |_| {}).unwrap();
    assert_eq!(more.steps_now, 2);
    let straight8 = tempfile::tempdir().unwrap();
    run_stage(&longer, straight8.path(), &device, |_| {}).unwrap();
    assert_eq!(strip(rows(killed.path())), strip(rows(straight8.path())));
    // A round of the learning curve nests its run folder three deep
    // (`curve/slice-02/original`): the job's end still finds it, the newest.
    let nested = runs.path().join("curve/slice-02/original");
    run_stage_until(&spec, &nested, &device, &past, |_| {}).unwrap();
    let snap = snapshot(runs.path(), &out).unwrap().unwrap();
    assert_eq!(snap.run, nested);
    assert_eq!(
        read_resume(&out).unwrap().run,
        Path::new("curve/slice-02/original")
    );
}

#[test]
fn another_configuration_is_refused_by_name_and_a_retarget_trains_from_the_teacher() {
    let _seeded = SEEDED.lock().unwrap_or_else(|e| e.into_inner());
    let data = tiny_data();
    let device = Device::flex().autodiff();
    let spec = tiny_original(data.path());
    let run = tempfile::tempdir().unwrap();
    let original = run_stage(&spec, run.path(), &device, |_| {}).unwrap();
    // The fit report looks at every sample drawn, once, in its group.
    let (net, _) = checkpoint::load(&original.checkpoint, &Device::flex()).unwrap();
    let set = std::sync::Arc::new(
        policy::train::loader::TrainSet::open(data.path(), &net.config).unwrap(),
    );
    let groups = policy::train::fit::fit(&net, 0, &set, 3, 4, &Device::flex());
    assert_eq!(groups.len(), 4);
    assert_eq!(groups.iter().map(|g| g.n).sum::<usize>(), 12);
    for g in &groups {
        assert!(
            g.kl >= 0.0 && (0.0..=1.0).contains(&g.argmax_agree),
            "{g:?}"
        );
    }
    let other = StageSpec {
        train: spec.train.clone().with_lr(1e-3),
        ..spec.clone()
    };
    let e = run_stage(&other, run.path(), &device, |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("`train`") && e.contains("spec.json"), "{e}");

    let ra = StageSpec {
        batch: 4,
        steps: 4,
        recalibrate_batches: 2,
        train: TrainConfig::new().with_unfreeze_every(Some(2)),
        ..StageSpec::retarget(
            "ra",
            &[0.75, 1.0],
            data.path(),
            &original.checkpoint,
            Preset::Tiny,
        )
    };
    let ra_dir = tempfile::tempdir().unwrap();
    let mut unfrozen = vec![];
    let out = run_stage(&ra, ra_dir.path(), &device, |u| {
        assert_eq!(u.report.per_scale.len(), 2);
        assert!(u.report.parts.kd >= 0.0 && u.report.parts.feat >= 0.0);
        unfrozen.push(u.report.unfrozen_stages);
    })
    .unwrap();
    assert_eq!(unfrozen, vec![1, 1, 2, 2]);
    let (net, card) = checkpoint::load(&out.checkpoint, &device).unwrap();
    assert_eq!(net.config.scales, vec![0.75, 1.0]);
    assert!(card.trained && card.training.is_some());
    // The cards say what each network saw: the Original 6 steps of 4 frames, the RA
    // those and its own 4 of 4 (it starts from the Original's weights); the data by
    // town and by the hash of every file, as `mrdrive data hashes` lists them.
    let (_, original_card) = checkpoint::load(&original.checkpoint, &Device::flex()).unwrap();
    let first = original_card.training.unwrap();
    assert_eq!(first.frames_seen, Some(24));
    let record = card.training.unwrap();
    assert_eq!(record.frames_seen, Some(24 + 16));
    // The RA names its teacher by digest, the Original (from scratch) names none.
    let teacher = std::fs::read(&original.checkpoint).unwrap();
    assert_eq!(
        record.start_sha256,
        Some(sim::output::record::sha256_hex(&teacher))
    );
    assert_eq!(first.start_sha256, None);
    assert!(record.build.starts_with("mrdrive "), "{}", record.build);
    let hashes = dataset::hashes::of_dataset(data.path()).unwrap();
    assert_eq!(hashes.len(), 4, "two episodes, a shard and labels each");
    assert_eq!(record.data_sha256, hashes);
    assert_eq!(first.data_sha256, hashes);
    assert_eq!(
        record.towns.values().sum::<usize>(),
        2,
        "{:?}",
        record.towns
    );
    assert_eq!(record.episodes, None);
    // By route too: the synthetic episodes drive one random route.
    let routes = std::collections::BTreeMap::from([("random".to_string(), 2)]);
    assert_eq!(record.routes, routes);
    // A card from a build before routes were counted gets them when the finished run
    // is asked for again (as the chain publishes it), its weights untouched.
    let (config, mut old) = checkpoint::read_manifest(&out.checkpoint).unwrap();
    old.training.as_mut().unwrap().routes.clear();
    checkpoint::write_manifest(&out.checkpoint, &config, &old).unwrap();
    let weights = std::fs::read(&out.checkpoint).unwrap();
    let again = run_stage(&ra, ra_dir.path(), &device, |_| {}).unwrap();
    assert_eq!(again.steps_now, 0, "done: nothing trained");
    let (_, card) = checkpoint::read_manifest(&again.checkpoint).unwrap();
    assert_eq!(card.training.unwrap().routes, routes);
    assert_eq!(std::fs::read(&again.checkpoint).unwrap(), weights);
    // The Original trained on (its final checkpoint rewritten) is no longer the teacher
    // the finished RA run was made from: the run is refused, not skipped.
    let longer = StageSpec {
        steps: 8,
        ..spec.clone()
    };
    run_stage(&longer, run.path(), &device, |_| {}).unwrap();
    let e = run_stage(&ra, ra_dir.path(), &device, |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("inputs.json") && e.contains("another teacher") && e.contains("delete"),
        "{e}"
    );
    // A teacher of another size is refused by name.
    let bad = StageSpec {
        preset: "cpu".into(),
        ..ra.clone()
    };
    let e = run_stage(&bad, tempfile::tempdir().unwrap().path(), &device, |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("final.safetensors") && e.contains("teacher"),
        "{e}"
    );
}

#[test]
fn a_stage_says_which_episodes_it_trains_without() {
    let _seeded = SEEDED.lock().unwrap_or_else(|e| e.into_inner());
    let data = tiny_data();
    let index = dataset::format::Index::load(data.path()).unwrap();
    let shard = data.path().join(&index.episodes[0].shard);
    let bytes = std::fs::read(&shard).unwrap();
    std::fs::write(&shard, &bytes[..bytes.len() - 100]).unwrap();
    let spec = StageSpec {
        steps: 2,
        ..tiny_original(data.path())
    };
    let run = tempfile::tempdir().unwrap();
    let mut reported = Vec::new();
    run_stage(&spec, run.path(), &Device::flex().autodiff(), |u| {
        reported.push(u.skipped.iter().map(|s| s.path.clone()).collect::<Vec<_>>());
    })
    .unwrap();
    assert_eq!(reported.len(), 2);
    assert!(
        reported.iter().all(|r| r == &vec![shard.clone()]),
        "{reported:?}"
    );
}

#[test]
fn a_stage_pinned_to_its_first_episodes_lists_only_their_files_on_its_card() {
    let _seeded = SEEDED.lock().unwrap_or_else(|e| e.into_inner());
    let data = tiny_data();
    let device = Device::flex().autodiff();
    let spec = StageSpec {
        episodes: Some(1),
        steps: 2,
        ..tiny_original(data.path())
    };
    let run = tempfile::tempdir().unwrap();
    let out = run_stage(&spec, run.path(), &device, |_| {}).unwrap();
    let (_, card) = checkpoint::load(&out.checkpoint, &Device::flex()).unwrap();
    let record = card.training.unwrap();
    assert_eq!(record.episodes, Some(1));
    assert_eq!(record.frames_seen, Some(8));
    assert_eq!(record.towns.values().sum::<usize>(), 1);
    let all = dataset::hashes::of_dataset(data.path()).unwrap();
    let first: std::collections::BTreeMap<String, String> = all
        .into_iter()
        .filter(|(file, _)| file.contains("00000"))
        .collect();
    assert_eq!(first.len(), 2);
    assert_eq!(record.data_sha256, first);
}
