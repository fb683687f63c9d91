//! The policy as a `Driver`: the image at the selector's scale in, a control out.

use crate::checkpoint::{self, CheckpointError, ModelCard};
use crate::device::{DeviceError, DeviceKind};
use crate::fused::FusedPolicy;
use crate::model::PolicyNet;
use crate::trigger::{Trigger, TriggerError, command_logits};
use burn::prelude::*;
use dataset::action::{NUM_ACTIONS, NUM_SPEED_BINS};
use dataset::decode::{Decoded, decode};
use sim::build::{DriverFactory, FactoryError};
use sim::driver::{Driver, DriverNeeds, Observation, VehicleControl};
use sim::runner::Prepared;
use sim::scenario::Scenario;
use std::path::Path;

/// A multi-resolution CNN policy driving the ego.
///
/// Each observation must carry the stitched rig image rendered at
/// `obs.scale` (the renderer draws at the chosen scale, nothing is resized
/// here); the BN branch of that scale is used. Inference runs in validation
/// mode (BN running statistics). On the CPU it goes through the fused path
/// ([`FusedPolicy`]: same logits as burn's forward to 1e-4, 3x faster),
/// deterministic for a fixed thread count; on a GPU device through burn.
#[derive(Debug)]
pub struct PolicyDriver {
    net: PolicyNet,
    device: Device,
    /// The CPU inference path (None on a GPU device).
    fused: Option<FusedPolicy>,
    name: String,
    card: ModelCard,
    /// The last decoding (for logs), if any.
    pub last: Option<Decoded>,
    warned: bool,
    /// A learned trigger read on each frame's pooled feature (CPU only).
    trigger: Option<Trigger>,
    /// The trigger's probability on the last frame.
    hint: Option<f32>,
    /// The checkpoint file and its digest, for run records.
    checkpoint: Option<sim::record::CheckpointId>,
    /// The trigger file and its digest, for run records.
    trigger_file: Option<sim::record::CheckpointId>,
}

impl PolicyDriver {
    /// A driver from a network (put into validation mode) and its card.
    pub fn new(net: PolicyNet, card: ModelCard, name: impl Into<String>, device: Device) -> Self {
        net.sync_running_stats();
        let net = net.valid();
        let fused = (device == Device::flex()).then(|| FusedPolicy::from_net(&net));
        PolicyDriver {
            net,
            device,
            fused,
            name: name.into(),
            card,
            last: None,
            warned: false,
            trigger: None,
            hint: None,
            checkpoint: None,
            trigger_file: None,
        }
    }

    /// Reads `trigger` (the file at `path`) on every frame, for the `learned`
    /// selector ([`Driver::scale_hint`]). It needs the fused CPU path and a
    /// trigger made for this network's features and scales, fit on this very
    /// checkpoint (its SHA-256) where the network was read from one.
    pub fn with_trigger(mut self, trigger: Trigger, path: &Path) -> Result<Self, TriggerError> {
        let Some(f) = &self.fused else {
            return Err(TriggerError::Misfit {
                path: path.to_path_buf(),
                field: "driver.device",
                why: "the trigger reads the fused CPU path's features".into(),
                fix: "drive the policy on the CPU (driver.device = \"cpu\")".into(),
            });
        };
        trigger.check_fits(path, f.feature_dim(), &self.net.config.scales)?;
        if let Some(net) = &self.checkpoint
            && trigger.card.checkpoint_sha256.as_ref() != Some(&net.sha256)
        {
            let short = |d: &str| d.chars().take(12).collect::<String>();
            return Err(TriggerError::Misfit {
                path: path.to_path_buf(),
                field: "card.checkpoint_sha256",
                why: match &trigger.card.checkpoint_sha256 {
                    Some(d) => format!(
                        "it was fit on the network {}..., but {} is {}...",
                        short(d),
                        net.file,
                        short(&net.sha256)
                    ),
                    None => "it does not say which network it was fit on (a file from \
                             before 2026-12-07)"
                        .to_string(),
                },
                fix: format!(
                    "fit it again on this network: mrdrive policy trigger --checkpoint {} \
                     --data DIR --out {}",
                    net.file,
                    path.display()
                ),
            });
        }
        self.name = format!("{}+trigger:{}", self.name, path.display());
        self.trigger = Some(trigger);
        Ok(self)
    }

