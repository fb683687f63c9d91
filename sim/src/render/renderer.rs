//! The renderer: one wgpu scene pass writing linear colour (16-bit float),
//! class id (R8Uint, flat) and depth for all views of a frame, a resolve pass
//! that anti-aliases and encodes sRGB, and a readback that strips the 256-byte
//! row padding into reused images.
//!
//! Anti-aliasing takes several samples per output pixel, by supersampling (the
//! scene drawn at k x the output size per axis), by 4x multisampling (MSAA:
//! the rasteriser keeps 4 coverage samples per pixel and shades once per
//! pixel and triangle), or both. Integer class targets cannot be resolved by
//! the hardware, so a second pass of ours filters every sample of an output
//! pixel down: colour by a box filter in linear light (a distant lamp becomes
//! a tinted pixel), class by a rule that keeps small objects (a lit lamp in
//! any sample wins; otherwise the most frequent class, ties to the higher
//! id). With one sample the resolve copies.
//!
//! The same frame is the same bytes on every x86-64 CPU with AVX2 and FMA
//! (tested against an emulated CPU: `tests/render_fingerprint.rs`): no sRGB
//! texture format (llvmpipe encodes those with the CPU's approximate
//! `rsqrtps`) and no `pow`; sRGB goes through exact tables ([`super::srgb`]),
//! and the shaders use only operations IEEE 754 rounds exactly.
//!
//! Lit lamps are drawn last and add their light to what lies behind them. A
//! lamp smaller than [`MIN_LAMP_PX`] supersampled pixels is drawn at that
//! size with its radiance cut by the area ratio, so no sample grid can miss
//! it and the output pixel still integrates the lamp's true light (a faint
//! tint at long range, as a real sensor gives).

use std::num::NonZeroU64;

use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3};
use thiserror::Error;
use world::{ActorSnapshot, LightState, Town};

use super::classes;
use super::gpu::{Gpu, GpuError};
use super::image::ClassImage;
use super::rig::{RigConfig, View};
use super::scene::{Dynamic, Instance, StaticScene, UNIT_MESHES, UnitMesh, Vertex};
use super::srgb;
use crate::driver::RgbImage;
use world::EgoPose;

/// How far from the ego static geometry is drawn (metres).
pub const DRAW_DISTANCE_M: f32 = 200.0;
/// How far from the ego small static things (lane paint, crosswalks, trees,
/// street lamps) are drawn (metres): beyond it a tree is under 2 pixels at
/// the CPU S0 and paint under a tenth of one, half-hidden by fog.
pub const DETAIL_DISTANCE_M: f32 = 120.0;
/// Smallest diameter a lit lamp is drawn at (drawn pixels) with one sample
/// per drawn pixel; its radiance is cut by the area ratio. 1.6 > sqrt(2) /
/// cos(22.5 deg): an octagon this size always covers a sample point of the
/// unit grid.
pub const MIN_LAMP_PX: f32 = 1.6;
/// The same with 4x MSAA (drawn pixels). Vulkan's standard 4-sample positions
/// (1/8 (3, 1), (7, 3), (1, 5), (5, 7)) tile the plane as a square lattice of
/// spacing sqrt(5) / 4 = 0.559 px, whose farthest point from every sample is
/// 0.395 px away: an octagon of diameter 2 x 0.395 / cos(22.5 deg) = 0.855 px
/// always covers one.
pub const MIN_LAMP_PX_MSAA4: f32 = 0.9;
/// Most vertices one static draw call holds (a multiple of 3). Measured on
/// lavapipe (Mesa 22.3) along real routes: 768 beats 192, 384 and 1536, and
/// is ~1.5x faster than unsplit runs of whole cells.
const MAX_DRAW_VERTICES: u32 = 768;
/// Most views one frame may hold (three rig cameras, or one top-down).
const MAX_VIEWS: usize = 4;
/// The scene pass's colour: linear light. Half floats blend everywhere (lamps
/// add their light) and hold far more than the 8 bits the output keeps.
const LINEAR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;
/// The output colour: 8-bit sRGB codes, written as integers by the resolve pass.
const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Uint;
const CLASS_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R8Uint;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The clear colour: the sky, linear (sRGB 150, 190, 230).
const SKY_LINEAR: wgpu::Color = wgpu::Color {
    r: 0.3049874,
    g: 0.5149178,
    b: 0.7912979,
    a: 1.0,
};

