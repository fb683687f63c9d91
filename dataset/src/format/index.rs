//! The index, `DIR/dataset.json`: the dataset's format, S0, camera views and
//! frame spacing, and every finished episode with its shard and label files.

use std::path::Path;

use serde::{Deserialize, Serialize};

use super::{DataError, FORMAT, write_atomic};

/// The index file's name inside a dataset directory.
pub const INDEX_FILE: &str = "dataset.json";

/// The route an episode drove: a file and id, or explicit waypoints (random routes).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RouteSpec {
    /// The route file, if the route came from one.
    pub file: Option<String>,
    /// The route's id.
    pub id: String,
    /// The waypoints as driven: x, y (metres, OpenDRIVE frame), heading (degrees).
    pub waypoints: Vec<[f32; 3]>,
}

impl RouteSpec {
    /// The route's name in summaries (`mrdrive data info`, a model card's `routes`):
    /// `<route file's name>#<id>` for a route from a file (`routes_town01.xml#3`),
    /// `random` for a random route.
    pub fn key(&self) -> String {
        match &self.file {
            Some(file) => {
                let name = std::path::Path::new(file)
                    .file_name()
                    .map_or(file.clone(), |f| f.to_string_lossy().into_owned());
                format!("{name}#{}", self.id)
            }
            None => "random".to_string(),
        }
    }
}

/// One driven episode in the index.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Episode {
    /// The index of the episode in the collection plan.
    pub id: u32,
    /// The shard's file name inside the dataset directory.
    pub shard: String,
    /// Frames in the shard.
    pub frames: u32,
    /// The town's name.
    pub town: String,
    /// The map file the episode drove (as given to the collector).
    pub map: String,
    /// Whether unsignalled junctions got generated lights.
    pub generate_lights: bool,
    /// The route.
    pub route: RouteSpec,
    /// The traffic seed.
    pub seed: u64,
    /// Target NPC vehicles.
    pub vehicles: u32,
    /// Target pedestrians.
    pub pedestrians: u32,
    /// Walkers sent across the road ahead of the ego per minute
    /// (`dataset::collect::CROSSINGS_PER_MIN`; 0 in an index written before it).
    #[serde(default)]
    pub crossings_per_min: f32,
    /// Walkers that were sent.
    #[serde(default)]
    pub walkers_sent: u32,
    /// Simulated time driven (seconds).
    pub sim_time_s: f64,
    /// The label file's name, once labelled.
    pub labels: Option<String>,
}

/// The dataset index (`dataset.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Index {
    /// Always [`FORMAT`].
    pub format: String,
    /// The dataset's name (for example `original` or `retarget`).
    pub name: String,
    /// Image size S0: width, height (pixels).
    pub s0: [u32; 2],
    /// Camera view yaw offsets (degrees, counter-clockwise: positive looks
    /// left); the first is 0 (the rig as mounted).
    pub view_yaws_deg: Vec<f32>,
    /// Loop ticks between frames.
    pub frame_every_ticks: u32,
    /// The loop's tick (seconds).
    pub tick_s: f64,
    /// Finished episodes, in plan order.
    pub episodes: Vec<Episode>,
}

impl Index {
    /// An empty index.
    pub fn new(
        name: &str,
        s0: [u32; 2],
        view_yaws_deg: Vec<f32>,
        frame_every_ticks: u32,
        tick_s: f64,
    ) -> Index {
        Index {
            format: FORMAT.to_string(),
            name: name.to_string(),
            s0,
            view_yaws_deg,
            frame_every_ticks,
            tick_s,
            episodes: Vec::new(),
        }
    }

    /// Seconds between frames.
    pub fn frame_s(&self) -> f64 {
        f64::from(self.frame_every_ticks) * self.tick_s
    }

    /// Reads `DIR/dataset.json`.
    pub fn load(dir: &Path) -> Result<Index, DataError> {
        let path = dir.join(INDEX_FILE);
        if !dir.is_dir() {
            return Err(DataError::Index {
                path,
                msg: format!(
                    "no dataset directory {}; make one with `mrdrive collect` (or `cargo xtask data`)",
                    dir.display()
                ),
            });
        }
        let text = std::fs::read_to_string(&path).map_err(|e| DataError::Index {
            path: path.clone(),
            msg: format!(
                "cannot read the index ({e}); a dataset directory needs the {INDEX_FILE} that `mrdrive collect` writes: collect again into this directory to rebuild it"
            ),
        })?;
        let index: Index = serde_json::from_str(&text).map_err(|e| DataError::Index {
            path: path.clone(),
            msg: format!("not a dataset index ({e}); collect again into a new directory"),
        })?;
        if index.format != FORMAT {
            return Err(DataError::Index {
                path,
                msg: format!(
                    "format is {:?}, this build reads {FORMAT:?}; collect the data again with this build",
                    index.format
                ),
            });
        }
        let bad_size = index.s0[0] < 3 || index.s0[1] < 1;
        if bad_size || index.view_yaws_deg.is_empty() || index.frame_every_ticks == 0 {
            return Err(DataError::Index {
                path,
                msg: "s0, view_yaws_deg or frame_every_ticks is empty or zero; collect again"
                    .into(),
            });
        }
        Ok(index)
    }

    /// Writes `DIR/dataset.json` atomically (temporary file, then rename).
    pub fn save(&self, dir: &Path) -> Result<(), DataError> {
        let path = dir.join(INDEX_FILE);
        let text = serde_json::to_string_pretty(self).expect("the index serialises");
        write_atomic(&path, text.as_bytes())
    }

    /// Total frames over every episode.
    pub fn frames(&self) -> u64 {
        self.episodes.iter().map(|e| u64::from(e.frames)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_route_is_named_by_its_files_name_and_id_or_as_random() {
        let route = |file: Option<&str>, id: &str| RouteSpec {
            file: file.map(String::from),
            id: id.into(),
            waypoints: Vec::new(),
        };
        let carla = route(Some("../shared/carla/routes_town01.xml"), "3");
        assert_eq!(carla.key(), "routes_town01.xml#3");
        assert_eq!(route(Some("gen01.toml"), "0").key(), "gen01.toml#0");
        assert_eq!(route(None, "random-17").key(), "random");
    }

    #[test]
    fn a_missing_index_says_how_to_make_one() {
        let dir = tempfile::tempdir().unwrap();
        let err = Index::load(dir.path()).unwrap_err().to_string();
        assert!(
            err.contains(INDEX_FILE) && err.contains("mrdrive collect"),
            "{err}"
        );
        let idx = Index::new("t", [6, 2], vec![0.0], 10, 0.025);
        idx.save(dir.path()).unwrap();
        assert_eq!(Index::load(dir.path()).unwrap(), idx);
    }
}
