//! The backward recursion over the state grid (WoR `rails/bellman.py`).
//!
//! `W_t = free_t * (R_t + V_t)` on every node, `V_T = 0`, and
//! `V_t(s) = max_a W_{t+1}(next(s, a))`, read by linear interpolation in x,
//! y, yaw and speed. Because a move depends only on the yaw and speed node,
//! every node of one (yaw, speed, action) triple shifts by the same offset:
//! the interpolation is four plane blends and one shifted bilinear read over
//! contiguous rows, which the compiler vectorises.

use glam::Vec2;

use super::dynamics::Move;
use super::grid::{Grid, locate};
use crate::action::NUM_ACTIONS;

/// How one (yaw, speed, action) triple moves a node: integer and fractional
/// shifts in nodes, and where the next yaw and speed fall among the nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition {
    /// Whole-node shift in x and y.
    pub shift: (isize, isize),
    /// Fractional shift in x and y (0..1).
    pub frac: (f32, f32),
    /// Lower yaw node and the upper node's weight.
    pub yaw: (usize, f32),
    /// Lower speed node and the upper node's weight.
    pub speed: (usize, f32),
}

/// Transitions `[yaw][speed][action]` for every node triple of `grid`.
pub fn transitions(grid: &Grid, moves: &[[Move; NUM_ACTIONS]]) -> Vec<Transition> {
    let spec = &grid.spec;
    let mut out = Vec::with_capacity(spec.yaws_rad.len() * spec.speeds_mps.len() * NUM_ACTIONS);
    for &yaw in &spec.yaws_rad {
        for row in moves {
            for m in row {
                out.push(transition(grid, yaw, m));
            }
        }
    }
    out
}

/// Where a move from yaw `yaw` (radians, ego frame) lands, in node units.
pub fn transition(grid: &Grid, yaw: f32, m: &Move) -> Transition {
    let d = Vec2::from_angle(yaw).rotate(m.delta) / grid.spec.cell_m;
    let (fx, fy) = (d.x.floor(), d.y.floor());
    Transition {
        shift: (fx as isize, fy as isize),
        frac: (d.x - fx, d.y - fy),
        yaw: locate(&grid.spec.yaws_rad, yaw + m.dyaw),
        speed: locate(&grid.spec.speeds_mps, m.speed_mps),
    }
}

/// Blends the four (yaw, speed) planes of `w` a transition lands between
/// into `out`, over the padded rows and columns the shifted read touches.
fn blend(grid: &Grid, w: &[Vec<f32>], t: &Transition, out: &mut [f32]) {
    let speeds = grid.spec.speeds_mps.len();
    let (k, tk) = t.yaw;
    let (l, tl) = t.speed;
    let parts = [
        ((1.0 - tk) * (1.0 - tl), k * speeds + l),
        ((1.0 - tk) * tl, k * speeds + l + 1),
        (tk * (1.0 - tl), (k + 1) * speeds + l),
        (tk * tl, (k + 1) * speeds + l + 1),
    ];
    let stride = grid.stride();
    let row0 = (grid.pad as isize + t.shift.1) as usize;
    let col0 = (grid.pad as isize + t.shift.0) as usize;
    let cols = grid.nx + 1;
    for r in row0..row0 + grid.ny + 1 {
        let span = r * stride + col0..r * stride + col0 + cols;
        let dst = &mut out[span.clone()];
        dst.fill(0.0);
        for &(wgt, plane) in &parts {
            if wgt == 0.0 {
                continue;
            }
            for (d, s) in dst.iter_mut().zip(&w[plane][span.clone()]) {
                *d += wgt * s;
            }
        }
    }
}

