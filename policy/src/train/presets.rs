//! Named network configurations: what `--preset` on the command line picks.

use std::fmt;
use std::str::FromStr;

use crate::backbone::Depth;
use crate::model::PolicyConfig;

/// A named network configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Preset {
    /// Half-width ResNet-18 at 240 x 96 (the CPU default).
    Cpu,
    /// ResNet-34 at 480 x 192 (the paper).
    Paper,
    /// Full-width ResNet-18 at 480 x 192.
    Resnet18,
    /// A tiny network (widths 8-16-16-32, 96 x 48) for smoke runs.
    Tiny,
}

impl Preset {
    /// Every preset, in the order the command line lists them.
    pub const ALL: [Preset; 4] = [Preset::Cpu, Preset::Paper, Preset::Resnet18, Preset::Tiny];

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Cpu => "cpu",
            Preset::Paper => "paper",
            Preset::Resnet18 => "resnet18",
            Preset::Tiny => "tiny",
        }
    }

    /// The config of this preset with scale set `scales` (fractions of S0).
    pub fn config(self, scales: &[f32]) -> PolicyConfig {
        let c = match self {
            Preset::Cpu => PolicyConfig::cpu_default(),
            Preset::Paper => PolicyConfig::paper(),
            Preset::Resnet18 => PolicyConfig {
                depth: Depth::Resnet18,
                ..PolicyConfig::paper()
            },
            Preset::Tiny => PolicyConfig::new(Depth::Resnet18, [8, 16, 16, 32])
                .with_input_height(48)
                .with_input_width(96),
        };
        c.with_scales(scales.to_vec())
    }
}

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A preset name that is not one.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown preset `{0}`; fix: use one of cpu, paper, resnet18, tiny")]
pub struct UnknownPreset(pub String);

impl FromStr for Preset {
    type Err = UnknownPreset;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Preset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| UnknownPreset(s.to_string()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_list_the_choices() {
        for p in Preset::ALL {
            assert_eq!(p.name().parse::<Preset>(), Ok(p));
            assert_eq!(p.to_string(), p.name());
        }
        let e = "resnet50".parse::<Preset>().unwrap_err().to_string();
        assert!(e.contains("resnet50") && e.contains("tiny"), "{e}");
    }

    #[test]
    fn presets_have_their_sizes_and_the_scales_given() {
        let paper = Preset::Paper.config(&[0.5, 1.0]);
        assert_eq!(paper.depth, Depth::Resnet34);
        assert_eq!((paper.input_width, paper.input_height), (480, 192));
        assert_eq!(paper.scales, vec![0.5, 1.0]);
        assert_eq!(Preset::Resnet18.config(&[1.0]).depth, Depth::Resnet18);
        let cpu = Preset::Cpu.config(&[1.0]);
        assert_eq!((cpu.input_width, cpu.input_height), (240, 96));
        let tiny = Preset::Tiny.config(&[1.0]);
        assert_eq!((tiny.input_width, tiny.input_height), (96, 48));
        for p in Preset::ALL {
            p.config(&[0.75, 1.0]).validate().unwrap();
        }
    }
}
