//! Policy checkpoints: weights in safetensors, and a JSON file beside them with the
//! config and a model card, so loading needs nothing else. Also imports a
//! torchvision ResNet state dict (saved as safetensors) into the backbone.
//!
//! `policy.safetensors` + `policy.json`:
//! ```json
//! { "format": "mrdrive-policy/1", "config": { ... PolicyConfig ... },
//!   "card": { "trained": false, "description": "...", "source": "..." } }
//! ```

use crate::model::{PolicyConfig, PolicyNet};
use burn::prelude::*;
use burn::store::{ApplyError, KeyRemapper, ModuleSnapshot, SafetensorsStore};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The format tag written into every checkpoint's JSON.
pub const FORMAT: &str = "mrdrive-policy/1";

/// What a checkpoint says about itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelCard {
    /// Whether the weights were trained (false: random initialisation).
    pub trained: bool,
    /// What the weights are, in a sentence.
    pub description: String,
    /// Where they came from (a training run, an imported file, a seed).
    pub source: String,
    /// How they were trained (for a trained checkpoint).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training: Option<TrainingRecord>,
}

/// What a training stage records on its checkpoint's card.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainingRecord {
    /// The stage (`original`, `nra-0.75`, `nra-1.0`, `ra`).
    pub stage: String,
    /// The dataset folder it trained on.
    pub data: String,
    /// Training samples (frame views) in the dataset.
    pub samples_in_data: usize,
    /// Steps taken.
    pub steps: usize,
    /// Samples per step.
    pub batch: usize,
    /// The stage's seed.
    pub seed: u64,
    /// Adam's learning rate.
    pub lr: f64,
    /// Where the loss curves are.
    pub losses: String,
    /// Training wall time over every session (seconds).
    pub wall_s: f64,
    /// The machine it trained on.
    pub machine: String,
    /// The checkpoint it started from, if not a fresh initialisation or a teacher.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub init: Option<String>,
    /// Which samples an epoch drew and how often (absent fields: WoR's, each once).
    #[serde(flatten)]
    pub sampling: crate::train::loader::Sampling,
    /// The build that trained it (`mrdrive 0.1.0 (<commit>)`; absent on older cards).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub build: String,
    /// How many of the dataset's episodes it trained on (its first N; absent: all).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub episodes: Option<usize>,
    /// Episodes it trained on, by town.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub towns: BTreeMap<String, usize>,
    /// Episodes it trained on, by route (`dataset::format::RouteSpec::key`:
    /// `routes_town01.xml#3`, `random` for every random route): whether its data drove
    /// a scenario's route (the default scenario's must not be among them for the
    /// default model). Absent on cards written before 2026-12-07.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub routes: BTreeMap<String, usize>,
    /// Frames drawn in training (steps x batch), this stage's and those of every
    /// network it started from (`init`, or a retargeting stage's teacher, whose
    /// weights the student starts from); absent where a card on the way is lost.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames_seen: Option<u64>,
    /// The SHA-256 of the network it started from (`init`, or a retargeting stage's
    /// teacher) when the stage finished: the path alone may since name another network
    /// (a round of the chain publishes over its own init). Absent for a fresh start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_sha256: Option<String>,
    /// The SHA-256 of every shard and label file it trained on, by
    /// `<dataset folder>/<file>` (as `mrdrive data hashes` lists them).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub data_sha256: BTreeMap<String, String>,
    /// The SHA-256 of the published checkpoint (`<name>.safetensors` in the models
    /// folder, half precision), written when the run is published
    /// (`train::publish::publish`): absent on a run folder's own card.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checkpoint_sha256: Option<String>,
    /// The closed-loop learning curve that sized its data, as a file beside the
    /// published model and whose curve it is; absent where none was drawn.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learning_curve: Option<String>,
}

impl ModelCard {
    /// The card of a randomly initialised network.
    pub fn random_init(seed: u64) -> Self {
        ModelCard {
            trained: false,
            description: "randomly initialised network: NOT TRAINED, drives at random".into(),
            source: format!("burn initialisers, device seed {seed}"),
            training: None,
        }
    }

