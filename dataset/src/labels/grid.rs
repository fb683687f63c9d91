//! The local state grid of the labeller: cells in the ego's frame at t = 0,
//! yaw nodes relative to its heading, speed nodes.
//!
//! A node grid (values live on the nodes, linear interpolation between
//! them, clamped at the yaw and speed ends, zero outside in x and y): one
//! convention for the dynamics, the rewards and the look-ups, unlike WoR's
//! mix of bin centres and edges (WOR.md §2).

use glam::Vec2;

/// The shape of the state grid.
#[derive(Debug, Clone, PartialEq)]
pub struct GridSpec {
    /// Node spacing in x and y (metres).
    pub cell_m: f32,
    /// Rearmost node, along the ego's heading (metres; negative is behind).
    pub x_min_m: f32,
    /// Foremost node (metres).
    pub x_max_m: f32,
    /// Nodes span -y_half_m..=y_half_m to the ego's left (metres).
    pub y_half_m: f32,
    /// Yaw nodes relative to the ego's heading at t = 0 (radians, ascending).
    pub yaws_rad: Vec<f32>,
    /// Speed nodes (metres per second, ascending, the first 0).
    pub speeds_mps: Vec<f32>,
}

impl Default for GridSpec {
    /// 0.5 m cells from 4 m behind to 14 m ahead and 9 m to each side (the
    /// ego covers at most ~10 m in the 1.25 s horizon), yaws -85..85 deg
    /// every 10 deg, speeds 0..8 m/s every 2 m/s.
    ///
    /// The ego's start state sits half a cell and half a yaw step away from
    /// every node, on purpose. Linear interpolation underestimates a value
    /// near its peak by an amount that grows fast as a state leaves a node and
    /// is flat half-way between nodes. Were the ego on a node, driving
    /// straight (which stays on the nodes) would look better than every
    /// steer by a grid artefact alone; half-way, nearby actions share nearly
    /// the same error. (The ±30 deg views and the 1, 3, 5, 7 m/s speed bins
    /// are half-way too.)
    fn default() -> Self {
        GridSpec {
            cell_m: 0.5,
            x_min_m: -4.25,
            x_max_m: 14.25,
            y_half_m: 9.25,
            yaws_rad: (-8..=9)
                .map(|k| (k as f32 * 10.0 - 5.0).to_radians())
                .collect(),
            speeds_mps: vec![0.0, 2.0, 4.0, 6.0, 8.0],
        }
    }
}

/// Linear interpolation position of `x` among ascending `nodes`, clamped:
/// (lower node index, weight of the upper node).
pub fn locate(nodes: &[f32], x: f32) -> (usize, f32) {
    let n = nodes.len();
    if n < 2 || x <= nodes[0] {
        return (0, 0.0);
    }
    if x >= nodes[n - 1] {
        return (n - 2, 1.0);
    }
    let i = nodes
        .partition_point(|&v| v <= x)
        .saturating_sub(1)
        .min(n - 2);
    let t = (x - nodes[i]) / (nodes[i + 1] - nodes[i]);
    (i, t)
}

/// Weights of the "hat" around `x` on `nodes` (linear interpolation weights):
/// `w[k]` is how much of a quantity at `x` goes to node `k`. Outside the
/// nodes, within one spacing, the end node gets the falling share; further
/// out nothing.
pub fn hat_weights(nodes: &[f32], x: f32, out: &mut [f32]) {
    out.fill(0.0);
    let n = nodes.len();
    if n == 0 {
        return;
    }
    if n == 1 {
        out[0] = 1.0;
        return;
    }
    if x < nodes[0] {
        let t = 1.0 - (nodes[0] - x) / (nodes[1] - nodes[0]);
        out[0] = t.max(0.0);
        return;
    }
    if x > nodes[n - 1] {
        let t = 1.0 - (x - nodes[n - 1]) / (nodes[n - 1] - nodes[n - 2]);
        out[n - 1] = t.max(0.0);
        return;
    }
    let (i, t) = locate(nodes, x);
    out[i] = 1.0 - t;
    out[i + 1] = t;
}

/// The node grid with its padded planes.
#[derive(Debug, Clone)]
pub struct Grid {
    /// The spec it was made from.
    pub spec: GridSpec,
    /// Nodes along x.
    pub nx: usize,
    /// Nodes along y.
    pub ny: usize,
    /// Zero cells around each plane, so shifted reads need no bounds checks.
    pub pad: usize,
}

impl Grid {
    /// A grid for `spec`; `max_move_m` is the longest move of one step.
    pub fn new(spec: GridSpec, max_move_m: f32) -> Grid {
        let nx = ((spec.x_max_m - spec.x_min_m) / spec.cell_m).round() as usize + 1;
        let ny = (2.0 * spec.y_half_m / spec.cell_m).round() as usize + 1;
        let pad = (max_move_m / spec.cell_m).ceil() as usize + 2;
        Grid { spec, nx, ny, pad }
    }

    /// Nodes of one unpadded plane.
    pub fn cells(&self) -> usize {
        self.nx * self.ny
    }

