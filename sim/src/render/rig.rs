//! World-on-Rails' camera rig (docs/protocol.md §4): three cameras, 60 deg FOV,
//! yaw -55/0/+55 deg (CARLA's clockwise yaw: left, centre, right), mounted at
//! x = 1.5 m, z = 2.4 m on the ego, each 160 x 240 (w x h), stitched side by
//! side to 480 x 240 and cropped by rows 0..47 to S0 = 480 x 192.
//!
//! The renderer draws the cropped picture directly at any scale r: the
//! output is floor(r W0) x floor(r H0), each camera gets a third of the width
//! (the remainder goes to the rightmost cameras) and its projection keeps the
//! 60 deg horizontal FOV over its share.

use glam::{Mat4, Vec2, Vec3, Vec4};
use world::EgoPose;

/// Near plane of the perspective cameras (metres).
pub const NEAR_M: f32 = 0.1;
/// The default anti-aliasing: supersampling factor per axis.
pub const DEFAULT_SUPERSAMPLE: u32 = 2;
/// The default anti-aliasing: multisamples per drawn pixel (1 or 4).
pub const DEFAULT_MSAA: u32 = 1;

/// The rig's geometry at the base size S0 and the anti-aliasing factor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigConfig {
    /// Width of one camera's full image at S0 (pixels).
    pub cam_width_px: u32,
    /// Height of one camera's full image at S0 (pixels), before the crop.
    pub cam_height_px: u32,
    /// Rows removed from the top of the stitched image at S0 (pixels).
    pub crop_top_px: u32,
    /// Horizontal field of view of each camera (degrees).
    pub fov_deg: f32,
    /// Yaw of each camera, left to right in the stitched image, in CARLA's
    /// convention (degrees, clockwise seen from above: negative looks left).
    pub yaws_deg: [f32; 3],
    /// Camera position in the ego frame: x forward, y left, z up (metres).
    pub mount_m: Vec3,
    /// Supersampling factor per axis: the scene is drawn at k x the output
    /// size and filtered down (see `render::renderer`). 1 disables it.
    pub supersample: u32,
    /// Multisampling: samples per drawn pixel, 1 (off) or 4 (the only other
    /// count lavapipe offers). Combines with `supersample`: every sample of
    /// every k x k block goes into the output pixel.
    pub msaa: u32,
}

impl RigConfig {
    /// The paper's rig: S0 = 480 x 192.
    pub fn paper() -> RigConfig {
        RigConfig {
            cam_width_px: 160,
            cam_height_px: 240,
            crop_top_px: 48,
            fov_deg: 60.0,
            yaws_deg: [-55.0, 0.0, 55.0],
            mount_m: Vec3::new(1.5, 0.0, 2.4),
            supersample: DEFAULT_SUPERSAMPLE,
            msaa: DEFAULT_MSAA,
        }
    }

    /// The CPU default: the paper's rig at half size, S0 = 240 x 96.
    pub fn cpu_default() -> RigConfig {
        RigConfig {
            cam_width_px: 80,
            cam_height_px: 120,
            crop_top_px: 24,
            ..RigConfig::paper()
        }
    }

    /// The anti-aliasing in words, for reports: `supersampling 2x`, `4x MSAA`,
    /// both joined by ` + `, or `none`.
    pub fn antialias(&self) -> String {
        let mut parts = Vec::new();
        if self.supersample > 1 {
            parts.push(format!("supersampling {}x", self.supersample));
        }
        if self.msaa > 1 {
            parts.push(format!("{}x MSAA", self.msaa));
        }
        match parts.is_empty() {
            true => "none".into(),
            false => parts.join(" + "),
        }
    }

    /// The base size S0 (width, height) in pixels.
    pub fn base_size(&self) -> (u32, u32) {
        (3 * self.cam_width_px, self.cam_height_px - self.crop_top_px)
    }