/// Why a frame could not be rendered.
#[derive(Debug, Error)]
pub enum RenderError {
    /// No device.
    #[error(transparent)]
    Gpu(#[from] GpuError),
    /// The scale gives an empty or absurd image.
    #[error(
        "scale {scale} gives no valid image size for base size {base_w}x{base_h}; use a scale in (0, 8], e.g. 0.75 or 1.0"
    )]
    BadScale {
        /// The scale asked for.
        scale: f32,
        /// Base width (pixels).
        base_w: u32,
        /// Base height (pixels).
        base_h: u32,
    },
    /// A top-down view of zero size or extent.
    #[error(
        "top-down view needs a size of at least 1x1 pixels and a positive extent; got {width}x{height}, {extent_m} m"
    )]
    BadTopDown {
        /// Width asked (pixels).
        width: u32,
        /// Height asked (pixels).
        height: u32,
        /// Extent asked (metres).
        extent_m: f32,
    },
    /// Reading the frame back failed.
    #[error("reading the frame back from the GPU failed: {0}")]
    Readback(String),
}

/// One view's uniform as the shader sees it.
#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
struct ViewUniform {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    lamp: [f32; 4],
}

/// Render targets and readback for one output size.
struct Targets {
    size: (u32, u32),
    /// The scene pass's targets (linear colour, class; k x the output size, `msaa`
    /// samples a pixel) and the resolve pass's bind group that reads them.
    hi: (wgpu::TextureView, wgpu::TextureView, wgpu::BindGroup),
    depth: wgpu::TextureView,
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    class: wgpu::Texture,
    class_view: wgpu::TextureView,
    readback: wgpu::Buffer,
    color_bpr: u32,
    class_bpr: u32,
    class_offset: u64,
    rgb: RgbImage,
    labels: ClassImage,
}

/// The offscreen camera renderer for one town. Build once, render many frames;
/// buffers are reused, so the steady state allocates nothing per frame.
pub struct Renderer {
    gpu: Gpu,
    rig: RigConfig,
    scene: StaticScene,
    scene_pipeline: wgpu::RenderPipeline,
    lamp_pipeline: wgpu::RenderPipeline,
    down_pipeline: wgpu::RenderPipeline,
    down_layout: wgpu::BindGroupLayout,
    down_params: wgpu::Buffer,
    srgb_tables: wgpu::Buffer,
    cam_buffer: wgpu::Buffer,
    cam_bind: wgpu::BindGroup,
    cam_stride: u64,
    cam_bytes: Vec<u8>,
    static_vb: wgpu::Buffer,
    instance_buf: wgpu::Buffer,
    instance_cap: usize,
    dynamic: Dynamic,
    instances: Vec<Instance>,
    instance_ranges: [(u32, u32); UNIT_MESHES],
    visible: Vec<Vec<(u32, u32)>>,
    /// Scratch for `collect_visible`: (distance from the eye (metres), cell index).
    order: Vec<(f32, usize)>,
    targets: Vec<Targets>,
}

impl Renderer {
    /// Opens a device and builds the town's static scene (trees and poles
    /// placed from `seed`).
    pub fn new(town: &Town, rig: RigConfig, seed: u64) -> Result<Renderer, RenderError> {
        let gpu = Gpu::new()?;
        Ok(Renderer::with_gpu(gpu, town, rig, seed))
    }

