//! [`SplatRenderer`]: the visibility pass, the additive attribute pass and the
//! normalise-and-shade compute pass, with their targets and readback.

use bytemuck::{Pod, Zeroable};
use image::RgbaImage;
use wgpu_profiler::{GpuProfiler, GpuProfilerQuery};

use crate::camera::Camera;
use crate::context::GpuContext;
use crate::error::{RenderError, Result};
use crate::geometry::{Backdrop, GpuVertex, SceneGeometry};
use crate::readback::{Accumulation, read_texture};
use crate::shading::Shading;
use crate::splat::{GpuSplat, Splat};
use crate::textures::Environment;

const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Format of the shaded image (a storage texture written by the compute pass).
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const MIN_SPLAT_CAPACITY: usize = 1024;

/// Uniforms of every pass; mirrors `struct Frame` in `shaders/frame.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    view: [[f32; 4]; 4],
    proj: [[f32; 4]; 4],
    inv_view: [[f32; 4]; 4],
    viewport: [f32; 4],
    ray: [f32; 4],
    params: [f32; 4],
    fluid: [f32; 4],
    flags: [f32; 4],
    sun: [f32; 4],
    absorption: [f32; 4],
}

/// Format of the scene pass's image (what the fluid refracts).
const SCENE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Render targets of one size.
struct Targets {
    width: u32,
    height: u32,
    /// The scene's depth, then the splats' visibility depth over it.
    depth: wgpu::Texture,
    depth_view: wgpu::TextureView,
    /// The scene pass's image: backdrop and geometry.
    scene_view: wgpu::TextureView,
    /// The farthest back-facing splat, or the geometry where nearer.
    back_depth_view: wgpu::TextureView,
    accum: wgpu::Texture,
    accum_view: wgpu::TextureView,
    output: wgpu::Texture,
    output_view: wgpu::TextureView,
}

/// Draws splats by two-pass splatting and deferred shading (thesis figure 2),
/// in front of opaque scene geometry.
///
/// A frame is five passes: the **scene pass** draws the backdrop and the
/// [`SceneGeometry`] (none unless [`set_geometry`](Self::set_geometry) gave
/// some) into an image and the depth buffer; the **back surface pass**
/// (only with [`Shading::absorption`] non-zero) finds the farthest
/// back-facing splat, or the geometry where nearer, for the fluid's thickness;
/// the **visibility** and **attribute passes** splat over the scene's
/// depth, so geometry hides the fluid behind it; the **shade pass**
/// normalises, and refracts the scene's image with Beer–Lambert absorption
/// through the thickness.
///
/// Create it once per [`GpuContext`]; each frame [`upload`](Self::upload) the
/// splats (the storage buffer only grows, so steady frames allocate nothing on
/// the GPU), then [`render`](Self::render) and either read the result back
/// ([`read_image`](Self::read_image), [`read_accumulation`](Self::read_accumulation),
/// [`read_depth`](Self::read_depth)) or copy it onto a window surface with
/// [`render_to_surface`](Self::render_to_surface).
pub struct SplatRenderer {
    accum_format: wgpu::TextureFormat,
    frame: wgpu::Buffer,
    splats: wgpu::Buffer,
    splat_capacity: usize,
    splat_count: u32,
    /// The splats produced on the GPU and their indirect draw arguments
    /// ([`use_gpu_splats`](Self::use_gpu_splats)); `None` draws the uploaded ones.
    gpu_source: Option<GpuSource>,
    staging: Vec<GpuSplat>,
    buffer_allocations: u32,
    splat_layout: wgpu::BindGroupLayout,
    splat_group: wgpu::BindGroup,
    visibility: wgpu::RenderPipeline,
    attribute: wgpu::RenderPipeline,
    /// The back surface pass and its bind group (the scene's depth).
    back: wgpu::RenderPipeline,
    back_layout: wgpu::BindGroupLayout,
    back_group: wgpu::BindGroup,
    /// The scene pass: backdrop, meshes, their bind group and buffers.
    backdrop: wgpu::RenderPipeline,
    mesh: wgpu::RenderPipeline,
    scene_layout: wgpu::BindGroupLayout,
    scene_group: wgpu::BindGroup,
    geometry: Option<MeshBuffers>,
    backdrop_kind: Backdrop,
    sun: glam::Vec3,
    shade_layout: wgpu::BindGroupLayout,
    shade: wgpu::ComputePipeline,
    shade_group: wgpu::BindGroup,
    env_view: wgpu::TextureView,
    back_view: wgpu::TextureView,
    env_sampler: wgpu::Sampler,
    back_sampler: wgpu::Sampler,
    blit_layout: wgpu::BindGroupLayout,
    blit_group: wgpu::BindGroup,
    blit: Option<(wgpu::TextureFormat, wgpu::RenderPipeline)>,
    targets: Targets,
}

