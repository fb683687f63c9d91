//! The matrix product `out [m, n] (+)= lhs [m, k] x rhs [k, n]` of every CPU path
//! (fused inference, the training convolutions), with one order of summation.
//!
//! **The promise.** Each output is one chain of fused multiply-adds over the inner
//! dimension in ascending order:
//!
//! ```text
//! acc = if accumulate { out[i, j] } else { 0 }
//! for kk in 0..k { acc = fma(lhs[i, kk], rhs[kk, j], acc) }
//! out[i, j] = acc
//! ```
//!
//! A fused multiply-add rounds once, exactly as IEEE 754 defines it, on every CPU.
//! So what follows (the blocking, the packing, the vector width of the micro-kernel,
//! how callers split the work across threads) only decides which outputs are
//! computed together and never changes a bit of any of them. Accumulating calls
//! continue the chain: two calls over `k = 0..a` and `a..b` give the bits of one
//! call over `0..b`.
//!
//! **How it is fast.** The layout is BLIS's (Van Zee and van de Geijn, 2015): the
//! right operand is packed in panels of `NR = 32` columns, k-major, a `KC`-deep
//! block at a time (or once and for all: [`PackedRhs`], the inference weights); the
//! left operand in panels of `MR = 8` rows, k-major, an `MC x KC` block at a time;
//! a micro-kernel ([`micro`]) keeps an `8 x 32` tile of the output in registers
//! through a `KC`-deep block and stores it; the next block loads it and goes on.
//! Tiles cut short by the matrix's edge run on a zero-padded copy.

pub(crate) mod micro;
pub(crate) mod pack;

use crate::isa::Isa;
use micro::{Lhs, PackedLhs, Panel, RowsLhs, Tile};

/// Rows of the left operand per packed panel (rows of a micro-kernel's tile).
pub const MR: usize = 8;
/// Columns of the right operand per packed panel (columns of a micro-kernel's tile).
pub const NR: usize = 32;
/// Depth of one block of the inner dimension: a panel of the right operand is
/// `KC x NR` floats (32 KiB), a panel of the left `MR x KC` (8 KiB).
pub(crate) const KC: usize = 256;
/// Rows of the left operand per packed block (`MC x KC`, 96 KiB: the L2 cache).
const MC: usize = 96;
/// Columns of the right operand per packed block (`KC x NC`, 256 KiB).
const NC: usize = 256;

/// A matrix operand read through strides: element `(i, j)` is
/// `data[i * row_stride + j * col_stride]`.
///
/// A row-major `[rows, cols]` array is `Mat::rows(data, cols)`; its transpose, read
/// without copying, is `Mat::transposed(data, cols)`.
#[derive(Debug, Clone, Copy)]
pub struct Mat<'a> {
    /// The stored values.
    pub data: &'a [f32],
    /// Distance between rows, in elements.
    pub row_stride: usize,
    /// Distance between columns, in elements.
    pub col_stride: usize,
}

impl<'a> Mat<'a> {
    /// A row-major array of `cols` columns.
    pub fn rows(data: &'a [f32], cols: usize) -> Self {
        Mat {
            data,
            row_stride: cols,
            col_stride: 1,
        }
    }

    /// The transpose of a row-major array of `cols` columns (its columns become rows).
    pub fn transposed(data: &'a [f32], cols: usize) -> Self {
        Mat {
            data,
            row_stride: 1,
            col_stride: cols,
        }
    }

    /// Whether a `rows x cols` view stays inside `data`.
    fn holds(&self, rows: usize, cols: usize) -> bool {
        rows == 0
            || cols == 0
            || (rows - 1) * self.row_stride + (cols - 1) * self.col_stride < self.data.len()
    }

    /// Element `(i, j)`.
    fn at(&self, i: usize, j: usize) -> f32 {
        self.data[i * self.row_stride + j * self.col_stride]
    }
}

/// A right operand `[k, n]` packed once for many products (a layer's weights at
/// inference): panels of [`NR`] columns, each `k` rows deep, the last padded with
/// zeros.
#[derive(Debug, Clone, PartialEq)]
pub struct PackedRhs {
    k: usize,
    n: usize,
    panels: Vec<f32>,
}

impl PackedRhs {
    /// Packs `rhs`, a `k x n` view.
    ///
    /// # Panics
    /// If the view leaves its data.
    pub fn new(rhs: Mat, k: usize, n: usize) -> PackedRhs {
        assert!(rhs.holds(k, n), "PackedRhs: view {k} x {n} leaves its data");
        let mut panels = vec![0.0; n.div_ceil(NR) * NR * k];
        for (p, panel) in panels.chunks_exact_mut((k * NR).max(1)).enumerate() {
            pack::rhs_panel(rhs, 0..k, p * NR..((p + 1) * NR).min(n), panel);
        }
        PackedRhs { k, n, panels }
    }

    /// The inner dimension.
    pub fn k(&self) -> usize {
        self.k
    }

