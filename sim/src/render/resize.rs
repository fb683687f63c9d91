//! Image resizing for training: the renderer draws each scale directly, but
//! training resizes a recorded frame to the other scales with this.

use crate::driver::RgbImage;

/// How to resample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Filter {
    /// Area averaging: each output pixel is the mean of the source area it
    /// covers (exact fractional coverage). Right for shrinking.
    Area,
    /// Bilinear interpolation at pixel centres (edge-clamped). Right for growing.
    Bilinear,
}

/// Resizes `src` to `width` x `height` into `dst` (its buffer is reused).
/// An empty source or target size gives an empty image.
pub fn resize_rgb(src: &RgbImage, width: u32, height: u32, filter: Filter, dst: &mut RgbImage) {
    dst.width = width;
    dst.height = height;
    dst.data.clear();
    if src.width == 0 || src.height == 0 || width == 0 || height == 0 {
        dst.width = 0;
        dst.height = 0;
        return;
    }
    dst.data.resize((width * height * 3) as usize, 0);
    match filter {
        Filter::Area => area(src, dst),
        Filter::Bilinear => bilinear(src, dst),
    }
}

/// Source spans (index, weight) covering each output index along one axis.
fn spans(n_src: u32, n_dst: u32) -> Vec<Vec<(usize, f32)>> {
    let scale = n_src as f64 / n_dst as f64;
    (0..n_dst)
        .map(|o| {
            let (a, b) = (o as f64 * scale, (o + 1) as f64 * scale);
            let mut v = Vec::new();
            let mut i = a.floor() as u32;
            while f64::from(i) < b && i < n_src {
                let lo = a.max(f64::from(i));
                let hi = b.min(f64::from(i + 1));
                if hi > lo {
                    v.push((i as usize, ((hi - lo) / scale) as f32));
                }
                i += 1;
            }
            v
        })
        .collect()
}

fn area(src: &RgbImage, dst: &mut RgbImage) {
    let xs = spans(src.width, dst.width);
    let ys = spans(src.height, dst.height);
    let sw = src.width as usize;
    for (oy, yspan) in ys.iter().enumerate() {
        for (ox, xspan) in xs.iter().enumerate() {
            let mut acc = [0f32; 3];
            for &(y, wy) in yspan {
                for &(x, wx) in xspan {
                    let i = (y * sw + x) * 3;
                    for (c, a) in acc.iter_mut().enumerate() {
                        *a += f32::from(src.data[i + c]) * wx * wy;
                    }
                }
            }
            let o = (oy * dst.width as usize + ox) * 3;
            for (d, a) in dst.data[o..o + 3].iter_mut().zip(acc) {
                *d = a.round().clamp(0.0, 255.0) as u8;
            }
        }
    }
}

fn bilinear(src: &RgbImage, dst: &mut RgbImage) {
    let sample = |n_src: u32, n_dst: u32, o: u32| {
        let x =
            ((o as f32 + 0.5) * n_src as f32 / n_dst as f32 - 0.5).clamp(0.0, (n_src - 1) as f32);
        let i = (x.floor() as u32).min(n_src - 1);
        let j = (i + 1).min(n_src - 1);
        (i as usize, j as usize, x - i as f32)
    };
    let sw = src.width as usize;
    for oy in 0..dst.height {
        let (y0, y1, fy) = sample(src.height, dst.height, oy);
        for ox in 0..dst.width {
            let (x0, x1, fx) = sample(src.width, dst.width, ox);
            let o = ((oy * dst.width + ox) * 3) as usize;
            for c in 0..3 {
                let p = |y: usize, x: usize| f32::from(src.data[(y * sw + x) * 3 + c]);
                let top = p(y0, x0) * (1.0 - fx) + p(y0, x1) * fx;
                let bot = p(y1, x0) * (1.0 - fx) + p(y1, x1) * fx;
                dst.data[o + c] = (top * (1.0 - fy) + bot * fy).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) -> RgbImage {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .flat_map(|(x, y)| f(x, y))
            .collect();
        RgbImage {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn area_halving_is_the_mean_of_2x2_blocks() {
        let src = img(4, 2, |x, y| [(x * 40 + y * 10) as u8, 7, (x * 3) as u8]);
        let mut dst = RgbImage::default();
        resize_rgb(&src, 2, 1, Filter::Area, &mut dst);
        assert_eq!((dst.width, dst.height), (2, 1));
        // Block 0: x in {0,1}, y in {0,1}: r = (0+40+10+50)/4 = 25, b = (0+3+0+3)/4 = 1.5 -> 2.
        assert_eq!(&dst.data[..3], &[25, 7, 2]);
        assert_eq!(&dst.data[3..], &[105, 7, 8]);
    }

    #[test]
    fn area_at_0_75_keeps_a_flat_image_flat_and_keeps_the_mean() {
        let flat = img(480, 192, |_, _| [10, 200, 77]);
        let mut dst = RgbImage::default();
        resize_rgb(&flat, 360, 144, Filter::Area, &mut dst);
        assert!(dst.data.chunks(3).all(|p| p == [10, 200, 77]));
        let stripes = img(8, 4, |x, _| if x % 2 == 0 { [0; 3] } else { [200; 3] });
        resize_rgb(&stripes, 6, 3, Filter::Area, &mut dst);
        let mean: f32 = dst.data.iter().map(|&v| f32::from(v)).sum::<f32>() / dst.data.len() as f32;
        assert!((mean - 100.0).abs() < 2.0, "mean {mean}");
    }

    #[test]
    fn bilinear_doubles_a_ramp_into_a_ramp() {
        let src = img(4, 1, |x, _| [(x * 80) as u8; 3]);
        let mut dst = RgbImage::default();
        resize_rgb(&src, 8, 1, Filter::Bilinear, &mut dst);
        let r: Vec<u8> = dst.data.chunks(3).map(|p| p[0]).collect();
        assert_eq!(r, vec![0, 20, 60, 100, 140, 180, 220, 240]);
    }

    #[test]
    fn same_size_is_a_copy() {
        let src = img(5, 3, |x, y| [x as u8, y as u8, 9]);
        for f in [Filter::Area, Filter::Bilinear] {
            let mut dst = RgbImage::default();
            resize_rgb(&src, 5, 3, f, &mut dst);
            assert_eq!(dst, src);
        }
    }
}