impl SplatRenderer {
    /// A renderer drawing `width`×`height` images with the given environment.
    ///
    /// # Errors
    /// [`RenderError::InvalidSize`] for a zero or oversized side,
    /// [`RenderError::InvalidTexture`] for an empty image or one larger than
    /// the device's textures can be.
    pub fn new(ctx: &GpuContext, width: u32, height: u32, env: &Environment) -> Result<Self> {
        check_size(ctx, width, height)?;
        env.validate(ctx.device.limits().max_texture_dimension_2d)?;
        let device = &ctx.device;
        let accum_format = if device
            .features()
            .contains(wgpu::Features::FLOAT32_BLENDABLE)
        {
            wgpu::TextureFormat::Rgba32Float
        } else {
            wgpu::TextureFormat::Rgba16Float
        };
        let frame = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame uniforms"),
            size: size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let splats = create_splat_buffer(device, MIN_SPLAT_CAPACITY);

        let visible = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let splat_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("splat layout"),
            entries: &[
                uniform_entry(0, visible),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::VERTEX,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: true },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let splat_group = splat_bind_group(device, &splat_layout, &frame, &splats);

        let splat_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("splat.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                concat!(
                    include_str!("shaders/frame.wgsl"),
                    include_str!("shaders/splat.wgsl")
                )
                .into(),
            ),
        });
        let splat_pipeline_layout =
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("splat pipeline layout"),
                bind_group_layouts: &[Some(&splat_layout)],
                immediate_size: 0,
            });
        let splat_pipeline =
            |label,
             vertex: &str,
             fragment: &str,
             write_depth,
             targets: &[Option<wgpu::ColorTargetState>]| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: Some(&splat_pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &splat_module,
                        entry_point: Some(vertex),
                        compilation_options: Default::default(),
                        buffers: &[],
                    },
                    primitive: wgpu::PrimitiveState {
                        topology: wgpu::PrimitiveTopology::TriangleStrip,
                        ..Default::default()
                    },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: DEPTH_FORMAT,
                        depth_write_enabled: Some(write_depth),
                        depth_compare: Some(wgpu::CompareFunction::LessEqual),
                        stencil: Default::default(),
                        bias: Default::default(),
                    }),
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &splat_module,
                        entry_point: Some(fragment),
                        compilation_options: Default::default(),
                        targets,
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            };
        let visibility = splat_pipeline(
            "visibility pass",
            "vs_splat_visibility",
            "fs_visibility",
            true,
            &[],
        );
        let additive = wgpu::BlendComponent {
            src_factor: wgpu::BlendFactor::One,
            dst_factor: wgpu::BlendFactor::One,
            operation: wgpu::BlendOperation::Add,
        };
        let attribute = splat_pipeline(
            "attribute pass",
            "vs_splat",
            "fs_attribute",
            false,
            &[Some(wgpu::ColorTargetState {
                format: accum_format,
                blend: Some(wgpu::BlendState {
                    color: additive,
                    alpha: additive,
                }),
                write_mask: wgpu::ColorWrites::ALL,
            })],
        );

        let depth_tex = |binding, visibility| wgpu::BindGroupLayoutEntry {
            binding,
            visibility,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Depth,
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let back_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("back surface layout"),
            entries: &[depth_tex(0, wgpu::ShaderStages::FRAGMENT)],
        });
        let back = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("back surface pass"),
            layout: Some(
                &device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("back surface pipeline layout"),
                    bind_group_layouts: &[Some(&splat_layout), Some(&back_layout)],
                    immediate_size: 0,
                }),
            ),
            vertex: wgpu::VertexState {
                module: &splat_module,
                entry_point: Some("vs_splat_back"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleStrip,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Greater),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &splat_module,
                entry_point: Some("fs_back"),
                compilation_options: Default::default(),
                targets: &[],
            }),
            multiview_mask: None,
            cache: None,
        });
        let (scene_layout, backdrop, mesh) = scene_pipelines(device);

        let compute = wgpu::ShaderStages::COMPUTE;
        let float_tex = |binding, filterable| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: compute,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        };
        let sampler = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: compute,
            ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
            count: None,
        };
        let shade_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("shade layout"),
            entries: &[
                uniform_entry(0, compute),
                float_tex(1, false),
                depth_tex(2, compute),
                float_tex(3, true),
                sampler(4),
                float_tex(5, true),
                sampler(6),
                wgpu::BindGroupLayoutEntry {
                    binding: 7,
                    visibility: compute,
                    ty: wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: OUTPUT_FORMAT,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                    count: None,
                },
                depth_tex(8, compute),
            ],
        });
        let shade_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("shade.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                concat!(
                    include_str!("shaders/frame.wgsl"),
                    include_str!("shaders/shade.wgsl")
                )
                .into(),
            ),
        });
        let shade = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("normalise and shade"),
            layout: Some(
                &device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some("shade pipeline layout"),
                    bind_group_layouts: &[Some(&shade_layout)],
                    immediate_size: 0,
                }),
            ),
            module: &shade_module,
            entry_point: Some("cs_shade"),
            compilation_options: Default::default(),
            cache: None,
        });

        let (env_view, back_view) = upload_environment(ctx, env);
        let env_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("environment sampler"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let back_sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("background sampler"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let blit_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("blit layout"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });

        let targets = create_targets(device, width, height, accum_format);
        let shade_group = shade_bind_group(
            device,
            &shade_layout,
            &frame,
            &targets,
            &env_view,
            [&env_sampler, &back_sampler],
        );
        let scene_group = scene_bind_group(
            device,
            &scene_layout,
            &frame,
            [&env_view, &back_view],
            [&env_sampler, &back_sampler],
        );
        let back_group = back_bind_group(device, &back_layout, &targets);
        let blit_group = blit_bind_group(device, &blit_layout, &targets);
        Ok(Self {
            accum_format,
            frame,
            splats,
            splat_capacity: MIN_SPLAT_CAPACITY,
            splat_count: 0,
            gpu_source: None,
            staging: Vec::new(),
            buffer_allocations: 1,
            splat_layout,
            splat_group,
            visibility,
            attribute,
            back,
            back_layout,
            back_group,
            backdrop,
            mesh,
            scene_layout,
            scene_group,
            geometry: None,
            backdrop_kind: Backdrop::Screen,
            sun: crate::geometry::SUN,
            shade_layout,
            shade,
            shade_group,
            env_view,
            back_view,
            env_sampler,
            back_sampler,
            blit_layout,
            blit_group,
            blit: None,
            targets,
        })
    }

    /// Image size in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.targets.width, self.targets.height)
    }

    /// Format of the attribute accumulation target: `Rgba32Float` where the
    /// device can blend it, `Rgba16Float` otherwise.
    pub fn accumulation_format(&self) -> wgpu::TextureFormat {
        self.accum_format
    }

    /// Number of splats last uploaded (0 while drawing GPU-resident splats,
    /// whose count stays on the GPU).
    pub fn splat_count(&self) -> usize {
        self.splat_count as usize
    }

    /// How many times the splat storage buffer has been (re)allocated, the first
    /// included. Grows only when an upload exceeds the capacity.
    pub fn buffer_allocations(&self) -> u32 {
        self.buffer_allocations
    }

    /// Changes the image size (recreating the targets when it differs).
    ///
    /// # Errors
    /// [`RenderError::InvalidSize`].
    pub fn resize(&mut self, ctx: &GpuContext, width: u32, height: u32) -> Result<()> {
        check_size(ctx, width, height)?;
        if (width, height) != self.size() {
            self.targets = create_targets(&ctx.device, width, height, self.accum_format);
            self.rebind_targets(ctx);
        }
        Ok(())
    }

    /// Replaces the environment map and background.
    ///
    /// # Errors
    /// [`RenderError::InvalidTexture`] for an empty image or one larger than
    /// the device's textures can be.
    pub fn set_environment(&mut self, ctx: &GpuContext, env: &Environment) -> Result<()> {
        env.validate(ctx.device.limits().max_texture_dimension_2d)?;
        (self.env_view, self.back_view) = upload_environment(ctx, env);
        self.rebind_targets(ctx);
        Ok(())
    }

    fn rebind_targets(&mut self, ctx: &GpuContext) {
        let device = &ctx.device;
        self.shade_group = shade_bind_group(
            device,
            &self.shade_layout,
            &self.frame,
            &self.targets,
            &self.env_view,
            [&self.env_sampler, &self.back_sampler],
        );
        self.scene_group = scene_bind_group(
            device,
            &self.scene_layout,
            &self.frame,
            [&self.env_view, &self.back_view],
            [&self.env_sampler, &self.back_sampler],
        );
        self.back_group = back_bind_group(device, &self.back_layout, &self.targets);
        self.blit_group = blit_bind_group(device, &self.blit_layout, &self.targets);
    }

    /// Replaces the opaque geometry drawn around the splats and what fills
    /// the pixels it leaves (see [`SceneGeometry`]). The default, no objects
    /// before the screen-space background, is the thesis's picture.
    ///
    /// # Errors
    /// [`RenderError::InvalidGeometry`] naming the object and field that is
    /// non-finite or negative; nothing changes then.
    pub fn set_geometry(&mut self, ctx: &GpuContext, geometry: &SceneGeometry) -> Result<()> {
        use wgpu::util::DeviceExt;
        let (vertices, indices) = geometry.flatten()?;
        self.geometry = (!indices.is_empty()).then(|| {
            let buffer = |label, contents: &[u8], usage| {
                ctx.device
                    .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some(label),
                        contents,
                        usage,
                    })
            };
            MeshBuffers {
                vertices: buffer(
                    "scene vertices",
                    bytemuck::cast_slice(&vertices),
                    wgpu::BufferUsages::VERTEX,
                ),
                indices: buffer(
                    "scene indices",
                    bytemuck::cast_slice(&indices),
                    wgpu::BufferUsages::INDEX,
                ),
                count: indices.len() as u32,
            }
        });
        self.backdrop_kind = geometry.backdrop;
        self.sun = geometry.sun.normalize();
        Ok(())
    }

    /// Uploads the splats to draw. The GPU buffer is reused while it is large
    /// enough and otherwise grows to the next power of two.
    ///
    /// # Errors
    /// [`RenderError::InvalidSplat`] naming the first splat with a non-finite
    /// field, a zero normal or a non-positive radius (nothing is uploaded then);
    /// [`RenderError::TooManySplats`] beyond the device's storage binding limit.
    pub fn upload(&mut self, ctx: &GpuContext, splats: &[Splat]) -> Result<()> {
        // Converted into a CPU buffer kept between frames (no allocation once it
        // is large enough); the GPU buffer is untouched if a splat is invalid.
        self.staging.clear();
        for (i, s) in splats.iter().enumerate() {
            self.staging.push(GpuSplat::from_splat(i, s)?);
        }
        let gpu = &self.staging;
        let bytes = std::mem::size_of_val(gpu.as_slice()) as u64;
        let max = ctx
            .device
            .limits()
            .max_storage_buffer_binding_size
            .min(ctx.device.limits().max_buffer_size);
        if bytes > max || u32::try_from(gpu.len()).is_err() {
            return Err(RenderError::TooManySplats {
                count: gpu.len(),
                bytes,
                max,
            });
        }
        if self.gpu_source.take().is_some() {
            self.splat_group =
                splat_bind_group(&ctx.device, &self.splat_layout, &self.frame, &self.splats);
        }
        if gpu.len() > self.splat_capacity {
            let per = size_of::<GpuSplat>() as u64;
            let capacity = gpu.len().next_power_of_two().min((max / per) as usize);
            self.splats = create_splat_buffer(&ctx.device, capacity);
            self.splat_capacity = capacity;
            self.buffer_allocations += 1;
            self.splat_group =
                splat_bind_group(&ctx.device, &self.splat_layout, &self.frame, &self.splats);
        }
        if !gpu.is_empty() {
            ctx.queue
                .write_buffer(&self.splats, 0, bytemuck::cast_slice(gpu));
        }
        self.splat_count = gpu.len() as u32;
        Ok(())
    }

    /// Draws splats that live on the GPU from now on (until the next
    /// [`upload`](Self::upload)): `splats` holds `vec4(position, radius),
    /// vec4(normal, 0)` per splat (32 bytes, unit normals, positive radii) and
    /// `draw_args` a `wgpu::util::DrawIndirectArgs` of 4 vertices and one
    /// instance per splat — what a GPU surface extractor writes. Nothing goes
    /// through the CPU; the buffers are only referenced.
    ///
    /// # Errors
    /// [`RenderError::InvalidSource`] when `splats` is not a storage buffer of
    /// one or more whole splats within the binding limit or `draw_args` not an indirect
    /// buffer of at least 16 bytes.
    pub fn use_gpu_splats(
        &mut self,
        ctx: &GpuContext,
        splats: &wgpu::Buffer,
        draw_args: &wgpu::Buffer,
    ) -> Result<()> {
        use wgpu::BufferUsages as U;
        let per = size_of::<GpuSplat>() as u64;
        let max = ctx.device.limits().max_storage_buffer_binding_size;
        if !splats.usage().contains(U::STORAGE)
            || !splats.size().is_multiple_of(per)
            || splats.size() < per
            || splats.size() > max
        {
            return Err(RenderError::InvalidSource(
                "splats must be a storage buffer of one or more whole 32-byte splats within the binding limit",
            ));
        }
        if !draw_args.usage().contains(U::INDIRECT) || draw_args.size() < 16 {
            return Err(RenderError::InvalidSource(
                "draw_args must be an indirect buffer of at least 16 bytes",
            ));
        }
        // Called every frame with the same buffers: bind them only when they change.
        if self.gpu_source.as_ref().is_none_or(|g| g.splats != *splats) {
            self.splat_group =
                splat_bind_group(&ctx.device, &self.splat_layout, &self.frame, splats);
        }
        self.gpu_source = Some(GpuSource {
            splats: splats.clone(),
            draw_args: draw_args.clone(),
        });
        self.splat_count = 0;
        Ok(())
    }

    /// Records the splat draw of a pass: uploaded or GPU-resident splats.
    fn draw_splats(&self, pass: &mut wgpu::RenderPass<'_>) {
        match &self.gpu_source {
            Some(g) => pass.draw_indirect(&g.draw_args, 0),
            None => pass.draw(0..4, 0..self.splat_count),
        }
    }

    /// Records the passes into `encoder` (scene, back surface when
    /// absorbing, visibility, attribute, shade).
    ///
    /// The camera and shading go into the renderer's one uniform buffer by
    /// `queue.write_buffer`, which takes effect before the next submit: two
    /// `encode` calls recorded into encoders submitted together both draw
    /// with the second call's camera and shading. Submit between calls.
    ///
    /// # Errors
    /// [`RenderError::InvalidCamera`], [`RenderError::InvalidShading`].
    pub fn encode(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        shading: &Shading,
    ) -> Result<()> {
        self.encode_timed(ctx, encoder, camera, shading, None)
    }

    /// [`encode`](Self::encode) with each pass timed by `profiler` ("scene
    /// pass", "back surface pass" when absorbing, "visibility pass",
    /// "attribute pass", "normalise and shade"), where the device has
    /// `wgpu::Features::TIMESTAMP_QUERY`. The caller resolves the profiler's
    /// queries and ends its frame.
    ///
    /// # Errors
    /// As [`encode`](Self::encode).
    pub fn encode_profiled(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        shading: &Shading,
        profiler: &GpuProfiler,
    ) -> Result<()> {
        self.encode_timed(ctx, encoder, camera, shading, Some(profiler))
    }

    fn encode_timed(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        shading: &Shading,
        profiler: Option<&GpuProfiler>,
    ) -> Result<()> {
        camera.validate()?;
        shading.validate()?;
        let (width, height) = self.size();
        let absorbing = shading.absorption.max_element() > 0.0;
        let flag = |on: bool| if on { 1.0 } else { 0.0 };
        let view = camera.view();
        let proj = camera.projection(width, height);
        let uniform = FrameUniform {
            view: view.to_cols_array_2d(),
            proj: proj.to_cols_array_2d(),
            inv_view: view.inverse().to_cols_array_2d(),
            viewport: [
                width as f32,
                height as f32,
                1.0 / width as f32,
                1.0 / height as f32,
            ],
            ray: [
                1.0 / proj.x_axis.x,
                1.0 / proj.y_axis.y,
                camera.near,
                camera.far,
            ],
            params: [
                shading.depth_epsilon,
                shading.refraction,
                shading.weight_scale,
                shading.view.code(),
            ],
            fluid: shading.fluid_colour.extend(shading.reflectivity).to_array(),
            flags: [
                flag(shading.cull_back_faces),
                flag(self.backdrop_kind == Backdrop::Environment),
                flag(absorbing),
                0.0,
            ],
            sun: self.sun.extend(0.0).to_array(),
            absorption: shading.absorption.extend(0.0).to_array(),
        };
        ctx.queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(&uniform));

        let t = &self.targets;
        let begin = |label: &str, encoder: &mut wgpu::CommandEncoder| {
            profiler.map(|p| p.begin_pass_query(label, encoder))
        };
        let end = |query: Option<GpuProfilerQuery>, encoder: &mut wgpu::CommandEncoder| {
            if let (Some(p), Some(q)) = (profiler, query) {
                p.end_query(encoder, q);
            }
        };
        let query = begin("scene pass", encoder);
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("scene pass"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &t.scene_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(depth_attachment(
                    &t.depth_view,
                    wgpu::LoadOp::Clear(1.0),
                )),
                timestamp_writes: query
                    .as_ref()
                    .and_then(|q| q.render_pass_timestamp_writes()),
                ..Default::default()
            });
            pass.set_bind_group(0, &self.scene_group, &[]);
            pass.set_pipeline(&self.backdrop);
            pass.draw(0..3, 0..1);
            if let Some(g) = &self.geometry {
                pass.set_pipeline(&self.mesh);
                pass.set_vertex_buffer(0, g.vertices.slice(..));
                pass.set_index_buffer(g.indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..g.count, 0, 0..1);
            }
        }
        end(query, encoder);
        if absorbing {
            let query = begin("back surface pass", encoder);
            {
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("back surface pass"),
                    color_attachments: &[],
                    depth_stencil_attachment: Some(depth_attachment(
                        &t.back_depth_view,
                        wgpu::LoadOp::Clear(0.0),
                    )),
                    timestamp_writes: query
                        .as_ref()
                        .and_then(|q| q.render_pass_timestamp_writes()),
                    ..Default::default()
                });
                pass.set_pipeline(&self.back);
                pass.set_bind_group(0, &self.splat_group, &[]);
                pass.set_bind_group(1, &self.back_group, &[]);
                self.draw_splats(&mut pass);
            }
            end(query, encoder);
        }
        let query = begin("visibility pass", encoder);
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("visibility pass"),
                color_attachments: &[],
                depth_stencil_attachment: Some(depth_attachment(&t.depth_view, wgpu::LoadOp::Load)),
                timestamp_writes: query
                    .as_ref()
                    .and_then(|q| q.render_pass_timestamp_writes()),
                ..Default::default()
            });
            pass.set_pipeline(&self.visibility);
            pass.set_bind_group(0, &self.splat_group, &[]);
            self.draw_splats(&mut pass);
        }
        end(query, encoder);
        let query = begin("attribute pass", encoder);
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("attribute pass"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &t.accum_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(depth_attachment(&t.depth_view, wgpu::LoadOp::Load)),
                timestamp_writes: query
                    .as_ref()
                    .and_then(|q| q.render_pass_timestamp_writes()),
                ..Default::default()
            });
            pass.set_pipeline(&self.attribute);
            pass.set_bind_group(0, &self.splat_group, &[]);
            self.draw_splats(&mut pass);
        }
        end(query, encoder);
        let query = begin("normalise and shade", encoder);
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("normalise and shade"),
                timestamp_writes: query
                    .as_ref()
                    .and_then(|q| q.compute_pass_timestamp_writes()),
            });
            pass.set_pipeline(&self.shade);
            pass.set_bind_group(0, &self.shade_group, &[]);
            pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        }
        end(query, encoder);
        Ok(())
    }

    /// Renders the uploaded splats into the internal targets and submits.
    ///
    /// # Errors
    /// [`RenderError::InvalidCamera`], [`RenderError::InvalidShading`].
    pub fn render(&self, ctx: &GpuContext, camera: &Camera, shading: &Shading) -> Result<()> {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.encode(ctx, &mut encoder, camera, shading)?;
        ctx.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Renders and copies the shaded image onto `target` (a window surface's
    /// texture view of `format`), all on the GPU. The caller presents.
    ///
    /// # Errors
    /// [`RenderError::InvalidCamera`], [`RenderError::InvalidShading`].
    pub fn render_to_surface(
        &mut self,
        ctx: &GpuContext,
        camera: &Camera,
        shading: &Shading,
        target: &wgpu::TextureView,
        format: wgpu::TextureFormat,
    ) -> Result<()> {
        if self.blit.as_ref().is_none_or(|(f, _)| *f != format) {
            self.blit = Some((format, self.create_blit(ctx, format)));
        }
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.encode(ctx, &mut encoder, camera, shading)?;
        if let Some((_, blit)) = &self.blit {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("blit to surface"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                ..Default::default()
            });
            pass.set_pipeline(blit);
            pass.set_bind_group(0, &self.blit_group, &[]);
            pass.draw(0..3, 0..1);
        }
        ctx.queue.submit([encoder.finish()]);
        Ok(())
    }

    fn create_blit(&self, ctx: &GpuContext, format: wgpu::TextureFormat) -> wgpu::RenderPipeline {
        let device = &ctx.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("blit.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shaders/blit.wgsl").into()),
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("blit pipeline layout"),
            bind_group_layouts: &[Some(&self.blit_layout)],
            immediate_size: 0,
        });
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("blit"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_fullscreen"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(if format.is_srgb() {
                    "fs_blit_srgb"
                } else {
                    "fs_blit"
                }),
                compilation_options: Default::default(),
                targets: &[Some(format.into())],
            }),
            multiview_mask: None,
            cache: None,
        })
    }

    /// Reads the shaded image (or debug view) of the last render back to the CPU.
    ///
    /// # Errors
    /// [`RenderError::Readback`].
    pub fn read_image(&self, ctx: &GpuContext) -> Result<RgbaImage> {
        let t = &self.targets;
        let bytes = read_texture(ctx, &t.output, wgpu::TextureAspect::All, 4)?;
        RgbaImage::from_raw(t.width, t.height, bytes)
            .ok_or_else(|| RenderError::Readback("image size mismatch".into()))
    }

    /// Reads the accumulation target (Σ wᵢ nᵢ, Σ wᵢ) of the last render.
    ///
    /// # Errors
    /// [`RenderError::Readback`].
    pub fn read_accumulation(&self, ctx: &GpuContext) -> Result<Accumulation> {
        let t = &self.targets;
        let texel = self.accum_format.block_copy_size(None).unwrap_or(16);
        let bytes = read_texture(ctx, &t.accum, wgpu::TextureAspect::All, texel)?;
        Accumulation::from_bytes(t.width, t.height, self.accum_format, &bytes)
    }

    /// Reads the visibility pass's depth buffer (0..1, 1 = nothing drawn),
    /// row-major from the top-left pixel.
    ///
    /// # Errors
    /// [`RenderError::Readback`].
    pub fn read_depth(&self, ctx: &GpuContext) -> Result<Vec<f32>> {
        let bytes = read_texture(ctx, &self.targets.depth, wgpu::TextureAspect::DepthOnly, 4)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }
}

