//! Pedestrians: walkers on a graph of sidewalks and crossings.
//!
//! The [`WalkGraph`] has nodes about 3 m apart along each sidewalk's middle
//! line (none where a walker would stand in a driving lane: a sidewalk lane
//! of one of a junction's connecting roads can lie across another's turn),
//! edges between neighbours, links between sidewalk ends that meet at a
//! corner (within `corner_link_m`), an edge across each crosswalk (its two
//! ends join the nearest sidewalk nodes) and "jaywalk" edges straight across
//! the road between facing sidewalks. A walker heads for a random goal node
//! (a bounded Dijkstra from where it is; a new goal with probability
//! `regoal_p` per tick, docs/protocol.md §2: 0.02) at its own speed (uniform in
//! 1.2-1.8 m/s). Only jaywalkers (a share `cross_factor` of the walkers, like
//! CARLA's `set_pedestrians_cross_factor`) use jaywalk edges. Before stepping
//! onto a crossing or jaywalk edge a walker waits while a vehicle moving
//! faster than 0.5 m/s is within `wait_vehicle_m` of the crossing (or
//! `wait_time_gap_s` seconds at its speed), for at most `max_wait_s`, then
//! goes anyway; and it waits as long as any vehicle stands on the crossing.
//! On the road it stops rather than step into the next 1.5 s of a moving
//! vehicle's path, and nowhere does it step within [`VEHICLE_MARGIN_M`] of a
//! vehicle's body; a walker held up by a vehicle for half a second turns back.

use crate::agents::actor::ActorKind;
use crate::map::town::Town;
use crate::physics::PEDESTRIAN_RADIUS_M;
use crate::rules::ahead::ActorView;
use crate::rules::lanes::LaneGrid;
use glam::Vec2;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Parameters of the walkers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PedestrianParams {
    /// Slowest walking speed (metres per second).
    pub min_speed_mps: f32,
    /// Fastest walking speed (metres per second).
    pub max_speed_mps: f32,
    /// Probability per tick of choosing a new goal.
    pub regoal_p: f32,
    /// Share of walkers that also cross the road between crosswalks (0..=1).
    pub cross_factor: f32,
    /// Distance within which sidewalk ends are joined at corners (metres).
    pub corner_link_m: f32,
    /// A walker waits to cross while a moving vehicle is this close to the crossing (metres).
    pub wait_vehicle_m: f32,
    /// ... or would reach it within this many seconds at its speed (seconds).
    pub wait_time_gap_s: f32,
    /// Longest wait before crossing anyway (seconds).
    pub max_wait_s: f32,
    /// A spawn spot is refused when a vehicle or walker is this close (metres).
    pub spawn_clearance_m: f32,
    /// Walkers sent across the road just ahead of the ego, per minute of
    /// driving: a collection aid (`traffic/crossings.rs`); 0 (off) by default.
    pub ego_crossings_per_min: f32,
}

impl Default for PedestrianParams {
    fn default() -> Self {
        PedestrianParams {
            min_speed_mps: 1.2,
            max_speed_mps: 1.8,
            regoal_p: 0.02,
            cross_factor: 0.1,
            corner_link_m: 8.0,
            wait_vehicle_m: 12.0,
            wait_time_gap_s: 4.0,
            max_wait_s: 10.0,
            spawn_clearance_m: 0.5,
            ego_crossings_per_min: 0.0,
        }
    }
}

/// Gap a walker keeps to a vehicle's body (metres, beyond its own radius).
pub const VEHICLE_MARGIN_M: f32 = 0.2;

/// How a walk edge is walked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeKind {
    /// Along a sidewalk or round a corner.
    Sidewalk,
    /// Over a crosswalk.
    Crosswalk,
    /// Straight over the road (jaywalkers only).
    Jaywalk,
}

/// A node of the walk graph.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkNode {
    /// Position (metres, ground plane).
    pub position: Vec2,
    /// Height of the walking surface (metres).
    pub z: f32,
    /// The sidewalk it lies on.
    pub sidewalk: u32,
}