    /// Reads the trigger file at `path` and drives with it as
    /// [`PolicyDriver::with_trigger`] does; its run records name the file
    /// and its digest ([`Driver::trigger`]).
    pub fn with_trigger_file(self, path: &Path) -> Result<Self, TriggerError> {
        let (trigger, id) = Trigger::load_identified(path)?;
        let mut driver = self.with_trigger(trigger, path)?;
        driver.trigger_file = Some(id);
        Ok(driver)
    }

    /// Loads a checkpoint (NAME.safetensors + NAME.json); the driver is named after the file.
    pub fn from_checkpoint(weights: &Path, device: Device) -> Result<Self, CheckpointError> {
        let (net, card) = checkpoint::load(weights, &device)?;
        if net.config.num_speed_bins != NUM_SPEED_BINS {
            return Err(CheckpointError::Manifest {
                path: checkpoint::manifest_path(weights),
                problem: format!(
                    "config.num_speed_bins = {}, but the driver decodes WoR's {NUM_SPEED_BINS} speed bins",
                    net.config.num_speed_bins
                ),
                fix: "train the policy with 4 speed bins (the default)".into(),
            });
        }
        let mut driver = Self::new(net, card, String::new(), device);
        // The name goes into result records: say where inference ran.
        let engine = if driver.is_fused() {
            "cpu, fused".to_string()
        } else {
            format!("burn, {:?}", driver.device)
        };
        driver.name = format!("policy:{} ({engine})", weights.display());
        let id = sim::record::CheckpointId::of(weights).map_err(|source| CheckpointError::Io {
            path: weights.to_path_buf(),
            source,
            fix: "check that the checkpoint file is readable",
        })?;
        driver.checkpoint = Some(id);
        Ok(driver)
    }

    /// Runs inference through burn's forward even on the CPU (for comparisons with the fused path).
    pub fn with_burn_forward(mut self) -> Self {
        self.fused = None;
        self
    }

    /// Whether inference goes through the fused CPU path.
    pub fn is_fused(&self) -> bool {
        self.fused.is_some()
    }

    /// The checkpoint's card (trained or not, where it came from).
    pub fn card(&self) -> &ModelCard {
        &self.card
    }

    /// The network.
    pub fn net(&self) -> &PolicyNet {
        &self.net
    }

    /// The scales this policy has BN branches for.
    pub fn scales(&self) -> &[f32] {
        &self.net.config.scales
    }

    /// The 28 logits for the observation's command at its speed, for an RGB8 image at scale `scale`.
    pub fn logits(
        &self,
        image: &sim::driver::RgbImage,
        scale: f32,
        command: usize,
        speed_mps: f32,
    ) -> [f32; NUM_ACTIONS] {
        self.infer(image, scale, command, speed_mps).0
    }

    /// The logits of [`PolicyDriver::logits`] and, with a trigger, its
    /// probability on the frame's pooled feature.
    fn infer(
        &self,
        image: &sim::driver::RgbImage,
        scale: f32,
        command: usize,
        speed_mps: f32,
    ) -> ([f32; NUM_ACTIONS], Option<f32>) {
        let cfg = &self.net.config;
        let branch = cfg
            .branch_of(scale)
            .unwrap_or_else(|| nearest_branch(&cfg.scales, scale));
        let (h, w) = (image.height as usize, image.width as usize);
        let mut hint = None;
        let all = match &self.fused {
            Some(f) => {
                let features = f.features(&f.normalize(&image.data, h, w), branch);
                hint = self.trigger.as_ref().map(|t| t.p_high(&features));
                f.action_logits(&features)
            }
            None => {
                let x = cfg.normalize_rgb8(&image.data, h, w);
                let x = Tensor::<4>::from_data(TensorData::new(x, [1, 3, h, w]), &self.device);
                self.net
                    .forward(x, branch, false)
                    .action_logits
                    .into_data()
                    .try_to_vec::<f32>()
                    .expect("f32 logits")
            }
        };
        (command_logits(&all, command, speed_mps), hint)
    }
}

/// Builds the [`PolicyDriver`] a scenario names (`driver.kind = "policy"`,
/// `driver.checkpoint`, `driver.device`): register it with
/// `sim::build::Drivers::with(DriverKind::Policy, PolicyFactory)`.
#[derive(Debug, Clone, Copy, Default)]
pub struct PolicyFactory;