fn check_size(ctx: &GpuContext, width: u32, height: u32) -> Result<()> {
    let max = ctx.device.limits().max_texture_dimension_2d;
    if width == 0 || height == 0 || width > max || height > max {
        return Err(RenderError::InvalidSize { width, height, max });
    }
    Ok(())
}

fn uniform_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

fn depth_attachment(
    view: &wgpu::TextureView,
    load: wgpu::LoadOp<f32>,
) -> wgpu::RenderPassDepthStencilAttachment<'_> {
    wgpu::RenderPassDepthStencilAttachment {
        view,
        depth_ops: Some(wgpu::Operations {
            load,
            store: wgpu::StoreOp::Store,
        }),
        stencil_ops: None,
    }
}

/// Splats that live on the GPU, drawn without going through the CPU.
#[derive(Debug)]
struct GpuSource {
    splats: wgpu::Buffer,
    draw_args: wgpu::Buffer,
}

fn create_splat_buffer(device: &wgpu::Device, capacity: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("splats"),
        size: (capacity * size_of::<GpuSplat>()) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn splat_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    splats: &wgpu::Buffer,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("splat bind group"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: frame.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: splats.as_entire_binding(),
            },
        ],
    })
}

fn shade_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    t: &Targets,
    env: &wgpu::TextureView,
    [env_sampler, scene_sampler]: [&wgpu::Sampler; 2],
) -> wgpu::BindGroup {
    use wgpu::BindingResource::{Sampler, TextureView};
    bind_in_order(
        device,
        "shade bind group",
        layout,
        [
            frame.as_entire_binding(),
            TextureView(&t.accum_view),
            TextureView(&t.depth_view),
            TextureView(env),
            Sampler(env_sampler),
            TextureView(&t.scene_view),
            Sampler(scene_sampler),
            TextureView(&t.output_view),
            TextureView(&t.back_depth_view),
        ],
    )
}