    /// The card of a network whose backbone was imported from `source`, a
    /// torchvision ResNet state dict, and whose heads are initialised (seed 0).
    pub fn torchvision_import(source: &Path) -> Self {
        ModelCard {
            trained: false,
            description: "backbone imported from a torchvision ResNet state dict; heads randomly initialised (seed 0): not a trained driving policy".into(),
            source: source.display().to_string(),
            training: None,
        }
    }
}

/// The JSON file beside the weights.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Manifest {
    format: String,
    config: PolicyConfig,
    card: ModelCard,
}

/// Why a checkpoint could not be saved or loaded.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// A file could not be read or written.
    #[error("{path}: {source}; fix: {fix}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
        /// What would fix it.
        fix: &'static str,
    },
    /// The JSON beside the weights is malformed or has a bad field.
    #[error("{path}: {problem}; fix: {fix}")]
    Manifest {
        /// The JSON file.
        path: PathBuf,
        /// What is wrong (names the field).
        problem: String,
        /// What would fix it.
        fix: String,
    },
    /// The weights file is unreadable or does not fit the network.
    #[error("{path}: {problem}; fix: {fix}")]
    Weights {
        /// The safetensors file.
        path: PathBuf,
        /// What is wrong (names the tensor).
        problem: String,
        /// What would fix it.
        fix: String,
    },
    /// The network's config is invalid.
    #[error(transparent)]
    Config(#[from] crate::model::ConfigError),
}

/// The JSON path of a checkpoint: the weights path with extension `.json`.
pub fn manifest_path(weights: &Path) -> PathBuf {
    weights.with_extension("json")
}

/// Saves `net` to `weights` (a `.safetensors` path) and its config + `card` beside it.
pub fn save(net: &PolicyNet, card: &ModelCard, weights: &Path) -> Result<(), CheckpointError> {
    net.sync_running_stats();
    let mut store = SafetensorsStore::from_file(weights)
        .overwrite(true)
        .metadata("mrdrive_format", FORMAT);
    let written = |problem: String| CheckpointError::Weights {
        path: weights.to_path_buf(),
        problem,
        fix: "check the folder exists and is writable".into(),
    };
    net.save_into(&mut store)
        .map_err(|e| written(format!("could not write: {e}")))?;
    // burn writes the metadata from a hash map, in a different order on every run.
    let mut bytes =
        std::fs::read(weights).map_err(|e| written(format!("could not read back: {e}")))?;
    sort_metadata(&mut bytes).map_err(written)?;
    std::fs::write(weights, bytes).map_err(|e| written(format!("could not write: {e}")))?;
    write_manifest(weights, &net.config, card)
}

/// Writes the JSON beside `weights` (its config and `card`), the weights untouched: a
/// card corrected after training keeps the network's SHA-256.
pub fn write_manifest(
    weights: &Path,
    config: &PolicyConfig,
    card: &ModelCard,
) -> Result<(), CheckpointError> {
    let manifest = Manifest {
        format: FORMAT.into(),
        config: config.clone(),
        card: card.clone(),
    };
    let json = serde_json::to_string_pretty(&manifest).expect("a manifest always serialises");
    let path = manifest_path(weights);
    std::fs::write(&path, json).map_err(|source| CheckpointError::Io {
        path,
        source,
        fix: "check the folder exists and is writable",
    })
}

/// Rewrites a safetensors file's header (`bytes` is the whole file) with its
/// `__metadata__` entries in key order, the header's length and the tensors unchanged,
/// so the same weights always give the same bytes (and the same SHA-256 in run records).
fn sort_metadata(bytes: &mut [u8]) -> Result<(), String> {
    let len = bytes
        .get(..8)
        .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")) as usize)
        .ok_or("no safetensors header")?;
    let header = bytes
        .get_mut(8..8 + len)
        .ok_or("a header past the file's end")?;
    let mut json: serde_json::Value =
        serde_json::from_slice(header).map_err(|e| format!("an unreadable header: {e}"))?;
    let Some(meta) = json.get_mut("__metadata__") else {
        return Ok(());
    };
    let sorted: std::collections::BTreeMap<String, serde_json::Value> =
        serde_json::from_value(meta.take()).map_err(|e| format!("metadata: {e}"))?;
    *meta = serde_json::Value::Object(sorted.into_iter().collect());
    let text = serde_json::to_vec(&json).expect("a header serialises");
    if text.len() > len {
        return Err(format!(
            "the sorted header grew from {len} to {} bytes",
            text.len()
        ));
    }
    header[..text.len()].copy_from_slice(&text);
    header[text.len()..].fill(b' ');
    Ok(())
}

