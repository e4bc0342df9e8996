//! Copying textures back to the CPU, and the float view of the accumulation target.

use glam::Vec3;

use crate::context::GpuContext;
use crate::error::{RenderError, Result};

/// The attribute pass's accumulation target read back: per pixel Σ wᵢ nᵢ (world
/// normals) and Σ wᵢ, row-major from the top-left pixel.
#[derive(Clone, Debug)]
pub struct Accumulation {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `[Σ w n_x, Σ w n_y, Σ w n_z, Σ w]` per pixel.
    pub texels: Vec<[f32; 4]>,
}

impl Accumulation {
    pub(crate) fn from_bytes(
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
        bytes: &[u8],
    ) -> Result<Self> {
        let texels: Vec<[f32; 4]> = match format {
            wgpu::TextureFormat::Rgba32Float => bytemuck::pod_collect_to_vec(bytes),
            wgpu::TextureFormat::Rgba16Float => bytes
                .chunks_exact(8)
                .map(|t| {
                    let h = |i: usize| f16_to_f32(u16::from_le_bytes([t[2 * i], t[2 * i + 1]]));
                    [h(0), h(1), h(2), h(3)]
                })
                .collect(),
            other => {
                return Err(RenderError::Readback(format!(
                    "unexpected accumulation format {other:?}"
                )));
            }
        };
        if texels.len() != (width * height) as usize {
            return Err(RenderError::Readback("accumulation size mismatch".into()));
        }
        Ok(Self {
            width,
            height,
            texels,
        })
    }

    /// Σ w at pixel `(x, y)`.
    ///
    /// # Panics
    /// If `(x, y)` lies outside the image.
    pub fn weight(&self, x: u32, y: u32) -> f32 {
        self.texels[self.index(x, y)][3]
    }

    /// The texel of pixel `(x, y)`, which must lie inside the image: a
    /// column past the width would otherwise read the next row's pixel.
    fn index(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside the {}×{} image",
            self.width,
            self.height
        );
        y as usize * self.width as usize + x as usize
    }

    /// The normalised attribute A = Σ wᵢ nᵢ / Σ wᵢ at `(x, y)` (not renormalised
    /// to unit length), or `None` where Σ w = 0.
    ///
    /// # Panics
    /// If `(x, y)` lies outside the image.
    pub fn normalised(&self, x: u32, y: u32) -> Option<Vec3> {
        let [a, b, c, w] = self.texels[self.index(x, y)];
        (w > 0.0).then(|| Vec3::new(a, b, c) / w)
    }

    /// Pixels with Σ w > 0.
    pub fn covered(&self) -> usize {
        self.texels.iter().filter(|t| t[3] > 0.0).count()
    }
}

/// Reads any 4-byte-per-texel colour texture (`Rgba8Unorm`, `Rgba8UnormSrgb`,
/// …) of the device back as an image, bytes unchanged. Useful to check what
/// was drawn onto an offscreen stand-in for a window surface.
///
/// # Errors
/// [`RenderError::Readback`] when the texture is not 4 bytes per texel, cannot
/// be copied from (no `COPY_SRC` usage, multisampled), is larger than the
/// device's largest buffer, or the copy fails.
pub fn read_texture_rgba8(ctx: &GpuContext, texture: &wgpu::Texture) -> Result<image::RgbaImage> {
    if texture.format().block_copy_size(None) != Some(4) {
        return Err(RenderError::Readback(format!(
            "{:?} is not 4 bytes per texel",
            texture.format()
        )));
    }
    let bytes = read_texture(ctx, texture, wgpu::TextureAspect::All, 4)?;
    image::RgbaImage::from_raw(texture.width(), texture.height(), bytes)
        .ok_or_else(|| RenderError::Readback("image size mismatch".into()))
}

/// IEEE half → single precision.
fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = (h >> 10) & 0x1f;
    let frac = f32::from(h & 0x3ff);
    sign * match exp {
        0 => frac * 2f32.powi(-24),
        31 if frac == 0.0 => f32::INFINITY,
        31 => f32::NAN,
        e => (1.0 + frac / 1024.0) * 2f32.powi(i32::from(e) - 15),
    }
}

