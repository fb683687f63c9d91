//! The loop's camera: what renders the policy's view ([`Camera`]), and the
//! wgpu rig ([`Renderer`]) as one.

use world::{ActorSnapshot, LightState};

use crate::driver::RgbImage;
use crate::render::{EgoPose, Renderer};

/// What the camera is asked to draw.
#[derive(Debug, Clone, Copy)]
pub struct CameraFrame<'a> {
    /// The ego (the rig is mounted on it).
    pub ego: &'a ActorSnapshot,
    /// Every actor, ego first.
    pub actors: &'a [ActorSnapshot],
    /// Light states by `LightIdx`.
    pub lights: &'a [LightState],
}

/// Something that renders the policy's view: the wgpu rig, or a test double.
pub trait Camera {
    /// Renders the rig at `scale` (fraction of S0).
    fn render(&mut self, frame: &CameraFrame<'_>, scale: f64) -> Result<&RgbImage, String>;
    /// The backend and adapter, for result records.
    fn backend(&self) -> String;
    /// Renders the rig at `scale` like [`Camera::render`] and paints its
    /// class image in the label palette into `labels`; `None` if this camera
    /// has no class image.
    fn render_labelled(
        &mut self,
        _frame: &CameraFrame<'_>,
        _scale: f64,
        _labels: &mut RgbImage,
    ) -> Option<Result<&RgbImage, String>> {
        None
    }
    /// Renders the bird's-eye view around the ego (forward up), `extent_m`
    /// metres across, `width` x `height` pixels; `None` if this camera cannot.
    fn render_bev(
        &mut self,
        _frame: &CameraFrame<'_>,
        _width: u32,
        _height: u32,
        _extent_m: f32,
    ) -> Option<Result<&RgbImage, String>> {
        None
    }
}

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
