//! [`SplatRenderer`]: the thesis's two-pass splatting with deferred shading,
//! in front of opaque scene geometry. One module per pass, the plumbing
//! they share written once:
//! - `scene`: backdrop and meshes into the scene image and depth;
//! - `splats`: the back surface, visibility and attribute passes;
//! - `compute`: the visibility and attribute passes in compute
//!   ([`SplatPath::Compute`]);
//! - `shade`: normalise and shade (compute);
//! - `blit`: the result onto a window surface;
//! - `targets`: the render targets and the environment's textures;
//! - `plumbing`: layout entries, bind groups, shader modules, timed passes.

mod blit;
mod compute;
mod plumbing;
mod scene;
mod shade;
mod splats;
mod targets;

use bytemuck::{Pod, Zeroable};
use image::RgbaImage;
use wgpu_profiler::GpuProfiler;

use crate::camera::Camera;
use crate::context::GpuContext;
use crate::error::{RenderError, Result};
use crate::geometry::{Backdrop, SceneGeometry};
use crate::readback::{Accumulation, read_buffer, read_texture};
use crate::shading::Shading;
use crate::splat::{GpuSplat, Splat};
use crate::textures::Environment;

use blit::Blit;
use compute::ComputeSplats;
use scene::ScenePass;
use shade::ShadePass;
use splats::SplatPasses;
pub use targets::OUTPUT_FORMAT;
use targets::{Surroundings, Targets, check_size};

const MIN_SPLAT_CAPACITY: usize = 1024;

/// How the visibility and attribute passes draw the splats. A new
/// renderer takes [`SplatPath::for_device`] of its adapter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SplatPath {
    /// The raster hardware: each splat a quad, depth-tested and blended.
    Raster,
    /// Compute shaders: splats binned to 8×8-pixel screen tiles, each tile's
    /// pixels tested against its splats in workgroup memory, past the raster
    /// hardware's blending rate (see `renderer/compute.rs`). The same images:
    /// FLIP ≤ 2e-6 against the raster path on the reference goldens.
    Compute,
}

impl SplatPath {
    /// The faster path on an adapter of `device_type`, as measured (BENCHMARKS.md, "Compute
    /// splatting beside raster splatting"): compute on a GPU, where it took
    /// 2.2–4.5× less GPU time than raster at 20k–1M surfels on an NVIDIA
    /// H200; raster on a CPU adapter (lavapipe, llvmpipe), where compute
    /// was slower at 20k and 100k surfels and within 10 % at 1M.
    pub fn for_device(device_type: wgpu::DeviceType) -> Self {
        match device_type {
            wgpu::DeviceType::Cpu => SplatPath::Raster,
            _ => SplatPath::Compute,
        }
    }

    /// Its name on the command line: `raster` or `compute`.
    pub fn name(self) -> &'static str {
        match self {
            SplatPath::Raster => "raster",
            SplatPath::Compute => "compute",
        }
    }
}

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
    scene: ScenePass,
    splat_passes: SplatPasses,
    shade: ShadePass,
    blit: Blit,
    around: Surroundings,
    targets: Targets,
    path: SplatPath,
    /// Whether `path` is the adapter's choice rather than the caller's: a
    /// chosen compute path gives way to raster where it cannot draw (a
    /// size or splat count past its memory, draw arguments it cannot read).
    chosen: bool,
    /// The compute splat passes, made when [`SplatPath::Compute`] is first
    /// chosen.
    compute: Option<ComputeSplats>,
}

