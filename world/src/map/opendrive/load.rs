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
    b.markings();
    b.sidewalks();
    b.objects();
    b.junction_outlines();
    let mut report = report;
    b.lights(opts, &mut report);
    b.generated_crosswalks();
    b.surface();
    b.bounds();
    Ok((b.town, report))
}
