//! The public entry points: load a file or a string, with options, into a
//! [`Town`] and a [`LoadReport`]; the order in which the parts are built.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

use super::{Builder, Ctx};
use crate::map::{MapError, Town};

/// What to do at junctions when the map has no traffic lights at all.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum UnsignalledJunctions {
    /// Leave them without lights.
    #[default]
    NoLights,
    /// Put one light per approach road at every junction with three or more
    /// approaches, each approach its own controller group.
    GenerateLights,
}

/// Options for loading a map.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// Lights for maps with no `<signal>` traffic lights.
    pub unsignalled: UnsignalledJunctions,
}

/// What a load found besides the town: counts from the file and the
/// importer's warnings.
#[derive(Debug, Clone, Default)]
pub struct LoadReport {
    /// The map file (or `<string>`).
    pub file: PathBuf,
    /// OpenDRIVE roads.
    pub roads: usize,
    /// Lanes of every type the importer baked (one per lane section).
    pub lanes: usize,
    /// `<signal>`s of every kind.
    pub signals: usize,
    /// Whether the traffic lights were generated rather than read.
    pub generated_lights: bool,
    /// The importer's warnings (`xodr::Provenance::warnings`), as text.
    pub warnings: Vec<String>,
}

impl LoadReport {
    /// What `mrdrive map info` prints about a map loaded as `town`, in
    /// `load_ms` milliseconds: its counts, lane length (metres), bounds, the
    /// lane graph's connectivity and the first 20 warnings.
    pub fn summary(&self, town: &Town, load_ms: f64) -> String {
        use std::fmt::Write;
        let in_junction = town.lanes.iter().filter(|l| l.junction.is_some()).count();
        let stop_lines: usize = town.lights.iter().map(|l| l.stop_lines.len()).sum();
        let from_map = town.crosswalks.iter().filter(|c| c.from_map).count();
        let (lo, hi) = town.bounds;
        let mut out = String::new();
        let lines = [
            ("map", self.file.display().to_string()),
            ("town", town.name.clone()),
            ("roads", self.roads.to_string()),
            ("lanes (all types)", self.lanes.to_string()),
            (
                "drivable lanes",
                format!("{} ({in_junction} in junctions)", town.lanes.len()),
            ),
            ("junctions", town.junctions.len().to_string()),
            (
                "traffic lights",
                if self.generated_lights {
                    format!(
                        "{n} (0 from the map, {n} generated at junctions of three or more approach roads)",
                        n = town.lights.len()
                    )
                } else {
                    format!("{n} ({n} from the map, 0 generated)", n = town.lights.len())
                },
            ),
            ("stop lines", stop_lines.to_string()),
            (
                "drivable lane length",
                format!("{:.1} m", town.total_lane_length_m()),
            ),
            ("lane markings", town.markings.len().to_string()),
            ("sidewalks", town.sidewalks.len().to_string()),
            (
                "crosswalks",
                format!(
                    "{} ({from_map} from the map, {} generated)",
                    town.crosswalks.len(),
                    town.crosswalks.len() - from_map
                ),
            ),
            ("buildings", town.buildings.len().to_string()),
            (
                "road surface",
                format!("{} triangles", town.road_surface.indices.len() / 3),
            ),
            (
                "bounds",
                format!(
                    "({:.1}, {:.1}) to ({:.1}, {:.1}) m, {:.1} m x {:.1} m",
                    lo.x,
                    lo.y,
                    hi.x,
                    hi.y,
                    hi.x - lo.x,
                    hi.y - lo.y
                ),
            ),
            (
                "lane graph strongly connected",
                if town.is_strongly_connected() {
                    "yes"
                } else {
                    "no"
                }
                .to_string(),
            ),
            ("load time", format!("{load_ms:.1} ms")),
            ("warnings", self.warnings.len().to_string()),
        ];
        for (name, value) in lines {
            let _ = writeln!(out, "{name}: {value}");
        }
        for w in self.warnings.iter().take(20) {
            let _ = writeln!(out, "  - {w}");
        }
        if self.warnings.len() > 20 {
            let _ = writeln!(out, "  ... and {} more", self.warnings.len() - 20);
        }
        out
    }
}

