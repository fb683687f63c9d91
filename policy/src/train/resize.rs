//! Resizing an image batch to a scale of S0: bilinear, `floor(r H0) x floor(r W0)`.

use crate::model::scaled_len;
use burn::prelude::*;
use burn::tensor::module::interpolate;
use burn::tensor::ops::{InterpolateMode, InterpolateOptions};

/// Bilinear resize (half-pixel centres, PyTorch's `align_corners=False`) to `[height, width]`.
pub fn resize_to(x: Tensor<4>, size: [usize; 2]) -> Tensor<4> {
    let [_, _, h, w] = x.dims();
    if [h, w] == size {
        return x;
    }
    let mut options = InterpolateOptions::new(InterpolateMode::Bilinear);
    options.align_corners = false;
    options.output_size = Some(size);
    interpolate(x, options)
}

/// Resizes a batch `[B, C, H0, W0]` at scale 1.0 to scale `r`: `floor(r H0) x floor(r W0)`.
pub fn resize_to_scale(x: Tensor<4>, r: f32) -> Tensor<4> {
    let [_, _, h, w] = x.dims();
    resize_to(x, [scaled_len(h, r), scaled_len(w, r)])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(t: Tensor<4>) -> Vec<f32> {
        t.into_data().try_to_vec::<f32>().unwrap()
    }

    #[test]
    fn sizes_are_floored_scales() {
        let device = Device::flex();
        let x = Tensor::<4>::zeros([2, 3, 96, 240], &device);
        assert_eq!(resize_to_scale(x.clone(), 0.75).dims(), [2, 3, 72, 180]);
        assert_eq!(resize_to_scale(x.clone(), 0.625).dims(), [2, 3, 60, 150]);
        assert_eq!(resize_to_scale(x.clone(), 0.55).dims(), [2, 3, 52, 132]);
        assert_eq!(resize_to_scale(x, 1.0).dims(), [2, 3, 96, 240]);
    }

    #[test]
    fn constants_stay_constant_and_ramps_sample_at_half_pixel_centres() {
        let device = Device::flex();
        let c = Tensor::<4>::full([1, 2, 8, 12], 3.5, &device);
        assert!(
            v(resize_to_scale(c, 0.75))
                .iter()
                .all(|x| (x - 3.5).abs() < 1e-6)
        );
        // f(x) = x along the width; at 3/4 size output column i samples input
        // coordinate (i + 0.5) * 4/3 - 0.5 (exact for a linear ramp away from the borders).
        let ramp: Vec<f32> = (0..8 * 12).map(|k| (k % 12) as f32).collect();
        let x = Tensor::<4>::from_data(TensorData::new(ramp, [1, 1, 8, 12]), &device);
        let y = v(resize_to_scale(x, 0.75));
        for i in 0..9 {
            let src = ((i as f32 + 0.5) * 12.0 / 9.0 - 0.5).clamp(0.0, 11.0);
            assert!((y[i] - src).abs() < 1e-4, "column {i}: {} vs {src}", y[i]);
            assert!((y[5 * 9 + i] - src).abs() < 1e-4);
        }
    }

    #[test]
    fn downsampling_a_checkerboard_blends_neighbours() {
        // Bilinear, not nearest: 2x2 -> 1x1 averages the four pixels.
        let device = Device::flex();
        let x = Tensor::<4>::from_data(
            TensorData::new(vec![0.0f32, 1.0, 1.0, 0.0], [1, 1, 2, 2]),
            &device,
        );
        let y = v(resize_to(x, [1, 1]));
        assert!((y[0] - 0.5).abs() < 1e-6, "{y:?}");
    }
}