/// Copies a whole 2D texture to the CPU, removing the 256-byte row padding.
/// What wgpu would reject as a validation error (a panic without an error
/// scope) is a [`RenderError::Readback`] instead.
pub(crate) fn read_texture(
    ctx: &GpuContext,
    texture: &wgpu::Texture,
    aspect: wgpu::TextureAspect,
    bytes_per_texel: u32,
) -> Result<Vec<u8>> {
    if !texture.usage().contains(wgpu::TextureUsages::COPY_SRC) || texture.sample_count() != 1 {
        return Err(RenderError::Readback(format!(
            "a texture of usage {:?} and {} samples cannot be read back: it needs COPY_SRC and one sample",
            texture.usage(),
            texture.sample_count()
        )));
    }
    let (width, height) = (texture.width(), texture.height());
    let row = u64::from(width) * u64::from(bytes_per_texel);
    let align = u64::from(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
    let padded = row.div_ceil(align) * align;
    let size = padded * u64::from(height);
    let max = ctx.device.limits().max_buffer_size;
    let (Ok(padded), Ok(row), true) = (u32::try_from(padded), usize::try_from(row), size <= max)
    else {
        return Err(RenderError::Readback(format!(
            "a {width}×{height} texture of {bytes_per_texel} bytes per texel needs a {size}-byte buffer, more than the device's {max}"
        )));
    };
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(height),
            },
        },
        texture.size(),
    );
    let mapped = submit_and_map(ctx, encoder, &buffer)?;
    let mut out = Vec::with_capacity(row * height as usize);
    for r in 0..height as usize {
        let start = r * padded as usize;
        out.extend_from_slice(&mapped[start..start + row]);
    }
    Ok(out)
}

/// Copies a whole storage buffer (made with `COPY_SRC`) to the CPU.
pub(crate) fn read_buffer(ctx: &GpuContext, source: &wgpu::Buffer) -> Result<Vec<u8>> {
    if !source.usage().contains(wgpu::BufferUsages::COPY_SRC) {
        return Err(RenderError::Readback(format!(
            "a buffer of usage {:?} cannot be read back: it needs COPY_SRC",
            source.usage()
        )));
    }
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: source.size(),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(source, 0, &buffer, 0, source.size());
    Ok(submit_and_map(ctx, encoder, &buffer)?.to_vec())
}

/// Submits `encoder`, which copies into `buffer`, and maps `buffer` once the
/// copy is done; [`RenderError::Device`] where the device has reported a
/// fault ([`GpuContext::check`]).
fn submit_and_map(
    ctx: &GpuContext,
    encoder: wgpu::CommandEncoder,
    buffer: &wgpu::Buffer,
) -> Result<wgpu::BufferView> {
    ctx.queue.submit([encoder.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    rx.recv()
        .map_err(|e| RenderError::Readback(e.to_string()))?
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    // A fault of the device since it was made (targets it could not
    // allocate, say) means what was copied is not the render.
    ctx.check()?;
    buffer
        .get_mapped_range(..)
        .map_err(|e| RenderError::Readback(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_floats_decode() {
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x3555), 0.333_251_95);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
    }

    /// A pixel past the width panics, as documented, instead of reading
    /// the next row's.
    #[test]
    fn pixels_outside_the_image_panic() {
        let acc = Accumulation {
            width: 2,
            height: 2,
            texels: vec![[0.0, 0.0, 1.0, 1.0]; 4],
        };
        assert_eq!(acc.weight(1, 1), 1.0);
        for (x, y) in [(2, 0), (0, 2)] {
            let read = std::panic::catch_unwind(|| acc.weight(x, y));
            assert!(read.is_err(), "({x}, {y})");
            assert!(std::panic::catch_unwind(|| acc.normalised(x, y)).is_err());
        }
    }
}
