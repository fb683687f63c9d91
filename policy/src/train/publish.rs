//! Publishing a finished run: its checkpoint (in half precision), card, loss log and
//! loss plot copied from the run folder to a models folder as `<name>.*`, the card
//! stamped with the published checkpoint's SHA-256 and where its curves are.

use std::path::{Path, PathBuf};

use super::stage::{FINAL_FILE, LOSSES_FILE};
use crate::checkpoint::{
    CheckpointError, TrainingRecord, read_manifest, write_f16, write_manifest,
};

/// The loss plot of a run folder (drawn by the command line from `losses.csv`).
pub const LOSSES_PLOT_FILE: &str = "losses.png";

/// The closed-loop learning curve `mrdrive train --all` draws in the models folder
/// it publishes into (the table of `experiments::pipeline::TrainPlan::curve_table`):
/// the Original's success on the curve's units after each slice of episodes and
/// each DAgger round.
pub const LEARNING_CURVE_FILE: &str = "original.curve.md";

/// The stage whose data the learning curve sized.
const CURVE_STAGE: &str = "original";

/// Why a run could not be published.
#[derive(Debug, thiserror::Error)]
pub enum PublishError {
    /// The models folder could not be made.
    #[error("{}: cannot create", path.display())]
    Create {
        /// The models folder.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A file of the run could not be copied.
    #[error("copying {} to {}", from.display(), to.display())]
    Copy {
        /// The file of the run folder.
        from: PathBuf,
        /// Where it was to go.
        to: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The checkpoint could not be written in half precision.
    #[error("publishing the checkpoint")]
    Weights(#[from] CheckpointError),
}

/// The published checkpoint of the network `name` in the models folder `out`.
pub fn published_checkpoint(out: &Path, name: &str) -> PathBuf {
    out.join(format!("{name}.safetensors"))
}

/// Copies the finished run in `run_dir` (its checkpoint and card, `losses.csv` and
/// [`LOSSES_PLOT_FILE`]) to `out` as `<name>.safetensors`, `<name>.json`,
/// `<name>.losses.csv` and `<name>.losses.png`. The checkpoint is written first, in
/// half precision (`checkpoint::write_f16`): the shipped models are what the
/// repository keeps, at half the bytes, and every check of a shipped model (the bar,
/// the study) drives this file. The card's training record then names that file's
/// SHA-256, its loss log and the learning curve ([`learning_curve`]). The plot may be
/// missing (a run gone on from a snapshot at its last step has no loss rows to
/// draw): then no plot is published and an older one under that name is removed.
pub fn publish(run_dir: &Path, out: &Path, name: &str) -> Result<(), PublishError> {
    std::fs::create_dir_all(out).map_err(|source| PublishError::Create {
        path: out.to_path_buf(),
        source,
    })?;
    let weights = run_dir.join(FINAL_FILE);
    let plot = run_dir.join(LOSSES_PLOT_FILE);
    if !plot.exists() {
        let _ = std::fs::remove_file(out.join(format!("{name}.losses.png")));
    }
    let copies = [
        (run_dir.join(LOSSES_FILE), format!("{name}.losses.csv")),
        (plot, format!("{name}.losses.png")),
    ];
    let published = published_checkpoint(out, name);
    write_f16(&weights, &published)?;
    let (config, mut card) = read_manifest(&weights)?;
    if let Some(record) = card.training.as_mut() {
        let bytes = std::fs::read(&published).map_err(|source| CheckpointError::Io {
            path: published.clone(),
            source,
            fix: "check the models folder is readable",
        })?;
        record.checkpoint_sha256 = Some(sim::record::sha256_hex(&bytes));
        record.losses = format!("{name}.losses.csv");
        record.learning_curve = learning_curve(out, record);
    }
    write_manifest(&published, &config, &card)?;
    let copies = copies
        .map(|(from, to)| (from, out.join(to)))
        .into_iter()
        .filter(|(from, _)| !from.ends_with(LOSSES_PLOT_FILE) || from.exists());
    for (from, to) in copies {
        std::fs::copy(&from, &to).map_err(|source| PublishError::Copy { from, to, source })?;
    }
    Ok(())
}

/// Where the learning curve of a model published into `out` with `record` is: the
/// Original's is [`LEARNING_CURVE_FILE`]; a network retargeted from it points to the
/// same file, by its teacher's SHA-256, as its retargeting set was sized as the
/// paper's and not by a curve of its own. `None` where `out` holds no curve.
fn learning_curve(out: &Path, record: &TrainingRecord) -> Option<String> {
    if !out.join(LEARNING_CURVE_FILE).exists() {
        return None;
    }
    Some(if record.stage == CURVE_STAGE {
        format!(
            "{LEARNING_CURVE_FILE}: this network's data, closed-loop success on the curve's \
             units after each slice of episodes and each DAgger round"
        )
    } else {
        let teacher = record.start_sha256.as_deref().unwrap_or("unknown");
        format!(
            "{LEARNING_CURVE_FILE}: its teacher's (the Original, SHA-256 {teacher}); the \
             retargeting set was sized as the paper's, not by a curve of its own"
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_is_published_in_half_precision_and_a_missing_file_is_named_but_the_plot() {
        let run = tempfile::tempdir().unwrap();
        let out = tempfile::tempdir().unwrap();
        let out = out.path().join("models");
        let device = burn::tensor::Device::flex();
        device.seed(3);
        let cfg = crate::model::PolicyConfig::new(crate::backbone::Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(64)
            .with_input_width(96);
        let card = crate::checkpoint::ModelCard::random_init(3);
        crate::checkpoint::save(&cfg.init(&device), &card, &run.path().join(FINAL_FILE)).unwrap();
        let others = [LOSSES_FILE, LOSSES_PLOT_FILE];
        for (i, f) in others.iter().enumerate() {
            std::fs::write(run.path().join(f), [i as u8]).unwrap();
        }
        publish(run.path(), &out, "ra5").unwrap();
        for (i, f) in ["ra5.losses.csv", "ra5.losses.png"].iter().enumerate() {
            assert_eq!(std::fs::read(out.join(f)).unwrap(), [i as u8], "{f}");
        }
        assert_eq!(
            std::fs::read(out.join("ra5.json")).unwrap(),
            std::fs::read(crate::checkpoint::manifest_path(
                &run.path().join(FINAL_FILE)
            ))
            .unwrap()
        );
        // The weights: every float tensor in half precision, about half the bytes,
        // loading with the run's card.
        let published = published_checkpoint(&out, "ra5");
        assert_eq!(published, out.join("ra5.safetensors"));
        let (full, half) = (
            std::fs::read(run.path().join(FINAL_FILE)).unwrap(),
            std::fs::read(&published).unwrap(),
        );
        assert!(
            half.len() * 10 < full.len() * 6,
            "{} vs {}",
            half.len(),
            full.len()
        );
        let file = safetensors::SafeTensors::deserialize(&half).unwrap();
        assert!(
            file.tensors()
                .iter()
                .all(|(_, t)| t.dtype() != safetensors::Dtype::F32)
        );
        let (_, loaded) = crate::checkpoint::load(&published, &device).unwrap();
        assert_eq!(loaded, card);
        let names: Vec<_> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert_eq!(names.len(), 4, "no temporary file left: {names:?}");
        // No plot (no loss rows to draw): published without one, the old one gone.
        std::fs::remove_file(run.path().join(LOSSES_PLOT_FILE)).unwrap();
        publish(run.path(), &out, "ra5").unwrap();
        assert!(!out.join("ra5.losses.png").exists());
        // A missing loss log is named.
        std::fs::remove_file(run.path().join(LOSSES_FILE)).unwrap();
        let err = publish(run.path(), &out, "ra5").unwrap_err().to_string();
        assert!(
            err.starts_with("copying ")
                && err.contains("losses.csv to ")
                && err.ends_with("ra5.losses.csv"),
            "{err}"
        );
        // Weights that are not a checkpoint are named.
        std::fs::write(run.path().join(FINAL_FILE), b"not a checkpoint").unwrap();
        std::fs::write(run.path().join(LOSSES_FILE), b"").unwrap();
        let err = publish(run.path(), &out, "ra5").unwrap_err();
        let chain = format!("{err}: {}", std::error::Error::source(&err).unwrap());
        assert!(chain.contains(FINAL_FILE), "{chain}");
    }

    #[test]
    fn a_published_card_names_its_checkpoints_sha256_its_losses_and_its_learning_curve() {
        let run = tempfile::tempdir().unwrap();
        let out = tempfile::tempdir().unwrap();
        let device = burn::tensor::Device::flex();
        device.seed(4);
        let cfg = crate::model::PolicyConfig::new(crate::backbone::Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(64)
            .with_input_width(96);
        let record: TrainingRecord = serde_json::from_str(
            r#"{"stage": "ra", "data": "d", "samples_in_data": 1, "steps": 1, "batch": 1,
                "seed": 0, "lr": 0.1, "losses": "see losses.csv beside the run",
                "wall_s": 1.0, "machine": "m", "start_sha256": "abc123"}"#,
        )
        .unwrap();
        let card = crate::checkpoint::ModelCard {
            training: Some(record),
            ..crate::checkpoint::ModelCard::random_init(4)
        };
        let net = cfg.init(&device);
        crate::checkpoint::save(&net, &card, &run.path().join(FINAL_FILE)).unwrap();
        std::fs::write(run.path().join(LOSSES_FILE), b"step,loss\n").unwrap();
        let stamped = |name: &str| {
            publish(run.path(), out.path(), name).unwrap();
            let published = published_checkpoint(out.path(), name);
            let sha = sim::record::sha256_hex(&std::fs::read(&published).unwrap());
            let (_, card) = read_manifest(&published).unwrap();
            (sha, card.training.unwrap())
        };
        // No curve in the models folder: the SHA-256 of the file as published and the
        // loss log beside it, no curve.
        let (sha, record) = stamped("ra");
        assert_eq!(record.checkpoint_sha256.as_deref(), Some(sha.as_str()));
        assert_eq!(record.losses, "ra.losses.csv");
        assert_eq!(record.learning_curve, None);
        // With the Original's curve beside it: a retargeted network points to it by its
        // teacher's digest; published again, the weights are the same bytes.
        std::fs::write(out.path().join(LEARNING_CURVE_FILE), "| curve |").unwrap();
        let (again, record) = stamped("ra");
        assert_eq!(again, sha);
        let curve = record.learning_curve.unwrap();
        assert!(
            curve.starts_with(LEARNING_CURVE_FILE)
                && curve.contains("teacher's (the Original, SHA-256 abc123)"),
            "{curve}"
        );
        // The Original's own curve.
        let mut card = card;
        card.training.as_mut().unwrap().stage = CURVE_STAGE.into();
        crate::checkpoint::save(&net, &card, &run.path().join(FINAL_FILE)).unwrap();
        let (_, record) = stamped("original");
        let curve = record.learning_curve.unwrap();
        assert!(curve.contains("this network's data"), "{curve}");
    }
}