/// Saves a network of `config` initialised on the CPU with device seed `seed`
/// to `weights`, with a card that says it is untrained (`mrdrive policy init`).
pub fn save_random_init(
    config: &PolicyConfig,
    seed: u64,
    weights: &Path,
) -> Result<(), CheckpointError> {
    config.validate()?;
    let device = Device::flex();
    device.seed(seed);
    save(
        &config.init(&device),
        &ModelCard::random_init(seed),
        weights,
    )
}

/// Saves to `weights` a network of `config` whose backbone comes from the
/// torchvision state dict `source` ([`load_torchvision_backbone`]) and whose
/// heads are initialised with seed 0 (`mrdrive policy import-torchvision`).
pub fn import_torchvision(
    source: &Path,
    prefix: &str,
    config: &PolicyConfig,
    weights: &Path,
) -> Result<(), CheckpointError> {
    let device = Device::flex();
    device.seed(0);
    let net = load_torchvision_backbone(source, prefix, config, &device)?;
    save(&net, &ModelCard::torchvision_import(source), weights)
}

/// Reads the JSON beside `weights`: the config (validated) and the card.
pub fn read_manifest(weights: &Path) -> Result<(PolicyConfig, ModelCard), CheckpointError> {
    let path = manifest_path(weights);
    let text = std::fs::read_to_string(&path).map_err(|source| CheckpointError::Io {
        path: path.clone(),
        source,
        fix: "a checkpoint is two files, NAME.safetensors and NAME.json; copy the .json with the weights",
    })?;
    let manifest: Manifest =
        serde_json::from_str(&text).map_err(|e| CheckpointError::Manifest {
            path: path.clone(),
            problem: format!("not a policy manifest ({e})"),
            fix: "restore the JSON written with the weights (fields: format, config, card)".into(),
        })?;
    if manifest.format != FORMAT {
        return Err(CheckpointError::Manifest {
            path,
            problem: format!("field `format` is {:?}", manifest.format),
            fix: format!("this build reads {FORMAT:?}"),
        });
    }
    manifest
        .config
        .validate()
        .map_err(|e| CheckpointError::Manifest {
            path,
            problem: e.to_string(),
            fix: "correct the config field named above".into(),
        })?;
    Ok((manifest.config, manifest.card))
}

/// Loads a checkpoint written by [`save`]: the JSON gives the network, the safetensors its weights.
pub fn load(weights: &Path, device: &Device) -> Result<(PolicyNet, ModelCard), CheckpointError> {
    let (config, card) = read_manifest(weights)?;
    let mut net = config.init(device);
    let mut store = open_weights(weights)?;
    apply(
        &mut net,
        &mut store,
        weights,
        |_| true,
        |_| false,
        |n| n.to_string(),
    )?;
    Ok((net, card))
}

fn open_weights(path: &Path) -> Result<SafetensorsStore, CheckpointError> {
    let bytes = std::fs::read(path).map_err(|source| CheckpointError::Io {
        path: path.to_path_buf(),
        source,
        fix: "give the path of an existing .safetensors file",
    })?;
    // A half-precision checkpoint is widened to the f32 the network computes in.
    let bytes = convert_floats(&bytes, safetensors::Dtype::F16, safetensors::Dtype::F32).map_err(
        |problem| CheckpointError::Weights {
            path: path.to_path_buf(),
            problem,
            fix: "give a checkpoint written by mrdrive (`mrdrive train`, `policy init`)".into(),
        },
    )?;
    Ok(SafetensorsStore::from_bytes(Some(bytes))
        .validate(false)
        .allow_partial(true))
}

