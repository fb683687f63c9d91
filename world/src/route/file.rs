//! Route files: CARLA leaderboard XML (read as is, converted from CARLA's
//! left-handed frame: `y_xodr = -y`, `yaw_xodr = -yaw`) and a small native
//! TOML form in the OpenDRIVE frame:
//!
//! ```toml
//! [[route]]
//! id = "0"
//! town = "gen01"
//! # x, y in metres (OpenDRIVE frame); an optional third value is the yaw in degrees
//! waypoints = [[10.0, -1.75], [120.0, -1.75, 0.0]]
//! ```

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::route::RouteError;

/// One route waypoint in the OpenDRIVE frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RouteWaypoint {
    /// Position (metres).
    pub position: Vec3,
    /// Heading if the file gives one (radians, counter-clockwise from +x).
    pub yaw_rad: Option<f32>,
}

/// A route: an id and its sparse waypoints.
#[derive(Debug, Clone, PartialEq)]
pub struct Route {
    /// The route's id in its file.
    pub id: String,
    /// The town it is for, if the file says.
    pub town: Option<String>,
    /// Waypoints in driving order.
    pub waypoints: Vec<RouteWaypoint>,
    /// The file it came from (for error messages).
    pub source: PathBuf,
}

/// All routes of one file.
#[derive(Debug, Clone)]
pub struct RouteFile {
    /// The file.
    pub path: PathBuf,
    /// Its routes in file order.
    pub routes: Vec<Route>,
}