/// Where pedestrians can walk.
#[derive(Debug, Clone, Default)]
pub struct WalkGraph {
    /// The nodes.
    pub nodes: Vec<WalkNode>,
    /// Out-edges per node: (to, length in metres, kind).
    pub edges: Vec<Vec<(u32, f32, EdgeKind)>>,
}

impl WalkGraph {
    /// Builds the walk graph of a town (see the module docs).
    pub fn new(town: &Town, params: &PedestrianParams) -> WalkGraph {
        let mut g = WalkGraph::default();
        let mut ends: Vec<(u32, u32)> = Vec::new(); // (node, sidewalk)
        // A place on a sidewalk where a walker would stand in a driving lane
        // is no place to walk: where a junction's connecting roads overlap, one
        // road's sidewalk lane can lie across another's turn (Town03's
        // junction 793: a node 1.7 m from road 806's lane, where a walker
        // waiting to cross held up the car whose turn it stood in, and the car
        // the walker). The sidewalk is cut there; each piece has its ends.
        let lanes = LaneGrid::new(town, 8.0);
        let on_road = |p: Vec2| lanes.within_any_lane(town, p, PEDESTRIAN_RADIUS_M);
        for (si, sw) in town.sidewalks.iter().enumerate() {
            let n = sw.inner.len().min(sw.outer.len());
            if n < 2 {
                continue;
            }
            let mid = |i: usize| {
                (
                    (sw.inner[i] + sw.outer[i]) * 0.5,
                    sw.inner[i].z + sw.height_m,
                )
            };
            // The piece being walked: its first node and last kept point.
            let mut piece: Option<(u32, Vec2)> = None;
            let mut last_off_road: Option<(Vec2, f32)> = None;
            for i in 0..n {
                let (p, z) = mid(i);
                let p = p.truncate();
                if on_road(p) {
                    // Close the piece at the last place off the road.
                    if let Some((first, last_kept)) = piece.take() {
                        if let Some((q, qz)) = last_off_road
                            && q != last_kept
                        {
                            let prev = g.nodes.len() as u32 - 1;
                            let id = g.add_node(q, qz, si as u32);
                            g.link(prev, id, EdgeKind::Sidewalk);
                        }
                        ends.push((first, si as u32));
                        ends.push((g.nodes.len() as u32 - 1, si as u32));
                    }
                    last_off_road = None;
                    continue;
                }
                last_off_road = Some((p, z));
                match piece {
                    None => piece = Some((g.add_node(p, z, si as u32), p)),
                    Some((first, last_kept)) => {
                        if (p - last_kept).length() >= 3.0 || i == n - 1 {
                            let prev = g.nodes.len() as u32 - 1;
                            let id = g.add_node(p, z, si as u32);
                            g.link(prev, id, EdgeKind::Sidewalk);
                            piece = Some((first, p));
                        }
                    }
                }
            }
            if let Some((first, _)) = piece {
                ends.push((first, si as u32));
                ends.push((g.nodes.len() as u32 - 1, si as u32));
            }
        }
        // Corners: join each sidewalk end to the nearest node of another sidewalk.
        for &(e, si) in &ends {
            let p = g.nodes[e as usize].position;
            if let Some(j) = g.nearest(p, params.corner_link_m, |n| n.sidewalk != si) {
                g.link(e, j, EdgeKind::Sidewalk);
            }
        }
        // Crosswalks.
        for cw in &town.crosswalks {
            let c: Vec<Vec2> = cw.corners.iter().map(|p| p.truncate()).collect();
            let m01 = (c[0] + c[1]) * 0.5;
            let m23 = (c[2] + c[3]) * 0.5;
            let m12 = (c[1] + c[2]) * 0.5;
            let m30 = (c[3] + c[0]) * 0.5;
            let (a, b) = if (m01 - m23).length() >= (m12 - m30).length() {
                (m01, m23)
            } else {
                (m12, m30)
            };
            let na = g.nearest(a, 4.0, |_| true);
            let nb = na
                .and_then(|na| g.nearest(b, 4.0, |n| n.sidewalk != g.nodes[na as usize].sidewalk));
            if let (Some(na), Some(nb)) = (na, nb) {
                g.link(na, nb, EdgeKind::Crosswalk);
            }
        }
        // Jaywalk edges from every second node to a facing sidewalk.
        let count = g.nodes.len();
        for i in (0..count).step_by(2) {
            let n = g.nodes[i];
            let dir = g.edges[i]
                .iter()
                .find(|e| e.2 == EdgeKind::Sidewalk && g.nodes[e.0 as usize].sidewalk == n.sidewalk)
                .map(|e| (g.nodes[e.0 as usize].position - n.position).normalize_or_zero());
            let Some(dir) = dir else { continue };
            let mut best: Option<(f32, u32)> = None;
            for (j, m) in g.nodes.iter().enumerate() {
                if m.sidewalk == n.sidewalk {
                    continue;
                }
                let d = m.position - n.position;
                let len = d.length();
                if !(5.0..=14.0).contains(&len) || (d / len).dot(dir).abs() > 0.3 {
                    continue;
                }
                if best.is_none_or(|b| len < b.0) {
                    best = Some((len, j as u32));
                }
            }
            if let Some((_, j)) = best
                && !g.edges[i].iter().any(|e| e.0 == j)
            {
                g.link(i as u32, j, EdgeKind::Jaywalk);
            }
        }
        g
    }

