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

    fn render_labelled(
        &mut self,
        frame: &CameraFrame<'_>,
        scale: f64,
        labels: &mut RgbImage,
    ) -> Option<Result<&RgbImage, String>> {
        let ego = EgoPose::from(frame.ego);
        let drawn = self.render_rig(&ego, frame.actors, frame.lights, scale as f32);
        Some(
            drawn
                .map(|(rgb, classes)| {
                    classes.to_label_rgb(labels);
                    rgb
                })
                .map_err(|e| e.to_string()),
        )
    }

    fn render_bev(
        &mut self,
        frame: &CameraFrame<'_>,
        width: u32,
        height: u32,
        extent_m: f32,
    ) -> Option<Result<&RgbImage, String>> {
        let ego = EgoPose::from(frame.ego);
        let drawn = self.render_top_down(&ego, frame.actors, frame.lights, width, height, extent_m);
        Some(drawn.map(|(rgb, _classes)| rgb).map_err(|e| e.to_string()))
    }
}
