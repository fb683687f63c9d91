//! The wgpu rig as the loop's [`Camera`].

use crate::driver::RgbImage;
use crate::render::{EgoPose, Renderer};
use crate::runner::{Camera, CameraFrame};

impl Camera for Renderer {
    fn render(&mut self, frame: &CameraFrame<'_>, scale: f64) -> Result<&RgbImage, String> {
        let ego = EgoPose::from(frame.ego);
        self.render_rig(&ego, frame.actors, frame.lights, scale as f32)
            .map(|(rgb, _labels)| rgb)
            .map_err(|e| e.to_string())
    }

    fn backend(&self) -> String {
        Renderer::backend(self)
    }
}