/// A scenario's policy driver could not be built.
#[derive(Debug, thiserror::Error)]
pub enum PolicyDriverError {
    /// No checkpoint is named.
    #[error(
        "driver.checkpoint is missing; fix: a policy driver needs `checkpoint = \"path/to/model.safetensors\"`"
    )]
    NoCheckpoint,
    /// The device named cannot be opened.
    #[error("driver.device")]
    Device(#[source] DeviceError),
    /// The checkpoint cannot be used.
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    /// The trigger cannot be used.
    #[error(transparent)]
    Trigger(#[from] TriggerError),
}

impl PolicyFactory {
    fn checkpoint(scenario: &Scenario) -> Result<&Path, PolicyDriverError> {
        scenario
            .driver
            .checkpoint
            .as_deref()
            .ok_or(PolicyDriverError::NoCheckpoint)
    }
}

impl DriverFactory for PolicyFactory {
    fn driver(
        &self,
        scenario: &Scenario,
        _prepared: &Prepared,
    ) -> Result<Box<dyn Driver>, FactoryError> {
        let weights = Self::checkpoint(scenario)?;
        let kind: DeviceKind = scenario
            .driver
            .device
            .as_deref()
            .unwrap_or("cpu")
            .parse()
            .map_err(PolicyDriverError::Device)?;
        let device = crate::device::open(kind).map_err(PolicyDriverError::Device)?;
        let driver = PolicyDriver::from_checkpoint(weights, device)?;
        Ok(Box::new(match &scenario.driver.trigger {
            Some(path) => driver
                .with_trigger_file(path)
                .map_err(PolicyDriverError::Trigger)?,
            None => driver,
        }))
    }

    fn input_size(&self, scenario: &Scenario) -> Result<Option<(u32, u32)>, FactoryError> {
        let (config, _) = checkpoint::read_manifest(Self::checkpoint(scenario)?)?;
        let [h, w] = config.input_size(1.0);
        Ok(Some((h as u32, w as u32)))
    }
}

fn nearest_branch(scales: &[f32], scale: f32) -> usize {
    (0..scales.len())
        .min_by(|&a, &b| {
            (scales[a] - scale)
                .abs()
                .total_cmp(&(scales[b] - scale).abs())
        })
        .expect("a policy has at least one scale")
}

impl Driver for PolicyDriver {
    fn name(&self) -> String {
        self.name.clone()
    }

    fn checkpoint(&self) -> Option<sim::record::CheckpointId> {
        self.checkpoint.clone()
    }

    fn trigger(&self) -> Option<sim::record::CheckpointId> {
        self.trigger_file.clone()
    }

    fn needs(&self) -> DriverNeeds {
        DriverNeeds {
            camera: true,
            privileged: false,
            labels: false,
        }
    }

    fn act(&mut self, obs: &Observation<'_>) -> VehicleControl {
        let Some(image) = obs.image else {
            if !self.warned {
                tracing::warn!("{}: observation without an image; braking", self.name);
                self.warned = true;
            }
            return VehicleControl {
                steer: 0.0,
                throttle: 0.0,
                brake: 1.0,
            };
        };
        let expected = self.net.config.input_size(obs.scale);
        if !self.warned
            && ([image.height as usize, image.width as usize] != expected
                || self.net.config.branch_of(obs.scale).is_none())
        {
            tracing::warn!(
                "{}: image {}x{} at scale {} but the policy expects {}x{} and scales {:?}; using the nearest branch",
                self.name,
                image.width,
                image.height,
                obs.scale,
                expected[1],
                expected[0],
                self.net.config.scales
            );
            self.warned = true;
        }
        let (logits, hint) = self.infer(image, obs.scale, obs.command as usize, obs.speed_mps);
        let d = decode(&logits, obs.speed_mps, obs.command);
        self.last = Some(d);
        self.hint = hint;
        d.control
    }

    fn scale_hint(&self) -> Option<f32> {
        self.hint
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backbone::Depth;
    use crate::model::PolicyConfig;
    use crate::trigger::{TRIGGER_FORMAT, TriggerCard};
    use sim::driver::Command;
    use sim::render::image::test_pattern;

    #[test]
    fn drives_at_each_scale_deterministically() {
        let device = Device::flex();
        device.seed(9);
        let cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(64)
            .with_input_width(96);
        let net = cfg.init(&device);
        let mut a = PolicyDriver::new(net.clone(), ModelCard::random_init(9), "a", device.clone());
        let mut b = PolicyDriver::new(net, ModelCard::random_init(9), "b", device.clone());
        assert!(a.needs().camera);
        for scale in [0.75f32, 1.0] {
            let [h, w] = cfg.input_size(scale);
            let img = test_pattern(w as u32, h as u32, 3);
            let obs = Observation {
                time_s: 0.0,
                speed_mps: 2.0,
                command: Command::LaneFollow,
                scale,
                image: Some(&img),
                labels: None,
                privileged: None,
            };
            let ca = a.act(&obs);
            assert_eq!(ca, b.act(&obs));
            assert_eq!(ca, a.act(&obs));
            assert!((-1.0..=1.0).contains(&ca.steer) && (0.0..=1.0).contains(&ca.throttle));
        }
        // The branch follows the scale: the same image through the two branches differs once
        // their BN statistics differ.
        let mut net = a.net().clone();
        let bn = &mut net.backbone.bn1.branches[0];
        bn.running_mean =
            burn::module::RunningState::new(bn.running_mean.value_sync().add_scalar(0.5));
        let c = PolicyDriver::new(net, ModelCard::random_init(9), "c", device);
        let img = test_pattern(96, 64, 1);
        assert_ne!(c.logits(&img, 0.75, 3, 2.0), c.logits(&img, 1.0, 3, 2.0));
        assert_eq!(a.logits(&img, 0.75, 3, 2.0), a.logits(&img, 1.0, 3, 2.0));
    }

    #[test]
    fn a_trigger_gives_a_hint_on_the_fused_path_only() {
        let device = Device::flex();
        device.seed(11);
        let cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(64)
            .with_input_width(96);
        let net = cfg.init(&device);
        // Zero weights: p = sigmoid(bias) on any feature.
        let trigger = |d: usize| Trigger {
            format: TRIGGER_FORMAT.into(),
            low: 0.75,
            high: 1.0,
            mean: vec![0.0; d],
            std: vec![1.0; d],
            weights: vec![0.0; d],
            bias: 2.0,
            card: TriggerCard::new("c".into(), "d".into(), 1),
        };
        let path = Path::new("t.json");
        let plain = PolicyDriver::new(net.clone(), ModelCard::random_init(11), "p", device.clone());
        assert_eq!(plain.scale_hint(), None);
        let mut d = plain.with_trigger(trigger(16), path).unwrap();
        assert_eq!(d.scale_hint(), None, "no frame seen yet");
        let img = test_pattern(96, 64, 2);
        let obs = Observation {
            time_s: 0.0,
            speed_mps: 2.0,
            command: Command::LaneFollow,
            scale: 1.0,
            image: Some(&img),
            labels: None,
            privileged: None,
        };
        d.act(&obs);
        let p = d.scale_hint().unwrap();
        assert!((p - 1.0 / (1.0 + (-2.0f32).exp())).abs() < 1e-6, "{p}");
        // A trigger for another feature size, or on burn's forward, is refused by field.
        let other = PolicyDriver::new(net.clone(), ModelCard::random_init(11), "o", device.clone());
        let e = other
            .with_trigger(trigger(8), path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("field `weights`"), "{e}");
        let burn =
            PolicyDriver::new(net, ModelCard::random_init(11), "b", device).with_burn_forward();
        let e = burn
            .with_trigger(trigger(16), path)
            .unwrap_err()
            .to_string();
        assert!(e.contains("driver.device"), "{e}");
    }

    #[test]
    fn fused_and_burn_forward_give_the_same_logits() {
        let device = Device::flex();
        device.seed(10);
        let cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(64)
            .with_input_width(96);
        let net = cfg.init(&device);
        let fused = PolicyDriver::new(net.clone(), ModelCard::random_init(10), "f", device.clone());
        let plain =
            PolicyDriver::new(net, ModelCard::random_init(10), "b", device).with_burn_forward();
        assert!(fused.is_fused() && !plain.is_fused());
        for scale in [0.75f32, 1.0] {
            let [h, w] = cfg.input_size(scale);
            let img = test_pattern(w as u32, h as u32, 5);
            for command in 0..6 {
                let a = fused.logits(&img, scale, command, 3.0);
                let b = plain.logits(&img, scale, command, 3.0);
                for (p, q) in a.iter().zip(&b) {
                    assert!(
                        (p - q).abs() < 1e-4,
                        "scale {scale} command {command}: {a:?} vs {b:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_checkpoint_with_other_speed_bins_is_refused_by_name() {
        let device = Device::flex();
        let cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(64)
            .with_input_width(96)
            .with_num_speed_bins(3);
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("bins3.safetensors");
        checkpoint::save(&cfg.init(&device), &ModelCard::random_init(0), &path).unwrap();
        let e = PolicyDriver::from_checkpoint(&path, device)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bins3.json") && e.contains("num_speed_bins = 3"),
            "{e}"
        );
    }

    #[test]
    fn the_factory_builds_a_scenario_policy_and_gives_the_rig_its_s0() {
        use sim::build::{Drivers, error_chain, rig_for};
        use sim::scenario::DriverKind;
        let device = Device::flex();
        let cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(64)
            .with_input_width(96);
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("tiny.safetensors");
        checkpoint::save(&cfg.init(&device), &ModelCard::random_init(0), &path).unwrap();
        let mut scenario = Scenario::from_toml_str(
            "[map]\nfile = \"t.xodr\"\n[route]\nfile = \"r.toml\"\nid = 0\n\
             [driver]\nkind = \"policy\"\ncheckpoint = \"m.safetensors\"\n",
            Path::new("s.toml"),
        )
        .unwrap();
        scenario.driver.checkpoint = Some(path.clone());
        let drivers = Drivers::new().with(DriverKind::Policy, PolicyFactory);
        assert_eq!(drivers.input_size(&scenario).unwrap(), Some((64, 96)));
        assert_eq!(rig_for(&scenario, &drivers).unwrap().base_size(), (96, 64));
        let prepared = Prepared {
            town: std::sync::Arc::new(world::Town::empty("t")),
            route: world::route::DenseRoute {
                id: "0".into(),
                points: vec![],
                length_m: 0.0,
                waypoint_points: vec![],
            },
            route_file: "r.toml".into(),
        };
        let driver = drivers.driver(&scenario, &prepared).unwrap();
        assert!(
            driver.name().contains("tiny.safetensors"),
            "{}",
            driver.name()
        );
        assert!(driver.needs().camera);
        // Its records carry the checkpoint's digest.
        let id = driver.checkpoint().expect("a policy names its checkpoint");
        assert!(id.file.ends_with("tiny.safetensors"), "{}", id.file);
        let bytes = std::fs::read(tmp.path().join("tiny.safetensors")).unwrap();
        assert_eq!(id.sha256, sim::record::sha256_hex(&bytes));
        assert_eq!(driver.trigger(), None);
        // And a learned trigger's, when the scenario names one.
        let trigger_path = tmp.path().join("tiny.trigger.json");
        let fit_on = |digest: Option<String>| Trigger {
            format: TRIGGER_FORMAT.into(),
            low: 0.75,
            high: 1.0,
            mean: vec![0.0; 16],
            std: vec![1.0; 16],
            weights: vec![0.0; 16],
            bias: 2.0,
            card: TriggerCard {
                checkpoint_sha256: digest,
                ..TriggerCard::new("c".into(), "d".into(), 1)
            },
        };
        scenario.driver.trigger = Some(trigger_path.clone());
        // A trigger fit on another network, or not saying which, is refused by name.
        for other in [Some("0".repeat(64)), None] {
            fit_on(other).save(&trigger_path).unwrap();
            let e = error_chain(&drivers.driver(&scenario, &prepared).err().unwrap());
            assert!(
                e.contains("card.checkpoint_sha256") && e.contains("mrdrive policy trigger"),
                "{e}"
            );
        }
        fit_on(Some(id.sha256.clone())).save(&trigger_path).unwrap();
        let with_trigger = drivers.driver(&scenario, &prepared).unwrap();
        let id = with_trigger.trigger().expect("the trigger is named");
        assert_eq!(id.file, trigger_path.display().to_string());
        let bytes = std::fs::read(&trigger_path).unwrap();
        assert_eq!(id.sha256, sim::record::sha256_hex(&bytes));
        scenario.driver.trigger = None;
        scenario.driver.device = Some("tpu".into());
        let e = error_chain(&drivers.driver(&scenario, &prepared).err().unwrap());
        assert!(e.contains("driver.device") && e.contains("tpu"), "{e}");
        scenario.driver.device = None;
        scenario.driver.checkpoint = Some(tmp.path().join("missing.safetensors"));
        let e = error_chain(&drivers.input_size(&scenario).err().unwrap());
        assert!(e.contains("missing.json"), "{e}");
    }

    #[test]
    fn no_image_means_brake() {
        let device = Device::flex();
        let cfg = PolicyConfig::new(Depth::Resnet18, [4, 8, 8, 16])
            .with_input_height(64)
            .with_input_width(96);
        let mut d = PolicyDriver::new(cfg.init(&device), ModelCard::random_init(0), "d", device);
        let obs = Observation {
            time_s: 0.0,
            speed_mps: 0.0,
            command: Command::Left,
            scale: 1.0,
            image: None,
            labels: None,
            privileged: None,
        };
        assert_eq!(d.act(&obs).brake, 1.0);
    }
}
