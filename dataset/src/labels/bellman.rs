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

/// The nodes a backup computes: x nodes `i`, y nodes `j`, yaw nodes `k`
/// (half-open ranges). Nodes outside keep the value 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    /// x nodes.
    pub i: (usize, usize),
    /// y nodes.
    pub j: (usize, usize),
    /// Yaw nodes.
    pub k: (usize, usize),
}

impl Region {
    /// Every node of the grid.
    pub fn all(grid: &Grid) -> Region {
        Region {
            i: (0, grid.nx),
            j: (0, grid.ny),
            k: (0, grid.spec.yaws_rad.len()),
        }
    }
}

/// The regions the ego can reach after 1, 2, ..., `steps` steps from the
/// start states (the origin, yaws within `start_yaws`, speeds of `first`),
/// moving by `first` once and by `later` after that; each grown by one node
/// so interpolated reads stay inside. Only there are values ever read, so
/// only there does the recursion compute them (most of the grid lies out of
/// reach in the early steps).
pub fn reach(
    grid: &Grid,
    start_yaws: (f32, f32),
    first: &[[Move; NUM_ACTIONS]],
    later: &[[Move; NUM_ACTIONS]],
    steps: usize,
) -> Vec<Region> {
    let (mut lo, mut hi) = (Vec2::ZERO, Vec2::ZERO);
    let (mut ylo, mut yhi) = start_yaws;
    let yaws = &grid.spec.yaws_rad;
    let mut out = Vec::with_capacity(steps);
    for t in 0..steps {
        let moves = if t == 0 { first } else { later };
        let mut headings: Vec<f32> = yaws
            .iter()
            .copied()
            .filter(|&y| y > ylo && y < yhi)
            .collect();
        headings.extend([ylo, yhi]);
        let (mut dlo, mut dhi) = (Vec2::splat(f32::MAX), Vec2::splat(f32::MIN));
        let (mut alo, mut ahi) = (f32::MAX, f32::MIN);
        for &h in &headings {
            for m in moves.iter().flatten() {
                let d = Vec2::from_angle(h).rotate(m.delta);
                dlo = dlo.min(d);
                dhi = dhi.max(d);
                alo = alo.min(m.dyaw);
                ahi = ahi.max(m.dyaw);
            }
        }
        lo += dlo;
        hi += dhi;
        ylo += alo;
        yhi += ahi;
        let a = grid.to_node(lo);
        let b = grid.to_node(hi);
        let clamp = |v: f32, n: usize| (v.max(0.0) as usize).min(n);
        let (k0, _) = locate(yaws, ylo);
        let (k1, _) = locate(yaws, yhi);
        out.push(Region {
            i: (
                clamp(a.x.floor() - 1.0, grid.nx),
                clamp(b.x.ceil() + 2.0, grid.nx),
            ),
            j: (
                clamp(a.y.floor() - 1.0, grid.ny),
                clamp(b.y.ceil() + 2.0, grid.ny),
            ),
            k: (k0.saturating_sub(1), (k1 + 3).min(yaws.len())),
        });
    }
    out
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
/// into `out`, over the padded rows and columns the shifted read of
/// `region` touches.
#[inline(always)]
fn blend(grid: &Grid, w: &[Vec<f32>], t: &Transition, region: &Region, out: &mut [f32]) {
    let speeds = grid.spec.speeds_mps.len();
    let (k, tk) = t.yaw;
    let (l, tl) = t.speed;
    let parts = [
        ((1.0 - tk) * (1.0 - tl), k * speeds + l),
        ((1.0 - tk) * tl, k * speeds + l + 1),
        (tk * (1.0 - tl), (k + 1) * speeds + l),
        (tk * tl, (k + 1) * speeds + l + 1),
    ];
    // The planes with a weight (at most four), without allocating.
    let mut kept: [(f32, &[f32]); 4] = [(0.0, &[]); 4];
    let mut n = 0;
    for &(wgt, p) in &parts {
        if wgt != 0.0 {
            kept[n] = (wgt, w[p].as_slice());
            n += 1;
        }
    }
    let parts = &kept[..n];
    let stride = grid.stride();
    let row0 = (grid.pad as isize + t.shift.1) as usize;
    let col0 = (grid.pad as isize + t.shift.0) as usize;
    let (i0, i1) = region.i;
    let (j0, j1) = region.j;
    for r in row0 + j0..row0 + j1 + 1 {
        let span = r * stride + col0 + i0..r * stride + col0 + i1 + 1;
        let dst = &mut out[span.clone()];
        match parts {
            [(a, pa)] => {
                for (d, x) in dst.iter_mut().zip(&pa[span]) {
                    *d = a * x;
                }
            }
            [(a, pa), (b, pb)] => {
                for ((d, x), y) in dst.iter_mut().zip(&pa[span.clone()]).zip(&pb[span]) {
                    *d = a * x + b * y;
                }
            }
            _ => {
                dst.fill(0.0);
                for &(wgt, plane) in parts {
                    for (d, s) in dst.iter_mut().zip(&plane[span.clone()]) {
                        *d += wgt * s;
                    }
                }
            }
        }
    }
}

/// One backup: `v[yaw * speeds + speed]` (unpadded) = max over actions of
/// the padded planes `w` read at each node's next state, for the nodes of
/// `region` (0 elsewhere).
///
/// On x86-64 CPUs with AVX2 the same code is compiled for 256-bit vectors
/// and chosen at run time (the labeller's hot loop, about 80 % of its time;
/// 1.15-1.2x faster labelling here; an AVX-512 build was slower on our rows
/// of about 36 nodes).
/// Every lane computes the same expression in the same order and nothing is
/// fused (Rust never contracts a * b + c into an FMA), so the values are
/// bit for bit those of the portable build: datasets stay reproducible
/// across machines.
pub fn backup(
    grid: &Grid,
    trans: &[Transition],
    w: &[Vec<f32>],
    v: &mut [Vec<f32>],
    region: &Region,
    scratch: &mut Vec<f32>,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, checked just above.
        unsafe { backup_avx2(grid, trans, w, v, region, scratch) };
        return;
    }
    backup_portable(grid, trans, w, v, region, scratch);
}

