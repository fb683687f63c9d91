//! Convolutions: [`nhwc`], inference's (one channels-last image, read in place), and
//! [`nchw`], training's (batches in burn's layout, through im2col), both on
//! [`gemm`](crate::gemm)'s fixed order of summation.

pub mod nchw;
pub mod nhwc;

pub use nhwc::{Conv2dNhwc, Padded, conv2d_nhwc, conv2d_nhwc_on};