    /// Builds the renderer on an already opened device.
    pub fn with_gpu(gpu: Gpu, town: &Town, rig: RigConfig, seed: u64) -> Renderer {
        let rig = RigConfig {
            supersample: rig.supersample.clamp(1, 5),
            msaa: if rig.msaa >= 4 { 4 } else { 1 },
            ..rig
        };
        let multisample = wgpu::MultisampleState {
            count: rig.msaa,
            ..Default::default()
        };
        let scene = StaticScene::build(town, seed);
        let device = &gpu.device;
        let align = u64::from(device.limits().min_uniform_buffer_offset_alignment);
        let cam_stride = (std::mem::size_of::<ViewUniform>() as u64).div_ceil(align) * align;
        let cam_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cameras"),
            size: cam_stride * MAX_VIEWS as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let srgb_bytes = srgb::uniform_bytes();
        let srgb_tables = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("sRGB tables"),
            size: srgb_bytes.len() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue.write_buffer(&srgb_tables, 0, &srgb_bytes);
        let uniform_entry = |binding, visibility, dynamic, size: u64| wgpu::BindGroupLayoutEntry {
            binding,
            visibility,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: dynamic,
                min_binding_size: NonZeroU64::new(size),
            },
            count: None,
        };
        let cam_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("camera layout"),
            entries: &[
                uniform_entry(
                    0,
                    wgpu::ShaderStages::VERTEX_FRAGMENT,
                    true,
                    std::mem::size_of::<ViewUniform>() as u64,
                ),
                uniform_entry(1, wgpu::ShaderStages::VERTEX, false, srgb_tables.size()),
            ],
        });
        let cam_bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("camera bind group"),
            layout: &cam_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                        buffer: &cam_buffer,
                        offset: 0,
                        size: NonZeroU64::new(std::mem::size_of::<ViewUniform>() as u64),
                    }),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: srgb_tables.as_entire_binding(),
                },
            ],
        });
        let scene_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("scene.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("scene.wgsl").into()),
        });
        let scene_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scene layout"),
            bind_group_layouts: &[Some(&cam_layout)],
            immediate_size: 0,
        });
        let vertex_attrs = wgpu::vertex_attr_array![0 => Float32x3, 1 => Uint32];
        let instance_attrs =
            wgpu::vertex_attr_array![2 => Float32x3, 3 => Float32, 4 => Float32x3, 5 => Uint32];
        let targets = [
            Some(wgpu::ColorTargetState::from(LINEAR_FORMAT)),
            Some(wgpu::ColorTargetState::from(CLASS_FORMAT)),
        ];
        let scene_pipe = |label, targets: &[Option<wgpu::ColorTargetState>], depth_write| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&scene_layout),
                vertex: wgpu::VertexState {
                    module: &scene_module,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[
                        Some(wgpu::VertexBufferLayout {
                            array_stride: std::mem::size_of::<Vertex>() as u64,
                            step_mode: wgpu::VertexStepMode::Vertex,
                            attributes: &vertex_attrs,
                        }),
                        Some(wgpu::VertexBufferLayout {
                            array_stride: std::mem::size_of::<Instance>() as u64,
                            step_mode: wgpu::VertexStepMode::Instance,
                            attributes: &instance_attrs,
                        }),
                    ],
                },
                primitive: wgpu::PrimitiveState {
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(depth_write),
                    depth_compare: Some(wgpu::CompareFunction::Greater),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample,
                fragment: Some(wgpu::FragmentState {
                    module: &scene_module,
                    entry_point: Some("fs_main"),
                    compilation_options: Default::default(),
                    targets,
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let scene_pipeline = scene_pipe("scene pipeline", &targets, true);
        // Lit lamps add their light to what is behind them (energy is kept
        // when a small lamp is drawn enlarged); the class is replaced.
        let additive = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::One,
            operation: wgpu::BlendOperation::Add,
        };
        let lamp_targets = [
            Some(wgpu::ColorTargetState {
                format: LINEAR_FORMAT,
                blend: Some(wgpu::BlendState {
                    color: additive,
                    alpha: additive,
                }),
                write_mask: wgpu::ColorWrites::ALL,
            }),
            Some(wgpu::ColorTargetState::from(CLASS_FORMAT)),
        ];
        let lamp_pipeline = scene_pipe("lamp pipeline", &lamp_targets, false);
        let down_source = match rig.msaa {
            1 => include_str!("downsample.wgsl").to_string(),
            _ => include_str!("downsample.wgsl").replace("texture_2d<", "texture_multisampled_2d<"),
        };
        let down_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("downsample.wgsl"),
            source: wgpu::ShaderSource::Wgsl(down_source.into()),
        });
        let tex_entry = |binding, sample_type| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type,
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: rig.msaa > 1,
            },
            count: None,
        };
        let down_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("resolve layout"),
            entries: &[
                tex_entry(0, wgpu::TextureSampleType::Float { filterable: false }),
                tex_entry(1, wgpu::TextureSampleType::Uint),
                uniform_entry(2, wgpu::ShaderStages::FRAGMENT, false, 16),
                uniform_entry(3, wgpu::ShaderStages::FRAGMENT, false, srgb_tables.size()),
            ],
        });
        let down_pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("resolve pipeline layout"),
            bind_group_layouts: &[Some(&down_layout)],
            immediate_size: 0,
        });
        let down_pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("resolve pipeline"),
            layout: Some(&down_pl),
            vertex: wgpu::VertexState {
                module: &down_module,
                entry_point: Some("vs_full"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &down_module,
                entry_point: Some("fs_down"),
                compilation_options: Default::default(),
                targets: &[
                    Some(wgpu::ColorTargetState::from(OUTPUT_FORMAT)),
                    Some(wgpu::ColorTargetState::from(CLASS_FORMAT)),
                ],
            }),
            multiview_mask: None,
            cache: None,
        });
        let small_mask: u32 = classes::CLASSES
            .iter()
            .filter(|c| c.small_object)
            .fold(0, |m, c| m | 1 << c.id);
        let down_params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("resolve params"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue.write_buffer(
            &down_params,
            0,
            bytemuck::cast_slice(&[rig.supersample, small_mask, rig.msaa, 0]),
        );
        let static_vb = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("static vertices"),
            size: (std::mem::size_of_val(scene.vertices.as_slice()) as u64).max(16),
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        gpu.queue
            .write_buffer(&static_vb, 0, bytemuck::cast_slice(&scene.vertices));
        let instance_cap = 1024;
        let instance_buf = make_instance_buffer(device, instance_cap);
        Renderer {
            rig,
            scene,
            scene_pipeline,
            lamp_pipeline,
            down_pipeline,
            down_layout,
            down_params,
            srgb_tables,
            cam_buffer,
            cam_bind,
            cam_stride,
            cam_bytes: vec![0; (cam_stride * MAX_VIEWS as u64) as usize],
            static_vb,
            instance_buf,
            instance_cap,
            dynamic: Dynamic::default(),
            instances: Vec::with_capacity(instance_cap),
            instance_ranges: [(0, 0); UNIT_MESHES],
            visible: vec![Vec::new(); MAX_VIEWS],
            order: Vec::new(),
            targets: Vec::new(),
            gpu,
        }
    }

    /// The rig this renderer draws.
    pub fn rig(&self) -> &RigConfig {
        &self.rig
    }

    /// The backend and adapter, for result records (golden images pin it).
    pub fn backend(&self) -> String {
        self.gpu.describe()
    }

    /// The static scene (for statistics and tests).
    pub fn scene(&self) -> &StaticScene {
        &self.scene
    }

    /// Renders the three-camera rig at `scale` of S0: the stitched, cropped
    /// colour image and its class image. `light_states` is indexed like
    /// `Town::lights` (missing entries: all lamps dark). The ego is not drawn.
    pub fn render_rig(
        &mut self,
        ego: &EgoPose,
        actors: &[ActorSnapshot],
        light_states: &[LightState],
        scale: f32,
    ) -> Result<(&RgbImage, &ClassImage), RenderError> {
        let (base_w, base_h) = self.rig.base_size();
        let size = self
            .rig
            .size_at(scale)
            .filter(|&(w, _)| w <= 8 * base_w)
            .ok_or(RenderError::BadScale {
                scale,
                base_w,
                base_h,
            })?;
        let cams = self.rig.views(ego, size);
        self.render_views(
            size,
            &cams,
            ego.position.truncate(),
            DRAW_DISTANCE_M,
            actors,
            light_states,
        )
    }

    /// Renders a top-down orthographic view around the ego (forward is up),
    /// `extent_m` metres across, `width` x `height` pixels.
    pub fn render_top_down(
        &mut self,
        ego: &EgoPose,
        actors: &[ActorSnapshot],
        light_states: &[LightState],
        width: u32,
        height: u32,
        extent_m: f32,
    ) -> Result<(&RgbImage, &ClassImage), RenderError> {
        let ok = width >= 1 && height >= 1 && width <= 8192 && height <= 8192;
        if !(ok && extent_m.is_finite() && extent_m > 0.0) {
            return Err(RenderError::BadTopDown {
                width,
                height,
                extent_m,
            });
        }
        let cam = View::top_down(ego.position, ego.heading, extent_m, [0, 0, width, height]);
        let reach = extent_m * (1.0 + height as f32 / width as f32);
        self.render_views(
            (width, height),
            &[cam],
            ego.position.truncate(),
            reach,
            actors,
            light_states,
        )
    }

    /// Draws `cams` into the targets of `size` and reads them back.
    fn render_views(
        &mut self,
        size: (u32, u32),
        cams: &[View],
        center: Vec2,
        reach_m: f32,
        actors: &[ActorSnapshot],
        light_states: &[LightState],
    ) -> Result<(&RgbImage, &ClassImage), RenderError> {
        let k = self.rig.supersample;
        let ti = match self.targets.iter().position(|t| t.size == size) {
            Some(i) => i,
            None => {
                let t = self.make_targets(size);
                self.targets.push(t);
                self.targets.len() - 1
            }
        };
        self.upload_instances(actors, light_states);
        self.upload_views(cams);
        self.collect_visible(cams, center, reach_m);
        let device = &self.gpu.device;
        let t = &self.targets[ti];
        let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("frame"),
        });
        {
            let (color_att, class_att, _) = &t.hi;
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("scene pass"),
                color_attachments: &[
                    Some(wgpu::RenderPassColorAttachment {
                        view: color_att,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(SKY_LINEAR),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                    Some(wgpu::RenderPassColorAttachment {
                        view: class_att,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color {
                                r: f64::from(classes::SKY),
                                g: 0.0,
                                b: 0.0,
                                a: 0.0,
                            }),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                ],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &t.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_vertex_buffer(0, self.static_vb.slice(..));
            pass.set_vertex_buffer(1, self.instance_buf.slice(..));
            for (i, cam) in cams.iter().enumerate() {
                let [x, y, w, h] = cam.viewport.map(|v| v * k);
                pass.set_viewport(x as f32, y as f32, w as f32, h as f32, 0.0, 1.0);
                pass.set_scissor_rect(x, y, w, h);
                pass.set_pipeline(&self.scene_pipeline);
                pass.set_bind_group(0, &self.cam_bind, &[(i as u64 * self.cam_stride) as u32]);
                for &(first, count) in &self.visible[i] {
                    pass.draw(first..first + count, 0..1);
                }
                for (u, (unit, &(first, count))) in self
                    .scene
                    .units
                    .iter()
                    .zip(&self.instance_ranges)
                    .enumerate()
                {
                    if count == 0 {
                        continue;
                    }
                    if u == UnitMesh::Disc as usize {
                        // Lamps last: they blend over what is already drawn.
                        pass.set_pipeline(&self.lamp_pipeline);
                        pass.set_bind_group(
                            0,
                            &self.cam_bind,
                            &[(i as u64 * self.cam_stride) as u32],
                        );
                    }
                    pass.draw(unit.0..unit.0 + unit.1, first..first + count);
                }
            }
        }
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("resolve pass"),
                color_attachments: &[
                    Some(wgpu::RenderPassColorAttachment {
                        view: &t.color_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                    Some(wgpu::RenderPassColorAttachment {
                        view: &t.class_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                            store: wgpu::StoreOp::Store,
                        },
                    }),
                ],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.down_pipeline);
            pass.set_bind_group(0, &t.hi.2, &[]);
            pass.draw(0..3, 0..1);
        }
        let (w, h) = t.size;
        let extent = wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        };
        for (tex, offset, bpr) in [
            (&t.color, 0, t.color_bpr),
            (&t.class, t.class_offset, t.class_bpr),
        ] {
            enc.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: tex,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &t.readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset,
                        bytes_per_row: Some(bpr),
                        rows_per_image: Some(h),
                    },
                },
                extent,
            );
        }
        self.gpu.queue.submit([enc.finish()]);
        self.read_back(ti)?;
        let t = &self.targets[ti];
        Ok((&t.rgb, &t.labels))
    }

    /// Fills the instance buffer: the identity instance, then each unit mesh's group.
    fn upload_instances(&mut self, actors: &[ActorSnapshot], light_states: &[LightState]) {
        self.dynamic.fill(actors, &self.scene.lamps, light_states);
        self.instances.clear();
        self.instances.push(Instance::IDENTITY);
        for (g, range) in self.dynamic.groups.iter().zip(&mut self.instance_ranges) {
            *range = (self.instances.len() as u32, g.len() as u32);
            self.instances.extend_from_slice(g);
        }
        if self.instances.len() > self.instance_cap {
            self.instance_cap = self.instances.len().next_power_of_two();
            self.instance_buf = make_instance_buffer(&self.gpu.device, self.instance_cap);
        }
        self.gpu
            .queue
            .write_buffer(&self.instance_buf, 0, bytemuck::cast_slice(&self.instances));
    }

    fn upload_views(&mut self, cams: &[View]) {
        let k = self.rig.supersample as f32;
        let min_lamp_px = match self.rig.msaa {
            1 => MIN_LAMP_PX,
            _ => MIN_LAMP_PX_MSAA4,
        };
        for (i, cam) in cams.iter().take(MAX_VIEWS).enumerate() {
            let u = ViewUniform {
                view_proj: cam.view_proj.to_cols_array_2d(),
                eye: cam.eye.extend(if cam.fog { 1.0 } else { 0.0 }).to_array(),
                lamp: match cam.focal_px {
                    Some(f) => [f * k, min_lamp_px, 0.0, 0.0],
                    None => [0.0; 4],
                },
            };
            let at = i * self.cam_stride as usize;
            self.cam_bytes[at..at + std::mem::size_of::<ViewUniform>()]
                .copy_from_slice(bytemuck::bytes_of(&u));
        }
        let used = cams.len().min(MAX_VIEWS) * self.cam_stride as usize;
        self.gpu
            .queue
            .write_buffer(&self.cam_buffer, 0, &self.cam_bytes[..used]);
    }

    /// For each view, the static vertex runs of cells within `reach_m` of
    /// `center` that the view may see, nearest cell first (so the depth test
    /// rejects hidden pixels before they are shaded), runs adjacent in the
    /// buffer merged and long ones split.
    fn collect_visible(&mut self, cams: &[View], center: Vec2, reach_m: f32) {
        let gap = |min: Vec2, max: Vec2, p: Vec2| (min - p).max(p - max).max(Vec2::ZERO).length();
        for (cam, visible) in cams.iter().zip(&mut self.visible) {
            visible.clear();
            self.order.clear();
            let eye = cam.eye.truncate();
            for (i, c) in self.scene.cells.iter().enumerate() {
                let reach = if c.detail {
                    reach_m.min(DETAIL_DISTANCE_M)
                } else {
                    reach_m
                };
                if gap(c.min, c.max, center) > reach || !cam.may_see(c.min, c.max) {
                    continue;
                }
                self.order.push((gap(c.min, c.max, eye), i));
            }
            self.order
                .sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            for &(_, i) in &self.order {
                let c = &self.scene.cells[i];
                match visible.last_mut() {
                    Some(last) if last.0 + last.1 == c.first => last.1 += c.count,
                    _ => visible.push((c.first, c.count)),
                }
                // Split long runs: lavapipe's clipper resets every vertex of
                // a draw each time its vertex buffer fills, so its cost grows
                // with the square of a draw's size.
                while let Some(last) = visible.last_mut().filter(|l| l.1 > MAX_DRAW_VERTICES) {
                    let rest = (last.0 + MAX_DRAW_VERTICES, last.1 - MAX_DRAW_VERTICES);
                    last.1 = MAX_DRAW_VERTICES;
                    visible.push(rest);
                }
            }
        }
    }

    fn make_targets(&self, size: (u32, u32)) -> Targets {
        let device = &self.gpu.device;
        let k = self.rig.supersample;
        let (w, h) = size;
        let tex_sampled = |label, w, h, format, usage, samples| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let tex = |label, w, h, format, usage| tex_sampled(label, w, h, format, usage, 1);
        let samples = self.rig.msaa;
        use wgpu::TextureUsages as U;
        let out_usage = U::RENDER_ATTACHMENT | U::COPY_SRC;
        let color = tex("colour", w, h, OUTPUT_FORMAT, out_usage);
        let class = tex("class", w, h, CLASS_FORMAT, out_usage);
        let depth = tex_sampled(
            "depth",
            w * k,
            h * k,
            DEPTH_FORMAT,
            U::RENDER_ATTACHMENT,
            samples,
        );
        let hi = {
            let usage = U::RENDER_ATTACHMENT | U::TEXTURE_BINDING;
            let c = tex_sampled(
                "linear colour (anti-aliased)",
                w * k,
                h * k,
                LINEAR_FORMAT,
                usage,
                samples,
            )
            .create_view(&Default::default());
            let l = tex_sampled(
                "class (anti-aliased)",
                w * k,
                h * k,
                CLASS_FORMAT,
                usage,
                samples,
            )
            .create_view(&Default::default());
            let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("resolve bind group"),
                layout: &self.down_layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(&c),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: wgpu::BindingResource::TextureView(&l),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: self.down_params.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: self.srgb_tables.as_entire_binding(),
                    },
                ],
            });
            (c, l, bind)
        };
        let pad = |bytes: u32| {
            bytes.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
        };
        let (color_bpr, class_bpr) = (pad(w * 4), pad(w));
        let class_offset = u64::from(color_bpr) * u64::from(h);
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: class_offset + u64::from(class_bpr) * u64::from(h),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Targets {
            size,
            hi,
            depth: depth.create_view(&Default::default()),
            color_view: color.create_view(&Default::default()),
            class_view: class.create_view(&Default::default()),
            color,
            class,
            readback,
            color_bpr,
            class_bpr,
            class_offset,
            rgb: RgbImage {
                width: w,
                height: h,
                data: vec![0; (w * h * 3) as usize],
            },
            labels: ClassImage {
                width: w,
                height: h,
                data: vec![0; (w * h) as usize],
            },
        }
    }

    /// Maps the readback buffer and copies it, without row padding, into the target's images.
    fn read_back(&mut self, ti: usize) -> Result<(), RenderError> {
        let t = &mut self.targets[ti];
        let slice = t.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| ());
        self.gpu
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        {
            let view = slice
                .get_mapped_range()
                .map_err(|e| RenderError::Readback(e.to_string()))?;
            let (w, h) = (t.size.0 as usize, t.size.1 as usize);
            for y in 0..h {
                let row = &view[y * t.color_bpr as usize..][..w * 4];
                let out = &mut t.rgb.data[y * w * 3..][..w * 3];
                for (o, i) in out.chunks_exact_mut(3).zip(row.chunks_exact(4)) {
                    o.copy_from_slice(&i[..3]);
                }
                let row = &view[t.class_offset as usize + y * t.class_bpr as usize..][..w];
                t.labels.data[y * w..][..w].copy_from_slice(row);
            }
        }
        t.readback.unmap();
        Ok(())
    }
}

fn make_instance_buffer(device: &wgpu::Device, cap: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("instances"),
        size: (cap * std::mem::size_of::<Instance>()) as u64,
        usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Where a lamp's centre is, for tests and the lamp-size command.
pub fn lamp_center(scene: &StaticScene, light: usize, state: LightState) -> Option<Vec3> {
    let (_, _, which) = super::scene::lamp_paint(state);
    scene.lamps.get(light).map(|l| l.centers[which])
}