    /// The columns.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Panel `p` from depth `pc` on.
    pub(crate) fn panel(&self, p: usize, pc: usize) -> &[f32] {
        &self.panels[(p * self.k + pc) * NR..]
    }
}

/// `out [m, n] (+)= lhs [m, k] x rhs [k, n]`, `out` row-major, on this thread, by the
/// fastest kernel this CPU has ([`Isa::current`]); each output one fixed chain (see
/// the module's promise).
///
/// # Panics
/// If `out` holds fewer than `m * n` values or a view leaves its data.
pub fn gemm(
    out: &mut [f32],
    (m, k, n): (usize, usize, usize),
    lhs: Mat,
    rhs: Mat,
    accumulate: bool,
) {
    gemm_on(Isa::current(), out, (m, k, n), lhs, rhs, accumulate);
}

/// [`gemm`] with the right operand packed beforehand.
///
/// # Panics
/// If `out` holds fewer than `m * rhs.n()` values or `lhs` leaves its data.
pub fn gemm_packed(out: &mut [f32], m: usize, lhs: Mat, rhs: &PackedRhs, accumulate: bool) {
    gemm_packed_on(Isa::current(), out, m, lhs, rhs, accumulate);
}

/// [`gemm`] on a given kernel (tests compare them; a kernel the CPU lacks runs the
/// best one it has).
pub fn gemm_on(
    isa: Isa,
    out: &mut [f32],
    (m, k, n): (usize, usize, usize),
    lhs: Mat,
    rhs: Mat,
    accumulate: bool,
) {
    assert!(rhs.holds(k, n), "gemm: rhs view {k} x {n} leaves its data");
    run(isa, out, (m, k, n), lhs, Rhs::Strided(rhs), accumulate);
}

/// [`gemm_packed`] on a given kernel.
pub fn gemm_packed_on(
    isa: Isa,
    out: &mut [f32],
    m: usize,
    lhs: Mat,
    rhs: &PackedRhs,
    accumulate: bool,
) {
    run(
        isa,
        out,
        (m, rhs.k, rhs.n),
        lhs,
        Rhs::Packed(rhs),
        accumulate,
    );
}