impl SplatRenderer {
    /// A renderer drawing `width`×`height` images with the given
    /// environment, by [`SplatPath::for_device`] of its adapter: compute on
    /// a GPU, where the compute path's memory fits. That chosen path gives
    /// way to raster, with a log line, where it later cannot draw (a size or
    /// splat count past its memory, GPU draw arguments it cannot read);
    /// [`set_splat_path`](Self::set_splat_path) fixes a path instead.
    ///
    /// # Errors
    /// [`RenderError::InvalidSize`] for a zero or oversized side,
    /// [`RenderError::InvalidTexture`] for an empty image or one larger than
    /// the device's textures can be; [`RenderError::Device`] where the
    /// device reports a fault, such as targets past its memory.
    pub fn new(ctx: &GpuContext, width: u32, height: u32, env: &Environment) -> Result<Self> {
        check_size(ctx, width, height)?;
        env.validate(ctx.device.limits().max_texture_dimension_2d)?;
        let device = &ctx.device;
        // Float32 blending where the device has it, else half floats.
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
        let targets = Targets::new(device, width, height, accum_format);
        let around = Surroundings::new(ctx, env);
        let mut renderer = Self {
            accum_format,
            scene: ScenePass::new(device, &frame, &around),
            splat_passes: SplatPasses::new(device, accum_format, &frame, &splats, &targets),
            shade: ShadePass::new(device, &frame, &targets, &around),
            blit: Blit::new(device, &targets),
            frame,
            splats,
            splat_capacity: MIN_SPLAT_CAPACITY,
            splat_count: 0,
            gpu_source: None,
            staging: Vec::new(),
            buffer_allocations: 1,
            around,
            targets,
            path: SplatPath::Raster,
            chosen: false,
            compute: None,
        };
        // The adapter's faster path, where its memory fits this size
        // (the raster path otherwise, which needs none).
        let preferred = SplatPath::for_device(ctx.adapter.get_info().device_type);
        if preferred == SplatPath::Compute {
            match renderer.set_splat_path(ctx, preferred) {
                Ok(()) => renderer.chosen = true,
                Err(e) => log::info!("{e}: splats drawn by the raster path"),
            }
        }
        // Targets the device could not allocate (16384² on lavapipe) are
        // reported as an uncaptured error, not by `create_texture`.
        ctx.check()?;
        Ok(renderer)
    }

    /// The splat path in use.
    pub fn splat_path(&self) -> SplatPath {
        self.path
    }

    /// Draws the splats by `path` from the next frame on, and keeps it: a
    /// path set here reports what it cannot draw as an error, where the
    /// adapter's own choice (see [`SplatRenderer::new`]) gives way to
    /// raster. Setting [`SplatPath::Raster`] frees the compute path's
    /// memory.
    ///
    /// # Errors
    /// [`RenderError::InvalidSource`] for [`SplatPath::Compute`] while
    /// drawing GPU-resident splats whose draw arguments are not a storage
    /// buffer (the compute passes read the count from them);
    /// [`RenderError::ComputeLimit`] when its memory for this size or splat
    /// buffer is past the device's storage binding limit. The path is
    /// unchanged then.
    pub fn set_splat_path(&mut self, ctx: &GpuContext, path: SplatPath) -> Result<()> {
        if path == SplatPath::Compute {
            if let Some(g) = &self.gpu_source {
                check_args_readable(&g.draw_args)?;
            }
            compute::check_fits(&ctx.device, self.size(), self.splat_buffer_len())?;
        }
        self.path = path;
        self.chosen = false;
        if path == SplatPath::Raster {
            self.release_compute();
        }
        self.reserve_compute(ctx);
        Ok(())
    }

    /// `check` of the compute path's needs: where it fails on a path the
    /// adapter chose, the raster path takes over (the error is logged);
    /// on a path the caller chose, the error.
    fn compute_or_raster(&mut self, check: Result<()>) -> Result<()> {
        match check {
            Err(e) if self.chosen => {
                log::info!("{e}: splats drawn by the raster path from now on");
                self.path = SplatPath::Raster;
                self.chosen = false;
                self.release_compute();
                Ok(())
            }
            other => other,
        }
    }

    /// A chosen compute path whose last frames needed more tile-list
    /// entries than one binding holds (every such frame draws the rest
    /// through the slow all-tiles list) gives way to raster.
    fn give_way_past_the_lists_limit(&mut self) {
        if let Some((bytes, max)) = self.compute.as_ref().and_then(ComputeSplats::past_limit) {
            let past = RenderError::ComputeLimit {
                what: "tile lists",
                bytes,
                max,
            };
            // Only an error for a path the caller set, and that one keeps
            // drawing: nothing to report here.
            let _ = self.compute_or_raster(Err(past));
        }
    }

    /// Frees the compute path's memory.
    fn release_compute(&mut self) {
        self.compute = None;
        self.shade.release_buffers();
    }

    /// Splats the bound splat buffer holds.
    fn splat_buffer_len(&self) -> u32 {
        let splats = match &self.gpu_source {
            Some(g) => g.splats.size() / size_of::<GpuSplat>() as u64,
            None => self.splat_capacity as u64,
        };
        u32::try_from(splats).unwrap_or(u32::MAX)
    }

