//! Where things stand: the grid of junction nodes, the streets between them
//! (the full grid less a few interior streets the seed removes), each
//! junction's arms and the turns through it, and the buildings on the lots
//! beside each street. Positions are metres in the OpenDRIVE frame, node
//! (0, 0) at the origin.

use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI};

use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::{GridTownParams, JUNCTION_HALF_M, LANE_WIDTH_M, SIDEWALK_WIDTH_M};

/// Half a street's width from its centre line to the sidewalk's outer edge (metres).
pub(super) const HALF_ROAD_M: f64 = LANE_WIDTH_M + SIDEWALK_WIDTH_M;

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
}

/// The grid of nodes: `blocks + 1` each way, `block_m` apart.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid {
    /// Nodes along x.
    nx: u32,
    /// Nodes along y.
    ny: u32,
    /// Distance between neighbouring nodes (metres).
    pub(super) block_m: f64,
}

impl Grid {
    /// The grid of a town's parameters.
    pub(super) fn of(p: &GridTownParams) -> Grid {
        Grid {
            nx: p.blocks_x + 1,
            ny: p.blocks_y + 1,
            block_m: p.block_size_m,
        }
    }

    /// A node's position (metres).
    pub(super) fn pos(&self, n: Node) -> (f64, f64) {
        (n.0 as f64 * self.block_m, n.1 as f64 * self.block_m)
    }

    /// A street's length between the junction squares at its ends (metres).
    pub(super) fn street_length(&self) -> f64 {
        self.block_m - 2.0 * JUNCTION_HALF_M
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
            })
            .collect()
    }

    /// Every street of the full grid, row by row: from each node east, then north.
    fn edges(&self) -> Vec<(Node, Node)> {
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
    fn interior(&self, n: Node) -> bool {
        n.0 > 0 && n.1 > 0 && n.0 + 1 < self.nx && n.1 + 1 < self.ny
    }

    /// Which `edges` the seed removes, to make interior T junctions: a fifth
    /// of the streets between interior nodes, taken in a shuffled order, each
    /// only while both its nodes still have four arms (so every node keeps
    /// three or more).
    fn removed(&self, edges: &[(Node, Node)], rng: &mut ChaCha8Rng) -> Vec<bool> {
        let mut degree: BTreeMap<Node, u32> = BTreeMap::new();
        for (a, b) in edges {
            *degree.entry(*a).or_default() += 1;
            *degree.entry(*b).or_default() += 1;
        }
        let candidates: Vec<usize> = (0..edges.len())
            .filter(|&k| self.interior(edges[k].0) && self.interior(edges[k].1))
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

/// A way through a junction: from one arm's incoming lane to another arm's
/// outgoing lane, as a connecting road on the incoming lane's reference line.
#[derive(Debug, Clone, Copy)]
pub(super) struct Turn<'a> {
    /// The arm the way comes in by.
    pub(super) from: Arm<'a>,
    /// The arm it leaves by.
    pub(super) to: Arm<'a>,
    /// Where it starts: the incoming street's end, on its centre line (metres).
    pub(super) start: (f64, f64),
    /// The heading of travel into the junction (radians).
    pub(super) heading: f64,
    /// Its length (metres).
    pub(super) length_m: f64,
    /// Its curvature (1/metres, positive to the left); `None` straight on.
    pub(super) curvature: Option<f64>,
    /// Whether the sidewalk on the right of travel continues along it: the
    /// rightmost way out (a right turn, else straight, else left).
    pub(super) sidewalk: bool,
}

/// Every way through the junction at `centre` with `arms`: from each arm to
/// each other arm, no U-turns, in arm order.
pub(super) fn turns<'a>(centre: (f64, f64), arms: &[Arm<'a>]) -> Vec<Turn<'a>> {
    let r = JUNCTION_HALF_M;
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
            let (length_m, curvature) = if turn.abs() < 0.1 {
                (2.0 * r, None)
            } else {
                let curv = if turn > 0.0 { 1.0 / r } else { -1.0 / r };
                (FRAC_PI_2 * r, Some(curv))
            };
            turns.push(Turn {
                from: *from,
                to: *to,
                start: (cx + from.dir.cos() * r, cy + from.dir.sin() * r),
                heading: travel,
                length_m,
                curvature,
                sidewalk: (turn - rightmost).abs() < 1e-9,
            });
        }
    }
    turns
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
/// street keeps its lots clear of the cross streets' lots at its ends.
pub(super) fn buildings(grid: &Grid, street: &Street, rng: &mut ChaCha8Rng) -> Vec<Building> {
    let r = JUNCTION_HALF_M;
    let len = grid.street_length();
    let vertical = street.a.0 == street.b.0;
    let clear = HALF_ROAD_M + 3.0 + 18.0 + 1.0 - r; // keep clear of the cross street's lots
    let (s_lo, s_hi) = if vertical {
        (clear, len - clear)
    } else {
        (1.0, len - 1.0)
    };
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
                t: side * (HALF_ROAD_M + setback + depth * 0.5),
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
