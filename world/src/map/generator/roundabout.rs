//! A single-lane roundabout at a grid node, written as CARLA's towns write
//! theirs: a ring of one-way roads round a central island, and one junction
//! per arm where the ring meets the street.
//!
//! Traffic goes round counter-clockwise (right-hand traffic). The ring's
//! reference line is the island's edge, [`ISLAND_RADIUS_M`] from the node;
//! its lane lies outside it, and a sidewalk outside the lane. The junction
//! of an arm at direction `θ` spans the ring from `θ - α` to `θ + α`
//! ([`ARM_HALF_ANGLE_RAD`]) and holds:
//!
//! - the ring going on (an arc of the island's edge);
//! - the entry, a right turn from the street's incoming lane onto the ring
//!   at `θ + α`;
//! - the exit, a right turn from the ring at `θ - α` onto the street's
//!   outgoing lane;
//! - the sidewalks along the entry and the exit.
//!
//! Entries and exits are cubic curves (`paramPoly3`) tangent to the street
//! and to the ring. The junction's `<priority>` gives the ring precedence
//! over the entry: a car yields on entry ([`crate::rules::conflicts`]).

use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::fmt::Write;

use super::elements::{junction_lanes, road_head, road_link, town_type};
use super::layout::{Arm, Grid, JunctionIds, Node};
use super::{LANE_WIDTH_M, SIDEWALK_HEIGHT_M, SIDEWALK_WIDTH_M};

/// The central island's radius: the ring's reference line (metres).
pub const ISLAND_RADIUS_M: f64 = 12.0;
/// Half the ring angle an arm's junction spans (radians, 25 degrees).
pub const ARM_HALF_ANGLE_RAD: f64 = 25.0 * PI / 180.0;

/// A pose in the plane: position (metres) and heading (radians).
#[derive(Debug, Clone, Copy)]
struct Pose {
    x: f64,
    y: f64,
    hdg: f64,
}

