//! The micro-kernels: one `MR x NR` tile of the output from `MR` rows of the left
//! operand (read through [`Lhs`]: a packed panel, or an image read in place) and an
//! `NR`-column panel of the right.
//!
//! Each output `c[i][j]` is `acc = fma(a(i, kk), b[kk][j], acc)` for `kk` in
//! `0..kc`, in order, starting from 0 or from the value in `c` (`load`). The vector
//! kernels hold a row of the tile across vector lanes and broadcast `a`; a lane never
//! talks to another, so a lane's chain is the scalar one, bit for bit.

use super::{MR, NR};

/// The output tile a kernel writes: `MR` rows `ldc` floats apart, `NR` columns each.
pub(crate) struct Tile {
    pub c: *mut f32,
    pub ldc: usize,
}

/// How a kernel reads its right operand: row `kk`'s `NR` consecutive floats.
pub(crate) trait Rhs {
    /// Where row `kk < kc` starts.
    ///
    /// # Safety
    /// `kk` is inside the rows the caller handed over.
    unsafe fn row(&self, kk: usize) -> *const f32;
}

/// The right operand's panel: `kc` rows of `NR` floats, `ldb` floats apart (`NR` when
/// packed; the matrix's row stride when read in place).
pub(crate) struct Panel {
    pub b: *const f32,
    pub ldb: usize,
}

impl Rhs for Panel {
    #[inline(always)]
    unsafe fn row(&self, kk: usize) -> *const f32 {
        // SAFETY: the caller's panel holds kc rows, ldb apart.
        unsafe { self.b.add(kk * self.ldb) }
    }
}

/// Rows gathered in place from an image: row `kk` is `NR` floats from
/// `x[base + offsets[kk]]` (a convolution's tap `kk` under `NR` neighbouring output
/// pixels of one row, stride 1).
pub(crate) struct GatherRhs {
    pub x: *const f32,
    pub base: usize,
    pub offsets: *const u32,
}

impl Rhs for GatherRhs {
    #[inline(always)]
    unsafe fn row(&self, kk: usize) -> *const f32 {
        // SAFETY: the caller's offsets hold kc entries, each NR floats inside the image
        // from `base`.
        unsafe { self.x.add(self.base + *self.offsets.add(kk) as usize) }
    }
}

/// How a kernel reads its `MR` rows of the left operand: element `(i, kk)`.
pub(crate) trait Lhs {
    /// Row `i < MR`, inner index `kk < kc`.
    ///
    /// # Safety
    /// The indices are inside the rows the caller handed over.
    unsafe fn at(&self, i: usize, kk: usize) -> f32;
}

/// A packed panel: `a[kk * MR + i]`.
pub(crate) struct PackedLhs(pub *const f32);

impl Lhs for PackedLhs {
    #[inline(always)]
    unsafe fn at(&self, i: usize, kk: usize) -> f32 {
        // SAFETY: the caller's panel holds kc * MR floats.
        unsafe { *self.0.add(kk * MR + i) }
    }
}

/// Rows read in place from a row-major matrix: `x[i * lda + kk]`.
pub(crate) struct RowsLhs {
    pub x: *const f32,
    pub lda: usize,
}

impl Lhs for RowsLhs {
    #[inline(always)]
    unsafe fn at(&self, i: usize, kk: usize) -> f32 {
        // SAFETY: the caller's rows hold kc elements each, lda apart.
        unsafe { *self.x.add(i * self.lda + kk) }
    }
}

/// Rows gathered in place (an implicit im2col): row `i`'s element `kk` is
/// `x[rows[i] + offsets[kk]]`, so a convolution reads its input image directly.
pub(crate) struct GatherLhs {
    pub x: *const f32,
    pub rows: [usize; MR],
    pub offsets: *const u32,
}

impl Lhs for GatherLhs {
    #[inline(always)]
    unsafe fn at(&self, i: usize, kk: usize) -> f32 {
        // SAFETY: the caller's offsets hold kc entries, each inside the image from
        // every row's start.
        unsafe { *self.x.add(self.rows[i] + *self.offsets.add(kk) as usize) }
    }
}

