//! Where things stand: the grid of junction nodes, the streets between them
//! (the full grid less a few interior streets the seed removes), each
//! junction's arms and the turns through it, and the buildings on the lots
//! beside each street. Positions are metres in the OpenDRIVE frame, node
//! (0, 0) at the origin.

use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI};

use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::{
    ARTERIAL_JUNCTION_HALF_M, Features, GridTownParams, JUNCTION_HALF_M, LANE_WIDTH_M,
    ROUNDABOUT_HALF_M, SIDEWALK_WIDTH_M,
};

/// Half a street's width from its centre line to the sidewalk's outer edge
/// (metres), for a street of `lanes` driving lanes each way.
pub(super) fn half_road_m(lanes: u32) -> f64 {
    f64::from(lanes) * LANE_WIDTH_M + SIDEWALK_WIDTH_M
}

/// A grid node, a junction's centre: column, row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct Node(pub(super) u32, pub(super) u32);

/// One street between two nodes, `a` < `b`, running from `a` to `b`.
#[derive(Debug, Clone)]
pub(super) struct Street {
    /// The road id (from 1, in grid order).
    pub(super) id: u32,
    /// The node it starts at.
    pub(super) a: Node,
    /// The node it ends at.
    pub(super) b: Node,
    /// Driving lanes each way (1, or 2 on an arterial).
    pub(super) lanes: u32,
}

/// The grid of nodes: `blocks + 1` each way, `block_m` apart, and the
/// town's [`Features`].
#[derive(Debug, Clone)]
pub(super) struct Grid {
    /// Nodes along x.
    nx: u32,
    /// Nodes along y.
    ny: u32,
    /// Distance between neighbouring nodes (metres).
    pub(super) block_m: f64,
    /// Arterials, roundabouts, which junctions get lights.
    pub(super) features: Features,
}

impl Grid {
    /// The grid of a town's parameters.
    pub(super) fn of(p: &GridTownParams) -> Grid {
        Grid {
            nx: p.blocks_x + 1,
            ny: p.blocks_y + 1,
            block_m: p.block_size_m,
            features: p.features.clone(),
        }
    }

    /// Whether node `n` is a roundabout.
    pub(super) fn roundabout(&self, n: Node) -> bool {
        self.features.roundabouts.contains(&(n.0, n.1))
    }

    /// Whether the street from `a` to `b` lies on an arterial row or column.
    pub(super) fn arterial(&self, a: Node, b: Node) -> bool {
        (a.1 == b.1 && self.features.arterial_rows.contains(&a.1))
            || (a.0 == b.0 && self.features.arterial_cols.contains(&a.0))
    }

    /// Whether two arterials cross at node `n`.
    pub(super) fn arterials_cross(&self, n: Node) -> bool {
        self.features.arterial_rows.contains(&n.1) && self.features.arterial_cols.contains(&n.0)
    }

    /// Whether an arterial passes through node `n`.
    pub(super) fn on_arterial(&self, n: Node) -> bool {
        self.features.arterial_rows.contains(&n.1) || self.features.arterial_cols.contains(&n.0)
    }

    /// Half the size of node `n`'s junction: streets end this far from it
    /// (metres). A roundabout's ring and its entries need
    /// [`ROUNDABOUT_HALF_M`]; a junction on an arterial
    /// [`ARTERIAL_JUNCTION_HALF_M`], for its two lanes each way.
    pub(super) fn half_m(&self, n: Node) -> f64 {
        if self.roundabout(n) {
            ROUNDABOUT_HALF_M
        } else if self.on_arterial(n) {
            ARTERIAL_JUNCTION_HALF_M
        } else {
            JUNCTION_HALF_M
        }
    }

    /// A node's position (metres).
    pub(super) fn pos(&self, n: Node) -> (f64, f64) {
        (n.0 as f64 * self.block_m, n.1 as f64 * self.block_m)
    }