/// Saves `net` like [`save`], its floating-point tensors in half precision (IEEE
/// binary16, rounded to nearest): half the bytes, for checkpoints kept in the
/// repository. [`load`] widens them back to f32; a value keeps about 3 significant
/// digits (relative error at most 2^-11 for normal values).
pub fn save_f16(net: &PolicyNet, card: &ModelCard, weights: &Path) -> Result<(), CheckpointError> {
    save(net, card, weights)?;
    write_f16(weights, weights)
}

/// Writes the checkpoint `weights` to `to` in half precision (as [`save_f16`] would
/// have saved it; a file already in half precision is copied as it is), through a
/// temporary file beside `to` renamed at the end, so `to` is never half written. The
/// card beside it is not touched: copy it with the weights.
pub fn write_f16(weights: &Path, to: &Path) -> Result<(), CheckpointError> {
    let fail = |path: &Path, problem: String, fix: &str| CheckpointError::Weights {
        path: path.to_path_buf(),
        problem,
        fix: fix.into(),
    };
    let read_fix = "give a checkpoint written by mrdrive (`mrdrive train`, `policy init`)";
    let bytes = std::fs::read(weights)
        .map_err(|e| fail(weights, format!("could not read: {e}"), read_fix))?;
    let half = convert_floats(&bytes, safetensors::Dtype::F32, safetensors::Dtype::F16)
        .map_err(|problem| fail(weights, problem, read_fix))?;
    let tmp = to.with_extension("safetensors.partial");
    std::fs::write(&tmp, half)
        .and_then(|()| std::fs::rename(&tmp, to))
        .map_err(|e| {
            fail(
                to,
                format!("could not write: {e}"),
                "check the folder exists and is writable",
            )
        })
}