    fn add_node(&mut self, position: Vec2, z: f32, sidewalk: u32) -> u32 {
        self.nodes.push(WalkNode {
            position,
            z,
            sidewalk,
        });
        self.edges.push(Vec::new());
        self.nodes.len() as u32 - 1
    }

    fn link(&mut self, a: u32, b: u32, kind: EdgeKind) {
        if a == b || self.edges[a as usize].iter().any(|e| e.0 == b) {
            return;
        }
        let len = (self.nodes[a as usize].position - self.nodes[b as usize].position).length();
        self.edges[a as usize].push((b, len, kind));
        self.edges[b as usize].push((a, len, kind));
    }

    fn nearest(&self, p: Vec2, max_m: f32, ok: impl Fn(&WalkNode) -> bool) -> Option<u32> {
        let mut best: Option<(f32, u32)> = None;
        for (i, n) in self.nodes.iter().enumerate() {
            let d = (n.position - p).length();
            if d <= max_m && ok(n) && best.is_none_or(|b| d < b.0) {
                best = Some((d, i as u32));
            }
        }
        best.map(|b| b.1)
    }

    /// Counts of edges by kind: (sidewalk, crosswalk, jaywalk).
    pub fn edge_counts(&self) -> (usize, usize, usize) {
        let mut c = (0, 0, 0);
        for e in self.edges.iter().flatten() {
            match e.2 {
                EdgeKind::Sidewalk => c.0 += 1,
                EdgeKind::Crosswalk => c.1 += 1,
                EdgeKind::Jaywalk => c.2 += 1,
            }
        }
        (c.0 / 2, c.1 / 2, c.2 / 2)
    }

    /// A random goal within a bounded search from `start`, and the node path to it (excluding `start`).
    pub fn random_route(&self, start: u32, jaywalker: bool, rng: &mut ChaCha8Rng) -> Vec<u32> {
        const MAX_EXPAND: usize = 120;
        let n = self.nodes.len();
        let mut parent_of = vec![u32::MAX; n];
        let mut done = vec![false; n];
        let mut order: Vec<u32> = Vec::new(); // expansion order
        let mut heap = BinaryHeap::new();
        heap.push(QItem(0.0, start, u32::MAX));
        while let Some(QItem(d, u, parent)) = heap.pop() {
            if std::mem::replace(&mut done[u as usize], true) {
                continue;
            }
            parent_of[u as usize] = parent;
            order.push(u);
            if order.len() >= MAX_EXPAND {
                break;
            }
            for &(v, len, kind) in &self.edges[u as usize] {
                if (kind != EdgeKind::Jaywalk || jaywalker) && !done[v as usize] {
                    heap.push(QItem(d + len, v, u));
                }
            }
        }
        let prev = order;
        if prev.len() < 2 {
            return Vec::new();
        }
        let goal_k = rng.random_range(1..prev.len());
        let mut route = vec![prev[goal_k]];
        let mut parent = parent_of[prev[goal_k] as usize];
        while parent != start && parent != u32::MAX {
            route.push(parent);
            parent = parent_of[parent as usize];
        }
        route.reverse();
        route
    }
}