    /// A street's length between the junctions at its ends (metres).
    pub(super) fn street_length(&self, st: &Street) -> f64 {
        self.block_m - self.half_m(st.a) - self.half_m(st.b)
    }

    /// Each node's junction id: 1000, 1001, ... row by row.
    pub(super) fn junction_ids(&self) -> BTreeMap<Node, u32> {
        (0..self.ny)
            .flat_map(|j| (0..self.nx).map(move |i| Node(i, j)))
            .enumerate()
            .map(|(k, n)| (n, 1000 + k as u32))
            .collect()
    }

    /// The streets: the full grid's, less those [`Grid::removed`] takes out,
    /// numbered from 1 in grid order.
    pub(super) fn streets(&self, rng: &mut ChaCha8Rng) -> Vec<Street> {
        let edges = self.edges();
        let removed = self.removed(&edges, rng);
        edges
            .iter()
            .zip(&removed)
            .filter(|(_, r)| !**r)
            .enumerate()
            .map(|(k, ((a, b), _))| Street {
                id: k as u32 + 1,
                a: *a,
                b: *b,
                lanes: if self.arterial(*a, *b) { 2 } else { 1 },
            })
            .collect()
    }

    /// Every street of the full grid, row by row: from each node east, then north.
    pub(super) fn edges(&self) -> Vec<(Node, Node)> {
        let (nx, ny) = (self.nx, self.ny);
        let mut edges = Vec::new();
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
        edges
    }

    /// Whether a node is off the grid's edge.
    pub(super) fn interior(&self, n: Node) -> bool {
        n.0 > 0 && n.1 > 0 && n.0 + 1 < self.nx && n.1 + 1 < self.ny
    }

    /// Which `edges` the seed removes, to make interior T junctions: a fifth
    /// of the streets between interior nodes (arterials and a roundabout's
    /// arms stay), taken in a shuffled order, each only while both its nodes
    /// still have four arms (so every node keeps three or more).
    fn removed(&self, edges: &[(Node, Node)], rng: &mut ChaCha8Rng) -> Vec<bool> {
        let mut degree: BTreeMap<Node, u32> = BTreeMap::new();
        for (a, b) in edges {
            *degree.entry(*a).or_default() += 1;
            *degree.entry(*b).or_default() += 1;
        }
        let candidates: Vec<usize> = (0..edges.len())
            .filter(|&k| {
                let (a, b) = edges[k];
                self.interior(a)
                    && self.interior(b)
                    && !self.arterial(a, b)
                    && !self.roundabout(a)
                    && !self.roundabout(b)
            })
            .collect();
        let to_remove = candidates.len() / 5;
        let mut removed = vec![false; edges.len()];
        // A Fisher-Yates shuffle, drawn from the seed.
        let mut order = candidates;
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
        removed
    }
}

/// One arm of a junction: a street leaving its node.
#[derive(Debug, Clone, Copy)]
pub(super) struct Arm<'a> {
    /// The direction from the node out along the street (radians).
    pub(super) dir: f64,
    /// The street.
    pub(super) street: &'a Street,
    /// Whether the street's `b` end is at this node (else its `a` end).
    pub(super) at_b: bool,
}

/// Each node's arms, sorted by direction from -pi to pi (south, east,
/// north, west).
pub(super) fn arms<'a>(grid: &Grid, streets: &'a [Street]) -> BTreeMap<Node, Vec<Arm<'a>>> {
    let mut arms: BTreeMap<Node, Vec<Arm<'a>>> = BTreeMap::new();
    for s in streets {
        let (ax, ay) = grid.pos(s.a);
        let (bx, by) = grid.pos(s.b);
        let out_a = (by - ay).atan2(bx - ax); // from a toward b
        arms.entry(s.a).or_default().push(Arm {
            dir: out_a,
            street: s,
            at_b: false,
        });
        arms.entry(s.b).or_default().push(Arm {
            dir: wrap(out_a + PI),
            street: s,
            at_b: true,
        });
    }
    for v in arms.values_mut() {
        v.sort_by(|x, y| x.dir.total_cmp(&y.dir));
    }
    arms
}

