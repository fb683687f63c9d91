//! Our town generator: grid towns written as OpenDRIVE text, so they load
//! through the same path as CARLA's maps.
//!
//! A town is a grid of `blocks_x` x `blocks_y` square blocks. Every grid node
//! is a junction: 4-way inside, T on the edges, a bend at the corners, and the
//! seed removes a few interior streets to make interior T junctions. Streets
//! have one driving lane per direction (3.5 m), a sidewalk each side (3 m,
//! raised 0.15 m), a broken yellow centre line and solid white edge lines.
//! Junctions with three or more arms get a traffic light per approach
//! (`<signal>` + `<controller>`, one controller group per approach). Building
//! footprints stand on lots beside the streets. Everything is drawn from the
//! seed with `ChaCha8Rng`: the same parameters give the same bytes.
//!
//! A town's [`Features`] add what CARLA's larger towns have: arterials of
//! two lanes each way along chosen rows and columns (a solid yellow centre
//! line, broken white between the lanes, wider junctions), lights only
//! where arterials cross ([`LightRule`]), and single-lane roundabouts at
//! chosen nodes (`roundabout.rs`). gen01, gen02 and held01 have none;
//! [`GridTownParams::gen03`] has all three.
//!
//! The steps, one file each:
//!
//! | file | step |
//! | --- | --- |
//! | `mod.rs` | the parameters and their checks, and [`generate_grid_town`], which runs the steps in order |
//! | `layout.rs` | the grid, the streets (the seed removes a few interior ones), each junction's arms and turns, the buildings on the lots |
//! | `signals.rs` | a traffic light per approach at the junctions the [`LightRule`] names |
//! | `elements.rs` | the OpenDRIVE elements roads share: a road's head and links, lane widths, a junction road's lanes |
//! | `roundabout.rs` | a roundabout: ring roads, and per arm a junction with the ring, the entry, the exit and their `<priority>` |
//! | `xml.rs` | the OpenDRIVE text: header, street roads, junctions' connecting and sidewalk roads, controllers, junctions |

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use layout::{Building, Grid};

mod elements;
mod layout;
mod roundabout;
mod signals;
mod xml;

/// Driving lane width (metres).
pub const LANE_WIDTH_M: f64 = 3.5;
/// Sidewalk width (metres).
pub const SIDEWALK_WIDTH_M: f64 = 3.0;
/// Sidewalk height above the road (metres).
pub const SIDEWALK_HEIGHT_M: f64 = 0.15;
/// Half the size of a junction's square (metres): streets end this far from the node.
pub const JUNCTION_HALF_M: f64 = 10.0;
/// Half the size of a junction on an arterial (metres): room for two lanes
/// each way and the turns between them.
pub const ARTERIAL_JUNCTION_HALF_M: f64 = 14.0;
/// How far from a roundabout's centre its streets end (metres).
pub const ROUNDABOUT_HALF_M: f64 = 28.0;
/// Speed limit on generated streets (km/h).
pub const SPEED_LIMIT_KMH: f64 = 30.0;
/// A traffic light signal's `zOffset` (metres): its pole's foot below the
/// ground it stands on, as in CARLA's towns (Town01's and Town02's 60 lights
/// carry -0.55 to -0.70 m). Our poles stand on the 0.15 m sidewalk, so with
/// the lamp housing `DEFAULT_LIGHT_HEAD_HEIGHT_M` = 3.0 m above the foot our
/// lamps hang 2.55 m above the road, CARLA's 2.30-2.45 m; with `zOffset="0"`
/// (3.15 m) a waiting car saw its lamp in the top rows of the picture, and a
/// policy trained on Town01 stood through every green.
pub const SIGNAL_Z_OFFSET_M: f64 = -0.6;

/// Parameters of a grid town.
#[derive(Debug, Clone, PartialEq)]
pub struct GridTownParams {
    /// The town's name (the OpenDRIVE header's `name`).
    pub name: String,
    /// Blocks along x.
    pub blocks_x: u32,
    /// Blocks along y.
    pub blocks_y: u32,
    /// Distance between neighbouring junction centres (metres).
    pub block_size_m: f64,
    /// Seed for removed streets and buildings.
    pub seed: u64,
    /// Arterials, roundabouts and which junctions get lights.
    pub features: Features,
}