    /// Output size (width, height) at scale `r`: floor(r W0) x floor(r H0).
    /// `None` when either is zero or the scale is not a positive number.
    pub fn size_at(&self, scale: f32) -> Option<(u32, u32)> {
        if !(scale.is_finite() && scale > 0.0) {
            return None;
        }
        let (w0, h0) = self.base_size();
        // A hair of slack so 0.75 * 192 = 144 exactly, whatever the rounding of 0.75.
        let f = |n: u32| (f64::from(scale) * f64::from(n) + 1e-6).floor() as u32;
        let (w, h) = (f(w0), f(h0));
        (w >= 3 && h >= 1 && w <= 16384 && h <= 16384).then_some((w, h))
    }

    /// The views of the three cameras for an output of `size` (width, height) pixels.
    pub fn views(&self, ego: &EgoPose, size: (u32, u32)) -> [View; 3] {
        let (w, h) = size;
        let (_, h0) = self.base_size();
        let sy = h as f32 / h0 as f32;
        let tan_half = (self.fov_deg.to_radians() * 0.5).tan();
        let f0 = self.cam_width_px as f32 * 0.5 / tan_half;
        let (s, c) = ego.heading.sin_cos();
        let fwd = Vec3::new(c, s, 0.0);
        let left = Vec3::new(-s, c, 0.0);
        let eye =
            ego.position + fwd * self.mount_m.x + left * self.mount_m.y + Vec3::Z * self.mount_m.z;
        std::array::from_fn(|i| {
            let x0 = (i as u32 * w) / 3;
            let x1 = ((i as u32 + 1) * w) / 3;
            let cw = x1 - x0;
            let fx = f0 * cw as f32 / self.cam_width_px as f32;
            let fy = f0 * sy;
            let cx = cw as f32 * 0.5;
            let cy = (self.cam_height_px as f32 * 0.5 - self.crop_top_px as f32) * sy;
            // CARLA's yaw is clockwise; ours is counter-clockwise.
            let yaw = ego.heading - self.yaws_deg[i].to_radians();
            View::perspective(eye, yaw, [x0, 0, cw, h], fx, fy, cx, cy)
        })
    }
}

/// One view of the scene (a rig camera or the top-down view): where it
/// draws in the output and its world-to-clip matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Viewport in output pixels: x, y, width, height.
    pub viewport: [u32; 4],
    /// World to clip space (reversed depth: near = 1, far -> 0).
    pub view_proj: Mat4,
    /// The camera's position (metres, world frame), for shading and fog.
    pub eye: Vec3,
    /// Whether fog applies (perspective views).
    pub fog: bool,
    /// Horizontal focal length (output pixels) for perspective views; `None` for orthographic.
    pub focal_px: Option<f32>,
    /// The ground-plane wedge a perspective view sees: inward normals of its
    /// left and right edges and its forward direction; `None` for orthographic.
    pub wedge: Option<[Vec2; 3]>,
}

impl View {
    /// Whether any part of the ground box `min..max` (metres) may be in view
    /// (conservative: only boxes wholly outside one wedge edge are refused).
    pub fn may_see(&self, min: Vec2, max: Vec2) -> bool {
        let Some(planes) = self.wedge else {
            return true;
        };
        let eye = self.eye.truncate();
        let corners = [min, Vec2::new(max.x, min.y), max, Vec2::new(min.x, max.y)];
        planes
            .iter()
            .all(|n| corners.iter().any(|c| n.dot(*c - eye) >= -1.0))
    }
}