/// A way through a junction: from a lane of one arm's incoming side to a
/// lane of another arm's outgoing side, as a connecting road on the incoming
/// street's reference line (its centre line).
#[derive(Debug, Clone, Copy)]
pub(super) struct Turn<'a> {
    /// The arm the way comes in by.
    pub(super) from: Arm<'a>,
    /// The arm it leaves by.
    pub(super) to: Arm<'a>,
    /// The lane it comes from, counted from the centre line (1 = innermost).
    pub(super) from_lane: u32,
    /// The lane it goes to, counted the same way.
    pub(super) to_lane: u32,
    /// Where it starts: the incoming street's end, on its centre line (metres).
    pub(super) start: (f64, f64),
    /// The heading of travel into the junction (radians).
    pub(super) heading: f64,
    /// Its length (metres).
    pub(super) length_m: f64,
    /// Its curvature (1/metres, positive to the left); `None` straight on.
    pub(super) curvature: Option<f64>,
    /// Whether the sidewalk on the right of travel continues along it: the
    /// outermost lane's way to the rightmost arm out (a right turn, else
    /// straight, else left).
    pub(super) sidewalk: bool,
}

impl Turn<'_> {
    /// How far right of the reference line its lane's left edge is at the
    /// start and at the end (metres): the lanes inside it.
    pub(super) fn offsets_m(&self) -> (f64, f64) {
        (
            f64::from(self.from_lane - 1) * LANE_WIDTH_M,
            f64::from(self.to_lane - 1) * LANE_WIDTH_M,
        )
    }

    /// The same for its sidewalk's inner edge: outside every lane of each arm.
    pub(super) fn sidewalk_offsets_m(&self) -> (f64, f64) {
        (
            f64::from(self.from.street.lanes) * LANE_WIDTH_M,
            f64::from(self.to.street.lanes) * LANE_WIDTH_M,
        )
    }
}

/// Every way through the junction at `centre` (streets ending `r` metres
/// from it) with `arms`: from each arm to each other arm, no U-turns, in arm
/// order. Straight on, each lane keeps its lane; a right turn goes from the
/// outermost lane to the outermost lane, a left turn from the innermost to
/// the innermost.
pub(super) fn turns<'a>(centre: (f64, f64), r: f64, arms: &[Arm<'a>]) -> Vec<Turn<'a>> {
    let (cx, cy) = centre;
    let mut turns = Vec::new();
    for from in arms {
        // The sidewalk on the right of travel continues toward the
        // rightmost way out (a right turn, else straight, else left).
        let travel_in = wrap(from.dir + PI);
        let rightmost = arms
            .iter()
            .filter(|a| a.street.id != from.street.id)
            .map(|a| wrap(a.dir - travel_in))
            .filter(|t| (t.abs() - PI).abs() >= 0.1)
            .fold(f64::MAX, f64::min);
        for to in arms {
            if from.street.id == to.street.id {
                continue;
            }
            // Travel direction entering the node is opposite the arm's outward direction.
            let travel = wrap(from.dir + PI);
            let turn = wrap(to.dir - travel);
            if (turn.abs() - PI).abs() < 0.1 {
                continue; // no U-turns
            }
            let (nf, nt) = (from.street.lanes, to.street.lanes);
            let (length_m, curvature, links) = if turn.abs() < 0.1 {
                let links: Vec<(u32, u32)> = (1..=nf.min(nt)).map(|k| (k, k)).collect();
                (2.0 * r, None, links)
            } else if turn > 0.0 {
                (FRAC_PI_2 * r, Some(1.0 / r), vec![(1, 1)])
            } else {
                (FRAC_PI_2 * r, Some(-1.0 / r), vec![(nf, nt)])
            };
            for (from_lane, to_lane) in links {
                turns.push(Turn {
                    from: *from,
                    to: *to,
                    from_lane,
                    to_lane,
                    start: (cx + from.dir.cos() * r, cy + from.dir.sin() * r),
                    heading: travel,
                    length_m,
                    curvature,
                    sidewalk: (turn - rightmost).abs() < 1e-9 && from_lane == nf,
                });
            }
        }
    }
    turns
}