/// What a town has beyond the plain grid: arterials of two lanes each way,
/// roundabouts, and which junctions get traffic lights.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Features {
    /// Rows of nodes (0 = the southmost) whose east-west streets are
    /// arterials: 2 driving lanes each way.
    pub arterial_rows: Vec<u32>,
    /// Columns of nodes (0 = the westmost) whose north-south streets are arterials.
    pub arterial_cols: Vec<u32>,
    /// Interior nodes (column, row) that are single-lane roundabouts, off
    /// the arterials: the ring has priority over the entries (OpenDRIVE
    /// junction `<priority>`).
    pub roundabouts: Vec<(u32, u32)>,
    /// Which junctions get traffic lights.
    pub lights: LightRule,
}

/// Which junctions of a generated town get traffic lights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LightRule {
    /// Every junction with three or more arms (gen01, gen02, held01).
    #[default]
    ThreeOrMoreArms,
    /// Only where two arterials cross; every other junction is unsignalled
    /// (first come, first served).
    WhereArterialsCross,
}

impl GridTownParams {
    /// The larger built-in town, about Town01's size (410 m x 328 m).
    pub fn gen01() -> Self {
        GridTownParams {
            name: "gen01".into(),
            blocks_x: 5,
            blocks_y: 4,
            block_size_m: 82.0,
            seed: 1,
            features: Features::default(),
        }
    }

    /// The smaller built-in town, about Town02's size (201 m x 201 m).
    pub fn gen02() -> Self {
        GridTownParams {
            name: "gen02".into(),
            blocks_x: 3,
            blocks_y: 3,
            block_size_m: 67.0,
            seed: 2,
            features: Features::default(),
        }
    }

    /// A town held out of every dataset and training run (309 m x 309 m, 4 x 4
    /// blocks of 74 m): the study's routes on it test policies on streets they
    /// never saw (docs/paper, "routes beyond the paper's four").
    pub fn held01() -> Self {
        GridTownParams {
            name: "held01".into(),
            blocks_x: 4,
            blocks_y: 4,
            block_size_m: 74.0,
            seed: 5,
            features: Features::default(),
        }
    }

    /// The town with all the traffic of CARLA's larger towns (360 m x 270 m,
    /// 4 x 3 blocks of 90 m): an east-west and a north-south arterial of two
    /// lanes each way, lights only where they cross, every other junction
    /// unsignalled, and a roundabout.
    pub fn gen03() -> Self {
        GridTownParams {
            name: "gen03".into(),
            blocks_x: 4,
            blocks_y: 3,
            block_size_m: 90.0,
            seed: 3,
            features: Features {
                arterial_rows: vec![1],
                arterial_cols: vec![2],
                roundabouts: vec![(1, 2)],
                lights: LightRule::WhereArterialsCross,
            },
        }
    }
}

/// Parameters the generator cannot build a town from.
#[derive(Debug, thiserror::Error)]
#[error("town generator: {what}. Fix: {fix}")]
pub struct GeneratorError {
    /// What is wrong.
    pub what: String,
    /// How to fix it.
    pub fix: String,
}

/// Generates the OpenDRIVE text of a grid town.
pub fn generate_grid_town(p: &GridTownParams) -> Result<String, GeneratorError> {
    check(p)?;
    let grid = Grid::of(p);
    // The seed draws the removed streets first, then each street's buildings in order.
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    let streets = grid.streets(&mut rng);
    let buildings: Vec<Vec<Building>> = streets
        .iter()
        .map(|st| layout::buildings(&grid, st, &mut rng))
        .collect();
    let arms = layout::arms(&grid, &streets);
    let lights = signals::lights(&grid, &arms);
    Ok(xml::town(p, &grid, &streets, &buildings, &arms, &lights))
}