impl Town {
    /// Loads an OpenDRIVE file with default [`LoadOptions`].
    pub fn from_xodr_file(path: impl AsRef<Path>) -> Result<Town, MapError> {
        load_xodr_file(path, &LoadOptions::default()).map(|(t, _)| t)
    }

    /// Loads OpenDRIVE text with default [`LoadOptions`]; `name` names the town
    /// and stands for the file in errors.
    pub fn from_xodr_str(xml: &str, name: &str) -> Result<Town, MapError> {
        load_xodr_str(xml, name, &LoadOptions::default()).map(|(t, _)| t)
    }
}

/// Loads an OpenDRIVE file into a [`Town`] and a [`LoadReport`].
pub fn load_xodr_file(
    path: impl AsRef<Path>,
    opts: &LoadOptions,
) -> Result<(Town, LoadReport), MapError> {
    let path = path.as_ref();
    let xml = std::fs::read(path).map_err(|source| MapError::Read {
        file: path.to_path_buf(),
        source,
    })?;
    let xml = String::from_utf8(xml).map_err(|e| MapError::Import {
        file: path.to_path_buf(),
        detail: format!(
            "not UTF-8 text (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ),
        fix: "give an OpenDRIVE .xodr file (XML text)".into(),
    })?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "town".into());
    load_impl(&xml, &name, path.to_path_buf(), opts)
}

/// Loads OpenDRIVE text into a [`Town`] named `name`.
pub fn load_xodr_str(
    xml: &str,
    name: &str,
    opts: &LoadOptions,
) -> Result<(Town, LoadReport), MapError> {
    load_impl(xml, name, PathBuf::from(format!("<{name}>")), opts)
}

fn load_impl(
    xml: &str,
    name: &str,
    file: PathBuf,
    opts: &LoadOptions,
) -> Result<(Town, LoadReport), MapError> {
    if !xml.contains("<OpenDRIVE") {
        return Err(MapError::Import {
            file,
            detail: "no <OpenDRIVE> root element".into(),
            fix: "give an OpenDRIVE .xodr file; if it was cut short, copy it again".into(),
        });
    }
    let (net, prov) = xodr::load_str_with_provenance(xml).map_err(|e| MapError::Import {
        file: file.clone(),
        detail: match &e {
            xodr::ImportError::Xml(x) => format!("{e} (at line {}, column {})", x.pos().row, x.pos().col),
            _ => e.to_string(),
        },
        fix: match e {
            xodr::ImportError::Xml(_) => "the XML is broken at the position named (a truncated file ends early); re-export or copy the file again".into(),
            _ => "the file holds no usable roads; check it is an OpenDRIVE map".into(),
        },
    })?;
    let ctx = Ctx {
        net: &net,
        file: &file,
    };
    ctx.reject_dropped_geometry(&prov.warnings)?;
    ctx.validate()?;
    let report = LoadReport {
        file: file.clone(),
        roads: net.roads().len(),
        lanes: net.lanes().len(),
        signals: net.signals().len(),
        generated_lights: false,
        warnings: prov.warnings.iter().map(|w| w.to_string()).collect(),
    };
    let mut b = Builder {
        ctx,
        prov: &prov,
        town: Town::empty(name),
        lane_of: HashMap::new(),
        junction_of: BTreeMap::new(),
    };
    b.junctions();
    b.lanes();
    b.reject_junctions_without_lanes(xml)?;
    b.priorities();
    b.markings();
    b.sidewalks();
    b.objects();
    b.junction_outlines();
    let mut report = report;
    b.warn_dangling_junction_lanes(&mut report.warnings);
    b.lights(opts, &mut report);
    b.generated_crosswalks();
    b.surface();
    b.bounds();
    Ok((b.town, report))
}