/// Each junction's id, by the node and the street whose end meets it: a
/// node's junction is 1000, 1001, ... row by row; a roundabout has one
/// junction per arm, the first arm's that id and the others 3000 + 10 x
/// (the node's number) + the arm.
pub(super) type JunctionIds = BTreeMap<(Node, u32), u32>;

pub(super) fn junction_ids(grid: &Grid, arms: &BTreeMap<Node, Vec<Arm<'_>>>) -> JunctionIds {
    let node_ids = grid.junction_ids();
    let mut ids = JunctionIds::new();
    for (node, list) in arms {
        let base = node_ids[node];
        for (k, arm) in list.iter().enumerate() {
            let id = if grid.roundabout(*node) && k > 0 {
                3000 + 10 * (base - 1000) + k as u32
            } else {
                base
            };
            ids.insert((*node, arm.street.id), id);
        }
    }
    ids
}

/// A building on a lot beside a street, placed in the street's frame (metres).
#[derive(Debug, Clone, Copy)]
pub(super) struct Building {
    /// Its centre along the street.
    pub(super) s: f64,
    /// Its centre across the street (positive to the left).
    pub(super) t: f64,
    /// Its length along the street.
    pub(super) length: f64,
    /// Its depth across the street.
    pub(super) depth: f64,
    /// Its height.
    pub(super) height: f64,
}

/// The buildings on the lots on each side of `street` (right, then left),
/// drawn from `rng`: lots one after another along the street, 10-22 m long,
/// 10-18 m deep, 1-3 m behind the sidewalk, 1-4 m apart. A north-south
/// street keeps its lots clear of the cross streets' lots at its ends (and
/// of a roundabout's ring).
pub(super) fn buildings(grid: &Grid, street: &Street, rng: &mut ChaCha8Rng) -> Vec<Building> {
    let len = grid.street_length(street);
    let vertical = street.a.0 == street.b.0;
    // Keep clear of the cross street's lots: an arterial's are farther out.
    let clear = |n: Node| {
        let cross_lanes = if grid.features.arterial_rows.contains(&n.1) {
            2
        } else {
            1
        };
        (half_road_m(cross_lanes) + 3.0 + 18.0 + 1.0 - grid.half_m(n)).max(1.0)
    };
    let (s_lo, s_hi) = if vertical {
        (clear(street.a), len - clear(street.b))
    } else {
        (1.0, len - 1.0)
    };
    let half_road = half_road_m(street.lanes);
    let mut buildings = Vec::new();
    for side in [-1.0f64, 1.0] {
        let mut s = s_lo + rng.random_range(0.0..3.0);
        while s_hi - s >= 8.0 {
            let length = rng.random_range(10.0..22.0f64).min(s_hi - s);
            let depth = rng.random_range(10.0..18.0f64);
            let setback = rng.random_range(1.0..3.0f64);
            let height = rng.random_range(6.0..30.0f64);
            buildings.push(Building {
                s: s + length * 0.5,
                t: side * (half_road + setback + depth * 0.5),
                length,
                depth,
                height,
            });
            s += length + rng.random_range(1.0..4.0);
        }
    }
    buildings
}

/// An angle wrapped into (-pi, pi] (radians).
fn wrap(a: f64) -> f64 {
    let mut a = a % (2.0 * PI);
    if a > PI {
        a -= 2.0 * PI;
    } else if a <= -PI {
        a += 2.0 * PI;
    }
    a
}
