//! The renderer's textures: the render targets of one size, and the
//! environment map and background the scene and shade passes sample.

use image::RgbaImage;

use crate::context::GpuContext;
use crate::error::{RenderError, Result};
use crate::textures::Environment;

/// The depth buffer's format (scene, visibility and back surface).
pub(super) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Format of the scene pass's image (what the fluid refracts).
pub(super) const SCENE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Format of the shaded output image.
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Render targets of one size.
pub(super) struct Targets {
    pub(super) width: u32,
    pub(super) height: u32,
    /// The scene's depth, then the splats' visibility depth over it.
    pub(super) depth: wgpu::Texture,
    pub(super) depth_view: wgpu::TextureView,
    /// The scene pass's image: backdrop and geometry.
    pub(super) scene_view: wgpu::TextureView,
    /// The farthest back-facing splat, or the geometry where nearer.
    pub(super) back_depth_view: wgpu::TextureView,
    pub(super) accum: wgpu::Texture,
    pub(super) accum_view: wgpu::TextureView,
    pub(super) output: wgpu::Texture,
    pub(super) output_view: wgpu::TextureView,
}

impl Targets {
    /// The targets of a `width`×`height` image, accumulating in `accum_format`.
    pub(super) fn new(
        device: &wgpu::Device,
        width: u32,
        height: u32,
        accum_format: wgpu::TextureFormat,
    ) -> Self {
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
        Self {
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
}

/// A `width`×`height` image this device can render.
///
/// # Errors
/// [`RenderError::InvalidSize`] for a zero side or one past the device's
/// texture limit.
pub(super) fn check_size(ctx: &GpuContext, width: u32, height: u32) -> Result<()> {
    let max = ctx.device.limits().max_texture_dimension_2d;
    if width == 0 || height == 0 || width > max || height > max {
        return Err(RenderError::InvalidSize { width, height, max });
    }
    Ok(())
}

/// The environment map and the background on the GPU, with their samplers:
/// what the scene pass draws behind the geometry and the shade pass
/// reflects and refracts.
pub(super) struct Surroundings {
    pub(super) environment: wgpu::TextureView,
    pub(super) background: wgpu::TextureView,
    pub(super) env_sampler: wgpu::Sampler,
    pub(super) back_sampler: wgpu::Sampler,
}

impl Surroundings {
    /// `env` uploaded, with its samplers.
    pub(super) fn new(ctx: &GpuContext, env: &Environment) -> Self {
        let (environment, background) = upload_environment(ctx, env);
        let env_sampler = ctx.device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("environment sampler"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::ClampToEdge,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let back_sampler = ctx.device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("background sampler"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        Self {
            environment,
            background,
            env_sampler,
            back_sampler,
        }
    }

    /// Replaces the images, keeping the samplers.
    pub(super) fn set(&mut self, ctx: &GpuContext, env: &Environment) {
        (self.environment, self.background) = upload_environment(ctx, env);
    }
}

/// The environment map and the background, uploaded: (environment, background).
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
