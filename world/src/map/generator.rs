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

use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI};
use std::fmt::Write;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Driving lane width (metres).
pub const LANE_WIDTH_M: f64 = 3.5;
/// Sidewalk width (metres).
pub const SIDEWALK_WIDTH_M: f64 = 3.0;
/// Sidewalk height above the road (metres).
pub const SIDEWALK_HEIGHT_M: f64 = 0.15;
/// Half the size of a junction's square (metres): streets end this far from the node.
pub const JUNCTION_HALF_M: f64 = 10.0;
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

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Node(u32, u32);

/// One street between two nodes, `a` < `b`, running from `a` to `b`.
#[derive(Debug, Clone)]
struct Street {
    id: u32,
    a: Node,
    b: Node,
}

/// Generates the OpenDRIVE text of a grid town.
pub fn generate_grid_town(p: &GridTownParams) -> Result<String, GeneratorError> {
    if !(1..=50).contains(&p.blocks_x) || !(1..=50).contains(&p.blocks_y) {
        return Err(GeneratorError {
            what: format!("blocks {} x {} out of range", p.blocks_x, p.blocks_y),
            fix: "use 1 to 50 blocks each way".into(),
        });
    }
    let min_block = 2.0 * JUNCTION_HALF_M + 10.0;
    if !p.block_size_m.is_finite() || p.block_size_m < min_block || p.block_size_m > 1000.0 {
        return Err(GeneratorError {
            what: format!("block size {} m out of range", p.block_size_m),
            fix: format!("use a block size from {min_block} m to 1000 m"),
        });
    }
    if p.blocks_x * p.blocks_y < 2 {
        return Err(GeneratorError {
            what: "a 1 x 1 grid is a single loop with no way to turn around".into(),
            fix: "use at least 2 blocks one way".into(),
        });
    }
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    let (nx, ny) = (p.blocks_x + 1, p.blocks_y + 1);
    let bsz = p.block_size_m;
    let pos = |n: Node| (n.0 as f64 * bsz, n.1 as f64 * bsz);

    // Streets of the full grid, then remove a few interior ones.
    let mut edges: Vec<(Node, Node)> = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            if i + 1 < nx {
                edges.push((Node(i, j), Node(i + 1, j)));
            }
            if j + 1 < ny {
                edges.push((Node(i, j), Node(i, j + 1)));
            }
        }
    }
    let interior = |n: Node| n.0 > 0 && n.1 > 0 && n.0 + 1 < nx && n.1 + 1 < ny;
    let mut degree: BTreeMap<Node, u32> = BTreeMap::new();
    for (a, b) in &edges {
        *degree.entry(*a).or_default() += 1;
        *degree.entry(*b).or_default() += 1;
    }
    let candidates: Vec<usize> = (0..edges.len())
        .filter(|&k| interior(edges[k].0) && interior(edges[k].1))
        .collect();
    let to_remove = candidates.len() / 5;
    let mut removed = vec![false; edges.len()];
    let mut order = candidates.clone();
    for k in (1..order.len()).rev() {
        let r = rng.random_range(0..=k);
        order.swap(k, r);
    }
    let mut count = 0;
    for k in order {
        if count >= to_remove {
            break;
        }
        let (a, b) = edges[k];
        if degree[&a] >= 4 && degree[&b] >= 4 {
            removed[k] = true;
            *degree.get_mut(&a).unwrap() -= 1;
            *degree.get_mut(&b).unwrap() -= 1;
            count += 1;
        }
    }
    let streets: Vec<Street> = edges
        .iter()
        .zip(&removed)
        .filter(|(_, r)| !**r)
        .enumerate()
        .map(|(k, ((a, b), _))| Street {
            id: k as u32 + 1,
            a: *a,
            b: *b,
        })
        .collect();

    let r = JUNCTION_HALF_M;
    let half_road = LANE_WIDTH_M + SIDEWALK_WIDTH_M;
    let node_ids: BTreeMap<Node, u32> = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| Node(i, j)))
        .enumerate()
        .map(|(k, n)| (n, 1000 + k as u32))
        .collect();

    let mut out = String::new();
    let (w, h) = (p.blocks_x as f64 * bsz, p.blocks_y as f64 * bsz);
    let _ = writeln!(out, "<?xml version=\"1.0\" encoding=\"UTF-8\"?>");
    let _ = writeln!(
        out,
        "<!-- Generated by mrdrive's grid town generator: blocks {}x{}, block size {} m, seed {}. -->",
        p.blocks_x, p.blocks_y, bsz, p.seed
    );
    let _ = writeln!(out, "<OpenDRIVE>");
    let _ = writeln!(
        out,
        "    <header revMajor=\"1\" revMinor=\"4\" name=\"{}\" version=\"1\" north=\"{:.3}\" south=\"{:.3}\" east=\"{:.3}\" west=\"{:.3}\" vendor=\"mrdrive\"/>",
        p.name,
        h + half_road,
        -half_road,
        w + half_road,
        -half_road
    );

    // Arms of each node: (direction into the node's outside, street, whether the street's b end is here).
    let mut arms: BTreeMap<Node, Vec<(f64, &Street, bool)>> = BTreeMap::new();
    for s in &streets {
        let (ax, ay) = pos(s.a);
        let (bx, by) = pos(s.b);
        let out_a = (by - ay).atan2(bx - ax); // from a toward b
        arms.entry(s.a).or_default().push((out_a, s, false));
        arms.entry(s.b)
            .or_default()
            .push((wrap(out_a + PI), s, true));
    }
    for v in arms.values_mut() {
        v.sort_by(|x, y| x.0.total_cmp(&y.0));
    }

    // Lights: per junction with >= 3 arms, one signal per arm's incoming lane.
    let mut signal_xml: BTreeMap<u32, String> = BTreeMap::new(); // street id -> signals
    let mut controllers = String::new();
    let mut junction_ctrls: BTreeMap<Node, String> = BTreeMap::new();
    let mut next_signal = 5000u32;
    let mut next_ctrl = 7000u32;
    for (node, list) in &arms {
        if list.len() < 3 {
            continue;
        }
        for (seq, (_, st, here_is_b)) in list.iter().enumerate() {
            let len = bsz - 2.0 * r;
            let (s, t, orient, hoff) = if *here_is_b {
                (len - 1.0, -(LANE_WIDTH_M + 1.5), "+", PI)
            } else {
                (1.0, LANE_WIDTH_M + 1.5, "-", 0.0)
            };
            let sid = next_signal;
            next_signal += 1;
            let cid = next_ctrl;
            next_ctrl += 1;
            let _ = writeln!(
                signal_xml.entry(st.id).or_default(),
                "            <signal s=\"{s:.3}\" t=\"{t:.3}\" id=\"{sid}\" name=\"TrafficLight\" dynamic=\"yes\" orientation=\"{orient}\" zOffset=\"{SIGNAL_Z_OFFSET_M:.3}\" country=\"OpenDRIVE\" type=\"1000001\" subtype=\"-1\" value=\"-1\" text=\"\" hOffset=\"{hoff:.6}\" pitch=\"0\" roll=\"0\" height=\"3.0\" width=\"0.5\"/>"
            );
            let _ = writeln!(
                controllers,
                "    <controller id=\"{cid}\" name=\"ctrl{cid}\" sequence=\"{seq}\">\n        <control signalId=\"{sid}\" type=\"0\"/>\n    </controller>"
            );
            let _ = writeln!(
                junction_ctrls.entry(*node).or_default(),
                "        <controller id=\"{cid}\" type=\"0\" sequence=\"{seq}\"/>"
            );
        }
    }

    // Streets.
    for st in &streets {
        let (ax, ay) = pos(st.a);
        let (bx, by) = pos(st.b);
        let hdg = (by - ay).atan2(bx - ax);
        let (ux, uy) = (hdg.cos(), hdg.sin());
        let len = bsz - 2.0 * r;
        let (x0, y0) = (ax + ux * r, ay + uy * r);
        let vertical = st.a.0 == st.b.0;
        let _ = writeln!(
            out,
            "    <road name=\"street{}\" length=\"{len:.6}\" id=\"{}\" junction=\"-1\">",
            st.id, st.id
        );
        let _ = writeln!(
            out,
            "        <link>\n            <predecessor elementType=\"junction\" elementId=\"{}\"/>\n            <successor elementType=\"junction\" elementId=\"{}\"/>\n        </link>",
            node_ids[&st.a], node_ids[&st.b]
        );
        let _ = writeln!(
            out,
            "        <type s=\"0\" type=\"town\">\n            <speed max=\"{SPEED_LIMIT_KMH}\" unit=\"km/h\"/>\n        </type>"
        );
        let _ = writeln!(
            out,
            "        <planView>\n            <geometry s=\"0\" x=\"{x0:.6}\" y=\"{y0:.6}\" hdg=\"{hdg:.9}\" length=\"{len:.6}\">\n                <line/>\n            </geometry>\n        </planView>"
        );
        let _ = writeln!(
            out,
            "        <elevationProfile>\n            <elevation s=\"0\" a=\"0\" b=\"0\" c=\"0\" d=\"0\"/>\n        </elevationProfile>"
        );
        let _ = writeln!(out, "        <lateralProfile/>");
        let _ = writeln!(out, "        <lanes>\n            <laneSection s=\"0\">");
        let sidewalk = |id: i32| {
            format!(
                "                    <lane id=\"{id}\" type=\"sidewalk\" level=\"false\">\n                        <link/>\n                        <width sOffset=\"0\" a=\"{SIDEWALK_WIDTH_M}\" b=\"0\" c=\"0\" d=\"0\"/>\n                        <height sOffset=\"0\" inner=\"{SIDEWALK_HEIGHT_M}\" outer=\"{SIDEWALK_HEIGHT_M}\"/>\n                    </lane>\n"
            )
        };
        let driving = |id: i32| {
            format!(
                "                    <lane id=\"{id}\" type=\"driving\" level=\"false\">\n                        <link/>\n                        <width sOffset=\"0\" a=\"{LANE_WIDTH_M}\" b=\"0\" c=\"0\" d=\"0\"/>\n                        <roadMark sOffset=\"0\" type=\"solid\" weight=\"standard\" color=\"white\" width=\"0.15\" laneChange=\"none\"/>\n                    </lane>\n"
            )
        };
        out.push_str("                <left>\n");
        out.push_str(&sidewalk(2));
        out.push_str(&driving(1));
        out.push_str("                </left>\n");
        out.push_str("                <center>\n                    <lane id=\"0\" type=\"none\" level=\"false\">\n                        <roadMark sOffset=\"0\" type=\"broken\" weight=\"standard\" color=\"yellow\" width=\"0.15\" laneChange=\"both\"/>\n                    </lane>\n                </center>\n");
        out.push_str("                <right>\n");
        out.push_str(&driving(-1));
        out.push_str(&sidewalk(-2));
        out.push_str("                </right>\n");
        let _ = writeln!(out, "            </laneSection>\n        </lanes>");
        // Buildings on lots beside the street.
        let mut objects = String::new();
        let clear = half_road + 3.0 + 18.0 + 1.0 - r; // keep clear of the cross street's lots
        let (s_lo, s_hi) = if vertical {
            (clear, len - clear)
        } else {
            (1.0, len - 1.0)
        };
        for side in [-1.0f64, 1.0] {
            let mut s = s_lo + rng.random_range(0.0..3.0);
            while s_hi - s >= 8.0 {
                let length = rng.random_range(10.0..22.0f64).min(s_hi - s);
                let depth = rng.random_range(10.0..18.0f64);
                let setback = rng.random_range(1.0..3.0f64);
                let height = rng.random_range(6.0..30.0f64);
                let t = side * (half_road + setback + depth * 0.5);
                let id = st.id * 100 + objects.matches("<object").count() as u32;
                let _ = writeln!(
                    objects,
                    "            <object type=\"building\" name=\"building\" id=\"b{id}\" s=\"{:.3}\" t=\"{t:.3}\" zOffset=\"0\" validLength=\"0\" orientation=\"none\" length=\"{length:.3}\" width=\"{depth:.3}\" height=\"{height:.3}\" hdg=\"0\" pitch=\"0\" roll=\"0\"/>",
                    s + length * 0.5
                );
                s += length + rng.random_range(1.0..4.0);
            }
        }
        if !objects.is_empty() {
            let _ = write!(out, "        <objects>\n{objects}        </objects>\n");
        }
        if let Some(sig) = signal_xml.get(&st.id) {
            let _ = write!(out, "        <signals>\n{sig}        </signals>\n");
        }
        let _ = writeln!(out, "    </road>");
    }

    // Junctions: a connecting road from every incoming lane to every other arm.
    let mut next_conn = 100_000u32;
    let mut junctions = String::new();
    for (node, list) in &arms {
        let (cx, cy) = pos(*node);
        let jid = node_ids[node];
        let mut conns = String::new();
        let mut k = 0;
        for (dir_in, st_in, in_is_b) in list {
            // The sidewalk on the right of travel continues toward the
            // rightmost way out (a right turn, else straight, else left).
            let travel_in = wrap(dir_in + PI);
            let rightmost = list
                .iter()
                .filter(|(_, st, _)| !std::ptr::eq(*st, *st_in))
                .map(|(d, _, _)| wrap(d - travel_in))
                .filter(|t| (t.abs() - PI).abs() >= 0.1)
                .fold(f64::MAX, f64::min);
            for (dir_out, st_out, out_is_b) in list {
                if std::ptr::eq(*st_in, *st_out) {
                    continue;
                }
                // Travel direction entering the node is opposite the arm's outward direction.
                let travel = wrap(dir_in + PI);
                let turn = wrap(dir_out - travel);
                let (sx, sy) = (cx + dir_in.cos() * r, cy + dir_in.sin() * r);
                let (len, shape) = if turn.abs() < 0.1 {
                    (2.0 * r, "<line/>".to_string())
                } else {
                    let curv = if turn > 0.0 { 1.0 / r } else { -1.0 / r };
                    (FRAC_PI_2 * r, format!("<arc curvature=\"{curv:.9}\"/>"))
                };
                if (turn.abs() - PI).abs() < 0.1 {
                    continue; // no U-turns
                }
                let cid = next_conn;
                next_conn += 1;
                let (pred_cp, pred_lane) = if *in_is_b { ("end", -1) } else { ("start", 1) };
                let (succ_cp, succ_lane) = if *out_is_b { ("end", 1) } else { ("start", -1) };
                let _ = writeln!(
                    out,
                    "    <road name=\"conn{cid}\" length=\"{len:.6}\" id=\"{cid}\" junction=\"{jid}\">"
                );
                let _ = writeln!(
                    out,
                    "        <link>\n            <predecessor elementType=\"road\" elementId=\"{}\" contactPoint=\"{pred_cp}\"/>\n            <successor elementType=\"road\" elementId=\"{}\" contactPoint=\"{succ_cp}\"/>\n        </link>",
                    st_in.id, st_out.id
                );
                let _ = writeln!(
                    out,
                    "        <type s=\"0\" type=\"town\">\n            <speed max=\"{SPEED_LIMIT_KMH}\" unit=\"km/h\"/>\n        </type>"
                );
                let _ = writeln!(
                    out,
                    "        <planView>\n            <geometry s=\"0\" x=\"{sx:.6}\" y=\"{sy:.6}\" hdg=\"{travel:.9}\" length=\"{len:.6}\">\n                {shape}\n            </geometry>\n        </planView>"
                );
                let _ = writeln!(
                    out,
                    "        <elevationProfile>\n            <elevation s=\"0\" a=\"0\" b=\"0\" c=\"0\" d=\"0\"/>\n        </elevationProfile>"
                );
                let _ = writeln!(out, "        <lateralProfile/>");
                let _ = writeln!(
                    out,
                    "        <lanes>\n            <laneSection s=\"0\">\n                <center>\n                    <lane id=\"0\" type=\"none\" level=\"false\">\n                        <roadMark sOffset=\"0\" type=\"none\" weight=\"standard\" color=\"white\" width=\"0\" laneChange=\"none\"/>\n                    </lane>\n                </center>\n                <right>\n                    <lane id=\"-1\" type=\"driving\" level=\"false\">\n                        <link>\n                            <predecessor id=\"{pred_lane}\"/>\n                            <successor id=\"{succ_lane}\"/>\n                        </link>\n                        <width sOffset=\"0\" a=\"{LANE_WIDTH_M}\" b=\"0\" c=\"0\" d=\"0\"/>\n                        <roadMark sOffset=\"0\" type=\"none\" weight=\"standard\" color=\"white\" width=\"0\" laneChange=\"none\"/>\n                    </lane>\n                </right>\n            </laneSection>\n        </lanes>\n    </road>"
                );
                let _ = writeln!(
                    conns,
                    "        <connection id=\"{k}\" incomingRoad=\"{}\" connectingRoad=\"{cid}\" contactPoint=\"start\">\n            <laneLink from=\"{pred_lane}\" to=\"-1\"/>\n        </connection>",
                    st_in.id
                );
                k += 1;
                if (turn - rightmost).abs() < 1e-9 {
                    // A sidewalk round the corner (or across a missing arm),
                    // on the same reference line, outside a bare 3.5 m strip.
                    let wid = next_conn;
                    next_conn += 1;
                    let (wp, ws) = (2 * pred_lane, 2 * succ_lane);
                    let _ = writeln!(
                        out,
                        "    <road name=\"walk{wid}\" length=\"{len:.6}\" id=\"{wid}\" junction=\"{jid}\">\n        <link>\n            <predecessor elementType=\"road\" elementId=\"{}\" contactPoint=\"{pred_cp}\"/>\n            <successor elementType=\"road\" elementId=\"{}\" contactPoint=\"{succ_cp}\"/>\n        </link>",
                        st_in.id, st_out.id
                    );
                    let _ = writeln!(
                        out,
                        "        <planView>\n            <geometry s=\"0\" x=\"{sx:.6}\" y=\"{sy:.6}\" hdg=\"{travel:.9}\" length=\"{len:.6}\">\n                {shape}\n            </geometry>\n        </planView>\n        <elevationProfile>\n            <elevation s=\"0\" a=\"0\" b=\"0\" c=\"0\" d=\"0\"/>\n        </elevationProfile>\n        <lateralProfile/>"
                    );
                    let _ = writeln!(
                        out,
                        "        <lanes>\n            <laneSection s=\"0\">\n                <center>\n                    <lane id=\"0\" type=\"none\" level=\"false\"/>\n                </center>\n                <right>\n                    <lane id=\"-1\" type=\"none\" level=\"false\">\n                        <link/>\n                        <width sOffset=\"0\" a=\"{LANE_WIDTH_M}\" b=\"0\" c=\"0\" d=\"0\"/>\n                    </lane>\n                    <lane id=\"-2\" type=\"sidewalk\" level=\"false\">\n                        <link>\n                            <predecessor id=\"{wp}\"/>\n                            <successor id=\"{ws}\"/>\n                        </link>\n                        <width sOffset=\"0\" a=\"{SIDEWALK_WIDTH_M}\" b=\"0\" c=\"0\" d=\"0\"/>\n                        <height sOffset=\"0\" inner=\"{SIDEWALK_HEIGHT_M}\" outer=\"{SIDEWALK_HEIGHT_M}\"/>\n                    </lane>\n                </right>\n            </laneSection>\n        </lanes>\n    </road>"
                    );
                    let _ = writeln!(
                        conns,
                        "        <connection id=\"{k}\" incomingRoad=\"{}\" connectingRoad=\"{wid}\" contactPoint=\"start\">\n            <laneLink from=\"{wp}\" to=\"-2\"/>\n        </connection>",
                        st_in.id
                    );
                    k += 1;
                }
            }
        }
        let ctrl = junction_ctrls.get(node).cloned().unwrap_or_default();
        let _ = write!(
            junctions,
            "    <junction id=\"{jid}\" name=\"junction{jid}\">\n{conns}{ctrl}    </junction>\n"
        );
    }
    out.push_str(&controllers);
    out.push_str(&junctions);
    out.push_str("</OpenDRIVE>\n");
    Ok(out)
}

fn wrap(a: f64) -> f64 {
    let mut a = a % (2.0 * PI);
    if a > PI {
        a -= 2.0 * PI;
    } else if a <= -PI {
        a += 2.0 * PI;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::opendrive::{LoadOptions, load_xodr_str};

    #[test]
    fn small_town_loads_clean_and_connected() {
        let p = GridTownParams {
            name: "t".into(),
            blocks_x: 2,
            blocks_y: 2,
            block_size_m: 60.0,
            seed: 3,
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