/// A bind group of `resources` at bindings 0, 1, 2, …
fn bind_in_order<const N: usize>(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: [wgpu::BindingResource<'_>; N],
) -> wgpu::BindGroup {
    let entries: Vec<_> = resources
        .into_iter()
        .enumerate()
        .map(|(i, resource)| wgpu::BindGroupEntry {
            binding: i as u32,
            resource,
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &entries,
    })
}

fn scene_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    [env, back]: [&wgpu::TextureView; 2],
    [env_sampler, back_sampler]: [&wgpu::Sampler; 2],
) -> wgpu::BindGroup {
    use wgpu::BindingResource::{Sampler, TextureView};
    bind_in_order(
        device,
        "scene bind group",
        layout,
        [
            frame.as_entire_binding(),
            TextureView(env),
            Sampler(env_sampler),
            TextureView(back),
            Sampler(back_sampler),
        ],
    )
}

fn back_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    t: &Targets,
) -> wgpu::BindGroup {
    bind_in_order(
        device,
        "back surface bind group",
        layout,
        [wgpu::BindingResource::TextureView(&t.depth_view)],
    )
}

/// The scene geometry's GPU buffers.
struct MeshBuffers {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    count: u32,
}

/// The scene pass's bind group layout and its two pipelines: the backdrop
/// (a full-screen triangle behind everything) and the meshes.
fn scene_pipelines(
    device: &wgpu::Device,
) -> (
    wgpu::BindGroupLayout,
    wgpu::RenderPipeline,
    wgpu::RenderPipeline,
) {
    let stages = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
    let texture = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: stages,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    };
    let sampler = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: stages,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    };
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("scene layout"),
        entries: &[
            uniform_entry(0, stages),
            texture(1),
            sampler(2),
            texture(3),
            sampler(4),
        ],
    });
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("scene.wgsl"),
        source: wgpu::ShaderSource::Wgsl(
            concat!(
                include_str!("shaders/frame.wgsl"),
                include_str!("shaders/scene.wgsl")
            )
            .into(),
        ),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("scene pipeline layout"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let vertex_layout = wgpu::VertexBufferLayout {
        array_stride: size_of::<GpuVertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x4, 1 => Float32x4, 2 => Float32x4],
    };
    let pipeline = |label, vs, fs, buffers: &[Option<wgpu::VertexBufferLayout<'_>>], mesh: bool| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some(vs),
                compilation_options: Default::default(),
                buffers,
            },
            primitive: wgpu::PrimitiveState {
                cull_mode: mesh.then_some(wgpu::Face::Back),
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(mesh),
                depth_compare: Some(if mesh {
                    wgpu::CompareFunction::Less
                } else {
                    wgpu::CompareFunction::Always
                }),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(fs),
                compilation_options: Default::default(),
                targets: &[Some(SCENE_FORMAT.into())],
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let backdrop = pipeline("backdrop", "vs_backdrop", "fs_backdrop", &[], false);
    let mesh = pipeline(
        "scene meshes",
        "vs_mesh",
        "fs_mesh",
        &[Some(vertex_layout)],
        true,
    );
    (layout, backdrop, mesh)
}

