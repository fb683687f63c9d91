//! Publishing a finished run: its checkpoint (in half precision), card, loss log and
//! loss plot copied from the run folder to a models folder as `<name>.*`.

use std::path::{Path, PathBuf};

use super::stage::{FINAL_FILE, LOSSES_FILE};
use crate::checkpoint::{CheckpointError, manifest_path, write_f16};

/// The loss plot of a run folder (drawn by the command line from `losses.csv`).
pub const LOSSES_PLOT_FILE: &str = "losses.png";

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
/// the study) drives this file. The plot may be missing (a run gone on from a snapshot at its
/// last step has no loss rows to draw): then no plot is published and an older one
/// under that name is removed.
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
        (manifest_path(&weights), format!("{name}.json")),
        (run_dir.join(LOSSES_FILE), format!("{name}.losses.csv")),
        (plot, format!("{name}.losses.png")),
    ];
    write_f16(&weights, &published_checkpoint(out, name))?;
    let copies = copies
        .map(|(from, to)| (from, out.join(to)))
        .into_iter()
        .filter(|(from, _)| !from.ends_with(LOSSES_PLOT_FILE) || from.exists());
    for (from, to) in copies {
        std::fs::copy(&from, &to).map_err(|source| PublishError::Copy { from, to, source })?;
    }
    Ok(())
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
            std::fs::read(manifest_path(&run.path().join(FINAL_FILE))).unwrap()
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
}