impl View {
    /// A pinhole camera at `eye` looking along `yaw` (radians, counter-clockwise
    /// from +x), level; focal lengths and principal point in viewport pixels.
    pub fn perspective(
        eye: Vec3,
        yaw: f32,
        viewport: [u32; 4],
        fx: f32,
        fy: f32,
        cx: f32,
        cy: f32,
    ) -> View {
        let (s, c) = yaw.sin_cos();
        let fwd = Vec3::new(c, s, 0.0);
        let right = Vec3::new(s, -c, 0.0);
        let down = -Vec3::Z;
        // Camera frame: x right, y down, z forward.
        let view = Mat4::from_cols(
            Vec4::new(right.x, down.x, fwd.x, 0.0),
            Vec4::new(right.y, down.y, fwd.y, 0.0),
            Vec4::new(right.z, down.z, fwd.z, 0.0),
            Vec4::new(-right.dot(eye), -down.dot(eye), -fwd.dot(eye), 1.0),
        );
        let (w, h) = (viewport[2] as f32, viewport[3] as f32);
        // x_ndc = 2 (fx X/Z + cx) / w - 1, y_ndc = 1 - 2 (fy Y/Z + cy) / h, z_ndc = near / Z.
        let proj = Mat4::from_cols(
            Vec4::new(2.0 * fx / w, 0.0, 0.0, 0.0),
            Vec4::new(0.0, -2.0 * fy / h, 0.0, 0.0),
            Vec4::new(2.0 * cx / w - 1.0, 1.0 - 2.0 * cy / h, 0.0, 1.0),
            Vec4::new(0.0, 0.0, NEAR_M, 0.0),
        );
        // Ground wedge: edges at atan(cx / fx) left and atan((w - cx) / fx) right, with a margin.
        let margin = 0.05;
        let (lh, rh) = ((cx / fx).atan() + margin, ((w - cx) / fx).atan() + margin);
        let f2 = fwd.truncate();
        let rot = |v: Vec2, a: f32| Vec2::from_angle(a).rotate(v);
        // Inward normal of the left edge: the edge direction turned clockwise.
        let left_n = rot(f2, lh).perp() * -1.0;
        let right_n = rot(f2, -rh).perp();
        let wedge = Some([left_n, right_n, f2]);
        View {
            viewport,
            view_proj: proj * view,
            eye,
            fog: true,
            focal_px: Some(fx),
            wedge,
        }
    }

    /// A top-down orthographic camera centred on `center`, image up along
    /// `heading`, covering `extent_m` metres across the viewport's width.
    pub fn top_down(center: Vec3, heading: f32, extent_m: f32, viewport: [u32; 4]) -> View {
        let (s, c) = heading.sin_cos();
        let up_img = Vec3::new(c, s, 0.0);
        let right = Vec3::new(s, -c, 0.0);
        let half_w = extent_m * 0.5;
        let half_h = half_w * viewport[3] as f32 / viewport[2] as f32;
        let (z_lo, z_hi) = (center.z - 10.0, center.z + 60.0);
        let rel = |v: Vec3| -v.dot(center);
        // Depth: higher points are nearer (reversed depth, 1 at z_hi).
        let m = Mat4::from_cols(
            Vec4::new(right.x / half_w, up_img.x / half_h, 0.0, 0.0),
            Vec4::new(right.y / half_w, up_img.y / half_h, 0.0, 0.0),
            Vec4::new(0.0, 0.0, 1.0 / (z_hi - z_lo), 0.0),
            Vec4::new(
                rel(right) / half_w,
                rel(up_img) / half_h,
                -z_lo / (z_hi - z_lo),
                1.0,
            ),
        );
        View {
            viewport,
            view_proj: m,
            eye: center + Vec3::Z * 1000.0,
            fog: false,
            focal_px: None,
            wedge: None,
        }
    }