    /// Sizes the compute passes' memory for the targets and the splat
    /// buffer, making them first when the compute path is on.
    fn reserve_compute(&mut self, ctx: &GpuContext) {
        if self.path != SplatPath::Compute {
            return;
        }
        let size = self.size();
        let splats = self.splat_buffer_len();
        let compute = match &mut self.compute {
            Some(c) => {
                c.reserve(&ctx.device, size, splats);
                c
            }
            None => self
                .compute
                .insert(ComputeSplats::new(&ctx.device, size, splats)),
        };
        self.shade.bind_buffers(
            &ctx.device,
            &self.frame,
            &self.targets,
            &self.around,
            compute.sums(),
            compute.depth_bits(),
        );
    }

    /// Frames drawn by the compute path whose tile lists outgrew their
    /// buffer (see [`SplatPath::Compute`]; as read back, a frame or more
    /// late). Such a frame is still drawn whole, the splats that did not
    /// fit from a list apart that every tile runs over, and the buffer grows
    /// for the next.
    pub fn compute_overflows(&self) -> u32 {
        self.compute.as_ref().map_or(0, ComputeSplats::overflows)
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
    /// [`RenderError::InvalidSize`]; [`RenderError::ComputeLimit`] on the
    /// compute splat path when its memory for that size is past the
    /// device's storage binding limit (nothing changes then);
    /// [`RenderError::Device`] where the device reports a fault, such as
    /// targets past its memory.
    pub fn resize(&mut self, ctx: &GpuContext, width: u32, height: u32) -> Result<()> {
        check_size(ctx, width, height)?;
        if self.path == SplatPath::Compute {
            let fits = compute::check_fits(&ctx.device, (width, height), self.splat_buffer_len());
            self.compute_or_raster(fits)?;
        }
        if (width, height) != self.size() {
            self.targets = Targets::new(&ctx.device, width, height, self.accum_format);
            self.rebind(ctx);
            self.reserve_compute(ctx);
        }
        ctx.check()
    }

    /// Replaces the environment map and background.
    ///
    /// # Errors
    /// [`RenderError::InvalidTexture`] for an empty image or one larger than
    /// the device's textures can be.
    pub fn set_environment(&mut self, ctx: &GpuContext, env: &Environment) -> Result<()> {
        env.validate(ctx.device.limits().max_texture_dimension_2d)?;
        self.around.set(ctx, env);
        self.rebind(ctx);
        Ok(())
    }

    /// Binds the passes to the current targets and surroundings.
    fn rebind(&mut self, ctx: &GpuContext) {
        let device = &ctx.device;
        self.shade
            .rebind(device, &self.frame, &self.targets, &self.around);
        self.scene.rebind(device, &self.frame, &self.around);
        self.splat_passes.rebind_targets(device, &self.targets);
        self.blit.rebind(device, &self.targets);
    }

    /// Replaces the opaque geometry drawn around the splats and what fills
    /// the pixels it leaves (see [`SceneGeometry`]). The default, no objects
    /// before the screen-space background, is the thesis's picture.
    ///
    /// # Errors
    /// [`RenderError::InvalidGeometry`] naming the object and field that is
    /// non-finite or negative; nothing changes then.
    pub fn set_geometry(&mut self, ctx: &GpuContext, geometry: &SceneGeometry) -> Result<()> {
        self.scene.set_geometry(&ctx.device, geometry)
    }

    /// Uploads the splats to draw. The GPU buffer is reused while it is large
    /// enough and otherwise grows to the next power of two.
    ///
    /// # Errors
    /// [`RenderError::InvalidSplat`] naming the first splat with a non-finite
    /// field, a zero normal, a non-positive radius, or a radius or
    /// coordinate beyond [`MAX_SPLAT_EXTENT`](crate::MAX_SPLAT_EXTENT) (nothing is
    /// uploaded then);
    /// [`RenderError::TooManySplats`] beyond the device's storage binding limit;
    /// [`RenderError::ComputeLimit`] on the compute splat path when its
    /// memory for them is past that limit.
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
        if self.path == SplatPath::Compute && gpu.len() > self.splat_capacity {
            let capacity = u32::try_from(gpu.len().next_power_of_two()).unwrap_or(u32::MAX);
            let fits = compute::check_fits(&ctx.device, self.size(), capacity);
            self.compute_or_raster(fits)?;
        }
        let gpu = &self.staging;
        if self.gpu_source.take().is_some() {
            self.splat_passes
                .bind(&ctx.device, &self.frame, &self.splats);
        }
        if gpu.len() > self.splat_capacity {
            let per = size_of::<GpuSplat>() as u64;
            let capacity = gpu.len().next_power_of_two().min((max / per) as usize);
            self.splats = create_splat_buffer(&ctx.device, capacity);
            self.splat_capacity = capacity;
            self.buffer_allocations += 1;
            self.splat_passes
                .bind(&ctx.device, &self.frame, &self.splats);
        }
        if !gpu.is_empty() {
            ctx.queue
                .write_buffer(&self.splats, 0, bytemuck::cast_slice(gpu));
        }
        self.splat_count = gpu.len() as u32;
        self.give_way_past_the_lists_limit();
        self.reserve_compute(ctx);
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
    /// buffer of at least 16 bytes (and, on the compute splat path, a storage
    /// buffer); [`RenderError::ComputeLimit`] on the compute splat path when
    /// its memory for them is past the binding limit.
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
        if self.path == SplatPath::Compute {
            let count = u32::try_from(splats.size() / per).unwrap_or(u32::MAX);
            let usable = check_args_readable(draw_args)
                .and_then(|()| compute::check_fits(&ctx.device, self.size(), count));
            self.compute_or_raster(usable)?;
        }
        // Called every frame with the same buffers: bind them only when they change.
        if self.gpu_source.as_ref().is_none_or(|g| g.splats != *splats) {
            self.splat_passes.bind(&ctx.device, &self.frame, splats);
        }
        self.gpu_source = Some(GpuSource {
            splats: splats.clone(),
            draw_args: draw_args.clone(),
        });
        self.splat_count = 0;
        self.give_way_past_the_lists_limit();
        self.reserve_compute(ctx);
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
                flag(self.scene.backdrop_kind == Backdrop::Environment),
                flag(absorbing),
                0.0,
            ],
            sun: self.scene.sun.extend(0.0).to_array(),
            absorption: shading.absorption.extend(0.0).to_array(),
        };
        ctx.queue
            .write_buffer(&self.frame, 0, bytemuck::bytes_of(&uniform));

        let t = &self.targets;
        let draw = |pass: &mut wgpu::RenderPass<'_>| self.draw_splats(pass);
        self.scene.record(encoder, profiler, t);
        if absorbing {
            self.splat_passes.record_back(encoder, profiler, t, &draw);
        }
        match (self.path, &self.compute) {
            (SplatPath::Compute, Some(compute)) => {
                let (splats, args) = match &self.gpu_source {
                    Some(g) => (&g.splats, Some(&g.draw_args)),
                    None => (&self.splats, None),
                };
                compute.record(
                    &ctx.device,
                    &ctx.queue,
                    encoder,
                    profiler,
                    &self.frame,
                    splats,
                    args,
                    self.splat_count,
                    t,
                );
            }
            _ => {
                self.splat_passes
                    .record_visibility(encoder, profiler, t, &draw);
                self.splat_passes
                    .record_attribute(encoder, profiler, t, &draw);
            }
        }
        let from_buffers = self.compute_drawn().is_some();
        self.shade.record(encoder, profiler, t, from_buffers);
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
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        self.encode(ctx, &mut encoder, camera, shading)?;
        self.blit.record(&ctx.device, &mut encoder, target, format);
        ctx.queue.submit([encoder.finish()]);
        Ok(())
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

    /// Reads the accumulation target (Σ wᵢ nᵢ, Σ wᵢ) of the last render;
    /// on the compute path, its sums (in f32, whatever
    /// [`accumulation_format`](Self::accumulation_format) is).
    ///
    /// # Errors
    /// [`RenderError::Readback`].
    pub fn read_accumulation(&self, ctx: &GpuContext) -> Result<Accumulation> {
        let t = &self.targets;
        if let Some(compute) = self.compute_drawn() {
            let bytes = read_buffer(ctx, compute.sums())?;
            return Accumulation::from_bytes(
                t.width,
                t.height,
                wgpu::TextureFormat::Rgba32Float,
                &bytes,
            );
        }
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
        let bytes = match self.compute_drawn() {
            Some(compute) => read_buffer(ctx, compute.depth_bits())?,
            None => read_texture(ctx, &self.targets.depth, wgpu::TextureAspect::DepthOnly, 4)?,
        };
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// The compute passes, where they draw the splats.
    fn compute_drawn(&self) -> Option<&ComputeSplats> {
        self.compute
            .as_ref()
            .filter(|_| self.path == SplatPath::Compute)
    }
}