/// Refuses parameters the generator cannot build a town from: 1 to 50
/// blocks each way (not 1 x 1), blocks wide enough for the two widest
/// neighbouring junctions and 10 m of street, and no wider than 1 km;
/// arterials on the grid; roundabouts at interior nodes off the arterials.
fn check(p: &GridTownParams) -> Result<(), GeneratorError> {
    if !(1..=50).contains(&p.blocks_x) || !(1..=50).contains(&p.blocks_y) {
        return Err(GeneratorError {
            what: format!("blocks {} x {} out of range", p.blocks_x, p.blocks_y),
            fix: "use 1 to 50 blocks each way".into(),
        });
    }
    // The widest junctions at the two ends of one street, and 10 m of street.
    let grid = Grid::of(p);
    let min_block = grid
        .edges()
        .iter()
        .map(|&(a, b)| grid.half_m(a) + grid.half_m(b))
        .fold(2.0 * JUNCTION_HALF_M, f64::max)
        + 10.0;
    if !p.block_size_m.is_finite() || p.block_size_m < min_block || p.block_size_m > 1000.0 {
        return Err(GeneratorError {
            what: format!("block size {} m out of range", p.block_size_m),
            fix: format!("use a block size from {min_block} m to 1000 m"),
        });
    }
    let f = &p.features;
    for &r in &f.arterial_rows {
        if r > p.blocks_y {
            return Err(GeneratorError {
                what: format!(
                    "arterial row {r} is off the grid (rows 0 to {})",
                    p.blocks_y
                ),
                fix: format!("use a row from 0 to {}", p.blocks_y),
            });
        }
    }
    for &c in &f.arterial_cols {
        if c > p.blocks_x {
            return Err(GeneratorError {
                what: format!(
                    "arterial column {c} is off the grid (columns 0 to {})",
                    p.blocks_x
                ),
                fix: format!("use a column from 0 to {}", p.blocks_x),
            });
        }
    }
    for &(i, j) in &f.roundabouts {
        let interior = i > 0 && j > 0 && i < p.blocks_x && j < p.blocks_y;
        if !interior || f.arterial_rows.contains(&j) || f.arterial_cols.contains(&i) {
            return Err(GeneratorError {
                what: format!(
                    "roundabout at node ({i}, {j}) is not an interior node off the arterials"
                ),
                fix: format!(
                    "put it at a node with column 1 to {} and row 1 to {}, on no arterial row or column",
                    p.blocks_x.saturating_sub(1),
                    p.blocks_y.saturating_sub(1)
                ),
            });
        }
    }
    if p.blocks_x * p.blocks_y < 2 {
        return Err(GeneratorError {
            what: "a 1 x 1 grid is a single loop with no way to turn around".into(),
            fix: "use at least 2 blocks one way".into(),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::opendrive::{LoadOptions, load_xodr_str};

    #[test]
    fn the_shipped_generated_towns_are_what_the_generator_writes() {
        // maps/gen01.xodr, gen02.xodr, held01.xodr and gen03.xodr are this generator's output
        // (`mrdrive map generate`, the parameters in each file's comment): a change
        // to the generator that moves a byte changes every gen01 run.
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        for p in [
            GridTownParams::gen01(),
            GridTownParams::gen02(),
            GridTownParams::held01(),
            GridTownParams::gen03(),
        ] {
            let path = root.join(format!("maps/{}.xodr", p.name));
            let shipped = std::fs::read_to_string(&path).unwrap();
            assert!(
                generate_grid_town(&p).unwrap() == shipped,
                "{} differs from the generator's output",
                path.display()
            );
        }
    }

    #[test]
    fn small_town_loads_clean_and_connected() {
        let p = GridTownParams {
            name: "t".into(),
            blocks_x: 2,
            blocks_y: 2,
            block_size_m: 60.0,
            seed: 3,
            features: Features::default(),
        };
        let xml = generate_grid_town(&p).unwrap();
        let (town, report) = load_xodr_str(&xml, "t", &LoadOptions::default()).unwrap();
        assert!(report.warnings.is_empty(), "{:#?}", report.warnings);
        assert!(
            town.is_strongly_connected(),
            "{:?}",
            town.lane_components().len()
        );
        // 3x3 nodes: 4 T + 1 four-way junction -> 4*3 + 4 = 16 lights.
        assert_eq!(town.lights.len(), 16);
        assert!(
            town.lights
                .iter()
                .all(|l| l.stop_lines.len() == 1 && l.junction.is_some())
        );
        // Every lamp hangs 2.55 m above the road: the sidewalk, the signal's
        // zOffset and the head; CARLA's Town01 and Town02 lamps hang at
        // 2.30-2.45 m (zOffset -0.70 to -0.55 m under the same head).
        for l in &town.lights {
            let lamp = l.position.z + l.head_height_m;
            let want = SIDEWALK_HEIGHT_M
                + SIGNAL_Z_OFFSET_M
                + f64::from(crate::map::opendrive::DEFAULT_LIGHT_HEAD_HEIGHT_M);
            assert!((f64::from(lamp) - want).abs() < 1e-4, "lamp at {lamp} m");
            assert!((2.5..2.6).contains(&lamp), "lamp at {lamp} m");
        }
        assert!(!town.buildings.is_empty());
        // Street sidewalks (2 per street, 12 streets) plus one piece per
        // junction arm joining it to the next street's (24 arms).
        assert_eq!(town.sidewalks.len(), 48);
        // Every sidewalk end meets another sidewalk's end: a closed network.
        let ends: Vec<glam::Vec3> = town
            .sidewalks
            .iter()
            .flat_map(|w| [w.inner[0], *w.inner.last().unwrap()])
            .collect();
        for (i, e) in ends.iter().enumerate() {
            let near = ends
                .iter()
                .enumerate()
                .filter(|(j, f)| *j != i && f.truncate().distance(e.truncate()) < 0.05)
                .count();
            assert_eq!(near, 1, "sidewalk end {e:?} meets {near} others");
        }
        assert!(
            town.markings
                .iter()
                .any(|m| m.kind == crate::MarkKind::Broken && m.color == crate::MarkColor::Yellow)
        );
        assert!(
            town.markings
                .iter()
                .any(|m| m.kind == crate::MarkKind::Solid && m.color == crate::MarkColor::White)
        );
    }

    #[test]
    fn stop_lines_sit_at_the_light_before_the_junction_and_markings_bound_the_lane() {
        use crate::road::geometry::{OrientedBox, box_touches_polyline, crosses_stop_line};
        use glam::Vec2;
        // Nodes at x = 0, 60, 120 and y = 0, 60; junction squares 10 m half size.
        let p = GridTownParams {
            name: "t".into(),
            blocks_x: 2,
            blocks_y: 1,
            block_size_m: 60.0,
            seed: 0,
            features: Features::default(),
        };
        let (town, _) = load_xodr_str(
            &generate_grid_town(&p).unwrap(),
            "t",
            &LoadOptions::default(),
        )
        .unwrap();
        // The eastbound lane of the street from (0, 0) to (60, 0) runs along
        // y = -1.75 and enters the T junction at (60, 0) at x = 50; its
        // light's pole stands 1 m before that, and so does the stop line.
        let sl = town
            .lights
            .iter()
            .flat_map(|l| l.stop_lines.iter())
            .find(|sl| sl.ends[0].truncate().distance(Vec2::new(49.0, 0.0)) < 0.5)
            .expect("a stop line at (49, 0)");
        assert!(
            sl.ends[0].truncate().distance(Vec2::new(49.0, 0.0)) < 0.02,
            "left end {:?}",
            sl.ends[0]
        );
        assert!(
            sl.ends[1].truncate().distance(Vec2::new(49.0, -3.5)) < 0.02,
            "right end {:?}",
            sl.ends[1]
        );
        let lane = town.lane(sl.lane);
        assert!(
            (sl.s - (lane.length_m() - 1.0)).abs() < 1e-3 && (lane.length_m() - 40.0).abs() < 0.01
        );
        let ends = [sl.ends[0].truncate(), sl.ends[1].truncate()];
        assert!(crosses_stop_line(
            Vec2::new(48.8, -1.75),
            Vec2::new(49.2, -1.75),
            ends
        ));
        assert!(!crosses_stop_line(
            Vec2::new(48.0, -1.75),
            Vec2::new(48.9, -1.75),
            ends
        ));
        // A 4.8 m x 2.1 m car centred in that lane touches no marking; moved
        // 1.0 m left (its left side at y = 0.3) it touches the centre line.
        let car = OrientedBox {
            center: Vec2::new(25.0, -1.75),
            heading: 0.0,
            half_length: 2.4,
            half_width: 1.05,
        };
        assert!(
            !town
                .markings
                .iter()
                .any(|m| box_touches_polyline(&car, &m.points))
        );
        let over = OrientedBox {
            center: Vec2::new(25.0, -0.75),
            ..car
        };
        let touched: Vec<_> = town
            .markings
            .iter()
            .filter(|m| box_touches_polyline(&over, &m.points))
            .collect();
        assert_eq!(touched.len(), 1);
        assert_eq!(
            (touched[0].kind, touched[0].color),
            (crate::MarkKind::Broken, crate::MarkColor::Yellow)
        );
        // Moved 1.0 m right it touches the solid white edge line at y = -3.5.
        let right = OrientedBox {
            center: Vec2::new(25.0, -2.75),
            ..car
        };
        let touched: Vec<_> = town
            .markings
            .iter()
            .filter(|m| box_touches_polyline(&right, &m.points))
            .collect();
        assert_eq!(touched.len(), 1);
        assert_eq!(
            (touched[0].kind, touched[0].color),
            (crate::MarkKind::Solid, crate::MarkColor::White)
        );
    }

    #[test]
    fn same_seed_same_bytes_other_seed_other_buildings() {
        let p = GridTownParams::gen02();
        assert_eq!(
            generate_grid_town(&p).unwrap(),
            generate_grid_town(&p).unwrap()
        );
        let q = GridTownParams {
            seed: 99,
            ..p.clone()
        };
        assert_ne!(
            generate_grid_town(&p).unwrap(),
            generate_grid_town(&q).unwrap()
        );
    }

    #[test]
    fn gen03_has_two_lane_arterials_unsignalled_junctions_and_a_roundabout() {
        let p = GridTownParams::gen03();
        let (town, report) = load_xodr_str(
            &generate_grid_town(&p).unwrap(),
            "gen03",
            &LoadOptions::default(),
        )
        .unwrap();
        assert!(report.warnings.is_empty(), "{:#?}", report.warnings);
        assert!(town.is_strongly_connected());
        // Arterials: street lanes with a neighbour of the same direction
        // (row 1 and column 2: 4 + 3 streets, 2 lanes each way, each lane
        // with one neighbour).
        let beside = town
            .lanes
            .iter()
            .filter(|l| l.junction.is_none() && (l.left.is_some() || l.right.is_some()))
            .count();
        assert_eq!(beside, (4 + 3) * 4, "lanes with a neighbour");
        // Lights only where the arterials cross: one four-way junction, an
        // approach each, two lanes per approach.
        assert_eq!(town.lights.len(), 4);
        assert!(town.lights.iter().all(|l| l.stop_lines.len() == 2));
        let lit: std::collections::BTreeSet<_> =
            town.lights.iter().filter_map(|l| l.junction).collect();
        assert_eq!(lit.len(), 1);
        // Junctions of three or more ways in, without lights: every other
        // grid junction (20 nodes less the 4 corners, the lit one and the
        // roundabout).
        let mut ways_in: std::collections::BTreeMap<u32, std::collections::BTreeSet<&str>> =
            Default::default();
        for l in &town.lanes {
            if let Some(j) = l.junction {
                for p in &l.predecessors {
                    ways_in
                        .entry(j.0)
                        .or_default()
                        .insert(&town.lanes[p.0 as usize].road_id);
                }
            }
        }
        let unlit = ways_in
            .iter()
            .filter(|(j, roads)| {
                roads.len() >= 3
                    && !lit.contains(&crate::map::JunctionIdx(**j))
                    && town.junctions[**j as usize].priorities.is_empty()
            })
            .count();
        assert_eq!(unlit, 20 - 4 - 1 - 1);
        // The roundabout: four junctions, each giving its ring priority over
        // its entry, which merges into the ring (the two conflict).
        let conflicts = crate::rules::JunctionConflicts::new(&town);
        let ring: Vec<_> = town
            .junctions
            .iter()
            .filter(|j| !j.priorities.is_empty())
            .collect();
        assert_eq!(ring.len(), 4);
        for j in ring {
            assert_eq!(j.priorities.len(), 1, "{}", j.od_id);
            let (high, low) = j.priorities[0];
            let (h, l) = (town.lane(high), town.lane(low));
            assert_eq!(h.junction, l.junction);
            assert_eq!(h.successors, l.successors, "the entry merges into the ring");
            assert!(
                h.predecessors
                    .iter()
                    .all(|p| town.lane(*p).road_id.starts_with("6")),
                "the ring comes from a ring road"
            );
            assert_eq!(conflicts.gives_way_to(low), &[high]);
            assert!(conflicts.gives_way_to(high).is_empty());
        }
    }

    #[test]
    fn every_lane_of_gen03_ends_where_its_successors_start() {
        // The spacer lanes that move a turn between the lanes of an arterial
        // and a street, and the roundabout's cubic entries and exits, join
        // their lanes end to start in position and heading.
        let (town, _) = load_xodr_str(
            &generate_grid_town(&GridTownParams::gen03()).unwrap(),
            "gen03",
            &LoadOptions::default(),
        )
        .unwrap();
        let mut joins = 0;
        for l in &town.lanes {
            let (end, end_hdg, _) = l.pose_at(l.length_m());
            for s in &l.successors {
                let (start, start_hdg, _) = town.lane(*s).pose_at(0.0);
                let d = end.distance(start);
                let turn = (end_hdg - start_hdg).sin().abs();
                // Headings are those of the 1 m centreline segments: on a
                // curve of 8.25 m radius a segment turns 0.12 rad.
                assert!(
                    d < 0.05 && turn < 0.1,
                    "road {} lane {} -> road {} lane {}: {d} m apart, {turn} rad",
                    l.road_id,
                    l.od_lane,
                    town.lane(*s).road_id,
                    town.lane(*s).od_lane
                );
                joins += 1;
            }
        }
        // Each of the 150 junction lanes is joined at both ends.
        assert_eq!(joins, 300);
    }

    #[test]
    fn bad_features_are_errors_that_name_the_fix() {
        let on_arterial = GridTownParams {
            features: Features {
                roundabouts: vec![(2, 2)],
                ..GridTownParams::gen03().features
            },
            ..GridTownParams::gen03()
        };
        let e = generate_grid_town(&on_arterial).unwrap_err().to_string();
        assert!(
            e.contains("roundabout at node (2, 2)") && e.contains("Fix"),
            "{e}"
        );
        let on_edge = GridTownParams {
            features: Features {
                roundabouts: vec![(0, 1)],
                ..Features::default()
            },
            ..GridTownParams::gen03()
        };
        assert!(generate_grid_town(&on_edge).is_err());
        let off_grid = GridTownParams {
            features: Features {
                arterial_rows: vec![9],
                ..Features::default()
            },
            ..GridTownParams::gen03()
        };
        let e = generate_grid_town(&off_grid).unwrap_err().to_string();
        assert!(e.contains("arterial row 9") && e.contains("Fix"), "{e}");
        // A roundabout needs longer blocks than a plain junction.
        // 28 m to the ring, 14 m to the arterial's junction, 10 m of street.
        let short = GridTownParams {
            block_size_m: 51.0,
            ..GridTownParams::gen03()
        };
        let e = generate_grid_town(&short).unwrap_err().to_string();
        assert!(e.contains("block size 51") && e.contains("52 m"), "{e}");
        let enough = GridTownParams {
            block_size_m: 52.0,
            ..GridTownParams::gen03()
        };
        assert!(generate_grid_town(&enough).is_ok());
    }

    #[test]
    fn bad_parameters_are_errors() {
        let p = GridTownParams {
            block_size_m: 5.0,
            ..GridTownParams::gen02()
        };
        let e = generate_grid_town(&p).unwrap_err().to_string();
        assert!(e.contains("block size") && e.contains("Fix"), "{e}");
        let p = GridTownParams {
            blocks_x: 0,
            ..GridTownParams::gen02()
        };
        assert!(generate_grid_town(&p).is_err());
    }
}