impl RouteFile {
    /// Reads a route file: `.toml` as our form, anything else as CARLA XML.
    pub fn load(path: impl AsRef<Path>) -> Result<RouteFile, RouteError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| RouteError::Read {
            file: path.to_path_buf(),
            source,
        })?;
        if path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
        {
            parse_toml(&text, path)
        } else {
            parse_carla_xml(&text, path)
        }
    }

    /// The route with id `id`; a missing id lists the ids the file has.
    pub fn route(&self, id: &str) -> Result<&Route, RouteError> {
        self.routes
            .iter()
            .find(|r| r.id == id)
            .ok_or_else(|| RouteError::MissingId {
                file: self.path.clone(),
                id: id.to_string(),
                available: self
                    .routes
                    .iter()
                    .map(|r| r.id.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// The ids in file order.
    pub fn ids(&self) -> Vec<&str> {
        self.routes.iter().map(|r| r.id.as_str()).collect()
    }
}

impl Route {
    /// The route as one `[[route]]` table of our TOML form: positions to the
    /// millimetre, headings to a thousandth of a degree (what [`parse_toml`]
    /// reads back to within those steps).
    pub fn toml(&self) -> String {
        let points: Vec<String> = self
            .waypoints
            .iter()
            .map(|w| match w.yaw_rad {
                Some(yaw) => format!(
                    "[{:.3}, {:.3}, {:.3}]",
                    w.position.x,
                    w.position.y,
                    yaw.to_degrees()
                ),
                None => format!("[{:.3}, {:.3}]", w.position.x, w.position.y),
            })
            .collect();
        let town = self
            .town
            .as_ref()
            .map_or(String::new(), |t| format!("town = {t:?}\n"));
        format!(
            "[[route]]\nid = {:?}\n{town}waypoints = [{}]\n",
            self.id,
            points.join(", ")
        )
    }
}

fn parse_err(
    path: &Path,
    what: impl Into<String>,
    location: impl Into<String>,
    fix: &str,
) -> RouteError {
    RouteError::Parse {
        file: path.to_path_buf(),
        what: what.into(),
        location: location.into(),
        fix: fix.into(),
    }
}

/// Parses CARLA leaderboard route XML (`<routes><route id town><waypoint x y z yaw/>`).
pub fn parse_carla_xml(text: &str, path: &Path) -> Result<RouteFile, RouteError> {
    let doc = roxmltree::Document::parse(text).map_err(|e| {
        parse_err(
            path,
            format!("not well-formed XML ({e})"),
            e.pos().to_string(),
            "repair the XML or copy the file again",
        )
    })?;
    let root = doc.root_element();
    if !root.has_tag_name("routes") {
        return Err(parse_err(
            path,
            format!("root element is <{}>, not <routes>", root.tag_name().name()),
            "line 1",
            "give a CARLA leaderboard route file (<routes><route id=...><waypoint .../>) or a .toml route file",
        ));
    }
    let mut routes = Vec::new();
    for r in root.children().filter(|n| n.has_tag_name("route")) {
        let line = doc.text_pos_at(r.range().start).row;
        let id = r
            .attribute("id")
            .ok_or_else(|| {
                parse_err(
                    path,
                    "<route> without id",
                    format!("line {line}"),
                    "give every <route> an id attribute",
                )
            })?
            .to_string();
        let mut waypoints = Vec::new();
        for w in r.children().filter(|n| n.has_tag_name("waypoint")) {
            let wline = doc.text_pos_at(w.range().start).row;
            let num = |name: &str, required: bool| -> Result<Option<f32>, RouteError> {
                match w.attribute(name) {
                    None if required => Err(parse_err(
                        path,
                        format!("waypoint without {name}"),
                        format!("line {wline} (route {id})"),
                        "give each waypoint x, y (and z, yaw) attributes",
                    )),
                    None => Ok(None),
                    Some(v) => match v.trim().parse::<f32>() {
                        Ok(f) if f.is_finite() && f.abs() < 1.0e6 => Ok(Some(f)),
                        _ => Err(parse_err(
                            path,
                            format!("waypoint {name}=\"{v}\" is not a finite number"),
                            format!("line {wline} (route {id})"),
                            "write a plain decimal number in metres (degrees for yaw)",
                        )),
                    },
                }
            };
            let x = num("x", true)?.unwrap_or(0.0);
            let y = num("y", true)?.unwrap_or(0.0);
            let z = num("z", false)?.unwrap_or(0.0);
            let yaw = num("yaw", false)?;
            waypoints.push(RouteWaypoint {
                position: Vec3::new(x, -y, z),
                yaw_rad: yaw.map(|d| -d.to_radians()),
            });
        }
        routes.push(Route {
            id,
            town: r.attribute("town").map(str::to_string),
            waypoints,
            source: path.to_path_buf(),
        });
    }
    Ok(RouteFile {
        path: path.to_path_buf(),
        routes,
    })
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct TomlFile {
    route: Vec<TomlRoute>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct TomlRoute {
    id: String,
    town: Option<String>,
    waypoints: Vec<Vec<f64>>,
}

/// Parses our TOML route form (see the module docs).
pub fn parse_toml(text: &str, path: &Path) -> Result<RouteFile, RouteError> {
    let f: TomlFile = toml::from_str(text).map_err(|e| {
        let loc = e.span().map(|s| {
            let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
            format!("line {line}")
        });
        parse_err(
            path,
            e.message().to_string(),
            loc.unwrap_or_else(|| "the file".into()),
            "write [[route]] tables with id = \"...\" and waypoints = [[x, y], [x, y, yaw_deg], ...]",
        )
    })?;
    let mut routes = Vec::new();
    for r in f.route {
        let mut waypoints = Vec::new();
        for (i, w) in r.waypoints.iter().enumerate() {
            if !(2..=3).contains(&w.len()) || w.iter().any(|v| !v.is_finite() || v.abs() > 1.0e6) {
                return Err(parse_err(
                    path,
                    format!("waypoint {i} is {w:?}"),
                    format!("route \"{}\"", r.id),
                    "give each waypoint as [x, y] or [x, y, yaw_deg] with finite numbers (metres, degrees)",
                ));
            }
            waypoints.push(RouteWaypoint {
                position: Vec3::new(w[0] as f32, w[1] as f32, 0.0),
                yaw_rad: w.get(2).map(|d| (*d as f32).to_radians()),
            });
        }
        routes.push(Route {
            id: r.id,
            town: r.town,
            waypoints,
            source: path.to_path_buf(),
        });
    }
    Ok(RouteFile {
        path: path.to_path_buf(),
        routes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_route_written_as_toml_reads_back() {
        let route = Route {
            id: "random-7".into(),
            town: Some("Town02".into()),
            waypoints: vec![
                RouteWaypoint {
                    position: Vec3::new(12.345_67, -190.5, 0.0),
                    yaw_rad: Some(-1.234_5),
                },
                RouteWaypoint {
                    position: Vec3::new(80.0, 3.25, 0.0),
                    yaw_rad: None,
                },
            ],
            source: PathBuf::from("random route, seed 7"),
        };
        let text = format!("# two routes\n{}\n{}", route.toml(), route.toml());
        assert!(
            text.contains("[[route]]\nid = \"random-7\"\ntown = \"Town02\"\n"),
            "{text}"
        );
        let back = parse_toml(&text, Path::new("r.toml")).unwrap();
        assert_eq!(back.routes.len(), 2);
        let r = back.route("random-7").unwrap();
        assert_eq!(r.town.as_deref(), Some("Town02"));
        for (a, b) in r.waypoints.iter().zip(&route.waypoints) {
            assert!((a.position - b.position).length() < 1e-3, "{a:?} {b:?}");
            match (a.yaw_rad, b.yaw_rad) {
                (Some(x), Some(y)) => assert!((x - y).abs() < 1e-4, "{x} {y}"),
                (x, y) => assert_eq!(x, y),
            }
        }
    }

    #[test]
    fn carla_xml_flips_y_and_yaw() {
        let xml = r#"<routes><route id="7" town="Town01">
            <waypoint x="1.5" y="2.0" z="0" yaw="90"/>
            <waypoint x="3" y="-4" z="0" yaw="-45"/></route></routes>"#;
        let f = parse_carla_xml(xml, Path::new("r.xml")).unwrap();
        let r = f.route("7").unwrap();
        assert_eq!(r.town.as_deref(), Some("Town01"));
        assert_eq!(r.waypoints[0].position, Vec3::new(1.5, -2.0, 0.0));
        assert!((r.waypoints[0].yaw_rad.unwrap() + std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert_eq!(r.waypoints[1].position, Vec3::new(3.0, 4.0, 0.0));
    }

    #[test]
    fn missing_id_lists_the_ids_and_names_the_file() {
        let xml =
            r#"<routes><route id="0"><waypoint x="0" y="0"/></route><route id="1"/></routes>"#;
        let f = parse_carla_xml(xml, Path::new("routes/some.xml")).unwrap();
        let e = f.route("5").unwrap_err().to_string();
        assert!(e.contains("routes/some.xml"), "{e}");
        assert!(e.contains("\"5\"") && e.contains("0, 1"), "{e}");
    }

    #[test]
    fn toml_form_and_its_errors() {
        let t = "[[route]]\nid = \"a\"\nwaypoints = [[1.0, 2.0], [3.0, 4.0, 90.0]]\n";
        let f = parse_toml(t, Path::new("x.toml")).unwrap();
        assert_eq!(f.ids(), vec!["a"]);
        assert_eq!(
            f.routes[0].waypoints[0].position,
            Vec3::new(1.0, 2.0, 0.0),
            "TOML is already in the OpenDRIVE frame"
        );
        let bad = "[[route]]\nid = \"a\"\nwaypoints = [[1.0]]\n";
        let e = parse_toml(bad, Path::new("x.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.toml") && e.contains("waypoint 0"), "{e}");
        let e = parse_toml("[[route]]\nwaypoints = []\n", Path::new("y.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("y.toml") && e.contains("id"), "{e}");
        let e = parse_carla_xml(
            "<routes><route id=\"0\"><waypoint x=\"1\"",
            Path::new("z.xml"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("z.xml") && e.contains("XML"), "{e}");
    }
}