/// Splats that live on the GPU, drawn without going through the CPU.
#[derive(Debug)]
struct GpuSource {
    splats: wgpu::Buffer,
    draw_args: wgpu::Buffer,
}

/// The compute path reads the splat count from GPU-resident draw arguments.
fn check_args_readable(draw_args: &wgpu::Buffer) -> Result<()> {
    if draw_args.usage().contains(wgpu::BufferUsages::STORAGE) {
        Ok(())
    } else {
        Err(RenderError::InvalidSource(
            "the compute splat path reads the splat count from draw_args: it must be a storage buffer too",
        ))
    }
}

fn create_splat_buffer(device: &wgpu::Device, capacity: usize) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("splats"),
        size: (capacity * size_of::<GpuSplat>()) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

#[cfg(test)]
mod layout_tests {
    use super::FrameUniform;
    use crate::splat::GpuSplat;

    /// The Rust uniform and vertex structs match their WGSL declarations.
    #[test]
    fn uniforms_match_their_wgsl() {
        crate::wgsl_layout!(
            include_str!("../shaders/frame.wgsl"),
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
            include_str!("../shaders/frame.wgsl"),
            include_str!("../shaders/disc.wgsl")
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

#[cfg(test)]
mod path_tests {
    use super::SplatPath;

    #[test]
    fn gpus_splat_in_compute_and_software_adapters_by_raster() {
        use wgpu::DeviceType as D;
        assert_eq!(SplatPath::for_device(D::Cpu), SplatPath::Raster);
        for gpu in [D::DiscreteGpu, D::IntegratedGpu, D::VirtualGpu, D::Other] {
            assert_eq!(SplatPath::for_device(gpu), SplatPath::Compute);
        }
    }
}

#[cfg(test)]
mod fallback_tests {
    use glam::Vec3;

    use super::{SplatPath, SplatRenderer};
    use crate::{Camera, Environment, GpuContext, Shading, Splat};

    /// A compute path the adapter chose gives way to raster where it cannot
    /// read the draw arguments; one the caller set reports the error.
    #[test]
    fn a_chosen_compute_path_gives_way_and_a_set_one_reports() {
        let Some(ctx) = GpuContext::headless_or_skip() else {
            return;
        };
        let buffer = |size, usage| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: None,
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let (splats, args) = (buffer(64, U::STORAGE), buffer(16, U::INDIRECT));
        let mut r = SplatRenderer::new(ctx, 32, 32, &Environment::procedural()).unwrap();
        // As on a GPU adapter: the compute path, chosen.
        r.set_splat_path(ctx, SplatPath::Compute).unwrap();
        r.chosen = true;
        r.use_gpu_splats(ctx, &splats, &args).unwrap();
        assert_eq!(r.splat_path(), SplatPath::Raster);
        assert!(r.compute.is_none() && !r.chosen);

        // Asked for by the caller, it is refused with the same reason.
        let err = r.set_splat_path(ctx, SplatPath::Compute).unwrap_err();
        assert!(err.to_string().contains("storage buffer"), "{err}");
        assert_eq!(r.splat_path(), SplatPath::Raster);
        let mut r = SplatRenderer::new(ctx, 32, 32, &Environment::procedural()).unwrap();
        r.set_splat_path(ctx, SplatPath::Compute).unwrap();
        let err = r.use_gpu_splats(ctx, &splats, &args).unwrap_err();
        assert!(err.to_string().contains("storage buffer"), "{err}");
        assert_eq!(r.splat_path(), SplatPath::Compute);
    }

    /// A chosen compute path whose frames need more tile-list entries than
    /// one binding holds (the limit lowered here) gives way to raster.
    #[test]
    fn a_chosen_compute_path_gives_way_past_the_lists_limit() {
        let Some(ctx) = GpuContext::headless_or_skip() else {
            return;
        };
        let mut r = SplatRenderer::new(ctx, 32, 32, &Environment::procedural()).unwrap();
        r.set_splat_path(ctx, SplatPath::Compute).unwrap();
        r.chosen = true;
        r.compute.as_mut().unwrap().limit_entries(64);
        let big: Vec<Splat> = (0..100)
            .map(|i| Splat::new(Vec3::new(0.0, 0.0, -0.001 * i as f32), Vec3::Z, 2.0))
            .collect();
        let camera = Camera::looking_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO);
        for _ in 0..2 {
            r.upload(ctx, &big).unwrap();
            assert_eq!(r.splat_path(), SplatPath::Compute);
            r.render(ctx, &camera, &Shading::default()).unwrap();
            ctx.device
                .poll(wgpu::PollType::wait_indefinitely())
                .unwrap();
        }
        r.upload(ctx, &big).unwrap();
        assert_eq!(r.splat_path(), SplatPath::Raster);
    }
}