fn blit_bind_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    t: &Targets,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("blit bind group"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::TextureView(&t.output_view),
        }],
    })
}

fn create_targets(
    device: &wgpu::Device,
    width: u32,
    height: u32,
    accum_format: wgpu::TextureFormat,
) -> Targets {
    let texture = |label, format, usage| {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        (texture, view)
    };
    use wgpu::TextureUsages as U;
    let (depth, depth_view) = texture(
        "visibility depth",
        DEPTH_FORMAT,
        U::RENDER_ATTACHMENT | U::TEXTURE_BINDING | U::COPY_SRC,
    );
    let (_, scene_view) = texture(
        "scene image",
        SCENE_FORMAT,
        U::RENDER_ATTACHMENT | U::TEXTURE_BINDING,
    );
    let (_, back_depth_view) = texture(
        "back surface depth",
        DEPTH_FORMAT,
        U::RENDER_ATTACHMENT | U::TEXTURE_BINDING,
    );
    let (accum, accum_view) = texture(
        "attribute accumulation",
        accum_format,
        U::RENDER_ATTACHMENT | U::TEXTURE_BINDING | U::COPY_SRC,
    );
    let (output, output_view) = texture(
        "shaded image",
        OUTPUT_FORMAT,
        U::STORAGE_BINDING | U::TEXTURE_BINDING | U::COPY_SRC,
    );
    Targets {
        width,
        height,
        depth,
        depth_view,
        scene_view,
        back_depth_view,
        accum,
        accum_view,
        output,
        output_view,
    }
}