/// A safetensors file (`bytes`) with every tensor of dtype `from` (F32 or F16) stored
/// as `to` (F16 or F32), the metadata kept in key order; the bytes unchanged when it
/// holds no tensor of `from`.
fn convert_floats(
    bytes: &[u8],
    from: safetensors::Dtype,
    to: safetensors::Dtype,
) -> Result<Vec<u8>, String> {
    use safetensors::{Dtype, SafeTensors, tensor::TensorView};
    let file = SafeTensors::deserialize(bytes).map_err(|e| format!("unreadable: {e}"))?;
    if file.tensors().iter().all(|(_, t)| t.dtype() != from) {
        return Ok(bytes.to_vec());
    }
    let (_, meta) = SafeTensors::read_metadata(bytes).map_err(|e| format!("unreadable: {e}"))?;
    let mut data: Vec<(String, Dtype, Vec<usize>, Vec<u8>)> = Vec::new();
    for (name, t) in file.tensors() {
        let raw = t.data();
        let converted: Vec<u8> = match (t.dtype() == from, from, to) {
            (false, _, _) => raw.to_vec(),
            (true, Dtype::F32, Dtype::F16) => raw
                .chunks_exact(4)
                .flat_map(|c| {
                    let v = f32::from_le_bytes(c.try_into().expect("4 bytes"));
                    half::f16::from_f32(v).to_le_bytes()
                })
                .collect(),
            (true, Dtype::F16, Dtype::F32) => raw
                .chunks_exact(2)
                .flat_map(|c| {
                    let v = half::f16::from_le_bytes(c.try_into().expect("2 bytes"));
                    v.to_f32().to_le_bytes()
                })
                .collect(),
            (true, _, _) => return Err(format!("cannot convert {from:?} to {to:?}")),
        };
        let dtype = if t.dtype() == from { to } else { t.dtype() };
        data.push((name, dtype, t.shape().to_vec(), converted));
    }
    let views: Vec<(String, TensorView<'_>)> = data
        .iter()
        .map(|(name, dtype, shape, raw)| {
            TensorView::new(*dtype, shape.clone(), raw)
                .map(|v| (name.clone(), v))
                .map_err(|e| format!("tensor {name}: {e}"))
        })
        .collect::<Result<_, _>>()?;
    let metadata = meta.metadata().clone();
    let mut out = safetensors::serialize(views, metadata).map_err(|e| format!("{e}"))?;
    sort_metadata(&mut out)?;
    Ok(out)
}

/// Applies the store to `net`; every tensor `required` must be present, every unused tensor
/// not `ignorable` is an error.
fn apply(
    net: &mut PolicyNet,
    store: &mut SafetensorsStore,
    path: &Path,
    required: impl Fn(&str) -> bool,
    ignorable: impl Fn(&str) -> bool,
    describe: impl Fn(&str) -> String,
) -> Result<(), CheckpointError> {
    let err = |problem: String, fix: &str| CheckpointError::Weights {
        path: path.to_path_buf(),
        problem,
        fix: fix.into(),
    };
    let result = net.load_from(store).map_err(|e| {
        err(
            format!("not a readable safetensors file ({e})"),
            "re-export the weights as safetensors",
        )
    })?;
    if let Some(e) = result.errors.first() {
        let what = match e {
            ApplyError::ShapeMismatch {
                path,
                expected,
                found,
            } => format!(
                "tensor `{}` has shape {:?}, the network expects {:?}",
                describe(path),
                found.as_slice(),
                expected.as_slice()
            ),
            ApplyError::DTypeMismatch {
                path,
                expected,
                found,
            } => {
                format!(
                    "tensor `{}` is {found:?}, the network expects {expected:?}",
                    describe(path)
                )
            }
            other => format!("{other}"),
        };
        return Err(err(
            format!("{what} ({} tensor error(s) in all)", result.errors.len()),
            "the weights are for another network shape: use the JSON config they were saved with",
        ));
    }
    let missing: Vec<&str> = result
        .missing
        .iter()
        .map(|(p, _)| p.as_str())
        .filter(|p| required(p))
        .collect();
    if let Some(first) = missing.first() {
        return Err(err(
            format!(
                "tensor `{}` is missing ({} missing in all)",
                describe(first),
                missing.len()
            ),
            "the weights are for another network (depth, widths or scales): use matching weights and config",
        ));
    }
    let unused: Vec<&String> = result.unused.iter().filter(|p| !ignorable(p)).collect();
    if let Some(first) = unused.first() {
        return Err(err(
            format!(
                "tensor `{first}` does not belong to this network ({} such in all)",
                unused.len()
            ),
            "the weights are for another network (depth, widths or scales): use matching weights and config",
        ));
    }
    Ok(())
}

/// Loads a torchvision ResNet state dict saved as safetensors (`conv1.weight`,
/// `bn1.running_mean`, `layer1.0.conv1.weight`, `layer2.0.downsample.1.weight`, ...)
/// into the backbone of a network built from `config`; every BN goes into every
/// branch. Keys may carry a `prefix` (e.g. `"backbone_wide."` for WoR's state dict);
/// `fc.*` and `num_batches_tracked` are ignored; the heads stay as initialised.
pub fn load_torchvision_backbone(
    weights: &Path,
    prefix: &str,
    config: &PolicyConfig,
    device: &Device,
) -> Result<PolicyNet, CheckpointError> {
    config.validate().map_err(|e| CheckpointError::Weights {
        path: weights.to_path_buf(),
        problem: e.to_string(),
        fix: "fix the config field named above".into(),
    })?;
    let single_cfg = config.clone().with_scales(vec![1.0]);
    let mut single = single_cfg.init(device);
    let p = regex_escape(prefix);
    let bn = |from: &str, to: &str| -> Vec<(String, String)> {
        [
            ("weight", "gamma"),
            ("bias", "beta"),
            ("running_mean", "running_mean"),
            ("running_var", "running_var"),
        ]
        .iter()
        .map(|(a, b)| (format!("^{p}{from}\\.{a}$"), format!("{to}.branches.0.{b}")))
        .collect()
    };
    let mut patterns = vec![
        (
            format!("^{p}conv1\\.weight$"),
            "backbone.conv1.weight".to_string(),
        ),
        (
            format!("^{p}(layer\\d)\\.(\\d+)\\.conv(\\d)\\.weight$"),
            "backbone.$1.$2.conv$3.weight".to_string(),
        ),
        (
            format!("^{p}(layer\\d)\\.(\\d+)\\.downsample\\.0\\.weight$"),
            "backbone.$1.$2.downsample.conv.weight".to_string(),
        ),
    ];
    patterns.extend(bn("bn1", "backbone.bn1"));
    patterns.extend(bn("(layer\\d)\\.(\\d+)\\.bn(\\d)", "backbone.$1.$2.bn$3"));
    patterns.extend(bn(
        "(layer\\d)\\.(\\d+)\\.downsample\\.1",
        "backbone.$1.$2.downsample.bn",
    ));
    let remapper = KeyRemapper::from_patterns(patterns).expect("the patterns are valid regexes");
    let mut store = open_weights(weights)?.remap(remapper);
    let fc = format!("{prefix}fc.");
    apply(
        &mut single,
        &mut store,
        weights,
        |name| name.starts_with("backbone."),
        |name| {
            name.ends_with("num_batches_tracked")
                || name.starts_with(&fc)
                || !name.starts_with(prefix)
        },
        |ours| format!("{prefix}{}", torchvision_name(ours)),
    )?;
    if config.scales.len() == 1 {
        let mut net = single;
        net.config = config.clone();
        return Ok(net);
    }
    single
        .to_multires(config.scales.clone())
        .map_err(|e| CheckpointError::Weights {
            path: weights.to_path_buf(),
            problem: e.to_string(),
            fix: "fix the config field named above".into(),
        })
}

/// The torchvision name of one of our backbone tensors (`backbone.layer2.0.downsample.bn.branches.0.gamma`
/// -> `layer2.0.downsample.1.weight`).
pub fn torchvision_name(ours: &str) -> String {
    let s = ours.strip_prefix("backbone.").unwrap_or(ours);
    let s = s
        .replace("downsample.conv.", "downsample.0.")
        .replace("downsample.bn.", "downsample.1.");
    let s = s
        .replace(".branches.0.gamma", ".weight")
        .replace(".branches.0.beta", ".bias");
    s.replace(".branches.0.", ".")
}

fn regex_escape(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c.to_string()
            } else {
                format!("\\{c}")
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backbone::Depth;

    fn tiny() -> PolicyConfig {
        PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(64)
            .with_input_width(96)
    }

    fn logits(net: &PolicyNet, device: &Device) -> TensorData {
        let x = Tensor::<4>::ones([1, 3, 64, 96], device);
        net.valid().forward(x, 1, false).action_logits.into_data()
    }

    #[test]
    fn save_then_load_gives_the_same_network_and_card() {
        let device = Device::flex();
        device.seed(5);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.safetensors");
        let net = tiny().init(&device);
        save(&net, &ModelCard::random_init(5), &path).unwrap();
        // Saving again overwrites.
        save(&net, &ModelCard::random_init(5), &path).unwrap();
        // The same weights, the same bytes (burn's metadata map has no fixed order).
        let again = dir.path().join("again.safetensors");
        save(&net, &ModelCard::random_init(5), &again).unwrap();
        assert!(std::fs::read(&path).unwrap() == std::fs::read(&again).unwrap());
        let (back, card) = load(&path, &device).unwrap();
        assert_eq!(card, ModelCard::random_init(5));
        assert!(!card.trained);
        assert_eq!(back.config, net.config);
        assert_eq!(logits(&net, &device), logits(&back, &device));
        // A random init by seed says so on its card (that the seed alone fixes
        // its weights is tested in its own process, policy/tests/random_init.rs:
        // the backend's random stream is shared by the threads of this test binary).
        let init = dir.path().join("init.safetensors");
        save_random_init(&tiny(), 5, &init).unwrap();
        let (back, card) = load(&init, &device).unwrap();
        assert_eq!(card, ModelCard::random_init(5));
        assert_eq!(back.config, tiny());
        let bad = tiny().with_scales(Vec::new());
        assert!(save_random_init(&bad, 5, &init).is_err());
    }

    #[test]
    fn a_half_precision_checkpoint_is_half_the_size_and_loads_as_f32() {
        let device = Device::flex();
        device.seed(6);
        let dir = tempfile::tempdir().unwrap();
        let (full, half) = (
            dir.path().join("f.safetensors"),
            dir.path().join("h.safetensors"),
        );
        let net = tiny().init(&device);
        save(&net, &ModelCard::random_init(6), &full).unwrap();
        save_f16(&net, &ModelCard::random_init(6), &half).unwrap();
        let (a, b) = (std::fs::read(&full).unwrap(), std::fs::read(&half).unwrap());
        assert!(
            b.len() * 10 < a.len() * 6,
            "{} vs {} bytes",
            b.len(),
            a.len()
        );
        let file = safetensors::SafeTensors::deserialize(&b).unwrap();
        assert!(
            file.tensors()
                .iter()
                .any(|(_, t)| t.dtype() == safetensors::Dtype::F16)
        );
        assert!(
            file.tensors()
                .iter()
                .all(|(_, t)| t.dtype() != safetensors::Dtype::F32)
        );
        // Every weight within f16's rounding of the f32 one; the same file twice.
        let (back, card) = load(&half, &device).unwrap();
        assert_eq!(card, ModelCard::random_init(6));
        let widened = dir.path().join("w.safetensors");
        save(&back, &card, &widened).unwrap();
        let w = std::fs::read(&widened).unwrap();
        let wf = safetensors::SafeTensors::deserialize(&w).unwrap();
        let mut n = 0;
        let orig = safetensors::SafeTensors::deserialize(&a).unwrap();
        for (name, t) in file.tensors() {
            let (o, r) = (orig.tensor(&name).unwrap(), wf.tensor(&name).unwrap());
            if o.dtype() != safetensors::Dtype::F32 {
                continue;
            }
            assert_eq!(t.shape(), o.shape());
            for (x, y) in o.data().chunks_exact(4).zip(r.data().chunks_exact(4)) {
                let (x, y) = (
                    f32::from_le_bytes(x.try_into().unwrap()),
                    f32::from_le_bytes(y.try_into().unwrap()),
                );
                assert!((x - y).abs() <= x.abs() * 1e-3 + 1e-7, "{name}: {x} vs {y}");
                n += 1;
            }
        }
        let orig = safetensors::SafeTensors::deserialize(&a).unwrap();
        let f32s: usize = orig
            .tensors()
            .iter()
            .filter(|(_, t)| t.dtype() == safetensors::Dtype::F32)
            .map(|(_, t)| t.data().len() / 4)
            .sum();
        assert_eq!(n, f32s);
        save_f16(&net, &ModelCard::random_init(6), &widened).unwrap();
        assert!(std::fs::read(&widened).unwrap() == b);
    }

    /// The record of `models/ra.json`, with a stopped-vehicle repeat of 3.
    fn ra_record() -> TrainingRecord {
        TrainingRecord {
            stage: "ra".into(),
            data: "data/retarget".into(),
            samples_in_data: 39444,
            steps: 600,
            batch: 32,
            seed: 1,
            lr: 0.00015,
            losses: "see losses.csv beside the run".into(),
            wall_s: 2047.006782124,
            machine: "Intel(R) Xeon(R) Processor, 2 cores".into(),
            init: None,
            sampling: crate::train::loader::Sampling {
                balanced: true,
                start_repeat: 8,
                stopped_vehicle_repeat: 3,
                ..Default::default()
            },
            build: String::new(),
            episodes: None,
            towns: BTreeMap::new(),
            routes: BTreeMap::new(),
            frames_seen: None,
            start_sha256: None,
            data_sha256: BTreeMap::new(),
            checkpoint_sha256: None,
            learning_curve: None,
        }
    }

    #[test]
    fn a_training_record_keeps_its_json_layout() {
        // The sampling fields sit flat after the others, as in every checkpoint's card.
        let want = r#"{
  "stage": "ra",
  "data": "data/retarget",
  "samples_in_data": 39444,
  "steps": 600,
  "batch": 32,
  "seed": 1,
  "lr": 0.00015,
  "losses": "see losses.csv beside the run",
  "wall_s": 2047.006782124,
  "machine": "Intel(R) Xeon(R) Processor, 2 cores",
  "balanced": true,
  "standing_keep": 1.0,
  "start_repeat": 8,
  "pedestrian_repeat": 1,
  "stopped_vehicle_repeat": 3
}"#;
        assert_eq!(serde_json::to_string_pretty(&ra_record()).unwrap(), want);
        let with_init = TrainingRecord {
            init: Some("models/original.safetensors".into()),
            ..ra_record()
        };
        let json = serde_json::to_string_pretty(&with_init).unwrap();
        assert!(json.contains(
            "\"machine\": \"Intel(R) Xeon(R) Processor, 2 cores\",\n  \"init\": \"models/original.safetensors\",\n  \"balanced\": true,"
        ), "{json}");
        assert_eq!(
            serde_json::from_str::<TrainingRecord>(&json).unwrap(),
            with_init
        );
        // A card written before a sampling field existed reads it as WoR's (once).
        let old = want.replace(",\n  \"stopped_vehicle_repeat\": 3", "");
        let back: TrainingRecord = serde_json::from_str(&old).unwrap();
        assert_eq!(back.sampling.stopped_vehicle_repeat, 1);
    }

    #[test]
    fn the_metadata_is_written_in_key_order_and_nothing_else_moves() {
        let header = br#"{"__metadata__":{"z":"1","a":"2","m":"3"},"t":{"dtype":"F32","shape":[1],"data_offsets":[0,4]}}    "#;
        let mut file = (header.len() as u64).to_le_bytes().to_vec();
        file.extend_from_slice(header);
        file.extend_from_slice(&1.5f32.to_le_bytes());
        let before = file.clone();
        sort_metadata(&mut file).unwrap();
        assert_eq!(file.len(), before.len());
        assert_eq!(file[..8], before[..8], "the header's length");
        assert_eq!(
            file[file.len() - 4..],
            before[before.len() - 4..],
            "the tensor"
        );
        let text = std::str::from_utf8(&file[8..8 + header.len()]).unwrap();
        assert!(
            text.starts_with(r#"{"__metadata__":{"a":"2","m":"3","z":"1"},"t":"#),
            "{text}"
        );
        // Sorting again changes nothing.
        let sorted = file.clone();
        sort_metadata(&mut file).unwrap();
        assert_eq!(file, sorted);
    }

    #[test]
    fn bad_checkpoints_name_file_field_and_fix() {
        let device = Device::flex();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.safetensors");
        let net = tiny().init(&device);
        save(&net, &ModelCard::random_init(0), &path).unwrap();

        // Missing JSON.
        let lone = dir.path().join("lone.safetensors");
        std::fs::copy(&path, &lone).unwrap();
        let e = load(&lone, &device).unwrap_err().to_string();
        assert!(e.contains("lone.json") && e.contains("fix"), "{e}");

        // A config field out of range.
        let json = std::fs::read_to_string(manifest_path(&path)).unwrap();
        std::fs::write(manifest_path(&path), json.replace("0.75", "-0.75")).unwrap();
        let e = load(&path, &device).unwrap_err().to_string();
        assert!(e.contains("p.json") && e.contains("`scales`"), "{e}");

        // Weights of another shape: the JSON says wider than the file holds.
        let mut wider = tiny();
        wider.widths = [4, 8, 8, 24];
        let m = Manifest {
            format: FORMAT.into(),
            config: wider,
            card: ModelCard::random_init(0),
        };
        std::fs::write(manifest_path(&path), serde_json::to_string(&m).unwrap()).unwrap();
        let e = load(&path, &device).unwrap_err().to_string();
        assert!(e.contains("p.safetensors") && e.contains("layer4"), "{e}");

        // Garbage weights.
        std::fs::write(
            manifest_path(&path),
            serde_json::to_string(&Manifest {
                config: tiny(),
                ..m
            })
            .unwrap(),
        )
        .unwrap();
        std::fs::write(&path, b"not safetensors").unwrap();
        let e = load(&path, &device).unwrap_err().to_string();
        assert!(
            e.contains("p.safetensors") && e.contains("safetensors"),
            "{e}"
        );

        // Missing weights.
        let e = load(&dir.path().join("none.safetensors"), &device)
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.json"), "{e}");
    }
}