#[derive(PartialEq)]
struct QItem(f32, u32, u32);
impl Eq for QItem {}
impl PartialOrd for QItem {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for QItem {
    fn cmp(&self, o: &Self) -> Ordering {
        // Min-heap on distance, ties by node id: deterministic.
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

/// One pedestrian.
#[derive(Debug, Clone)]
pub struct Pedestrian {
    /// Actor id.
    pub id: u32,
    /// Position (metres, ground plane).
    pub position: Vec2,
    /// Height of the ground under it (metres).
    pub z: f32,
    /// Heading (radians).
    pub yaw: f32,
    /// Its walking speed (metres per second).
    pub speed_mps: f32,
    /// Its current speed (metres per second; 0 while waiting or blocked).
    pub current_speed_mps: f32,
    /// Whether it also crosses between crosswalks.
    pub jaywalker: bool,
    /// The node it came from.
    pub from: u32,
    /// Nodes still to visit, next first.
    pub route: Vec<u32>,
    /// Ticks spent waiting at the current curb.
    pub wait_ticks: u32,
    /// Consecutive ticks its walk was blocked by a vehicle.
    pub blocked_ticks: u32,
    /// Whether its last decision was to stand still short of a vehicle's body.
    pub held_by_vehicle: bool,
    /// Crosswalks it has walked over.
    pub crosswalk_legs: u32,
    /// Times it has crossed the road between crosswalks.
    pub jaywalk_legs: u32,
    /// Sent across the road ahead of the ego (`traffic/crossings.rs`): until it
    /// reaches its next node it does not wait at the kerb for moving vehicles.
    pub sent: bool,
    /// Its own random stream.
    pub rng: ChaCha8Rng,
}

impl Pedestrian {
    /// The position it wants to reach this tick (metres); may wait, re-plan or pick a new goal.
    pub fn decide(
        &mut self,
        g: &WalkGraph,
        p: &PedestrianParams,
        vehicles: &[ActorView],
        dt_s: f32,
    ) -> (Vec2, f32) {
        self.held_by_vehicle = false;
        if self.rng.random::<f32>() < p.regoal_p || self.route.is_empty() {
            let start = self.route.first().copied().unwrap_or(self.from);
            let mut r = g.random_route(start, self.jaywalker, &mut self.rng);
            if start != self.from {
                r.insert(0, start);
            }
            self.route = r;
        }
        let Some(&next) = self.route.first() else {
            return (self.position, self.z);
        };
        let target = g.nodes[next as usize].position;
        // Is the leg to `next` a road crossing, and are we still at its start?
        let kind = g.edges[self.from as usize]
            .iter()
            .find(|e| e.0 == next)
            .map(|e| e.2);
        let at_curb = (self.position - g.nodes[self.from as usize].position).length() < 0.05;
        if matches!(kind, Some(EdgeKind::Crosswalk | EdgeKind::Jaywalk)) && at_curb {
            let a = self.position;
            let patient = !self.sent && (self.wait_ticks as f32 * dt_s) < p.max_wait_s;
            let busy = vehicles.iter().any(|v| {
                if v.kind == ActorKind::Pedestrian {
                    return false;
                }
                let d = seg_dist(v.position, a, target);
                // A moving vehicle nearby (waited for at most `max_wait_s`), or any
                // vehicle standing on the crossing itself (waited for as long as it stands there).
                (patient
                    && v.speed_mps > 0.5
                    && d < p.wait_vehicle_m.max(v.speed_mps * p.wait_time_gap_s))
                    || d < v.half_length_m + 1.0
            });
            if busy {
                self.wait_ticks += 1;
                return (self.position, self.z);
            }
        }
        let to = target - self.position;
        let d = to.length();
        let step = self.speed_mps * dt_s;
        // On the road: do not walk into the path of a moving vehicle.
        if matches!(kind, Some(EdgeKind::Crosswalk | EdgeKind::Jaywalk)) && d > 1e-6 {
            let ahead = self.position + to / d * (self.speed_mps * 1.0).min(d);
            if vehicles.iter().any(|v| {
                v.kind != ActorKind::Pedestrian && v.speed_mps > 0.3 && sweeps_over(v, ahead, 1.5)
            }) {
                return (self.position, self.z);
            }
        }
        // Never walk into a vehicle's body: stop short of it (stepping away stays allowed).
        let np = if d <= step {
            target
        } else {
            self.position + to / d * step
        };
        if vehicles.iter().any(|v| {
            v.kind != ActorKind::Pedestrian && {
                let after = box_dist(v, np);
                after < PEDESTRIAN_RADIUS_M + VEHICLE_MARGIN_M && after < box_dist(v, self.position)
            }
        }) {
            self.held_by_vehicle = true;
            return (self.position, self.z);
        }
        let z0 = g.nodes[self.from as usize].z;
        let z1 = g.nodes[next as usize].z;
        if d <= step {
            (target, z1)
        } else {
            let np = self.position + to / d * step;
            let total = (target - g.nodes[self.from as usize].position)
                .length()
                .max(1e-3);
            let t = 1.0 - (d - step) / total;
            (np, z0 + (z1 - z0) * t.clamp(0.0, 1.0))
        }
    }

    /// Records where it got to; advances along its route when a node is reached.
    pub fn arrive(&mut self, g: &WalkGraph, position: Vec2, z: f32, dt_s: f32) {
        let moved = position - self.position;
        self.current_speed_mps = moved.length() / dt_s;
        if moved.length_squared() > 1e-8 {
            self.yaw = moved.y.atan2(moved.x);
            self.wait_ticks = 0;
        }
        self.position = position;
        self.z = z;
        if let Some(&next) = self.route.first()
            && (g.nodes[next as usize].position - position).length() < 1e-3
        {
            match g.edges[self.from as usize]
                .iter()
                .find(|e| e.0 == next)
                .map(|e| e.2)
            {
                Some(EdgeKind::Crosswalk) => self.crosswalk_legs += 1,
                Some(EdgeKind::Jaywalk) => self.jaywalk_legs += 1,
                _ => {}
            }
            self.from = next;
            self.route.remove(0);
            self.sent = false;
        }
    }
}

impl Pedestrian {
    /// A walker standing still at node `from` of `g`, with no route yet.
    pub fn new(
        id: u32,
        g: &WalkGraph,
        from: u32,
        speed_mps: f32,
        jaywalker: bool,
        rng: ChaCha8Rng,
    ) -> Self {
        let node = &g.nodes[from as usize];
        Pedestrian {
            id,
            position: node.position,
            z: node.z,
            yaw: 0.0,
            speed_mps,
            current_speed_mps: 0.0,
            jaywalker,
            from,
            route: Vec::new(),
            wait_ticks: 0,
            blocked_ticks: 0,
            held_by_vehicle: false,
            crosswalk_legs: 0,
            jaywalk_legs: 0,
            sent: false,
            rng,
        }
    }

    /// Counts a blocked step; after `patience` blocked ticks in a row it turns
    /// back: it walks its leg the other way, to the node it came from, which
    /// the leg's far end becomes. Blocked again on the way back (a car now
    /// between it and that kerb), it turns again, so it never stands for good
    /// between two cars that wait for it. At the node it came from, it drops
    /// its route and draws a new one.
    pub fn note_blocked(&mut self, g: &WalkGraph, blocked: bool, patience: u32) {
        if !blocked {
            self.blocked_ticks = 0;
            return;
        }
        self.blocked_ticks += 1;
        if self.blocked_ticks > patience {
            self.blocked_ticks = 0;
            let back = g.nodes[self.from as usize].position;
            match self.route.first() {
                Some(&next) if (back - self.position).length() > 1e-3 => {
                    self.route = vec![self.from];
                    self.from = next;
                }
                _ => self.route = Vec::new(),
            }
        }
    }
}

/// Whether a vehicle keeping its speed and heading comes within 1 m of `p` in the next `horizon_s` seconds.
fn sweeps_over(v: &ActorView, p: Vec2, horizon_s: f32) -> bool {
    let dir = Vec2::from_angle(v.yaw);
    let rel = p - v.position;
    let along = rel.dot(dir);
    let across = dir.perp_dot(rel).abs();
    let margin = 1.0;
    across < v.half_width_m + margin
        && along > -(v.half_length_m + margin)
        && along < v.half_length_m + margin + v.speed_mps * horizon_s
}

/// Distance from `p` to a vehicle's footprint (metres; 0 inside).
fn box_dist(v: &ActorView, p: Vec2) -> f32 {
    let local = Vec2::from_angle(-v.yaw).rotate(p - v.position);
    let q = local.abs() - Vec2::new(v.half_length_m, v.half_width_m);
    q.max(Vec2::ZERO).length()
}

fn seg_dist(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
    (a + ab * t - p).length()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::agents::actor::ActorKind;
    use crate::map::testtown::grid;
    use rand::SeedableRng;

    #[test]
    fn walk_graph_joins_sidewalks_crosswalks_and_jaywalks() {
        let t = grid(3, 3, 60.0);
        let g = WalkGraph::new(&t, &PedestrianParams::default());
        let (side, cross, jay) = g.edge_counts();
        assert!(side > 100, "{side}");
        assert_eq!(cross, t.crosswalks.len());
        assert!(jay > 20, "{jay}");
        // Connected without jaywalk edges: a flood fill reaches every node.
        let mut seen = vec![false; g.nodes.len()];
        let mut stack = vec![0u32];
        while let Some(u) = stack.pop() {
            if std::mem::replace(&mut seen[u as usize], true) {
                continue;
            }
            for e in &g.edges[u as usize] {
                if e.2 != EdgeKind::Jaywalk {
                    stack.push(e.0);
                }
            }
        }
        assert!(seen.iter().all(|&s| s), "walk graph is not connected");
    }

    fn walker_at(g: &WalkGraph, from: u32, route: Vec<u32>) -> Pedestrian {
        Pedestrian {
            route,
            ..Pedestrian::new(1, g, from, 1.5, false, ChaCha8Rng::seed_from_u64(5))
        }
    }

    /// The walk graph of a 3 x 3 grid town whose walkers draw a new goal with
    /// probability `regoal_p` a tick, its parameters, and the two ends of its
    /// first crosswalk.
    fn grid_crosswalk(regoal_p: f32) -> (WalkGraph, PedestrianParams, (u32, u32)) {
        let t = grid(3, 3, 60.0);
        let p = PedestrianParams {
            regoal_p,
            ..PedestrianParams::default()
        };
        let g = WalkGraph::new(&t, &p);
        let ends = (0..g.nodes.len() as u32)
            .find_map(|a| {
                g.edges[a as usize]
                    .iter()
                    .find(|e| e.2 == EdgeKind::Crosswalk)
                    .map(|e| (a, e.0))
            })
            .unwrap();
        (g, p, ends)
    }

    #[test]
    fn walker_waits_while_a_car_stands_on_its_crossing_and_never_walks_into_one() {
        let (g, p, (a, b)) = grid_crosswalk(0.0);
        let (pa, pb) = (g.nodes[a as usize].position, g.nodes[b as usize].position);
        let along = (pb - pa).normalize();
        // A car stands across the middle of the crossing (its long side blocks the walk).
        let car = ActorView {
            id: 9,
            kind: ActorKind::Vehicle,
            position: (pa + pb) * 0.5,
            yaw: along.perp().to_angle(),
            speed_mps: 0.0,
            half_length_m: 2.4,
            half_width_m: 1.08,
        };
        let clear = |w: &Pedestrian| box_dist(&car, w.position);
        // At the curb: it waits, longer than `max_wait_s`, while the car stands there.
        let mut w = walker_at(&g, a, vec![b]);
        for _ in 0..((p.max_wait_s / 0.025) as u32 + 200) {
            let (np, z) = w.decide(&g, &p, &[car], 0.025);
            w.arrive(&g, np, z, 0.025);
        }
        assert!((w.position - pa).length() < 1e-4, "stepped off the curb");
        // Already on the crossing when the car stopped there: it stops short of the car's body.
        let mut w = walker_at(&g, a, vec![b]);
        w.position = pa + along * 0.5;
        let mut held = false;
        for _ in 0..400 {
            let (np, z) = w.decide(&g, &p, &[car], 0.025);
            held |= w.held_by_vehicle;
            w.arrive(&g, np, z, 0.025);
            assert!(
                clear(&w) >= PEDESTRIAN_RADIUS_M + VEHICLE_MARGIN_M - 1e-4,
                "walked into the car: {} m from its body",
                clear(&w)
            );
        }
        assert!(held, "the walker was never held by the car");
    }

    #[test]
    fn a_walker_turned_back_on_a_crossing_walks_back_before_it_draws_a_new_way() {
        // Blocked half-way over a crossing, it turns back to the kerb it came from;
        // a new goal drawn then starts at that kerb, which it reaches first instead
        // of cutting across the road to the new route's first node.
        let (g, p, (a, b)) = grid_crosswalk(1.0);
        let (pa, pb) = (g.nodes[a as usize].position, g.nodes[b as usize].position);
        let mut w = walker_at(&g, a, vec![b]);
        w.position = pa + (pb - pa) * 0.5;
        w.note_blocked(&g, true, 0);
        assert_eq!((w.from, w.route.clone()), (b, vec![a]));
        let (np, _) = w.decide(&g, &p, &[], 0.025);
        assert_eq!(w.route.first(), Some(&a), "route {:?}", w.route);
        // Its step heads for the kerb it came from.
        let step = (np - w.position).normalize();
        let back = (pa - w.position).normalize();
        assert!(step.dot(back) > 0.999, "stepped {step} not back {back}");
        // Blocked again on the way back, it turns again, toward the far kerb.
        w.note_blocked(&g, true, 0);
        assert_eq!((w.from, w.route.clone()), (a, vec![b]));
    }

    #[test]
    fn walker_follows_its_route_at_its_speed() {
        let t = grid(3, 3, 60.0);
        let p = PedestrianParams::default();
        let g = WalkGraph::new(&t, &p);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let route = g.random_route(0, false, &mut rng);
        assert!(!route.is_empty());
        for w in std::iter::once(&0)
            .chain(route.iter())
            .collect::<Vec<_>>()
            .windows(2)
        {
            let e = g.edges[*w[0] as usize]
                .iter()
                .find(|e| e.0 == *w[1])
                .expect("route follows edges");
            assert_ne!(e.2, EdgeKind::Jaywalk);
        }
        let mut ped = Pedestrian {
            route,
            ..Pedestrian::new(1, &g, 0, 1.5, false, rng)
        };
        let pp = PedestrianParams { regoal_p: 0.0, ..p };
        let mut total = 0.0;
        for _ in 0..40 {
            let (np, z) = ped.decide(&g, &pp, &[], 0.025);
            total += (np - ped.position).length();
            ped.arrive(&g, np, z, 0.025);
        }
        assert!((total - 1.5).abs() < 1e-3, "{total}");
    }
}