fn upload_environment(
    ctx: &GpuContext,
    env: &Environment,
) -> (wgpu::TextureView, wgpu::TextureView) {
    let upload = |label, img: &RgbaImage| {
        let size = wgpu::Extent3d {
            width: img.width(),
            height: img.height(),
            depth_or_array_layers: 1,
        };
        let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8Unorm,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        ctx.queue.write_texture(
            texture.as_image_copy(),
            img.as_raw(),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * img.width()),
                rows_per_image: Some(img.height()),
            },
            size,
        );
        texture.create_view(&Default::default())
    };
    (
        upload("environment map", &env.environment),
        upload("background", &env.background),
    )
}

#[cfg(test)]
mod layout_tests {
    use super::FrameUniform;
    use crate::splat::GpuSplat;

    /// The Rust uniform and vertex structs match their WGSL declarations.
    #[test]
    fn uniforms_match_their_wgsl() {
        crate::wgsl_layout!(
            include_str!("shaders/frame.wgsl"),
            "Frame",
            FrameUniform {
                view,
                proj,
                inv_view,
                viewport,
                ray,
                params,
                fluid,
                flags,
                sun,
                absorption
            }
        )
        .unwrap();
        let splat = concat!(
            include_str!("shaders/frame.wgsl"),
            include_str!("shaders/splat.wgsl")
        );
        crate::wgsl_layout!(
            splat,
            "Splat",
            GpuSplat {
                position_radius,
                normal
            }
        )
        .unwrap();
    }
}