/// Where the right operand's panels come from.
enum Rhs<'a> {
    /// Packed block by block, here.
    Strided(Mat<'a>),
    /// Packed already.
    Packed(&'a PackedRhs),
}

thread_local! {
    /// Per-thread packing buffers: the left block, the right block.
    static BUFFERS: std::cell::RefCell<(Vec<f32>, Vec<f32>)> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// The blocked loops (BLIS's order: column blocks, depth blocks, row blocks, then
/// panels), each tile continuing its outputs' chains block after block.
fn run(
    isa: Isa,
    out: &mut [f32],
    (m, k, n): (usize, usize, usize),
    lhs: Mat,
    rhs: Rhs,
    accumulate: bool,
) {
    assert!(
        out.len() >= m * n,
        "gemm: out holds {} < {m} x {n}",
        out.len()
    );
    assert!(lhs.holds(m, k), "gemm: lhs view {m} x {k} leaves its data");
    if m == 0 || n == 0 {
        return;
    }
    if k == 0 {
        if !accumulate {
            out[..m * n].fill(0.0);
        }
        return;
    }
    let isa = isa.min(Isa::best());
    BUFFERS.with_borrow_mut(|(abuf, bbuf)| {
        abuf.resize(MC * KC, 0.0);
        for jc in (0..n).step_by(NC) {
            let nc = NC.min(n - jc);
            let panels = nc.div_ceil(NR);
            for pc in (0..k).step_by(KC) {
                let kc = KC.min(k - pc);
                // The right block: panel p at `bblock + p * stride`, rows `ldb` apart.
                // A row-major operand is read in place (its rows are contiguous runs
                // of columns); only a panel cut short by the edge, or a transposed
                // operand, is packed.
                let (bblock, stride, ldb, in_place): (&[f32], usize, usize, bool) = match &rhs {
                    Rhs::Strided(r) if r.col_stride == 1 => {
                        let edge_cols = nc % NR;
                        if edge_cols > 0 {
                            bbuf.resize(KC * NR, 0.0);
                            let cols = jc + nc - edge_cols..jc + nc;
                            pack::rhs_panel(*r, pc..pc + kc, cols, bbuf);
                        }
                        (&r.data[pc * r.row_stride + jc..], NR, r.row_stride, true)
                    }
                    Rhs::Strided(r) => {
                        bbuf.resize(panels * KC * NR, 0.0);
                        for p in 0..panels {
                            let cols = jc + p * NR..(jc + (p + 1) * NR).min(n);
                            pack::rhs_panel(*r, pc..pc + kc, cols, &mut bbuf[p * kc * NR..]);
                        }
                        (&bbuf[..], kc * NR, NR, false)
                    }
                    Rhs::Packed(r) => (r.panel(jc / NR, pc), k * NR, NR, false),
                };
                let load = accumulate || pc > 0;
                // A row-major left operand is read in place, all but a panel cut
                // short by the last row; any other layout is packed.
                let lhs_in_place = lhs.col_stride == 1;
                for ic in (0..m).step_by(MC) {
                    let mc = MC.min(m - ic);
                    let row_panels = mc.div_ceil(MR);
                    for p in 0..row_panels {
                        let rows = ic + p * MR..(ic + (p + 1) * MR).min(m);
                        if !lhs_in_place || rows.len() < MR {
                            pack::lhs_panel(lhs, rows, pc..pc + kc, &mut abuf[p * kc * MR..]);
                        }
                    }
                    for jp in 0..panels {
                        let j0 = jc + jp * NR;
                        let cols = NR.min(n - j0);
                        let panel = if in_place && cols < NR {
                            Panel {
                                b: bbuf.as_ptr(),
                                ldb: NR,
                            }
                        } else {
                            let b = &bblock[jp * stride..];
                            assert!(
                                b.len() >= (kc - 1) * ldb + NR,
                                "gemm: a panel leaves its data"
                            );
                            Panel { b: b.as_ptr(), ldb }
                        };
                        for ip in 0..row_panels {
                            let i0 = ic + ip * MR;
                            let rows = MR.min(m - i0);
                            let a = &abuf[ip * kc * MR..][..kc * MR];
                            let in_place = lhs_in_place && rows == MR;
                            let rows_at = (i0 * lhs.row_stride + pc).min(lhs.data.len());
                            let a_rows = RowsLhs {
                                x: lhs.data[rows_at..].as_ptr(),
                                lda: lhs.row_stride,
                            };
                            let dest = Dest {
                                out: &mut out[..m * n],
                                at: i0 * n + j0,
                                ldc: n,
                                rows,
                                width: cols,
                            };
                            // SAFETY: the packed panel holds kc * MR floats; rows read in
                            // place lie in the view (checked by `holds`); the right panel
                            // holds kc rows of NR; `tile_on` checks the destination.
                            unsafe {
                                match in_place {
                                    true => tile_on(isa, kc, &a_rows, &panel, dest, load),
                                    false => {
                                        tile_on(isa, kc, &PackedLhs(a.as_ptr()), &panel, dest, load)
                                    }
                                }
                            };
                        }
                    }
                }
            }
        }
    });
}

/// Where a micro-kernel call writes: `rows x width` outputs of `out` from `at`, rows
/// `ldc` apart (at most an `MR x NR` tile).
pub(crate) struct Dest<'o> {
    pub out: &'o mut [f32],
    pub at: usize,
    pub ldc: usize,
    pub rows: usize,
    pub width: usize,
}

/// One micro-kernel call into `dest`: in place when it is a whole `MR x NR` tile, else
/// through a zero-padded `MR x NR` copy (loaded from `dest` first when `load`). The
/// outputs' chains are the same either way.
///
/// # Safety
/// `a` reads `MR x kc` elements inside its data, `b` holds `kc` rows, and `isa` is one
/// this CPU has (the destination is checked here).
pub(crate) unsafe fn tile_on<A: Lhs, B: micro::Rhs>(
    isa: Isa,
    kc: usize,
    a: &A,
    b: &B,
    dest: Dest<'_>,
    load: bool,
) {
    let Dest {
        out,
        at,
        ldc,
        rows,
        width,
    } = dest;
    if rows == MR && width == NR {
        assert!(
            at + (MR - 1) * ldc + NR <= out.len(),
            "a tile leaves its output"
        );
        let tile = Tile {
            c: out[at..].as_mut_ptr(),
            ldc,
        };
        // SAFETY: the caller's operands; the tile's MR rows of NR lie in `out` (asserted).
        unsafe { kernel_on(isa, kc, a, b, &tile, load) };
        return;
    }
    let mut edge = [0.0f32; MR * NR];
    if load {
        for i in 0..rows {
            edge[i * NR..][..width].copy_from_slice(&out[at + i * ldc..][..width]);
        }
    }
    let tile = Tile {
        c: edge.as_mut_ptr(),
        ldc: NR,
    };
    // SAFETY: the caller's operands, into the MR x NR copy.
    unsafe { kernel_on(isa, kc, a, b, &tile, load) };
    for i in 0..rows {
        out[at + i * ldc..][..width].copy_from_slice(&edge[i * NR..][..width]);
    }
}

/// One micro-kernel call on `isa`, any left operand.
///
/// # Safety
/// `a` reads `MR x kc` elements inside its data, the panel holds `kc` rows, the tile
/// lies in one allocation, and `isa` is one this CPU has.
pub(crate) unsafe fn kernel_on<A: Lhs, B: micro::Rhs>(
    isa: Isa,
    kc: usize,
    a: &A,
    b: &B,
    tile: &Tile,
    load: bool,
) {
    // SAFETY: the caller's contract, and the panels' sizes checked above.
    unsafe {
        match isa {
            #[cfg(target_arch = "x86_64")]
            Isa::Avx512 => micro::avx512(kc, a, b, tile, load),
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => micro::avx2(kc, a, b, tile, load),
            _ => micro::scalar(kc, a, b, tile, load),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests;
