//! The CPU arithmetic of mrdrive's networks, apart from the networks themselves
//! (as burn keeps its backends' kernels apart from its modules).
//!
//! One promise runs through the crate: **every output of a product is one chain of
//! fused multiply-adds over the inner dimension, in ascending order**, starting from
//! zero (or from the value already in the output, when accumulating). Vector width,
//! cache blocking, tile sizes and thread count decide only *which* outputs are
//! computed together, never the order in which one output is summed, so an AVX-512
//! machine, an AVX2 machine, the scalar fallback, one thread or eight all give the
//! same bits (tested, kernel against kernel, on every machine that has them).
//!
//! Read in this order: [`gemm`] (the product and its promise), [`conv`] (inference's
//! convolutions reading the image in place, and training's through im2col),
//! [`batch_norm`] (training-mode BatchNorm), [`isa`] (which kernel this CPU runs).
//! `policy` registers the training kernels with burn and runs inference on them.

pub mod batch_norm;
pub mod conv;
pub mod gemm;
pub mod isa;

pub use gemm::{Mat, PackedRhs, gemm, gemm_packed};