    /// Row length of a padded plane.
    pub fn stride(&self) -> usize {
        self.nx + 2 * self.pad
    }

    /// Values in one padded plane.
    pub fn padded_len(&self) -> usize {
        self.stride() * (self.ny + 2 * self.pad)
    }

    /// Index in a padded plane of node (i, j).
    pub fn padded_at(&self, i: usize, j: usize) -> usize {
        (j + self.pad) * self.stride() + i + self.pad
    }

    /// Position of node (i, j) in the ego frame: forward, left (metres).
    pub fn node(&self, i: usize, j: usize) -> Vec2 {
        Vec2::new(
            self.spec.x_min_m + i as f32 * self.spec.cell_m,
            -self.spec.y_half_m + j as f32 * self.spec.cell_m,
        )
    }

    /// Continuous node coordinates (i, j) of a point in the ego frame.
    pub fn to_node(&self, p: Vec2) -> Vec2 {
        Vec2::new(
            (p.x - self.spec.x_min_m) / self.spec.cell_m,
            (p.y + self.spec.y_half_m) / self.spec.cell_m,
        )
    }

    /// Bilinear read of a padded plane at continuous node coordinates: the
    /// padding is zero, so values fade to 0 over one cell outside the grid.
    pub fn sample(&self, plane: &[f32], at: Vec2) -> f32 {
        let pad = self.pad as f32;
        let (fi, fj) = (at.x.floor() + pad, at.y.floor() + pad);
        let s = self.stride();
        let rows = self.ny + 2 * self.pad;
        if !(fi >= 0.0 && fj >= 0.0 && fi + 1.0 < s as f32 && fj + 1.0 < rows as f32) {
            return 0.0;
        }
        let (tx, ty) = (at.x - at.x.floor(), at.y - at.y.floor());
        let k = fj as usize * s + fi as usize;
        (1.0 - ty) * ((1.0 - tx) * plane[k] + tx * plane[k + 1])
            + ty * ((1.0 - tx) * plane[k + s] + tx * plane[k + s + 1])
    }
}

/// A frame between the world and the grid: the ego's pose at t = 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EgoFrame {
    /// The ego's centre (metres, world frame).
    pub origin: Vec2,
    /// The ego's heading (radians).
    pub yaw: f32,
}

impl EgoFrame {
    /// A world point in the ego frame.
    pub fn to_local(&self, p: Vec2) -> Vec2 {
        Vec2::from_angle(-self.yaw).rotate(p - self.origin)
    }

    /// An ego-frame point in the world.
    pub fn to_world(&self, p: Vec2) -> Vec2 {
        self.origin + Vec2::from_angle(self.yaw).rotate(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_origin_lies_half_way_between_nodes_and_samples_bilinearly() {
        let g = Grid::new(GridSpec::default(), 2.5);
        let o = g.to_node(Vec2::ZERO);
        assert_eq!((o.x.fract(), o.y.fract()), (0.5, 0.5));
        // The views (0 and +-30 deg) lie half-way between yaw nodes too.
        let step = g.spec.yaws_rad[1] - g.spec.yaws_rad[0];
        for view in [0f32, 30.0, -30.0] {
            let gap = g
                .spec
                .yaws_rad
                .iter()
                .map(|y| (y - view.to_radians()).abs())
                .fold(f32::MAX, f32::min);
            assert!((gap - step / 2.0).abs() < 1e-4, "view {view}: {gap}");
        }
        let mut plane = vec![0.0; g.padded_len()];
        let (i, j) = (o.x as usize, o.y as usize);
        plane[g.padded_at(i, j)] = 1.0;
        assert_eq!(g.sample(&plane, o), 0.25);
        assert_eq!(g.sample(&plane, o - Vec2::splat(0.5)), 1.0);
        assert_eq!(g.sample(&plane, Vec2::new(-3.0, 3.0)), 0.0);
    }

    #[test]
    fn hat_weights_split_between_neighbours_and_fade_outside() {
        let nodes = [0.0, 2.0, 4.0];
        let mut w = [0.0; 3];
        hat_weights(&nodes, 3.5, &mut w);
        assert_eq!(w, [0.0, 0.25, 0.75]);
        hat_weights(&nodes, 5.0, &mut w);
        assert_eq!(w, [0.0, 0.0, 0.5]);
        hat_weights(&nodes, 7.0, &mut w);
        assert_eq!(w, [0.0; 3]);
        assert_eq!(locate(&nodes, 9.0), (1, 1.0));
    }

    #[test]
    fn ego_frame_round_trips() {
        let f = EgoFrame {
            origin: Vec2::new(10.0, -3.0),
            yaw: 1.0,
        };
        let p = Vec2::new(4.0, 7.0);
        assert!((f.to_world(f.to_local(p)) - p).length() < 1e-5);
        let ahead = f.to_world(Vec2::X);
        assert!((ahead - f.origin - Vec2::from_angle(1.0)).length() < 1e-6);
    }
}