/// One backup: `v[yaw * speeds + speed]` (unpadded) = max over actions of
/// the padded planes `w` read at each node's next state.
pub fn backup(
    grid: &Grid,
    trans: &[Transition],
    w: &[Vec<f32>],
    v: &mut [Vec<f32>],
    scratch: &mut Vec<f32>,
) {
    scratch.resize(grid.padded_len(), 0.0);
    let stride = grid.stride();
    let (nx, ny) = (grid.nx, grid.ny);
    for (node, out) in v.iter_mut().enumerate() {
        out.fill(0.0);
        for t in &trans[node * NUM_ACTIONS..(node + 1) * NUM_ACTIONS] {
            blend(grid, w, t, scratch);
            let (fx, fy) = t.frac;
            let (w00, w10, w01, w11) = (
                (1.0 - fx) * (1.0 - fy),
                fx * (1.0 - fy),
                (1.0 - fx) * fy,
                fx * fy,
            );
            let row0 = (grid.pad as isize + t.shift.1) as usize;
            let col0 = (grid.pad as isize + t.shift.0) as usize;
            for j in 0..ny {
                let a = (row0 + j) * stride + col0;
                let top = &scratch[a..a + nx + 1];
                let bottom = &scratch[a + stride..a + stride + nx + 1];
                let dst = &mut out[j * nx..(j + 1) * nx];
                for i in 0..nx {
                    let q = w00 * top[i] + w10 * top[i + 1] + w01 * bottom[i] + w11 * bottom[i + 1];
                    if q > dst[i] {
                        dst[i] = q;
                    }
                }
            }
        }
    }
}

/// `W` at one continuous state: local position (metres), yaw (radians, ego
/// frame), speed (metres per second); 0 off the grid in x and y.
pub fn sample(grid: &Grid, w: &[Vec<f32>], p: Vec2, yaw: f32, speed_mps: f32) -> f32 {
    let speeds = grid.spec.speeds_mps.len();
    let (k, tk) = locate(&grid.spec.yaws_rad, yaw);
    let (l, tl) = locate(&grid.spec.speeds_mps, speed_mps);
    let at = grid.to_node(p);
    let mut q = 0.0;
    for (wk, kk) in [(1.0 - tk, k), (tk, k + 1)] {
        for (wl, ll) in [(1.0 - tl, l), (tl, l + 1)] {
            let wgt = wk * wl;
            if wgt != 0.0 {
                q += wgt * grid.sample(&w[kk * speeds + ll], at);
            }
        }
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::labels::grid::GridSpec;

    /// The plane-shift backup equals a direct interpolation node by node.
    #[test]
    fn backup_matches_direct_interpolation() {
        let spec = GridSpec {
            cell_m: 0.5,
            x_min_m: -2.0,
            x_max_m: 4.0,
            y_half_m: 3.0,
            yaws_rad: vec![-0.5, 0.0, 0.5],
            speeds_mps: vec![0.0, 2.0, 4.0],
        };
        let grid = Grid::new(spec, 1.5);
        let moves: Vec<[Move; NUM_ACTIONS]> = (0..3)
            .map(|l| {
                std::array::from_fn(|a| Move {
                    delta: Vec2::new(0.13 * a as f32 % 1.1, 0.07 * (a as f32 - 13.0) % 0.9),
                    dyaw: 0.02 * (a as f32 - 14.0),
                    speed_mps: (l as f32 * 2.0 + 0.3 * (a as f32 % 5.0) - 0.5).max(0.0),
                })
            })
            .collect();
        let trans = transitions(&grid, &moves);
        let planes = 9;
        let w: Vec<Vec<f32>> = (0..planes)
            .map(|p| {
                let mut plane = vec![0.0; grid.padded_len()];
                for j in 0..grid.ny {
                    for i in 0..grid.nx {
                        plane[grid.padded_at(i, j)] = ((i * 7 + j * 3 + p * 5) % 11) as f32 * 0.1;
                    }
                }
                plane
            })
            .collect();
        let mut v = vec![vec![0.0; grid.cells()]; planes];
        backup(&grid, &trans, &w, &mut v, &mut Vec::new());
        for (k, &yaw) in grid.spec.yaws_rad.iter().enumerate() {
            for (l, row) in moves.iter().enumerate() {
                for j in 0..grid.ny {
                    for i in 0..grid.nx {
                        let p = grid.node(i, j);
                        let best = row
                            .iter()
                            .map(|m| {
                                sample(
                                    &grid,
                                    &w,
                                    p + Vec2::from_angle(yaw).rotate(m.delta),
                                    yaw + m.dyaw,
                                    m.speed_mps,
                                )
                            })
                            .fold(0.0f32, f32::max);
                        let got = v[k * 3 + l][j * grid.nx + i];
                        assert!(
                            (got - best).abs() < 1e-5,
                            "node ({i},{j}) yaw {k} speed {l}: {got} vs {best}"
                        );
                    }
                }
            }
        }
    }
}