    /// Projects a world point to output pixel coordinates (x right, y down;
    /// pixel (i, j) covers [i, i+1) x [j, j+1)), or `None` when it is behind
    /// the camera or outside the viewport.
    pub fn project(&self, p: Vec3) -> Option<Vec2> {
        let c = self.view_proj * p.extend(1.0);
        if c.w <= 0.0 {
            return None;
        }
        let ndc = c.truncate() / c.w;
        if ndc.x.abs() > 1.0 || ndc.y.abs() > 1.0 {
            return None;
        }
        let [x, y, w, h] = self.viewport.map(|v| v as f32);
        Some(Vec2::new(
            x + (ndc.x + 1.0) * 0.5 * w,
            y + (1.0 - ndc.y) * 0.5 * h,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_follow_the_protocol() {
        let paper = RigConfig::paper();
        assert_eq!(paper.base_size(), (480, 192));
        assert_eq!(paper.size_at(1.0), Some((480, 192)));
        assert_eq!(paper.size_at(0.75), Some((360, 144)));
        let cpu = RigConfig::cpu_default();
        assert_eq!(cpu.base_size(), (240, 96));
        assert_eq!(cpu.size_at(0.75), Some((180, 72)));
        assert_eq!(cpu.size_at(0.0), None);
        assert_eq!(cpu.size_at(f32::NAN), None);
    }

    #[test]
    fn centre_camera_puts_the_horizon_at_the_cropped_principal_row() {
        let rig = RigConfig::paper();
        let ego = EgoPose {
            position: Vec3::new(10.0, -3.0, 0.0),
            heading: 0.7,
        };
        let cams = rig.views(&ego, (480, 192));
        assert_eq!(cams[1].viewport, [160, 0, 160, 192]);
        // A far point at camera height straight ahead: centre column, row 120 - 48 = 72.
        let dir = Vec3::new(0.7f32.cos(), 0.7f32.sin(), 0.0);
        let eye = ego.position + dir * 1.5 + Vec3::Z * 2.4;
        let px = cams[1].project(eye + dir * 500.0).unwrap();
        assert!((px - Vec2::new(240.0, 72.0)).length() < 1e-2, "{px}");
        // 30 deg to the left is the centre camera's left edge.
        let a = 0.7 + std::f32::consts::FRAC_PI_6 - 1e-4;
        let l = Vec3::new(a.cos(), a.sin(), 0.0);
        let px = cams[1].project(eye + l * 100.0 - Vec3::Z * 0.0001);
        assert!(px.is_some_and(|p| (p.x - 160.0).abs() < 0.05), "{px:?}");
    }

    #[test]
    fn carla_negative_yaw_is_the_left_camera() {
        let rig = RigConfig::cpu_default();
        let ego = EgoPose::default();
        let cams = rig.views(&ego, rig.base_size());
        // A point 55 deg to the left (counter-clockwise) lands in the left third.
        let a = 55f32.to_radians();
        let p = Vec3::new(1.5, 0.0, 2.4) + Vec3::new(a.cos(), a.sin(), 0.0) * 50.0;
        let px = cams[0].project(p).unwrap();
        assert!((px.x - 40.0).abs() < 0.01 && px.x < 80.0, "{px}");
        assert!(cams[1].project(p).is_none());
    }

    #[test]
    fn the_wedge_keeps_boxes_in_view_and_drops_boxes_behind() {
        let rig = RigConfig::cpu_default();
        let cams = rig.views(&EgoPose::default(), rig.base_size());
        let centre = &cams[1];
        let b = |x: f32, y: f32| (Vec2::new(x, y), Vec2::new(x + 10.0, y + 10.0));
        let (lo, hi) = b(50.0, -5.0);
        assert!(centre.may_see(lo, hi), "straight ahead");
        let (lo, hi) = b(-60.0, -5.0);
        assert!(!centre.may_see(lo, hi), "behind");
        let (lo, hi) = b(5.0, 40.0);
        assert!(
            !centre.may_see(lo, hi),
            "far left is not the centre camera's"
        );
        assert!(cams[0].may_see(lo, hi), "but the left camera's");
        // A box around the eye is always drawn.
        assert!(centre.may_see(Vec2::new(-5.0, -5.0), Vec2::new(5.0, 5.0)));
    }

    #[test]
    fn top_down_puts_the_ego_in_the_middle_and_forward_up() {
        let cam = View::top_down(Vec3::new(5.0, 5.0, 0.0), 0.0, 40.0, [0, 0, 200, 200]);
        let c = cam.project(Vec3::new(5.0, 5.0, 0.0)).unwrap();
        assert!((c - Vec2::new(100.0, 100.0)).length() < 1e-3);
        let ahead = cam.project(Vec3::new(15.0, 5.0, 0.0)).unwrap();
        assert!((ahead - Vec2::new(100.0, 50.0)).length() < 1e-3, "{ahead}");
        let left = cam.project(Vec3::new(5.0, 15.0, 0.0)).unwrap();
        assert!((left - Vec2::new(50.0, 100.0)).length() < 1e-3, "{left}");
    }
}