/// The cubic from `a` to `b` tangent to both headings, in `a`'s frame
/// (`u` along its heading, `v` to its left), over the normalised parameter
/// p in [0, 1]: the `paramPoly3` coefficients `[aU, bU, cU, dU, aV, bV, cV,
/// dV]` and the curve's arc length (metres).
fn hermite(a: Pose, b: Pose) -> ([f64; 8], f64) {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let (c, s) = (a.hdg.cos(), a.hdg.sin());
    let (u1, v1) = (c * dx + s * dy, -s * dx + c * dy);
    let dh = b.hdg - a.hdg;
    // Tangents as long as the chord: a curve without loops or cusps for
    // turns up to a right angle.
    let t = dx.hypot(dy);
    let (tu, tv) = (t * dh.cos(), t * dh.sin());
    let coef = [
        0.0,
        t,
        3.0 * u1 - 2.0 * t - tu,
        -2.0 * u1 + t + tu,
        0.0,
        0.0,
        3.0 * v1 - tv,
        -2.0 * v1 + tv,
    ];
    // Arc length by Simpson's rule on 2,000 intervals.
    let speed = |p: f64| {
        let du = coef[1] + 2.0 * coef[2] * p + 3.0 * coef[3] * p * p;
        let dv = coef[5] + 2.0 * coef[6] * p + 3.0 * coef[7] * p * p;
        du.hypot(dv)
    };
    let n = 2000;
    let h = 1.0 / n as f64;
    let mut sum = speed(0.0) + speed(1.0);
    for k in 1..n {
        sum += speed(k as f64 * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    (coef, sum * h / 3.0)
}

fn poly_shape(coef: &[f64; 8]) -> String {
    format!(
        "<paramPoly3 aU=\"{:.9}\" bU=\"{:.9}\" cU=\"{:.9}\" dU=\"{:.9}\" aV=\"{:.9}\" bV=\"{:.9}\" cV=\"{:.9}\" dV=\"{:.9}\" pRange=\"normalized\"/>",
        coef[0], coef[1], coef[2], coef[3], coef[4], coef[5], coef[6], coef[7]
    )
}

/// The point of the island's edge at angle `a` (radians from the node),
/// heading round the ring.
fn on_ring(centre: (f64, f64), a: f64) -> Pose {
    Pose {
        x: centre.0 + ISLAND_RADIUS_M * a.cos(),
        y: centre.1 + ISLAND_RADIUS_M * a.sin(),
        hdg: a + FRAC_PI_2,
    }
}

/// The ring road's lanes: its driving lane (solid white at its outer edge,
/// the island's edge marked on the centre lane) and the sidewalk outside it.
fn ring_lanes(out: &mut String) {
    let _ = writeln!(
        out,
        "        <lanes>\n            <laneSection s=\"0\">\n                <center>\n                    <lane id=\"0\" type=\"none\" level=\"false\">\n                        <roadMark sOffset=\"0\" type=\"solid\" weight=\"standard\" color=\"white\" width=\"0.15\" laneChange=\"none\"/>\n                    </lane>\n                </center>\n                <right>\n                    <lane id=\"-1\" type=\"driving\" level=\"false\">\n                        <link></link>\n                        <width sOffset=\"0\" a=\"{LANE_WIDTH_M}\" b=\"0\" c=\"0\" d=\"0\"/>\n                        <roadMark sOffset=\"0\" type=\"solid\" weight=\"standard\" color=\"white\" width=\"0.15\" laneChange=\"none\"/>\n                    </lane>\n                    <lane id=\"-2\" type=\"sidewalk\" level=\"false\">\n                        <link/>\n                        <width sOffset=\"0\" a=\"{SIDEWALK_WIDTH_M}\" b=\"0\" c=\"0\" d=\"0\"/>\n                        <height sOffset=\"0\" inner=\"{SIDEWALK_HEIGHT_M}\" outer=\"{SIDEWALK_HEIGHT_M}\"/>\n                    </lane>\n                </right>\n            </laneSection>\n        </lanes>\n    </road>"
    );
}

/// Writes the roundabout at `node` with `arms` (sorted by direction, so
/// counter-clockwise): its ring roads (ids 60000 + 10 x the junction's
/// number + the arm) and each arm's junction roads (ids from `next_conn`)
/// to `out`, and its junctions to `junctions`.
pub(super) fn roads(
    out: &mut String,
    junctions: &mut String,
    grid: &Grid,
    node: Node,
    arms: &[Arm<'_>],
    junction_ids: &JunctionIds,
    next_conn: &mut u32,
) {
    let centre = grid.pos(node);
    let d = grid.half_m(node);
    let alpha = ARM_HALF_ANGLE_RAD;
    let n = arms.len();
    let jid = |k: usize| junction_ids[&(node, arms[k % n].street.id)];
    // The ring road after arm k runs from its junction to arm k + 1's.
    let ring_id = |k: usize| 60_000 + 10 * (jid(0) - 1000) + (k % n) as u32;
    for k in 0..n {
        let a0 = arms[k].dir + alpha;
        let mut sweep = arms[(k + 1) % n].dir - alpha - a0;
        if sweep <= 0.0 {
            sweep += TAU;
        }
        let len = ISLAND_RADIUS_M * sweep;
        let start = on_ring(centre, a0);
        let links = format!(
            "            <predecessor elementType=\"junction\" elementId=\"{}\"/>\n            <successor elementType=\"junction\" elementId=\"{}\"/>\n",
            jid(k),
            jid(k + 1)
        );
        road_head(
            out,
            &format!("ring{}", ring_id(k)),
            ring_id(k),
            -1,
            &links,
            &town_type(),
            (start.x, start.y),
            start.hdg,
            len,
            &format!("<arc curvature=\"{:.9}\"/>", 1.0 / ISLAND_RADIUS_M),
        );
        ring_lanes(out);
    }
    let mut by_arm: BTreeMap<usize, String> = BTreeMap::new();
    for (k, arm) in arms.iter().enumerate() {
        let j = jid(k);
        let before = ring_id(k + n - 1);
        let after = ring_id(k);
        let street = arm.street.id;
        // The street's lanes and contact point at this end.
        let (cp, lane_in, lane_out) = if arm.at_b {
            ("end", -1, 1)
        } else {
            ("start", 1, -1)
        };
        let (c, s) = (arm.dir.cos(), arm.dir.sin());
        let street_end = (centre.0 + c * d, centre.1 + s * d);
        let mut conns = String::new();
        // The ring going on.
        let through = *next_conn;
        let a_in = arm.dir - alpha;
        let p = on_ring(centre, a_in);
        road_head(
            out,
            &format!("conn{through}"),
            through,
            i64::from(j),
            &(road_link("predecessor", before, "end") + &road_link("successor", after, "start")),
            &town_type(),
            (p.x, p.y),
            p.hdg,
            2.0 * alpha * ISLAND_RADIUS_M,
            &format!("<arc curvature=\"{:.9}\"/>", 1.0 / ISLAND_RADIUS_M),
        );
        junction_road_lanes(out, "driving", -1, -1);
        connection(&mut conns, before, through, -1, -1);
        // The entry, and its sidewalk.
        let entry = through + 1;
        let street_pose = |hdg: f64| Pose {
            x: street_end.0,
            y: street_end.1,
            hdg,
        };
        curve_roads(
            out,
            &mut conns,
            Curve {
                id: entry,
                junction: j,
                from: street_pose(arm.dir + PI),
                to: on_ring(centre, arm.dir + alpha),
                links: road_link("predecessor", street, cp)
                    + &road_link("successor", after, "start"),
                incoming: street,
                lane: (lane_in, -1),
            },
        );
        // The exit, and its sidewalk.
        let exit = entry + 2;
        curve_roads(
            out,
            &mut conns,
            Curve {
                id: exit,
                junction: j,
                from: on_ring(centre, a_in),
                to: street_pose(arm.dir),
                links: road_link("predecessor", before, "end")
                    + &road_link("successor", street, cp),
                incoming: before,
                lane: (-1, lane_out),
            },
        );
        *next_conn = exit + 2;
        let _ = writeln!(
            conns,
            "        <priority high=\"{through}\" low=\"{entry}\"/>"
        );
        by_arm.insert(
            k,
            format!("    <junction id=\"{j}\" name=\"junction{j}\">\n{conns}    </junction>\n"),
        );
    }
    for (_, j) in by_arm {
        junctions.push_str(&j);
    }
}

/// An entry or an exit of a roundabout: a cubic from `from` to `to` carrying
/// a driving lane (road `id`) and, on the same curve, a sidewalk (road
/// `id + 1`), in junction `junction`, linked by `links`, entered from road
/// `incoming`; `lane` is the driving lane's (predecessor, successor) lane id
/// (the sidewalks' are twice those).
struct Curve {
    id: u32,
    junction: u32,
    from: Pose,
    to: Pose,
    links: String,
    incoming: u32,
    lane: (i32, i32),
}

/// Writes a [`Curve`]'s two roads to `out` and their connections to `conns`.
fn curve_roads(out: &mut String, conns: &mut String, c: Curve) {
    let (coef, len) = hermite(c.from, c.to);
    let (pred, succ) = c.lane;
    for (id, kind, pred, succ, to) in [
        (c.id, "driving", pred, succ, -1),
        (c.id + 1, "sidewalk", 2 * pred, 2 * succ, -2),
    ] {
        let (name, extra) = if kind == "driving" {
            ("conn", town_type())
        } else {
            ("walk", String::new())
        };
        road_head(
            out,
            &format!("{name}{id}"),
            id,
            i64::from(c.junction),
            &c.links,
            &extra,
            (c.from.x, c.from.y),
            c.from.hdg,
            len,
            &poly_shape(&coef),
        );
        junction_road_lanes(out, kind, pred, succ);
        connection(conns, c.incoming, id, pred, to);
    }
}

/// A junction's `<connection>` of road `road` entered from road `incoming`,
/// its lane `from` into lane `to`, numbered after those in `conns`.
fn connection(conns: &mut String, incoming: u32, road: u32, from: i32, to: i32) {
    let id = conns.matches("<connection ").count();
    let _ = writeln!(
        conns,
        "        <connection id=\"{id}\" incomingRoad=\"{incoming}\" connectingRoad=\"{road}\" contactPoint=\"start\">\n            <laneLink from=\"{from}\" to=\"{to}\"/>\n        </connection>"
    );
}

/// A roundabout junction road's lanes: its driving lane (unmarked) or, for a
/// sidewalk, a bare strip as wide as a lane and the sidewalk outside it.
fn junction_road_lanes(out: &mut String, kind: &str, pred: i32, succ: i32) {
    let (offsets, width) = if kind == "driving" {
        ((0.0, 0.0), LANE_WIDTH_M)
    } else {
        ((LANE_WIDTH_M, LANE_WIDTH_M), SIDEWALK_WIDTH_M)
    };
    // The spacer's length does not matter: its width is constant.
    let lanes = junction_lanes(kind, offsets, 1.0, width, pred, succ);
    let centre_mark = if kind == "driving" {
        ">\n                        <roadMark sOffset=\"0\" type=\"none\" weight=\"standard\" color=\"white\" width=\"0\" laneChange=\"none\"/>\n                    </lane>"
    } else {
        "/>"
    };
    let _ = writeln!(
        out,
        "        <lanes>\n            <laneSection s=\"0\">\n                <center>\n                    <lane id=\"0\" type=\"none\" level=\"false\"{centre_mark}\n                </center>\n                <right>\n{lanes}                </right>\n            </laneSection>\n        </lanes>\n    </road>"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_hermite_curve_joins_both_poses_tangentially() {
        let a = Pose {
            x: 28.0,
            y: 0.0,
            hdg: PI,
        };
        let b = on_ring((0.0, 0.0), ARM_HALF_ANGLE_RAD);
        let (c, len) = hermite(a, b);
        let at = |p: f64| {
            let u = c[0] + c[1] * p + c[2] * p * p + c[3] * p * p * p;
            let v = c[4] + c[5] * p + c[6] * p * p + c[7] * p * p * p;
            let (ch, sh) = (a.hdg.cos(), a.hdg.sin());
            (a.x + ch * u - sh * v, a.y + sh * u + ch * v)
        };
        let end = at(1.0);
        assert!((end.0 - b.x).abs() < 1e-9 && (end.1 - b.y).abs() < 1e-9);
        let near = at(1.0 - 1e-6);
        let hdg = (end.1 - near.1).atan2(end.0 - near.0);
        let diff = (hdg - b.hdg).rem_euclid(TAU);
        assert!(
            diff.min(TAU - diff) < 1e-4,
            "end heading {hdg} vs {}",
            b.hdg
        );
        // Longer than the chord, shorter than the two legs of its triangle.
        let chord = (b.x - a.x).hypot(b.y - a.y);
        assert!(len > chord && len < 1.3 * chord, "{len} vs chord {chord}");
    }
}