/// The portable kernel: the definition, in plain Rust.
///
/// # Safety
/// `a` reads `MR` rows of `kc` elements, the panel's `kc` rows of `NR` floats and the
/// tile's `MR` rows of `NR` floats each lie inside one allocation.
pub(crate) unsafe fn scalar<A: Lhs, B: Rhs>(kc: usize, a: &A, p: &B, t: &Tile, load: bool) {
    let mut acc = [[0.0f32; NR]; MR];
    if load {
        for (i, row) in acc.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                // SAFETY: row i, column j of the tile (the caller's contract).
                *v = unsafe { *t.c.add(i * t.ldc + j) };
            }
        }
    }
    for kk in 0..kc {
        // SAFETY: kk < kc, so the panel row lies inside the panel.
        let bk = unsafe { p.row(kk) };
        for (i, row) in acc.iter_mut().enumerate() {
            // SAFETY: i < MR, kk < kc.
            let ai = unsafe { a.at(i, kk) };
            for (j, v) in row.iter_mut().enumerate() {
                // SAFETY: j < NR.
                *v = ai.mul_add(unsafe { *bk.add(j) }, *v);
            }
        }
    }
    for (i, row) in acc.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            // SAFETY: as above.
            unsafe { *t.c.add(i * t.ldc + j) = *v };
        }
    }
}

/// The AVX-512 kernel: the whole `8 x 32` tile in 16 registers.
///
/// # Safety
/// As [`scalar`], on a CPU with AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
pub(crate) unsafe fn avx512<A: Lhs, B: Rhs>(kc: usize, a: &A, p: &B, t: &Tile, load: bool) {
    use std::arch::x86_64::*;
    const _: () = assert!(MR == 8 && NR == 32);
    // SAFETY: every pointer below stays inside the caller's panels and tile.
    unsafe {
        let mut acc = [[_mm512_setzero_ps(); 2]; MR];
        if load {
            for (i, row) in acc.iter_mut().enumerate() {
                row[0] = _mm512_loadu_ps(t.c.add(i * t.ldc));
                row[1] = _mm512_loadu_ps(t.c.add(i * t.ldc + 16));
            }
        }
        for kk in 0..kc {
            let bk = p.row(kk);
            let b0 = _mm512_loadu_ps(bk);
            let b1 = _mm512_loadu_ps(bk.add(16));
            for (i, row) in acc.iter_mut().enumerate() {
                let ai = _mm512_set1_ps(a.at(i, kk));
                row[0] = _mm512_fmadd_ps(ai, b0, row[0]);
                row[1] = _mm512_fmadd_ps(ai, b1, row[1]);
            }
        }
        for (i, row) in acc.iter().enumerate() {
            _mm512_storeu_ps(t.c.add(i * t.ldc), row[0]);
            _mm512_storeu_ps(t.c.add(i * t.ldc + 16), row[1]);
        }
    }
}

/// The AVX2 kernel: the `8 x 32` tile as four `4 x 16` quarters, each in 8 registers
/// (16 would leave none for the operands).
///
/// # Safety
/// As [`scalar`], on a CPU with AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
pub(crate) unsafe fn avx2<A: Lhs, B: Rhs>(kc: usize, a: &A, p: &B, t: &Tile, load: bool) {
    use std::arch::x86_64::*;
    const _: () = assert!(MR == 8 && NR == 32);
    // SAFETY: every pointer below stays inside the caller's panels and tile.
    unsafe {
        for r0 in [0, 4] {
            for c0 in [0, 16] {
                let at = |i: usize| t.c.add((r0 + i) * t.ldc + c0);
                let mut acc = [[_mm256_setzero_ps(); 2]; 4];
                if load {
                    for (i, row) in acc.iter_mut().enumerate() {
                        row[0] = _mm256_loadu_ps(at(i));
                        row[1] = _mm256_loadu_ps(at(i).add(8));
                    }
                }
                for kk in 0..kc {
                    let bk = p.row(kk).add(c0);
                    let b0 = _mm256_loadu_ps(bk);
                    let b1 = _mm256_loadu_ps(bk.add(8));
                    for (i, row) in acc.iter_mut().enumerate() {
                        let ai = _mm256_set1_ps(a.at(r0 + i, kk));
                        row[0] = _mm256_fmadd_ps(ai, b0, row[0]);
                        row[1] = _mm256_fmadd_ps(ai, b1, row[1]);
                    }
                }
                for (i, row) in acc.iter().enumerate() {
                    _mm256_storeu_ps(at(i), row[0]);
                    _mm256_storeu_ps(at(i).add(8), row[1]);
                }
            }
        }
    }
}