/// [`backup`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn backup_avx2(
    grid: &Grid,
    trans: &[Transition],
    w: &[Vec<f32>],
    v: &mut [Vec<f32>],
    region: &Region,
    scratch: &mut Vec<f32>,
) {
    backup_impl(grid, trans, w, v, region, scratch);
}

/// [`backup`] for any CPU (the baseline target's vectors).
pub fn backup_portable(
    grid: &Grid,
    trans: &[Transition],
    w: &[Vec<f32>],
    v: &mut [Vec<f32>],
    region: &Region,
    scratch: &mut Vec<f32>,
) {
    backup_impl(grid, trans, w, v, region, scratch);
}

/// The body of [`backup`], inlined into each compiled variant.
#[inline(always)]
fn backup_impl(
    grid: &Grid,
    trans: &[Transition],
    w: &[Vec<f32>],
    v: &mut [Vec<f32>],
    region: &Region,
    scratch: &mut Vec<f32>,
) {
    scratch.resize(grid.padded_len(), 0.0);
    let stride = grid.stride();
    let nx = grid.nx;
    let speeds = grid.spec.speeds_mps.len();
    let (i0, i1) = region.i;
    let (j0, j1) = region.j;
    for (node, out) in v.iter_mut().enumerate() {
        out.fill(0.0);
        let k = node / speeds;
        if k < region.k.0 || k >= region.k.1 {
            continue;
        }
        for t in &trans[node * NUM_ACTIONS..(node + 1) * NUM_ACTIONS] {
            blend(grid, w, t, region, scratch);
            let (fx, fy) = t.frac;
            let (w00, w10, w01, w11) = (
                (1.0 - fx) * (1.0 - fy),
                fx * (1.0 - fy),
                (1.0 - fx) * fy,
                fx * fy,
            );
            let row0 = (grid.pad as isize + t.shift.1) as usize;
            let col0 = (grid.pad as isize + t.shift.0) as usize;
            for j in j0..j1 {
                let a = (row0 + j) * stride + col0 + i0;
                let n = i1 - i0;
                let top = &scratch[a..a + n + 1];
                let bottom = &scratch[a + stride..a + stride + n + 1];
                let dst = &mut out[j * nx + i0..j * nx + i1];
                for i in 0..n {
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
        backup(
            &grid,
            &trans,
            &w,
            &mut v,
            &Region::all(&grid),
            &mut Vec::new(),
        );
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
        // The run-time choice (AVX2 where the CPU has it) gives the portable
        // build's values bit for bit, on the whole grid and on a region.
        for region in [
            Region::all(&grid),
            Region {
                i: (2, 9),
                j: (1, 7),
                k: (0, 2),
            },
        ] {
            let mut portable = vec![vec![0.0; grid.cells()]; planes];
            backup_portable(&grid, &trans, &w, &mut portable, &region, &mut Vec::new());
            let mut chosen = vec![vec![0.0; grid.cells()]; planes];
            backup(&grid, &trans, &w, &mut chosen, &region, &mut Vec::new());
            let bits =
                |v: &[Vec<f32>]| -> Vec<u32> { v.iter().flatten().map(|x| x.to_bits()).collect() };
            assert_eq!(bits(&chosen), bits(&portable));
            assert!(portable.iter().flatten().any(|&x| x > 0.0));
        }
    }
}
