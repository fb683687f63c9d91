//! The class image (one class id per pixel) and PNG output of rendered frames.

use std::path::Path;

use super::classes::{self, ClassId};
use crate::driver::RgbImage;

/// A per-pixel semantic class image, row-major, one byte a pixel, no padding.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ClassImage {
    /// Width (pixels).
    pub width: u32,
    /// Height (pixels).
    pub height: u32,
    /// `width * height` class ids (see [`classes::CLASSES`]).
    pub data: Vec<ClassId>,
}

impl ClassImage {
    /// The class at pixel (x, y) (x right, y down); `None` outside.
    pub fn get(&self, x: u32, y: u32) -> Option<ClassId> {
        (x < self.width && y < self.height).then(|| self.data[(y * self.width + x) as usize])
    }

    /// How many pixels carry class `id`.
    pub fn count(&self, id: ClassId) -> usize {
        self.data.iter().filter(|&&c| c == id).count()
    }

    /// Paints the label picture (each class in its table colour) into `out`.
    pub fn to_label_rgb(&self, out: &mut RgbImage) {
        out.width = self.width;
        out.height = self.height;
        out.data.clear();
        out.data
            .extend(self.data.iter().flat_map(|&c| classes::label_rgb(c)));
    }
}

/// The RGB pixel at (x, y); `None` outside.
pub fn rgb_at(img: &RgbImage, x: u32, y: u32) -> Option<[u8; 3]> {
    if x >= img.width || y >= img.height {
        return None;
    }
    let i = ((y * img.width + x) * 3) as usize;
    Some([img.data[i], img.data[i + 1], img.data[i + 2]])
}

/// A deterministic stand-in for a rendered frame of `width` x `height`
/// pixels: byte `i` is `(131 i + 7 seed) mod 251`, so neighbouring pixels
/// differ and each seed gives another image. For tests and benchmarks that
/// need an image of a given size.
pub fn test_pattern(width: u32, height: u32, seed: u64) -> RgbImage {
    let n = width as u64 * height as u64 * 3;
    RgbImage {
        width,
        height,
        data: (0..n)
            .map(|i| ((i * 131 + seed.wrapping_mul(7)) % 251) as u8)
            .collect(),
    }
}

/// Writes an RGB image as PNG.
pub fn save_png(img: &RgbImage, path: &Path) -> Result<(), image::ImageError> {
    image::save_buffer(
        path,
        &img.data,
        img.width,
        img.height,
        image::ExtendedColorType::Rgb8,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn label_picture_uses_the_table_colours() {
        let img = ClassImage {
            width: 2,
            height: 1,
            data: vec![classes::ROAD, classes::LAMP_RED],
        };
        let mut out = RgbImage::default();
        img.to_label_rgb(&mut out);
        assert_eq!(rgb_at(&out, 0, 0), Some(classes::label_rgb(classes::ROAD)));
        assert_eq!(rgb_at(&out, 1, 0), Some([255, 0, 0]));
        assert_eq!(img.get(1, 0), Some(classes::LAMP_RED));
        assert_eq!(img.get(2, 0), None);
        assert_eq!(img.count(classes::ROAD), 1);
    }

    #[test]
    fn the_test_pattern_has_its_size_and_differs_by_seed() {
        let a = test_pattern(5, 3, 0);
        assert_eq!((a.width, a.height, a.data.len()), (5, 3, 45));
        assert_eq!(&a.data[..3], &[0, 131, 11]);
        assert_eq!(a, test_pattern(5, 3, 0));
        let b = test_pattern(5, 3, 1);
        assert!(a.data.iter().zip(&b.data).all(|(x, y)| x != y));
    }
}
